#!/usr/bin/env python3
"""Compare redundik's resolvers with mink, pink and PlaCo on identical robots and tasks (issues 3, 11, 12).

Usage (from a checkout, with ``pip install -e ".[test,peers]"``)::

    python benchmarks/compare_resolvers.py                  # full run: ≥ 2000 timed steps per case
    python benchmarks/compare_resolvers.py --quick          # under a minute
    python benchmarks/compare_resolvers.py --json out.json --out benchmarks/results/
    python benchmarks/compare_resolvers.py --placo-python .venv-placo/bin/python

Writes ``compare_resolvers.md`` (tables and targets), ``.json`` and ``.png`` to ``--out`` and prints the ratios.
Method, robots, PlaCo's own interpreter and timing rules: ``docs/benchmark.md``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))  # the harness is the checkout's package benchmarks.bench, not in the wheel

from benchmarks.bench import KNOWN_ROBOTS, METHODS, BenchConfig, ratio_lines, run_benchmark, write_all  # noqa: E402
from redundik.errors import RedundikError  # noqa: E402

DEFAULT_OUT = ROOT / "benchmarks" / "results"


def main(argv: list[str] | None = None) -> int:
    """Parse arguments, run, write the reports; returns the exit code."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="short run (under a minute)")
    parser.add_argument("--steps", type=int, default=None, help="timed steps per case (default 2000, quick 300)")
    parser.add_argument("--json", type=Path, default=None, help="also write the JSON summary here")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder (default benchmarks/results)")
    parser.add_argument("--robots", nargs="+", default=None, help="subset of " + " ".join(KNOWN_ROBOTS))
    parser.add_argument("--methods", nargs="+", default=None, help="subset of " + " ".join(METHODS))
    parser.add_argument(
        "--placo-python", default=None, help="PlaCo's interpreter (default $REDUNDIK_PLACO_PYTHON or .venv-placo)"
    )
    parser.add_argument("--batch-steps", type=int, default=None, help="timed calls of the batch case")
    args = parser.parse_args(argv)
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
    command = "python benchmarks/compare_resolvers.py " + " ".join(argv if argv is not None else sys.argv[1:])
    try:
        result = run_benchmark(config)
    except RedundikError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    paths = write_all(result, args.out, command.strip(), args.json)
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
