"""daqp's C entry point for compiled code: ``hqp``'s level QPs solved inside the compiled cascade.

A level QP of ``hqp``'s constrained cascade is written by ``hqp_kernels.qp_cascade_run`` into a buffer already in
daqp's form. Handing it back to Python for ``daqp.solve`` cost a return from the compiled call, the wrapper's argument
parsing and result dict, and a second compiled call to go on: about as much again as daqp's own setup and solve on
a 10-joint snake. daqp's Python extension exports its C functions, so the compiled cascade calls
``daqp_quadprog`` itself (``hqp_kernels.native_quadprog``) — the very call ``daqp.solve`` makes, on the same arrays,
with the same settings.

That call writes daqp's structs field by field, so it is made only for the daqp versions whose headers were read
for their layout (``LAYOUTS``), on a little-endian 64-bit process, and after two checks at first use: the
settings that ``daqp_default_settings`` writes are read back at their offsets, and a few QPs solved both ways give
the same x, exit flag and iteration count, bit for bit. Otherwise (another version, a failed check) every level QP
goes back to Python as before, and ``status()`` says why. A QP daqp does not solve at once is always returned
to Python, which poses it with every retry.
"""

from __future__ import annotations

import ctypes
import sys
from typing import Any

import numpy as np

from redundik._coldstart import compiled_here
from redundik.resolvers.linalg import _Kernels

HK = _Kernels("hqp_kernels")  # (numba loads on first use, not when redundik is imported)

#: daqp versions whose ``DAQPProblem``, ``DAQPResult`` and ``DAQPSettings`` layouts ``native_quadprog`` writes
#: (read from their ``include/types.h`` and ``include/api.h``).
LAYOUTS: frozenset[str] = frozenset({"0.11.0"})
#: Switch for comparisons and tests: False sends every level QP back to Python.
enabled = True

_SETTINGS_WORDS = 32  # DAQPSettings is 136 bytes in 0.11.0; room to spare
_entry: tuple[int, Any] | None = None
_reason: str | None = None  # why the native call is off (None: not yet decided, or on)
_decided = False


def _find() -> tuple[int, Any] | str:
    """(address of ``daqp_quadprog``, ctypes ``daqp_default_settings``) or why not."""
    if sys.byteorder != "little" or ctypes.sizeof(ctypes.c_void_p) != 8:
        return "not a little-endian 64-bit process"
    try:
        from importlib import metadata  # (30 ms to import: only when daqp's native call is first looked for)

        import daqp

        version = metadata.version("daqp")
    except Exception as exc:
        return f"daqp not found ({exc})"
    if version not in LAYOUTS:
        return f"daqp {version}: its struct layout was not checked (known: {', '.join(sorted(LAYOUTS))})"
    try:
        lib = ctypes.CDLL(daqp.__file__)
        quadprog = ctypes.cast(lib.daqp_quadprog, ctypes.c_void_p).value
        defaults = lib.daqp_default_settings
    except (OSError, AttributeError) as exc:
        return f"daqp's C functions not exported ({exc})"
    if not quadprog:
        return "daqp_quadprog has no address"
    defaults.argtypes = [ctypes.c_void_p]
    defaults.restype = None
    return int(quadprog), defaults


def _settings(defaults: Any, iter_limit: int, primal_tol: float) -> np.ndarray:
    """A ``DAQPSettings`` of daqp's defaults but ``iter_limit`` and ``primal_tol`` (the two ``DaqpBackend`` sets)."""
    buf = np.zeros(_SETTINGS_WORDS, dtype=np.int64)
    defaults(buf.ctypes.data)
    buf.view(np.float64)[0] = primal_tol
    buf.view(np.int32)[11] = iter_limit
    return buf


def _layout_ok(defaults: Any) -> bool:
    """The defaults ``daqp_default_settings`` writes, read back at the offsets of 0.11.0's ``DAQPSettings``."""
    buf = np.zeros(_SETTINGS_WORDS, dtype=np.int64)
    defaults(buf.ctypes.data)
    f, i = buf.view(np.float64), buf.view(np.int32)
    expected_f = {0: 1e-6, 1: 1e-12, 2: 1e-11, 3: 1e-8, 4: 1e-14, 6: 1e30, 7: -1e-6, 8: -1.0, 9: 1e-6, 12: 3.7e-11}
    return all(f[k] == v for k, v in expected_f.items()) and i[10] == 10 and i[11] == 10000 and i[33] == 1


def _self_test(quadprog: int, defaults: Any) -> str | None:
    """A few QPs solved through ``hqp_kernels.native_quadprog`` and through ``daqp.solve``: the same x, exit flag
    and iterations (bit for bit: the same C call on the same arrays), else why not."""
    import daqp

    rng = np.random.default_rng(7)
    for nvar, nr, neq, tight in ((3, 0, 0, False), (4, 3, 0, False), (5, 6, 0, True), (6, 2, 0, True), (7, 4, 2, True)):
        B = rng.standard_normal((nvar, nvar))
        buf = np.zeros(nvar * nvar + nvar + nr * nvar + 2 * (nvar + nr))
        P, q, G, upper, lower = HK.qp_views(buf, nvar, nr)
        P[:] = B @ B.T + 0.1 * np.eye(nvar)
        q[:] = rng.standard_normal(nvar) * (5.0 if tight else 1.0)
        G[:] = rng.standard_normal((nr, nvar))
        upper[:nvar] = 0.5
        lower[:nvar] = -0.5
        upper[nvar:] = 0.3
        lower[nvar:] = -np.inf
        lower[nvar + nr - neq :] = upper[nvar + nr - neq :] = 0.1
        native = NativeDaqp.layout(quadprog, _settings(defaults, 1000, 1e-10), 10**9, nvar, nr)
        flag, iters = HK.native_quadprog(native.ctl, native.x, buf, nvar, nr, neq)
        sense = np.zeros(nvar + nr, dtype=np.int32)
        sense[nvar + nr - neq :] = 5
        x_ref, _, flag_ref, info = daqp.solve(P, q, G, upper, lower, sense, iter_limit=1000, primal_tol=1e-10)
        same = np.array_equal(native.x[:nvar], np.asarray(x_ref))
        if not (same and flag == flag_ref and flag in (1, 2) and iters == info["iterations"]):
            return (
                f"the self-test QP ({nvar} variables, {nr} rows) differs from daqp.solve (flag {flag} vs {flag_ref}, "
                f"iterations {iters} vs {info['iterations']}, same x: {same})"
            )
    return None


