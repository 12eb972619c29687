"""No cold-start stall: the first steps run the kernels' own code interpreted while a thread compiles them.

A resolver's first step in a process asks :func:`ready` whether its compiled kernels are loaded. When they are not,
a background thread runs :func:`redundik.warmup.warm_up` for that resolver from its second step on (compiling the
kernels into the on-disk cache of :mod:`redundik._kernel_cache`, or loading them from it), and until it is done:

* the resolver takes its per-task path (``info["path"] == "interpreted"``), not the fused step;
* every kernel that path calls runs as its *twin*: the kernel's own Python function (``py_func``), run by the
  interpreter with NumPy, its calls to other kernels bound to their twins — the same code, so the same answers to
  rounding, and no compilation in the caller's thread.

The twins are put in the lazy kernel namespaces of :mod:`redundik.resolvers.linalg` (``K``, ``FK``, ``HK``: every
resolver and task reaches its kernels through them) and in place of any kernel bound in a module global; the kernel
modules themselves are never touched (numba reads their globals when it compiles). ``Resolver.step``'s check of q,
which runs before the resolver asks, takes the twin while :func:`cold`. The cost, measured: an interpreted ``pinv``
step of a 7-joint arm 0.17 ms on the twins, 0.3–0.4 ms while the thread compiles (it holds the interpreter's lock
for much of its work; single steps up to some 60 ms). When the thread is done it puts
the compiled kernels back, and the resolver takes its compiled step from its next step on: no indirection is left
on the hot path.

``REDUNDIK_COLD_START=wait`` turns this off: the first step compiles in the caller's thread (numba's default).
"""

from __future__ import annotations

import atexit
import logging
import os
import sys
import threading
import types
from typing import Any

from redundik import _kernel_cache

_LOG = logging.getLogger("redundik")

#: Environment variable: ``background`` (the default) or ``wait``.
MODE_ENV = "REDUNDIK_COLD_START"

#: Resolvers whose kernels are loaded (their steps take the compiled path).
HOT: set[str] = set()
_pending: list[str] = []  # resolvers the thread is to warm up, in order
_compilers: set[int] = set()  # threads that compile: they call the kernels themselves, never the twins
_lock = threading.Lock()
_worker: threading.Thread | None = None
_saved: list[tuple[dict[str, Any], str, Any]] = []  # (namespace, key, original) of every switch put in place
_twins: dict[int, Any] = {}  # id(dispatcher) → its twin
#: ``redundik.warmup.warm_up``, set by the package's facade (this base module imports nothing above it).
WARM_UP: Any = None


def background() -> bool:
    """Whether a cold start compiles in the background (``REDUNDIK_COLD_START`` is not ``wait``)."""
    return os.environ.get(MODE_ENV, "background").strip().lower() != "wait"


def ready(resolver: str) -> bool:
    """True when ``resolver``'s compiled kernels are loaded (or this thread compiles them): its step may take the
    compiled path. Otherwise puts the kernels' twins in place and returns False (the step runs interpreted); the
    background thread that compiles them starts at the next call, so that the first step does not share the
    interpreter with it."""
    if resolver in HOT:
        return True
    if threading.get_ident() in _compilers:
        return True
    if not background():
        HOT.add(resolver)
        return True
    with _lock:
        if resolver in HOT:  # (made hot while this thread waited for the lock)
            return True
        if resolver not in _pending:  # the thread starts at the next call: this first step runs uncontended
            _pending.append(resolver)
            _install()
        else:
            _start()
    return False


def cold() -> bool:
    """True while no resolver's kernels are loaded in a background-compiling process (outside a compiling thread):
    a kernel called now would compile in the caller's thread, its twin (:func:`twin`) does not."""
    return not HOT and background() and threading.get_ident() not in _compilers


def wait(timeout: float | None = None) -> bool:
    """Block until the background thread is done (at most ``timeout`` seconds); True when it is."""
    with _lock:
        if _pending:
            _start()
    worker = _worker
    if worker is not None:
        worker.join(timeout)
        return not worker.is_alive()
    return True


def compiling() -> Any:
    """A context manager marking the current thread as compiling: its kernel calls go to numba, never the twins,
    and :func:`ready` answers True (``warm_up`` runs in it)."""
    return _Compiling()


class _Compiling:
    def __enter__(self) -> None:
        self.ident = threading.get_ident()
        self.outer = self.ident in _compilers
        _compilers.add(self.ident)

    def __exit__(self, *exc: object) -> None:
        if not self.outer:
            _compilers.discard(self.ident)


def _start() -> None:
    """Start the background thread if it is not running (under ``_lock``)."""
    global _worker
    if _worker is not None and _worker.is_alive():
        return
    _LOG.warning(
        "redundik: compiling the kernels of %s in the background (cache: %s); steps run interpreted until then",
        ", ".join(_pending),
        _kernel_cache.cache_dir(),
    )
    if _worker is None:
        atexit.register(_at_exit)
    _worker = threading.Thread(target=_run, name="redundik-compile", daemon=True)
    _worker.start()


def _at_exit() -> None:
    """Say so when the process ends before the background compilation (what it finished stays cached)."""
    if _worker is not None and _worker.is_alive():
        _LOG.warning(
            "redundik: the process ended while the kernels of %s were compiling (what was finished is cached in %s); "
            "`redundik compile` or rk.warm_up() completes the cache",
            ", ".join(_pending),
            _kernel_cache.cache_dir(),
        )


