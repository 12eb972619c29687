"""No cold-start stall: the first steps run the kernels' own code interpreted while a thread compiles them.

A resolver's first step in a process asks :func:`ready` whether its compiled kernels are loaded. When they are not,
a background thread runs :func:`redundik.warmup.warm_up` for that resolver from its second step on (compiling the
kernels into the on-disk cache of :mod:`redundik._kernel_cache`, or loading them from it), and until it is done:

* the resolver takes its per-task path (``info["path"] == "interpreted"``), not the fused step;
* every kernel that path calls runs as its *twin*: the kernel's own Python function (``py_func``), run by the
  interpreter with NumPy, its calls to other kernels bound to their twins — the same code, so the same answers to
  rounding, and no compilation in the caller's thread.

The twins are put in the lazy kernel namespaces (:class:`redundik._kernel_cache.KernelNamespace`: ``K``, ``FK``,
``HK`` of the resolvers, the tasks' and the collision world's — every resolver and task reaches its kernels through
one) and in place of any kernel bound in a module global; the kernel modules themselves are never touched (numba
reads their globals when it compiles). ``Resolver.step``'s check of q, which runs before the resolver asks, takes
the twin while :func:`cold`. While a task file loads (:func:`loading`) the namespaces hand out the twins
themselves (:func:`serve_twins`): its collision world, its stacks' rows and a resolver's check compile nothing in the
caller's thread; ``FrameTask.set_target`` ahead of the loop takes its twins itself (:func:`twins_of`).

The cost, measured: an interpreted ``pinv`` step of a 7-joint arm 0.17 ms on the twins, 0.3–0.4 ms while the thread
compiles (it holds the interpreter's lock for much of its work; single steps up to some 60 ms). When the thread is done
it puts the compiled kernels back, and the resolver takes its compiled step from its next step on: no indirection is
left on the hot path.

Numba itself is imported by that thread, not before the first step: ``import redundik`` in a background-compiling
process defers numba (:func:`redundik._kernel_cache.defer_numba`, when no one imported it yet), so the kernel
modules hold their plain functions, which the first steps run as twins; the thread imports numba, decorates them
(:func:`adopt`) and hands the dispatchers to whatever held the functions. Importing numba and decorating the kernels
took about 0.2 s of every first q̇; the first step is now a few milliseconds. An entry point that wants compiled
kernels from its first call (``solve_ik``, the batch API) decorates them at once (:func:`compiled_now`), and the
namespaces hand out the kernels from then on; a process that never steps a resolver decorates them in a thread of
its own :data:`ADOPT_DELAY` after it first uses a kernel (what it reaches through a namespace stays a twin).

``REDUNDIK_COLD_START=wait`` turns this off: numba is imported with the kernels and the first step compiles in the
caller's thread (numba's default).
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import os
import sys
import threading
import types
from collections.abc import Iterator
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
_loading = threading.local()  # its ``depth``: how many :func:`loading` blocks this thread is in
_compiled_wanted = False  # compiled_now() was called: the namespaces hand out the kernels, not their twins
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
    if not background():  # (the first step compiles in this thread; ``wait`` may have been chosen after
        compiled_now()  # ``import redundik`` deferred numba: the kernels are decorated first, never run as functions)
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


def serve_twins() -> bool:
    """True while the kernel namespaces hand out twins rather than fill themselves (:data:`_kernel_cache.SERVE_TWINS
    <redundik._kernel_cache.SERVE_TWINS>`): in this thread, inside :func:`loading` (a task file's load), while no
    resolver's kernels are loaded in a background-compiling process that did not ask for compiled kernels
    (:func:`compiled_now`). Costs an attribute read outside a load."""
    return getattr(_loading, "depth", 0) > 0 and not HOT and not _compiled_wanted and background()


@contextlib.contextmanager
def loading() -> Iterator[None]:
    """Inside: what runs before a loop's first step — a task file's load (its collision world, its stacks' rows, a
    resolver's check) — takes the kernels' interpreted twins while the process is cold (:func:`serve_twins`), so
    that it compiles nothing in the caller's thread. Outside, a kernel called before the first step compiles (or
    loads) as it is called; ``FrameTask.set_target`` ahead of the loop takes its twins itself (:func:`twins_of`)."""
    depth = getattr(_loading, "depth", 0)
    _loading.depth = depth + 1
    try:
        yield
    finally:
        _loading.depth = depth


def twin_here(kernel: Any) -> Any:
    """What a namespace hands out for ``kernel`` while :func:`serve_twins`: its twin (:func:`twin`), or the kernel
    itself in a thread that compiles."""
    return kernel if threading.get_ident() in _compilers else twin(kernel)


def compiled_here() -> bool:
    """True when a kernel called from this thread now runs compiled — not its twin (a resolver's kernels are being
    compiled in the background: every namespace holds switches) nor its plain function (numba not adopted yet). What
    a kernel that calls C through an address needs (daqp's entry, ``hqp_native``): it has no interpreted twin."""
    if _saved:  # (switches in place: only a compiling thread reaches the kernels themselves)
        return threading.get_ident() in _compilers
    if _kernel_cache.deferred():  # (numba not adopted yet: a kernel is still its plain function)
        return False
    if HOT:  # (the common answer, without reading the environment: called at every cascade)
        return True
    return not background() or threading.get_ident() in _compilers


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


#: The interpreter's thread switch interval [s] while the background thread works (:func:`_run`).
SWITCH_INTERVAL = 1e-4


def _run() -> None:
    """The background thread: warm up each pending resolver, then hand them to :func:`ready`.

    Its work (importing numba, loading or compiling the kernels) reads many files, and each read lets the caller's
    thread take the interpreter's lock back for a whole switch interval (5 ms by default): with a step loop that never
    sleeps, that stretches a 1-second job to minutes. The switch interval is :data:`SWITCH_INTERVAL` while the thread
    works, and put back after (unless something else changed it meanwhile)."""
    _with_short_switches(_work)


def _with_short_switches(work: Any) -> None:
    """``work()`` with the switch interval at most :data:`SWITCH_INTERVAL` (see :func:`_run`)."""
    before = sys.getswitchinterval()
    short = min(before, SWITCH_INTERVAL)
    sys.setswitchinterval(short)
    try:
        work()
    finally:
        if sys.getswitchinterval() == short:
            sys.setswitchinterval(before)


def _work() -> None:
    warm_up = WARM_UP
    if warm_up is None:  # (the package's facade sets it: ``redundik/__init__.py``)
        _LOG.warning("redundik: no warm-up registered; the kernels compile at their first call instead")
        with _lock:
            HOT.update(_pending)
            _pending.clear()
        return

    adopt()  # numba imported and the kernels decorated here, not in the caller's thread (when deferred)
    _LOG.warning(
        "redundik: compiling the kernels of %s in the background (cache: %s); steps run interpreted until then",
        ", ".join(_pending),
        _kernel_cache.cache_dir(),
    )
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


_FORK_HELD: list[Any] = []  # the release of each lock :func:`_before_fork` took, in the order taken


def _before_fork() -> None:
    """``os.fork`` in a process whose kernels may be compiling: take the locks that the compiling thread holds while it
    works — numba's compiler lock (compiling or loading a kernel), llvmlite's lock (any LLVM call) and this module's —
    so that the fork happens between two of its kernels. A child forked while that thread held one inherited it
    locked by a thread it does not have: its first compile waited forever (a ``multiprocessing`` pool made during a
    cold start hung). The fork waits at most for the kernel being compiled."""
    compiler = sys.modules.get("numba.core.compiler_lock")
    if compiler is not None:
        lock = compiler.global_compiler_lock
        lock.acquire()
        _FORK_HELD.append(lock.release)
    ffi = sys.modules.get("llvmlite.binding.ffi")
    llvm = getattr(getattr(ffi, "lib", None), "_lock", None)
    if llvm is not None and hasattr(llvm, "__enter__"):
        llvm.__enter__()
        _FORK_HELD.append(lambda: llvm.__exit__(None, None, None))
    _lock.acquire()
    _FORK_HELD.append(_lock.release)


def _after_fork_in_parent() -> None:
    while _FORK_HELD:
        _FORK_HELD.pop()()


def _after_fork_in_child() -> None:
    """The locks released (the forking thread, the child's only one, holds them) and the compiling thread forgotten:
    the child's next step that asks :func:`ready` starts its own thread for what is still pending."""
    _after_fork_in_parent()
    _compilers.clear()


if hasattr(os, "register_at_fork"):  # (POSIX)
    os.register_at_fork(before=_before_fork, after_in_parent=_after_fork_in_parent, after_in_child=_after_fork_in_child)


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
    calls bound to that kernel's twin (built for all kernels at the first request). A twin (what a namespace hands
    out before the first step) is its own twin."""
    if isinstance(kernel, _Switch):  # (a namespace holds the kernel's switch during a cold start)
        return kernel.twin
    if id(kernel) not in _twins:
        if not _kernel_cache.is_kernel(kernel):
            return kernel
        _build_twins()
    return _twins[id(kernel)]


class _Twins:
    """A kernel namespace seen through its twins (:func:`twins_of`); its other attributes (constants) as they are."""

    def __init__(self, space: Any) -> None:
        self._space = space

    def __getattr__(self, name: str) -> Any:
        value = getattr(self._space, name)
        return twin(value) if isinstance(value, _Switch) or _kernel_cache.is_kernel(value) else value


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
    dispatchers = {id(d): d for funcs in list(_kernel_cache.KERNELS.values()) for d in list(funcs.values())}
    spaces: dict[str, dict[str, Any]] = {}
    for mod_name, funcs in list(_kernel_cache.KERNELS.items()):  # (snapshots: another thread may import)
        space = spaces[mod_name] = dict(vars(sys.modules[mod_name]))
        for disp in list(funcs.values()):
            f = getattr(disp, "py_func", disp)  # (the function itself while numba is deferred)
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
    for mod_name, module in _redundik_modules():
        if mod_name in _kernel_cache.KERNELS:
            continue
        space = vars(module)
        spaces[id(space)] = space
        for value in list(space.values()):
            if isinstance(value, _kernel_cache.KernelNamespace):
                value.fill()  # imports its module and fills its namespace
                spaces[id(value.__dict__)] = value.__dict__
    _build_twins()  # (after the namespaces loaded their modules)
    kernels = {id(d): d for funcs in list(_kernel_cache.KERNELS.values()) for d in list(funcs.values())}
    for space in spaces.values():
        for key, value in list(space.items()):
            if id(value) in kernels and kernels[id(value)] is value and (compiled_too or not _compiled(value)):
                _saved.append((space, key, value))
                space[key] = _Switch(value, _twins[id(value)])


def _compiled(kernel: Any) -> bool:
    """Whether numba compiled ``kernel`` for some argument types already (a deferred function: no)."""
    return bool(getattr(kernel, "signatures", None))


def adopt() -> None:
    """Decorate the kernels numba was deferred for (:func:`redundik._kernel_cache.materialize`) and hand their
    dispatchers to whatever held the functions: a switch's compiled side, the original a switch puts back, a
    namespace or module global that still holds a function (a switch now, while cold; the dispatcher otherwise).
    Called by the thread that compiles, before it compiles."""
    if not _kernel_cache.deferred():
        return
    made = _kernel_cache.materialize()
    with _lock:
        for k, (space, key, value) in enumerate(_saved):
            disp = made.get(id(value))
            if disp is not None:
                _saved[k] = (space, key, disp)
        for space in _spaces():
            for key, value in list(space.items()):
                if isinstance(value, _Switch):
                    value.kernel = made.get(id(value.kernel), value.kernel)
                elif id(value) in made:
                    disp = made[id(value)]
                    if _saved:  # (cold: the twin in front, its dispatcher put back by _restore)
                        _saved.append((space, key, disp))
                        space[key] = _Switch(disp, twin(value))
                    else:
                        space[key] = disp


#: Seconds after the first use of a kernel namespace at which a process that never started the compiling thread
#: decorates its deferred kernels in a thread of its own (a script that evaluates tasks or potentials, never a step).
ADOPT_DELAY = 1.0
_timer: threading.Timer | None = None
_timer_lock = threading.Lock()  # (not ``_lock``: a namespace is first used under it, by ``_install``)


def _adopt_soon() -> None:
    """:data:`redundik._kernel_cache.FIRST_USE`: schedule :func:`adopt` in a thread, once."""
    global _timer
    with _timer_lock:
        if _timer is None:
            _timer = threading.Timer(ADOPT_DELAY, _with_short_switches, (adopt,))
            _timer.daemon = True
            _timer.start()


_kernel_cache.FIRST_USE.append(_adopt_soon)


def compiled_now() -> None:
    """For an entry point that wants compiled kernels from its first call (``solve_ik``, the batch API): numba
    imported and the deferred kernels decorated now, in the caller's thread (a no-op once done), and the kernel
    namespaces hand out the kernels from now on, not their twins (:func:`serve_twins`). In a compiling thread only
    the decoration."""
    global _compiled_wanted
    if _kernel_cache.deferred():
        adopt()
    if threading.get_ident() not in _compilers:
        _compiled_wanted = True


_kernel_cache.SERVE_TWINS = serve_twins
_kernel_cache.TWIN_HERE = twin_here


def _redundik_modules() -> list[tuple[str, types.ModuleType]]:
    """redundik's loaded modules, as (name, module), from one snapshot of ``sys.modules``: the compiling thread
    walks them while the caller's thread may import (iterating ``sys.modules`` itself then raises "dictionary
    changed size during iteration", and the thread dies with its kernels never adopted)."""
    loaded = list(sys.modules.items())  # (one C-level copy: no other thread runs during it)
    return [(name, mod) for name, mod in loaded if name.startswith("redundik.") and isinstance(mod, types.ModuleType)]


def _spaces() -> list[dict[str, Any]]:
    """The namespaces that may hold kernels (the kernel modules excepted): every redundik module's globals and the
    filled kernel namespaces."""
    spaces: dict[int, dict[str, Any]] = {}
    for mod_name, module in _redundik_modules():
        if mod_name in _kernel_cache.KERNELS:
            continue
        space = vars(module)
        spaces[id(space)] = space
        for value in list(space.values()):
            if isinstance(value, _kernel_cache.KernelNamespace) and "_module" in value.__dict__:
                if len(value.__dict__) > 1:
                    spaces[id(value.__dict__)] = value.__dict__
    return list(spaces.values())


def _restore() -> None:
    """Put the compiled kernels back wherever a switch is (under ``_lock``; a foreground step meanwhile meets either
    the switch or the kernel: the same answers)."""
    for space, key, value in _saved:
        if isinstance(space.get(key), _Switch):
            space[key] = value
    _saved.clear()
    for _, module in _redundik_modules():  # kernels bound to a switch later
        space = vars(module)
        for key, value in list(space.items()):
            if isinstance(value, _Switch):
                space[key] = value.kernel
