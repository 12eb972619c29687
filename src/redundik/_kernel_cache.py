"""Where numba caches redundik's compiled kernels: a folder of the user's cache named by a stamp of every source.

Numba stamps a cached function with the hash of its own file only. A kernel that calls a kernel of another module
(``hqp_fused.fused_hqp_step`` → ``hqp_kernels.closed_step`` → ``kernels.damped_svd_factors``) has that code
compiled into it, and module constants (``fused.HEADER``, ``trajectory.CIRCLE``) frozen in: after that other module
changes, numba alone would load stale machine code. Here that cannot happen: every kernel is cached in
``<cache root>/kernels-<stamp>``, the stamp hashing every file of :data:`KERNEL_SOURCES` and the numba, NumPy and
Python versions, so that any change to any of them starts a new, empty folder. Only numba's public configuration is
used (``numba.config.CACHE_DIR``, set while :func:`jit` decorates a kernel and restored at once, so that the
user's own numba functions keep their cache folder).

The cache root is ``$REDUNDIK_CACHE_DIR`` when set, else the user's cache folder (``$XDG_CACHE_HOME/redundik`` or
``~/.cache/redundik``; ``~/Library/Caches/redundik`` on macOS, ``%LOCALAPPDATA%/redundik/Cache`` on Windows): a
read-only site-packages is never written to. When that folder cannot be created the kernels are compiled without an
on-disk cache (compiled again in each process, never stale).
"""

from __future__ import annotations

import hashlib
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

#: The package's root folder.
PACKAGE_ROOT = Path(__file__).resolve().parent
#: Environment variable naming the cache root (overrides the user cache folder).
CACHE_ENV = "REDUNDIK_CACHE_DIR"
#: Every redundik source compiled code depends on: the modules with compiled functions and the modules whose
#: constants or functions they import (checked against the imports by ``tests/test_kernel_cache.py``).
KERNEL_SOURCES: tuple[str, ...] = (
    "kinematics/lie_kernels.py",
    "_kernel_cache.py",
    "resolvers/kernels.py",
    "resolvers/qr_kernels.py",
    "resolvers/svd_kernels.py",
    "resolvers/damping_kernels.py",
    "resolvers/cholesky_kernels.py",
    "resolvers/box_kernels.py",
    "resolvers/layouts.py",
    "resolvers/hqp_kernels.py",
    "resolvers/fused_kernels.py",
    "resolvers/hqp_fused.py",
    "resolvers/hqp_layout.py",
    "resolvers/hqp_algebra.py",
    "resolvers/hqp_level_qp.py",
    "resolvers/hqp_native.py",
    "resolvers/hqp_cascade.py",
    "resolvers/fused.py",
    "tasks/trajectory.py",
    "tasks/target_kernels.py",
    "tasks/row_kernels.py",
    "tasks/potential_kernels.py",
    "collision/kernels.py",
    "ik/kernels.py",
    "resolvers/jerk_kernels.py",
)

#: Every kernel :func:`jit` made: ``{module name: {function name: numba dispatcher}}`` (read by
#: :mod:`redundik._coldstart` to run the same code interpreted while it compiles).
KERNELS: dict[str, dict[str, Any]] = {}

_stamps: dict[Path, str] = {}


def sources_stamp(root: Path = PACKAGE_ROOT) -> str:
    """Hex SHA-256 (16 digits) of :data:`KERNEL_SOURCES` under ``root`` (names and contents; a missing file counts
    as ``<missing>``) and of the numba, NumPy and Python versions; computed once per root and process."""
    stamp = _stamps.get(root)
    if stamp is None:
        import numba
        import numpy

        h = hashlib.sha256()
        for part in (numba.__version__, numpy.__version__, sys.version, sys.platform):
            h.update(part.encode() + b"\0")
        for rel in KERNEL_SOURCES:
            h.update(rel.encode() + b"\0")
            try:
                h.update((root / rel).read_bytes())
            except OSError:
                h.update(b"<missing>")
        stamp = _stamps[root] = h.hexdigest()[:16]
    return stamp


def cache_root() -> Path:
    """The folder under which the kernels' stamped folders live: ``$REDUNDIK_CACHE_DIR``, else the user cache."""
    env = os.environ.get(CACHE_ENV)
    if env:
        return Path(env).expanduser()
    if sys.platform == "win32":  # pragma: no cover - not the CI's platform
        base = Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
        return base / "redundik" / "Cache"
    if sys.platform == "darwin":  # pragma: no cover - not the CI's platform
        return Path.home() / "Library" / "Caches" / "redundik"
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg and Path(xdg).is_absolute() else Path.home() / ".cache") / "redundik"


def cache_dir() -> Path:
    """The folder of this install's compiled kernels: ``<cache root>/kernels-<stamp>``."""
    return cache_root() / f"kernels-{sources_stamp()}"


_writable_memo: dict[Path, bool] = {}


def _writable(folder: Path) -> bool:
    known = _writable_memo.get(folder)
    if known is None:
        known = _writable_memo[folder] = _make_writable(folder)
    return known


def _make_writable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    return os.access(folder, os.W_OK | os.X_OK)


def jit(fn: Callable[..., Any]) -> Any:
    """``numba.njit(cache=True, nogil=True)`` with the cache in :func:`cache_dir` (``cache=False`` when that folder
    cannot be written); numba's configured cache folder is restored after the decoration."""
    import numba

    folder = cache_dir()
    cached = _writable(folder)
    config: Any = numba.config  # (its settings are set from the environment at import: untyped)
    saved = config.CACHE_DIR
    config.CACHE_DIR = str(folder) if cached else saved
    try:
        dispatcher = numba.njit(cache=cached, nogil=True)(fn)
    finally:
        config.CACHE_DIR = saved
    KERNELS.setdefault(fn.__module__, {})[fn.__name__] = dispatcher
    return dispatcher


class KernelNamespace:
    """The compiled kernels of a module (a dotted name), imported on first use (numba loads then, not when redundik
    is imported); after the first access every kernel is a plain attribute. A cold start
    (:mod:`redundik._coldstart`) puts the kernels' interpreted twins in these namespaces while they compile."""

    def __init__(self, module: str) -> None:
        self.__dict__["_module"] = module

    def __getattr__(self, name: str) -> Any:
        import importlib

        kernels = importlib.import_module(self.__dict__["_module"])
        self.__dict__.update({k: v for k, v in vars(kernels).items() if not k.startswith("__")})
        return getattr(kernels, name)
