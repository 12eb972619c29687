#!/usr/bin/env python3
"""Compare redundik's resolvers with mink and pink on identical robots and tasks (issue 3, item 6).

Usage::

    python benchmarks/compare_resolvers.py                  # full run: ≥ 2000 timed steps per case
    python benchmarks/compare_resolvers.py --quick          # within a minute
    python benchmarks/compare_resolvers.py --json out.json --out benchmarks/results/

Writes ``compare_resolvers.md`` (table), ``.json`` and ``.png`` to ``--out`` and prints the ratios to the faster
peer. The same run is ``redundik bench``. Method, robots and timing rules: ``docs/benchmark.md``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from redundik.errors import RedundikError
from redundik.peers.bench import BenchConfig, ratio_lines, run_benchmark, write_all

DEFAULT_OUT = Path(__file__).resolve().parent / "results"


def main(argv: list[str] | None = None) -> int:
    """Parse arguments, run, write the reports; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="short run (within a minute)")
    parser.add_argument("--steps", type=int, default=None, help="timed steps per case (default 2000, quick 300)")
    parser.add_argument("--json", type=Path, default=None, help="also write the JSON summary here")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder (default benchmarks/results)")
    parser.add_argument("--robots", nargs="+", default=None, help="subset of planar3r panda panda_tight talos")
    parser.add_argument("--methods", nargs="+", default=None, help="subset of pinv feedback wqp hqp mink pink")
    args = parser.parse_args(argv)
    config = BenchConfig.quick() if args.quick else BenchConfig()
    if args.steps is not None:
        config.steps = args.steps
    if args.robots:
        config.robots = tuple(args.robots)
    if args.methods:
        config.methods = tuple(args.methods)
    command = "python benchmarks/compare_resolvers.py " + " ".join(argv if argv is not None else sys.argv[1:])
    try:
        result = run_benchmark(config)
    except RedundikError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    paths = write_all(result, args.out, command.strip(), args.json)
    print("\nmedian step time / faster peer's (mink or pink, fastest backend):")
    for line in ratio_lines(result):
        print("  " + line)
    for t in result.targets():
        print(f"  target {t['target']}: {t['value'] if t['value'] is None else round(t['value'], 3)} → met={t['met']}")
    for key, p in paths.items():
        if p is not None:
            print(f"{key}: {p}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