def _run() -> None:
    """The background thread: warm up each pending resolver, then hand them to :func:`ready`."""
    warm_up = WARM_UP
    if warm_up is None:  # (the package's facade sets it: ``redundik/__init__.py``)
        _LOG.warning("redundik: no warm-up registered; the kernels compile at their first call instead")
        with _lock:
            HOT.update(_pending)
            _pending.clear()
        return

    while True:
        with _lock:
            if not _pending:
                return
            name = _pending[0]
        try:
            seconds = warm_up([name])[name]
            _LOG.info("redundik: the kernels of %s are ready (%.1f s in the background)", name, seconds)
        except Exception as exc:
            _LOG.warning("redundik: compiling the kernels of %s in the background failed: %s", name, exc)
        with _lock:
            _pending.remove(name)
            HOT.add(name)
            if not _pending:  # the compiled kernels back in every namespace (a dict assignment each: atomic)
                _restore()


class _Switch:
    """A kernel as its namespaces hold it during a cold start: numba's dispatcher in a compiling thread, its twin in
    any other (a compiled kernel called there with other argument types would compile, in the caller's thread)."""

    __slots__ = ("kernel", "twin")

    def __init__(self, kernel: Any, twin: Any) -> None:
        self.kernel, self.twin = kernel, twin

    def __call__(self, *args: Any) -> Any:
        if not _saved or threading.get_ident() in _compilers:  # (a switch kept by a caller past the restore)
            return self.kernel(*args)
        return self.twin(*args)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.kernel, name)


def twin(kernel: Any) -> Any:
    """The twin of a kernel made by :func:`redundik._kernel_cache.jit`: its Python function with every kernel it
    calls bound to that kernel's twin (built for all kernels at the first request)."""
    if isinstance(kernel, _Switch):  # (a namespace holds the kernel's switch during a cold start)
        return kernel.twin
    if id(kernel) not in _twins:
        _build_twins()
    return _twins[id(kernel)]


class _Twins:
    """A kernel namespace seen through its twins (:func:`twins_of`); its other attributes (constants) as they are."""

    def __init__(self, space: Any) -> None:
        self._space = space

    def __getattr__(self, name: str) -> Any:
        value = getattr(self._space, name)
        return twin(value) if isinstance(value, _Switch) or hasattr(value, "py_func") else value


_twin_spaces: dict[int, _Twins] = {}


def twins_of(space: Any) -> Any:
    """``space`` (a :class:`~redundik._kernel_cache.KernelNamespace`) while no resolver's kernels are loaded in a
    background-compiling process (:func:`cold`): a view of it whose kernels are their twins — for a kernel called
    before the first step (``FrameTask.set_target`` ahead of the loop), which would otherwise compile in the
    caller's thread. Otherwise ``space`` itself. Costs a set's truth test once a resolver is hot."""
    if HOT or not cold():
        return space
    view = _twin_spaces.get(id(space))
    if view is None:
        view = _twin_spaces[id(space)] = _Twins(space)
    return view


def _build_twins() -> None:
    dispatchers = {id(d): d for funcs in _kernel_cache.KERNELS.values() for d in funcs.values()}
    spaces: dict[str, dict[str, Any]] = {}
    for mod_name, funcs in _kernel_cache.KERNELS.items():
        space = spaces[mod_name] = dict(vars(sys.modules[mod_name]))
        for disp in funcs.values():
            f = disp.py_func
            fn = types.FunctionType(f.__code__, space, f.__name__, f.__defaults__, f.__closure__)
            fn.__kwdefaults__ = f.__kwdefaults__
            _twins[id(disp)] = fn
    for space in spaces.values():
        for key, value in list(space.items()):
            if id(value) in dispatchers and dispatchers[id(value)] is value:
                space[key] = _twins[id(value)]


def _install(compiled_too: bool = False) -> None:
    """Put switches in place of the kernels in redundik's namespaces (the kernel modules excepted): the lazy kernel
    namespaces of :mod:`redundik.resolvers.linalg` (loaded first) and any kernel bound in a module global. A kernel
    this process has compiled already keeps its place (a resolver made hot before stays compiled) unless
    ``compiled_too`` (tests)."""
    if _saved:
        return

    spaces: dict[int, dict[str, Any]] = {}
    for mod_name in [m for m in sys.modules if m.startswith("redundik.") and m not in _kernel_cache.KERNELS]:
        space = vars(sys.modules[mod_name])
        spaces[id(space)] = space
        for value in list(space.values()):
            if isinstance(value, _kernel_cache.KernelNamespace):
                value.__getattr__("__name__")  # imports its module and fills its namespace
                spaces[id(value.__dict__)] = value.__dict__
    _build_twins()  # (after the namespaces loaded their modules)
    kernels = {id(d): d for funcs in _kernel_cache.KERNELS.values() for d in funcs.values()}
    for space in spaces.values():
        for key, value in list(space.items()):
            if id(value) in kernels and kernels[id(value)] is value and (compiled_too or not value.signatures):
                _saved.append((space, key, value))
                space[key] = _Switch(value, _twins[id(value)])


def _restore() -> None:
    """Put the compiled kernels back wherever a switch is (under ``_lock``; a foreground step meanwhile meets either
    the switch or the kernel: the same answers)."""
    for space, key, value in _saved:
        if isinstance(space.get(key), _Switch):
            space[key] = value
    _saved.clear()
    for mod_name in [m for m in sys.modules if m.startswith("redundik.")]:  # kernels bound to a switch later
        space = vars(sys.modules[mod_name])
        for key, value in list(space.items()):
            if isinstance(value, _Switch):
                space[key] = value.kernel
