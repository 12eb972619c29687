"""The resolver benchmark (issues 3, 11, 12): redundik's resolvers against mink, pink and PlaCo, the snake
scaling, the batch API against the loop, and the collision case — side by side, in one interleaved run.

It lives in the checkout, not in the wheel (issue 10: the harness out of the core package). Entry point:
``python benchmarks/compare_resolvers.py`` (``--quick`` a few minutes). See ``docs/benchmark.md``.
"""

from benchmarks.bench.harness import (
    BATCH_METHODS,
    KNOWN_ROBOTS,
    METHODS,
    QUICK_ROBOTS,
    ROBOTS,
    BenchConfig,
    BenchResult,
    CaseResult,
    case_status,
    run_benchmark,
    summarise,
)
from benchmarks.bench.report import markdown, plot, ratio_lines, readme_table, to_json, write_all, write_json

__all__ = [
    "BATCH_METHODS",
    "KNOWN_ROBOTS",
    "METHODS",
    "QUICK_ROBOTS",
    "ROBOTS",
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
