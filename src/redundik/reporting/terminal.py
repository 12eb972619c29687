"""Terminal output of ``redundik run``: a compact rich table of the runs."""

from __future__ import annotations

from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table


def _num(x: float | None, fmt: str = ".3g") -> str:
    return "–" if x is None else format(x, fmt)


def summary_table(summary: dict[str, Any]) -> Table:
    """One row per run: resolver, task errors, subtask values, median step time, limit violations, damping."""
    unit = summary.get("length_unit", "m")
    table = Table(
        title=f"{summary['task']}: {summary['robot']}, dt = {summary['dt']} s, {summary['steps']} steps",
        title_justify="left",
        padding=(0, 1),
    )
    table.add_column("run\n(resolver)", no_wrap=True)
    table.add_column(escape(f"error [{unit}]") + "\nmax / final", justify="right", no_wrap=True)
    table.add_column("subtasks\ninitial → final", min_width=12, ratio=1)
    table.add_column("µs/step\nmedian", justify="right", no_wrap=True)
    table.add_column("limit\nviol.", justify="right", no_wrap=True)
    table.add_column("damped", justify="right", no_wrap=True)
    for name, r in summary["runs"].items():
        items = [f"{k} {_num(v['initial'])} → {_num(v['final'])}" for k, v in r["subtasks"].items() if "initial" in v]
        for k, v in r["subtasks"].items():
            if "waypoints" in v:  # a round trip short of a waypoint is flagged
                wp = v["waypoints"]
                note = f"{escape(k)}: {wp['reached']}/{len(wp['values'])} waypoints reached"
                items.append(note if wp["reached"] == len(wp["values"]) else f"[yellow]{note}[/yellow]")
        if "min_clearance" in r:
            items.append(f"min clearance {_num(r['min_clearance'])}")
        if "trace_JWJT" in r:
            items.append(f"tr(JWJᵀ) {_num(r['trace_JWJT']['initial'])} → {_num(r['trace_JWJT']['final'])}")
        if "plant" in r:  # a run through a simulated plant: the kinematic run's error and the actuator effort
            effort = max(r.get("actuator_effort", {}).get("max_abs", {}).values(), default=None)
            items.append(f"{r['plant']} plant; kinematic max {_num(r.get('kinematic_max_task_error'), '.2g')}")
            items.append(f"max |τ| {_num(effort)} N·m")
        viol = str(r["limit_violations"])
        damped = str(r.get("damped_steps", 0)) + (f" ({r['fallbacks']} fb)" if r.get("fallbacks") else "")
        table.add_row(
            f"[bold]{name}[/bold]\n[dim]({r['resolver']})[/dim]",
            f"{_num(r['max_task_error'], '.2g')} / {_num(r['final_task_error'], '.2g')}",
            "; ".join(items) or "–",
            f"{r['step_time_us']['median']:.0f}",
            f"[red]{viol}[/red]" if r["limit_violations"] else viol,
            damped,
        )
    return table


def print_summary(summary: dict[str, Any], console: Console | None = None) -> None:
    """Print :func:`summary_table`."""
    (console or Console()).print(summary_table(summary))
