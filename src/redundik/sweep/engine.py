"""Where a sweep runs: in-process (default) or on Dask (``dask.distributed``, extra ``sweep``).

The problems are cut into chunks of ``chunk_size`` problems (problem order, the last chunk shorter): the same
chunks whichever way the sweep runs. In-process, the chunks run one after the other; on Dask, each chunk is one
task (:func:`remote_chunk`): the worker rebuilds the plan from the file's data once (cached by its digest), runs the
chunk and returns its columns; the results are put back in chunk order. So the table is identical in-process, on
a ``LocalCluster`` of any size and on an existing cluster (tested).

Dask is imported only when a Dask engine is asked for. On an existing cluster (``--scheduler ADDRESS``) every
worker needs redundik installed and the robot config at the same absolute path as here (``example-robot-data``
robots come with the package).
"""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from redundik._extras import require
from redundik.errors import RedundikError
from redundik.sweep.plan import SweepPlan, load_sweep
from redundik.sweep.solve import STATUSES, run_chunk

#: Most workers ``local:N`` may start.
MAX_LOCAL_WORKERS = 64


class SweepError(RedundikError):
    """A sweep could not run (bad engine, a cluster that cannot be reached, a chunk that failed)."""


@dataclass
class SweepResult:
    """The results of a sweep, one row per problem in problem order.

    Attributes:
        columns: Column name → array of length n_problems (see :mod:`redundik.sweep`).
        engine: Where it ran (``in-process``, ``dask local:N``, ``dask tcp://…``).
        chunks: Number of chunks.
        workers: Number of workers (1 in-process).
        seconds: Wall time of the chunks (cluster start-up excluded) [s].
    """

    columns: dict[str, np.ndarray]
    engine: str
    chunks: int
    workers: int
    seconds: float
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def n_problems(self) -> int:
        """Number of rows."""
        return int(self.columns["problem"].shape[0])

    @property
    def n_converged(self) -> int:
        """Number of problems that converged."""
        return int(np.count_nonzero(self.columns["converged"]))


def chunk_bounds(n: int, size: int) -> list[tuple[int, int]]:
    """The chunks [(start, stop), …] of n problems in chunks of ``size`` (deterministic, problem order)."""
    return [(s, min(s + size, n)) for s in range(0, n, size)]


