"""The resolver benchmark (issue 3, item 6): redundik's resolvers and the peers mink and pink, side by side.

It lives in :mod:`redundik.peers` because it is the one place, with the task adapters, that imports the peers
(guarded: without them it runs redundik's methods only). Entry points: ``benchmarks/compare_resolvers.py`` and
``redundik bench``. See ``docs/benchmark.md``.
"""

from redundik.peers.bench.harness import METHODS, BenchConfig, BenchResult, CaseResult, run_benchmark
from redundik.peers.bench.report import markdown, plot, ratio_lines, to_json, write_all, write_json

__all__ = [
    "METHODS",
    "BenchConfig",
    "BenchResult",
    "CaseResult",
    "markdown",
    "plot",
    "ratio_lines",
    "run_benchmark",
    "to_json",
    "write_all",
    "write_json",
]
