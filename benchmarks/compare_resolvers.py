#!/usr/bin/env python3
"""Compare redundik's resolvers with mink, pink and PlaCo on identical robots and tasks (issues 3, 11, 12).

Usage (from a checkout, with ``pip install -e ".[test,peers]"``)::

    python benchmarks/compare_resolvers.py                  # full run: ≥ 2000 timed steps per case
    python benchmarks/compare_resolvers.py --quick          # a few minutes (--cold-start warm: shorter)
    python benchmarks/compare_resolvers.py --json out.json --out benchmarks/results/
    python benchmarks/compare_resolvers.py --placo-python .venv-placo/bin/python
    python benchmarks/compare_resolvers.py --repeat 3         # three full runs: median ratio and spread per case
    python benchmarks/compare_resolvers.py --robots panda --ik-poses 1000   # and the ik_convergence case

The ``ik_convergence`` case (rk.solve_ik against TRAC-IK on reachable Panda, UR5 and xArm7 poses,
``benchmarks/ik_convergence.py``) runs in full and ``--quick`` runs (200 poses per robot), with ``--robots`` only on
``--ik-poses N``; its rows are in the JSON's ``meta.ik_convergence``.

Writes ``compare_resolvers.md`` (tables and targets), ``.json`` and ``.png`` to ``--out`` and prints the ratios.
Method, robots, PlaCo's own interpreter and timing rules: ``docs/benchmark.md``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))  # the harness is the checkout's package benchmarks.bench, not in the wheel

from benchmarks.bench import KNOWN_ROBOTS, METHODS, BenchConfig, ratio_lines, run_benchmark, write_all  # noqa: E402
from benchmarks.bench.cases import IK_CONVERGENCE, IK_POSES, IK_POSES_QUICK, ik_convergence_case  # noqa: E402
from benchmarks.bench.repeat import repeat_markdown, summarise_runs  # noqa: E402
from benchmarks.bench.report import markdown, readme_table, targets_table  # noqa: E402
from redundik.errors import RedundikError  # noqa: E402

DEFAULT_OUT = ROOT / "benchmarks" / "results"


def _replace_between(path: Path, tag: str, body: str) -> Path:
    text = path.read_text(encoding="utf-8")
    start, end = f"<!-- {tag}:start -->", f"<!-- {tag}:end -->"
    i, j = text.index(start) + len(start), text.index(end)
    path.write_text(text[:i] + "\n" + body.strip() + "\n" + text[j:], encoding="utf-8")
    return path


def update_docs(result: object, command: str, summary: dict[str, object] | None = None) -> list[Path]:
    """This run's full report into docs/benchmark.md and the compact table + targets into README.md; with a
    ``--repeat`` summary, the summary (median and spread over the runs) first in both, then the first run's report."""
    if summary is not None:
        text = repeat_markdown(summary, command)
        return [
            _replace_between(ROOT / "docs" / "benchmark.md", "results",
                             text + "\nThe first of these runs in full:\n\n" + markdown(result)),  # type: ignore[arg-type]
            _replace_between(ROOT / "README.md", "readme-results", text),
        ]  # fmt: skip
    readme = (
        f"Last full run (`{command}`, one interleaved run on this 2-core shared machine: absolute µs are inflated "
        "by the load, the ratios come from the same run); `wqp`/`hqp` on their default backend, each peer on its "
        "fastest; × faster peer = median over the faster non-failed of mink and pink.\n\n"
        + readme_table(result)  # type: ignore[arg-type]
        + "\nTargets (issues 11 and 31), measured in this run:\n\n"
        + "\n".join(targets_table(result))  # type: ignore[arg-type]
        + "\n"
    )
    return [
        _replace_between(ROOT / "docs" / "benchmark.md", "results", markdown(result, command)),  # type: ignore[arg-type]
        _replace_between(ROOT / "README.md", "readme-results", readme),
    ]


def _write_summary(summary: dict[str, object], out: Path, command: str, json_path: Path | None) -> dict[str, Path]:
    """The ``--repeat`` summary as ``compare_resolvers_repeat.md`` and ``.json`` in ``out`` (and at ``json_path``)."""
    from redundik.reporting.paths import safe_path

    md = safe_path(out, "compare_resolvers_repeat.md")
    md.write_text(repeat_markdown(summary, command), encoding="utf-8")
    doc = json.dumps(summary, indent=2, allow_nan=False)
    js = safe_path(out, "compare_resolvers_repeat.json")
    js.write_text(doc, encoding="utf-8")
    paths = {"repeat markdown": md, "repeat json": js}
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(doc, encoding="utf-8")
        paths["json_requested"] = json_path
    return paths


