"""Sweep throughput: 2 Dask workers vs 1 on a ≥ 20 000-problem sweep, and batch vs loop inside one chunk.

    python benchmarks/sweep_scaling.py [--file sweeps/panda_reach.yaml] [--workers 1,2] [--json PATH]

* **Scaling**: for each worker count N, a ``LocalCluster`` of N single-threaded worker processes is started and
  warmed up (every worker builds the plan and loads the compiled kernels once), then the whole sweep is timed
  (``run_sweep(plan, client=…)``: submission, the chunks, gathering). Speed-up = t(1) / t(N). The tables of all
  runs are checked to be identical.
  The workers' CPU seconds are reported too: equal CPU for 1 and 2 workers and a CPU share below 100 % say that
  the missing speed-up is the cores being shared with other jobs, not the sweep's overhead.
* **In-chunk**: one chunk of ``--chunk`` problems iterated to convergence with one ``BatchResolver.solve`` per
  iteration (``batch``) vs the same problems one by one through ``resolver.step`` (``loop``), in this process.

The machine's load average is printed before and after each measurement (other jobs share the cores: read the
ratios with it). Wall times, not a unit test.
"""

from __future__ import annotations

import os

# timed after untimed warm-up steps: the kernels compile in the caller's thread, not in redundik's background one
os.environ.setdefault("REDUNDIK_COLD_START", "wait")

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from redundik.sweep import load_sweep, run_chunk, run_sweep  # noqa: E402
from redundik.sweep.engine import dask_client, remote_chunk  # noqa: E402


def _load() -> str:
    return "/".join(f"{v:.2f}" for v in os.getloadavg())


def in_chunk(plan, start: int, size: int) -> dict[str, float]:  # type: ignore[no-untyped-def]
    """Problems/s of one chunk, batch vs loop (same problems, same iteration)."""
    stop = min(start + size, plan.n_problems)
    # compile or load the kernels and warm the caches of both, untimed: the whole chunk for the batch (a few
    # problems may bind no limit and leave the box-QP kernel unloaded), a few problems for the loop
    run_chunk(plan, start, stop, "batch")
    run_chunk(plan, start, start + 4, "loop")
    out: dict[str, float] = {"problems": stop - start}
    for method in ("batch", "loop"):
        t0 = time.perf_counter()
        cols = run_chunk(plan, start, stop, method)
        dt = time.perf_counter() - t0
        out[f"{method}_s"] = dt
        out[f"{method}_problems_per_s"] = (stop - start) / dt
        out[f"{method}_steps"] = float(cols["iterations"].sum())
        out[f"{method}_qp_steps"] = float(cols["qp_steps"].sum())
    out["speedup"] = out["batch_problems_per_s"] / out["loop_problems_per_s"]
    return out


def scaling(plan, workers: list[int]) -> tuple[list[dict[str, object]], bool]:  # type: ignore[no-untyped-def]
    """Wall time of the whole sweep per worker count; and whether every run gave the same table."""
    rows: list[dict[str, object]] = []
    tables = []
    for n in workers:
        with dask_client(local=n) as client:
            client.run(remote_chunk, plan.key, plan.payload, 0, 4, "batch")  # every worker: plan + kernels once
            before = _load()
            cpu0 = client.run(time.process_time)
            res = run_sweep(plan, client=client)
            cpu1 = client.run(time.process_time)
            after = _load()
        cpu = sum(cpu1[w] - cpu0[w] for w in cpu1)  # CPU seconds the workers got
        tables.append(res.columns)
        rows.append(
            {
                "workers": n,
                "problems": res.n_problems,
                "chunks": res.chunks,
                "seconds": round(res.seconds, 2),
                "problems_per_s": round(res.n_problems / res.seconds, 1),
                "converged": res.n_converged,
                "worker_cpu_s": round(cpu, 2),
                "cpu_share": round(cpu / (n * res.seconds), 3),  # 1.0: each worker had a core to itself
                "load_before": before,
                "load_after": after,
            }
        )
        print(
            f"  {n} worker(s): {res.seconds:.1f} s, {res.n_problems / res.seconds:.0f} problems/s "
            f"(load {before} → {after}); worker CPU {cpu:.1f} s = {cpu / (n * res.seconds):.0%} of {n} core(s)",
            flush=True,
        )
    same = all(all(np.array_equal(t[k], tables[0][k]) for k in t) for t in tables[1:])
    base = float(rows[0]["seconds"])  # type: ignore[arg-type]
    for r in rows:
        r["speedup_vs_first"] = round(base / float(r["seconds"]), 3)  # type: ignore[arg-type]
    return rows, same


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--file", type=Path, default=ROOT / "sweeps" / "panda_reach.yaml")
    ap.add_argument("--workers", default="1,2", help="comma-separated worker counts (first = the baseline)")
    ap.add_argument("--chunk", type=int, default=256, help="problems of the in-chunk batch-vs-loop measurement")
    ap.add_argument("--chunk-start", type=int, default=10240, help="first problem of that chunk")
    ap.add_argument("--skip-scaling", action="store_true")
    ap.add_argument("--skip-chunk", action="store_true")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    plan = load_sweep(args.file)
    print(f"{plan.name}: {plan.n_problems} problems, chunks of {plan.spec.chunk_size}, cores {os.cpu_count()}")
    report: dict[str, object] = {"sweep": plan.name, "problems": plan.n_problems, "cpu_count": os.cpu_count()}
    if not args.skip_chunk:
        data = dict(plan.payload["data"])
        for resolver in (plan.spec.resolver.name, "pinv" if plan.spec.resolver.name == "wqp" else "wqp"):
            data["resolver"] = {
                "name": resolver,
                "options": plan.spec.resolver.options if resolver == plan.spec.resolver.name else {},
            }
            p = load_sweep(data, Path(plan.payload["base_dir"]))
            before = _load()
            c = in_chunk(p, args.chunk_start, args.chunk)
            c["load_before"], c["load_after"] = before, _load()  # type: ignore[assignment]
            report[f"in_chunk_{resolver}"] = c
            print(
                f"  in-chunk, {resolver} ({int(c['problems'])} problems): batch {c['batch_problems_per_s']:.0f} "
                f"problems/s, loop {c['loop_problems_per_s']:.0f} problems/s → {c['speedup']:.1f}× "
                f"(qp steps {int(c['batch_qp_steps'])} of {int(c['batch_steps'])}; load {before} → {c['load_after']})"
            )
    if not args.skip_scaling:
        rows, same = scaling(plan, [int(w) for w in args.workers.split(",")])
        report["scaling"] = rows
        report["identical_tables"] = same
        ups = ", ".join(f"{r['workers']}: {r['speedup_vs_first']}×" for r in rows)
        print(f"  speed-up: {ups}; same tables: {same}")
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
