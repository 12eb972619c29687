"""Numba's on-disk cache of redundik's compiled kernels, stamped with every source they are compiled from.

Numba stamps a cached function with the hash of its own file only. A kernel that calls a kernel of another module
(``fused_kernels.fused_hqp_step`` → ``hqp_kernels.closed_step`` → ``kernels.damped_svd_factors``) has that code
compiled into it, and module constants (``fused.HEADER``, ``trajectory.CIRCLE``) frozen in: after that other module
changes — an edit, or an upgrade, since pip leaves the old cache files in ``__pycache__`` — numba would load the
stale machine code and the step would silently compute the old answer (seen here: ``hqp``'s fused step kept a
damping rule its own module no longer had). The locators below give every function of redundik's files the stamp
(numba's own, the hash of :data:`KERNEL_SOURCES`), so that a change to any of them recompiles all of them.

If numba's locator list is not where this module expects it (a numba release that moved it), nothing is installed
and numba's own stamps apply; the tests check that the locator is in use.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Any

#: The package's root folder.
PACKAGE_ROOT = Path(__file__).resolve().parent
#: Every redundik source compiled code depends on: the modules with compiled functions and the modules whose
#: constants or functions they import (checked against the imports by ``tests/test_kernel_cache.py``).
KERNEL_SOURCES: tuple[str, ...] = (
    "kinematics/lie_kernels.py",
    "resolvers/kernels.py",
    "resolvers/hqp_kernels.py",
    "resolvers/fused_kernels.py",
    "resolvers/fused.py",
    "tasks/trajectory.py",
    "tasks/target_kernels.py",
    "tasks/potential_kernels.py",
    "collision/kernels.py",
    "ik/kernels.py",
    "resolvers/jerk_kernels.py",
)

_memo: dict[tuple[object, ...], bytes] = {}


def sources_stamp(root: Path = PACKAGE_ROOT) -> bytes:
    """SHA-256 of :data:`KERNEL_SOURCES` under ``root`` (names and contents; a missing file counts as empty),
    memoised on the files' modification times and sizes."""
    paths = [root / rel for rel in KERNEL_SOURCES]
    key: list[object] = [str(root)]
    for p in paths:
        try:
            st = os.stat(p)
            key.append((st.st_mtime_ns, st.st_size))
        except OSError:
            key.append(None)
    memo_key = tuple(key)
    stamp = _memo.get(memo_key)
    if stamp is None:
        h = hashlib.sha256()
        for rel, p in zip(KERNEL_SOURCES, paths, strict=True):
            h.update(rel.encode())
            try:
                h.update(p.read_bytes())
            except OSError:
                h.update(b"<missing>")
        stamp = _memo[memo_key] = h.digest()
    return stamp


def _ours(py_file: str) -> bool:
    try:
        return Path(py_file).resolve().is_relative_to(PACKAGE_ROOT)
    except (OSError, ValueError):
        return False


_installed = False


def install() -> bool:
    """Put the redundik-stamped locators first in numba's list (idempotent); True when they are in place. Called by
    each kernel module before its first compiled function is defined."""
    global _installed
    if _installed:
        return True
    try:
        from numba.core import caching
    except ImportError:  # pragma: no cover - numba is a dependency of the core
        return False

    def named(name: str) -> Any:  # numba 0.6x names them with a leading underscore, later releases without
        return getattr(caching, name, None) or getattr(caching, f"_{name}", None)

    impl = named("CacheImpl")
    bases = [named(n) for n in ("UserProvidedCacheLocator", "InTreeCacheLocator", "UserWideCacheLocator")]
    if impl is None or not isinstance(getattr(impl, "_locator_classes", None), list) or None in bases:
        return False
    ours = []
    for base in bases:
        ours.append(_stamped(base))
    impl._locator_classes[:0] = ours
    _installed = True
    return True


def _stamped(base: Any) -> Any:
    """A subclass of numba's locator ``base`` for redundik's files only, stamped with :func:`sources_stamp`."""

    class Stamped(base):  # type: ignore[misc]
        @classmethod
        def from_function(cls, py_func: Any, py_file: str) -> Any:
            if not _ours(py_file):
                return None
            return super().from_function(py_func, py_file)

        def get_source_stamp(self) -> Any:
            return (super().get_source_stamp(), sources_stamp())

    Stamped.__name__ = Stamped.__qualname__ = f"Redundik{base.__name__}"
    return Stamped