def main(argv: list[str] | None = None) -> int:
    """Parse arguments, run, write the reports; returns the exit code."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="short run (a few minutes, the cold start included)")
    parser.add_argument("--steps", type=int, default=None, help="timed steps per case (default 2000, quick 300)")
    parser.add_argument("--json", type=Path, default=None, help="also write the JSON summary here")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder (default benchmarks/results)")
    parser.add_argument("--robots", nargs="+", default=None, help="subset of " + " ".join(KNOWN_ROBOTS))
    parser.add_argument("--methods", nargs="+", default=None, help="subset of " + " ".join(METHODS))
    parser.add_argument(
        "--placo-python", default=None, help="PlaCo's interpreter (default $REDUNDIK_PLACO_PYTHON or .venv-placo)"
    )
    parser.add_argument("--batch-steps", type=int, default=None, help="timed calls of the batch case")
    parser.add_argument(
        "--update-docs", action="store_true", help="write this run's tables into docs/benchmark.md and README.md"
    )
    parser.add_argument(
        "--repeat", type=int, default=1, help="full runs (each interleaved); >1 reports median ratio and spread"
    )
    parser.add_argument(
        "--cold-start", choices=("cold", "warm", "off"), default="cold",
        help="cold_start case: empty cache then warm (default), the user's cache only, or not run",
    )  # fmt: skip
    parser.add_argument(
        "--ik-poses", type=int, default=None,
        help=f"{IK_CONVERGENCE} case: poses per robot (default {IK_POSES}, quick {IK_POSES_QUICK}, 0 with --robots)",
    )  # fmt: skip
    args = parser.parse_args(argv)
    if args.repeat < 1:
        print(f"error: --repeat must be ≥ 1, got {args.repeat}", file=sys.stderr)
        return 2
    config = BenchConfig.quick() if args.quick else BenchConfig()
    if args.steps is not None:
        config.steps = args.steps
    if args.robots:
        config.robots = tuple(args.robots)
    if args.methods:
        config.methods = tuple(args.methods)
    if args.batch_steps is not None:
        config.batch_steps = args.batch_steps
    config.placo_python = args.placo_python
    config.cold_start = args.cold_start
    command = "python benchmarks/compare_resolvers.py " + " ".join(argv if argv is not None else sys.argv[1:])
    results = []
    for i in range(args.repeat):
        if args.repeat > 1:
            print(f"== run {i + 1} of {args.repeat}")
        try:
            results.append(run_benchmark(config))
        except RedundikError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        poses = IK_POSES_QUICK if args.quick else IK_POSES
        if args.ik_poses is not None or args.robots:  # a chosen set of robots runs the IK case only when asked
            poses = args.ik_poses or 0
        if poses > 0:  # rk.solve_ik vs TRAC-IK: in the JSON's meta under its case name
            print(f"{IK_CONVERGENCE}: {poses} poses per robot")
            results[-1].meta[IK_CONVERGENCE] = ik_convergence_case(poses)
    result = results[0]
    if args.repeat == 1:
        paths = write_all(result, args.out, command.strip(), args.json)
        summary = None
    else:
        paths = {}
        for i, res in enumerate(results):
            paths[f"run {i + 1}"] = write_all(res, Path(args.out) / f"run{i + 1}", command.strip())["markdown"]
        summary = summarise_runs(results)
        paths.update(_write_summary(summary, args.out, command.strip(), args.json))
    if args.update_docs:
        for p in update_docs(result, command.strip(), summary):
            print(f"updated: {p}")
    if summary is not None:
        print(repeat_markdown(summary))
        for key, p in paths.items():
            print(f"{key}: {p}")
        return 0
    print("\nmedian step time / the faster of mink and pink (fastest backend), and / PlaCo:")
    for line in ratio_lines(result):
        print("  " + line)
    for t in result.targets():
        val = "–" if t["value"] is None else f"{t['value']:.3g}"
        met = {True: "met", False: "NOT met", None: "not measured"}[t["met"]]
        print(f"  target {t['target']}: {val} → {met}")
    for s in result.skipped:
        print(f"  skipped: {s}")
    for key, p in paths.items():
        if p is not None:
            print(f"{key}: {p}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
