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
import logging
import os
import sys
import threading
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
    "kinematics/layouts.py",
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
    "resolvers/hqp_cascade_call.py",
    "resolvers/hqp_selection.py",
    "resolvers/fused.py",
    "tasks/trajectory.py",
    "tasks/layouts.py",
    "tasks/target_kernels.py",
    "tasks/row_kernels.py",
    "tasks/potential_kernels.py",
    "collision/kernels.py",
    "collision/layouts.py",
    "ik/kernels.py",
    "ik/layouts.py",
    "resolvers/jerk_kernels.py",
    "resolvers/batch_kernels.py",
    "resolvers/feedback_kernels.py",
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
        if not known:  # (said once per folder: every process then compiles every kernel, tens of seconds)
            logging.getLogger("redundik").warning(
                "redundik: the kernel cache folder %s cannot be created or written: the kernels compile in every "
                "process, uncached; set %s to a writable folder (or `redundik compile` where it can write)",
                folder,
                CACHE_ENV,
            )
    return known


def _make_writable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    return os.access(folder, os.W_OK | os.X_OK)


#: While True, :func:`jit` returns the function itself and numba is not imported (:func:`defer_numba`).
_deferred = False
#: The functions :func:`jit` returned undecorated, and the module globals made later (:func:`later`), in the order
#: they were made; :func:`materialize` turns them into numba's objects.
_pending_kernels: list[Callable[..., Any]] = []
_pending_globals: list[tuple[str, str, Callable[[], Any]]] = []
_pending_ids: set[int] = set()
#: Called when a kernel namespace is first used while numba is deferred (``_coldstart`` schedules the
#: decoration then, so that no process keeps running the kernels' Python code).
FIRST_USE: list[Callable[[], None]] = []
#: function → its dispatcher, for the functions :func:`materialize` decorated.
DISPATCHERS: dict[int, Any] = {}
_materialize_lock = threading.RLock()


def defer_numba() -> None:
    """Make :func:`jit` return functions undecorated until :func:`materialize` (numba not imported meanwhile: about
    0.2 s of a process's start), when numba is not imported yet. A background cold start does it
    (:mod:`redundik._coldstart`): the first steps run the kernels' own code anyway."""
    global _deferred
    with _materialize_lock:
        if "numba" not in sys.modules:
            _deferred = True


def is_kernel(value: Any) -> bool:
    """Whether ``value`` is a kernel :func:`jit` made: a dispatcher, or a function while numba is deferred."""
    return hasattr(value, "py_func") or id(value) in _pending_ids


def deferred() -> bool:
    """Whether kernels made now stay undecorated (numba not imported yet)."""
    return _deferred


def _decorate(fn: Callable[..., Any]) -> Any:
    import numba

    folder = cache_dir()
    cached = _writable(folder)
    config: Any = numba.config  # (its settings are set from the environment at import: untyped)
    saved = config.CACHE_DIR
    config.CACHE_DIR = str(folder) if cached else saved
    try:
        return numba.njit(cache=cached, nogil=True)(fn)
    finally:
        config.CACHE_DIR = saved


def jit(fn: Callable[..., Any]) -> Any:
    """``numba.njit(cache=True, nogil=True)`` with the cache in :func:`cache_dir` (``cache=False`` when that folder
    cannot be written); numba's configured cache folder is restored after the decoration. While numba is deferred
    (:func:`defer_numba`) the function itself, decorated by :func:`materialize`."""
    with _materialize_lock:
        if _deferred:
            _pending_kernels.append(fn)
            _pending_ids.add(id(fn))
            KERNELS.setdefault(fn.__module__, {})[fn.__name__] = fn
            return fn
    dispatcher = _decorate(fn)
    KERNELS.setdefault(fn.__module__, {})[fn.__name__] = dispatcher
    return dispatcher


def later(module: str, name: str, make: Callable[[], Any]) -> Any:
    """A module global that needs numba (a ``numba.extending.intrinsic``): ``make()`` now, or — while numba is
    deferred — a stand-in bound to ``make()`` by :func:`materialize` (called before then: an error)."""
    with _materialize_lock:
        if _deferred:
            _pending_globals.append((module, name, make))

            def stand_in(*args: Any) -> Any:
                raise RuntimeError(f"{module}.{name} needs numba: it is made when the kernels are compiled")

            return stand_in
    return make()


def materialize() -> dict[int, Any]:
    """Import numba and decorate every function :func:`jit` left undecorated: each module global that held one now
    holds its dispatcher (the globals :func:`later` deferred made first). Returns function id → dispatcher."""
    global _deferred
    with _materialize_lock:
        if not _deferred:
            return DISPATCHERS
        import numba  # noqa: F401 - (the import this whole deferral is about)

        for module, name, make in _pending_globals:
            vars(sys.modules[module])[name] = make()
        made = [(fn, _decorate(fn)) for fn in _pending_kernels]
        for fn, disp in made:
            DISPATCHERS[id(fn)] = disp
            KERNELS[fn.__module__][fn.__name__] = disp
        for module in KERNELS:  # (every dispatcher made before any global changes): defined or imported there
            space = vars(sys.modules[module])
            for key, value in list(space.items()):
                disp = DISPATCHERS.get(id(value))
                if disp is not None and disp.py_func is value:
                    space[key] = disp
        _pending_kernels.clear()
        _pending_globals.clear()
        _pending_ids.clear()
        _deferred = False
        return DISPATCHERS


def _never() -> bool:
    return False


def _as_is(kernel: Any) -> Any:
    return kernel


#: Whether a kernel namespace hands out twins now instead of filling itself, and what it hands out for a kernel
#: then: :mod:`redundik._coldstart` sets them (a task file's load in a background-compiling process, no resolver's
#: kernels loaded yet; the kernel's interpreted twin, the kernel itself in a thread that compiles).
SERVE_TWINS: Callable[[], bool] = _never
TWIN_HERE: Callable[[Any], Any] = _as_is


class KernelNamespace:
    """The compiled kernels of a module (a dotted name), imported on first use (numba loads then, not when redundik
    is imported); after the first access every kernel is a plain attribute.

    While :data:`SERVE_TWINS` (a task file's load, before any resolver's kernels are loaded in a background cold
    start: ``_coldstart.loading``) a namespace stays empty and hands out each kernel's interpreted twin
    (:data:`TWIN_HERE`): the load's collision world, task rows and resolver checks run their own code interpreted
    instead of compiling in the caller's thread. It fills itself at its first access after that. A cold start's
    first step fills every namespace and puts switches to the twins in it
    while the kernels compile (:mod:`redundik._coldstart`)."""

    def __init__(self, module: str) -> None:
        self.__dict__["_module"] = module

    def _kernels(self) -> Any:
        """The kernel module, imported on first use."""
        import importlib

        if _deferred:  # (kernels wanted while numba is deferred: decorated soon, whatever the caller does next)
            for hook in FIRST_USE:
                hook()
        # (import_module, not sys.modules: it waits for an import another thread has under way — the cold start's
        # compiling thread — where sys.modules would give the module half made)
        return importlib.import_module(self.__dict__["_module"])

    def fill(self) -> None:
        """Import the module and copy its public names into this namespace (its kernels as the module holds them)."""
        self.__dict__.update({k: v for k, v in vars(self._kernels()).items() if not k.startswith("__")})

    def __getattr__(self, name: str) -> Any:
        value = getattr(self._kernels(), name)
        if SERVE_TWINS():  # (cold: the twin, and the namespace left empty)
            return TWIN_HERE(value) if is_kernel(value) else value
        self.fill()
        return value