def _assemble(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    cols = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    cols["status"] = np.array(STATUSES, dtype=object)[cols["status"].astype(np.int64)]
    return cols


# ---------------------------------------------------------------------------------------------- remote side
_PLANS: dict[str, SweepPlan] = {}
_PLANS_LOCK = threading.Lock()


def remote_chunk(key: str, payload: dict[str, Any], start: int, stop: int, method: str) -> dict[str, np.ndarray]:
    """Run one chunk on a worker: rebuild the plan from ``payload`` once per worker process (cached by ``key``)."""
    from pathlib import Path

    with _PLANS_LOCK:
        plan = _PLANS.get(key)
        if plan is None:
            plan = load_sweep(payload["data"], Path(payload["base_dir"]))
            _PLANS.clear()  # one sweep at a time per worker
            _PLANS[key] = plan
    return run_chunk(plan, start, stop, method)


# ---------------------------------------------------------------------------------------------- engines
def parse_local(spec: str) -> int:
    """N of ``local:N`` (1 ≤ N ≤ :data:`MAX_LOCAL_WORKERS`).

    Raises:
        SweepError: anything else.
    """
    m = re.fullmatch(r"local:([0-9]{1,3})", spec.strip())
    n = int(m.group(1)) if m else 0
    if not 1 <= n <= MAX_LOCAL_WORKERS:
        raise SweepError(f"--dask: expected local:N with 1 ≤ N ≤ {MAX_LOCAL_WORKERS}, got {spec[:40]!r}")
    return n


#: Schemes of a Dask scheduler address another process can connect to (``inproc://`` lives inside one process).
SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")
_ADDRESS = re.compile(
    r"(?:(?P<scheme>[A-Za-z][A-Za-z0-9+.-]*)://)?(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(?P<port>[0-9]+)"
)


def check_scheduler_address(address: str) -> str:
    """``address`` if it has the shape of a Dask scheduler address, ``[SCHEME://]HOST:PORT`` (nothing is contacted).

    Raises:
        SweepError: anything else, saying what was expected (a malformed port otherwise waits out the 10 s connect
            timeout, ``local:N`` is the ``--dask`` option's value, and ``inproc://`` cannot reach another process).
    """
    shown = repr(address[:60] + ("..." if len(address) > 60 else ""))
    expected = "expected a scheduler address [SCHEME://]HOST:PORT, e.g. tcp://10.0.0.5:8786"
    if re.fullmatch(r"local:.*", address.strip()):
        raise SweepError(f"--scheduler: {shown} is a local cluster size: use --dask {address.strip()[:20]}")
    m = _ADDRESS.fullmatch(address) if len(address) <= 255 else None
    if m is None:
        raise SweepError(f"--scheduler: {expected}, got {shown}")
    scheme = m.group("scheme")
    if scheme is not None and scheme.lower() not in SCHEMES:
        raise SweepError(
            f"--scheduler: scheme {scheme[:20]!r} cannot reach a scheduler in another process; "
            f"expected one of {', '.join(SCHEMES)}, got {shown}"
        )
    port = int(m.group("port")[:6])
    if not 1 <= port <= 65535:
        raise SweepError(f"--scheduler: the port must be 1 to 65535, got {m.group('port')[:12]} in {shown}")
    return address


@contextmanager
def dask_client(local: int | None = None, scheduler: str | None = None, processes: bool = True) -> Iterator[Any]:
    """A ``distributed.Client``: on a new ``LocalCluster`` of ``local`` single-threaded workers, or on ``scheduler``.

    Raises:
        SweepError: neither or both given, or the scheduler cannot be reached.
        MissingDependencyError: ``dask.distributed`` is not installed (extra ``sweep``).
    """
    if (local is None) == (scheduler is None):
        raise SweepError("give exactly one of a local cluster size (--dask local:N) or a scheduler address")
    distributed = require("distributed", "a sweep on Dask")
    import logging

    if local is not None:
        cluster = distributed.LocalCluster(
            n_workers=local,
            threads_per_worker=1,
            processes=processes,
            dashboard_address=":0",  # no fixed port: never collides with another cluster
            silence_logs=logging.ERROR,
        )
        try:
            client = distributed.Client(cluster)
            try:
                yield client
            finally:
                client.close()
        finally:
            cluster.close()
        return
    assert scheduler is not None  # one of local / scheduler is given (checked by the caller)
    try:
        client = distributed.Client(scheduler, timeout="10s")
    except (OSError, TimeoutError, ValueError) as exc:
        reason = " ".join(str(exc).split())
        reason = reason if len(reason) <= 200 else reason[:197] + "..."
        raise SweepError(f"cannot reach the Dask scheduler {scheduler[:100]!r}: {reason}") from None
    try:
        yield client
    finally:
        client.close()


def run_sweep(
    plan: SweepPlan,
    *,
    client: Any = None,
    dask: str | None = None,
    scheduler: str | None = None,
    method: str = "batch",
    progress: Callable[[int, int], None] | None = None,
) -> SweepResult:
    """Run every problem of ``plan``: in-process, on a given Dask ``client``, ``dask="local:N"`` or ``scheduler``.

    Args:
        plan: The sweep.
        client: An existing ``distributed.Client`` (kept open).
        dask: ``"local:N"``: start a ``LocalCluster`` of N single-threaded worker processes for this sweep.
        scheduler: Address of an existing Dask scheduler.
        method: ``"batch"`` or ``"loop"`` (see :func:`redundik.sweep.solve.run_chunk`).
        progress: Called with (chunks done, chunks) after each chunk.

    Raises:
        SweepError: more than one engine, a bad engine, or a chunk that failed on a worker (with its reason).
    """
    if sum(x is not None for x in (client, dask, scheduler)) > 1:
        raise SweepError("give at most one of a client, --dask local:N or --scheduler ADDRESS")
    bounds = chunk_bounds(plan.n_problems, plan.spec.chunk_size)
    if client is None and dask is None and scheduler is None:
        t0 = time.perf_counter()
        parts = []
        for k, (s, e) in enumerate(bounds):
            parts.append(run_chunk(plan, s, e, method))
            if progress is not None:
                progress(k + 1, len(bounds))
        return SweepResult(_assemble(parts), "in-process", len(bounds), 1, time.perf_counter() - t0)
    if client is not None:
        return _run_on(client, plan, bounds, method, progress, "dask")
    if dask is not None:
        n = parse_local(dask)
        with dask_client(local=n) as c:
            return _run_on(c, plan, bounds, method, progress, f"dask local:{n}")
    if not isinstance(scheduler, str):
        raise SweepError(f"scheduler: expected an address string, got {type(scheduler).__name__}")
    scheduler = check_scheduler_address(scheduler)  # (as the CLI checks it: a bad address said before any wait)
    with dask_client(scheduler=scheduler) as c:
        return _run_on(c, plan, bounds, method, progress, f"dask {scheduler}")


def _run_on(
    client: Any,
    plan: SweepPlan,
    bounds: list[tuple[int, int]],
    method: str,
    progress: Callable[[int, int], None] | None,
    engine: str,
) -> SweepResult:
    distributed = require("distributed", "a sweep on Dask")
    workers = len(client.scheduler_info().get("workers", {})) or 1
    key, payload = plan.key, plan.payload
    t0 = time.perf_counter()
    futures = [client.submit(remote_chunk, key, payload, s, e, method, pure=False) for s, e in bounds]
    parts: list[dict[str, np.ndarray] | None] = [None] * len(bounds)
    index = {f.key: k for k, f in enumerate(futures)}
    try:
        for done, fut in enumerate(distributed.as_completed(futures), start=1):
            parts[index[fut.key]] = fut.result()
            if progress is not None:
                progress(done, len(bounds))
    except RedundikError as exc:
        raise SweepError(f"a chunk failed on a worker: {exc}") from None
    except Exception as exc:
        raise SweepError(f"a chunk failed on a worker: {type(exc).__name__}: {exc}") from None
    finally:
        for f in futures:
            f.release()
    seconds = time.perf_counter() - t0
    return SweepResult(_assemble([p for p in parts if p is not None]), engine, len(bounds), workers, seconds)
