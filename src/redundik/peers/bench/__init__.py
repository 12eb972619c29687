"""The resolver benchmark (issue 3, item 6): redundik's resolvers and the peers mink and pink, side by side.

It lives in :mod:`redundik.peers` because it is the one place, with the task adapters, that imports the peers
(guarded: without them it runs redundik's methods only). Entry points: ``benchmarks/compare_resolvers.py`` and
``redundik bench``. See ``docs/benchmark.md``.
"""

from redundik.peers.bench.harness import (
    METHODS,
    BenchConfig,
    BenchResult,
    CaseResult,
    case_status,
    run_benchmark,
    summarise,
)
from redundik.peers.bench.report import markdown, plot, ratio_lines, readme_table, to_json, write_all, write_json

__all__ = [
    "METHODS",
    "BenchConfig",
    "BenchResult",
    "CaseResult",
    "case_status",
    "markdown",
    "plot",
    "ratio_lines",
    "readme_table",
    "run_benchmark",
    "summarise",
    "to_json",
    "write_all",
    "write_json",
]
