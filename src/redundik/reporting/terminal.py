"""Terminal output of ``redundik run``: a compact rich table of the runs."""

from __future__ import annotations

from typing import Any

from rich.console import Console
from rich.table import Table


def _num(x: float | None, fmt: str = ".3g") -> str:
    return "–" if x is None else format(x, fmt)


def summary_table(summary: dict[str, Any]) -> Table:
    """One row per run: resolver, task errors, subtask values, step time, limit violations, damping."""
    unit = summary.get("length_unit", "m")
    table = Table(title=f"{summary['task']} — {summary['robot']}, dt = {summary['dt']} s, {summary['steps']} steps")
    table.add_column("run", style="bold")
    table.add_column("resolver")
    table.add_column(f"max err [{unit}]", justify="right")
    table.add_column(f"final err [{unit}]", justify="right")
    table.add_column("subtasks initial → final")
    table.add_column("step µs (med/p90)", justify="right")
    table.add_column("limit viol.", justify="right")
    table.add_column("damped", justify="right")
    for name, r in summary["runs"].items():
        subs = ", ".join(f"{k}: {_num(v['initial'])} → {_num(v['final'])}" for k, v in r["subtasks"].items())
        extra = []
        if "min_clearance" in r:
            extra.append(f"min clearance {_num(r['min_clearance'])}")
        if "trace_JWJT" in r:
            extra.append(f"tr(JWJᵀ) {_num(r['trace_JWJT']['initial'])} → {_num(r['trace_JWJT']['final'])}")
        viol = str(r["limit_violations"])
        table.add_row(
            name,
            r["resolver"],
            _num(r["max_task_error"]),
            _num(r["final_task_error"]),
            "; ".join(x for x in [subs, *extra] if x) or "–",
            f"{r['step_time_us']['median']:.0f} / {r['step_time_us']['p90']:.0f}",
            f"[red]{viol}[/red]" if r["limit_violations"] else viol,
            str(r.get("damped_steps", 0)) + (f" ({r['fallbacks']} fallbacks)" if r.get("fallbacks") else ""),
        )
    return table


def print_summary(summary: dict[str, Any], console: Console | None = None) -> None:
    """Print :func:`summary_table`."""
    (console or Console()).print(summary_table(summary))