def entry() -> int:
    """The address of ``daqp_quadprog`` for ``hqp_kernels.native_quadprog``, 0 when the native call is off (see
    ``status()``); decided once per process."""
    global _entry, _reason, _decided
    if not _decided:
        if not compiled_here():  # the C call (and its self-test) is made by compiled kernels, never their interpreted
            return 0  # twins (a cold start): the backend's own solve until then, decided once they are loaded
        _decided = True
        found = _find()
        if isinstance(found, str):
            _reason = found
        elif not _layout_ok(found[1]):
            _reason = "daqp_default_settings did not write the expected settings layout"
        else:
            _entry = found
            _reason = _self_test(*found)
            if _reason is not None:
                _entry = None
    return _entry[0] if (_entry is not None and enabled) else 0


def status() -> str:
    """Whether ``hqp`` solves its level QPs through daqp's C entry point, and if not why."""
    on = entry() != 0
    if on:
        return "on: daqp_quadprog called from the compiled cascade"
    return f"off: {_reason or 'switched off (daqp_native.enabled = False)'}"


class NativeDaqp:
    """The ``native`` array of ``hqp_kernels.qp_cascade_run`` for one backend's settings and one plan's largest level
    QP: daqp's function and settings, its structs and its sense, and ``x`` (the solution and multipliers).

    The structs hold addresses of these arrays, so the object keeps them alive; one cascade uses it at a time (as
    one resolver steps one robot at a time).
    """

    __slots__ = ("ctl", "key", "settings", "x")

    def __init__(self) -> None:
        self.ctl = np.zeros(0, dtype=np.int64)
        self.settings = np.zeros(0, dtype=np.int64)
        self.x = np.zeros(0)
        self.key: tuple[Any, ...] = ()

    @classmethod
    def layout(cls, quadprog: int, settings: np.ndarray, split_min_n: int, nvar_max: int, nr_max: int) -> NativeDaqp:
        """The arrays for QPs of up to ``nvar_max`` variables and ``nr_max`` rows."""
        self = cls()
        m_max = nvar_max + nr_max
        self.ctl = np.zeros(HK.NAT_SENSE + (m_max + 1) // 2 + 1, dtype=np.int64)
        self.ctl[HK.NAT_FN] = quadprog
        self.ctl[HK.NAT_SETTINGS] = settings.ctypes.data
        self.ctl[HK.NAT_SPLIT_MIN] = split_min_n
        self.settings = settings
        self.x = np.zeros(nvar_max + m_max)
        return self

    def __reduce__(self) -> tuple[type[NativeDaqp], tuple[()]]:
        """A copy or a pickle is empty (laid out again at its first use): the arrays hold addresses of this object's
        memory and of this process's daqp, which a copy must not call through (the original may be freed, another
        process has daqp elsewhere)."""
        return (NativeDaqp, ())

    def serves(self, backend: Any, nvar: int, nr: int) -> bool:
        """These arrays are :meth:`for_backend`'s answer for ``backend`` and QPs of that size (the native call still
        on): the check made at every cascade, without building anything."""
        key = self.key
        return (
            enabled
            and compiled_here()
            and len(key) == 6
            and key[4] >= nvar
            and key[5] >= nr
            and key[1] == backend.iter_limit
            and key[2] == backend.primal_tol
            and key[3] == backend._split_min_n
        )

    @classmethod
    def for_backend(cls, backend: Any, nvar: int, nr: int, cached: NativeDaqp | None) -> NativeDaqp | None:
        """The arrays for ``backend`` (a ``DaqpBackend``: its iteration limit, primal tolerance and split size) and QPs
        of up to ``nvar`` variables and ``nr`` rows, ``cached`` when it has those settings and room enough (else
        grown); ``None`` when the native call is off, or while kernels called from this thread run interpreted (a
        cold start: another resolver's kernels compiling puts every kernel's twin in place)."""
        if not compiled_here():
            return None
        quadprog = entry()
        if not quadprog:
            return None
        key = (quadprog, backend.iter_limit, backend.primal_tol, backend._split_min_n)
        if cached is not None and cached.key[:4] == key and cached.key[4] >= nvar and cached.key[5] >= nr:
            return cached
        if cached is not None and cached.key[:4] == key:  # grown: twice the room, so that it seldom happens
            nvar, nr = max(nvar, 2 * cached.key[4]), max(nr, 2 * cached.key[5])
        assert _entry is not None
        settings = _settings(_entry[1], backend.iter_limit, backend.primal_tol)
        made = cls.layout(quadprog, settings, backend._split_min_n, nvar, nr)
        made.key = (*key, nvar, nr)
        return made
