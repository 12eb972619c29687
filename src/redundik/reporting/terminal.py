"""Terminal output of ``redundik run``: a compact rich table of the runs."""

from __future__ import annotations

from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table


def _num(x: float | None, fmt: str = ".3g") -> str:
    return "–" if x is None else format(x, fmt)


def clearance(run: dict[str, Any]) -> float | None:
    """A run's smallest clearance [length unit] from its summary: the collision world's smallest signed distance
    (``min_collision_distance``) and the clearance monitors' (``min_clearance``), the smaller; ``None`` if it has
    neither (negative: penetration)."""
    values = [float(run[k]) for k in ("min_collision_distance", "min_clearance") if run.get(k) is not None]
    return min(values) if values else None


def _limit_cell(r: dict[str, Any]) -> str:
    """Steps with a joint-limit violation and the largest violation [rad or length unit], red when any."""
    n = int(r["limit_violations"])
    if not n:
        return "0"
    worst = r.get("max_limit_violation")
    return f"[red]{n}[/red]" + (f"\n[red]max {_num(worst, '.2g')}[/red]" if worst is not None else "")


def _clearance_cell(r: dict[str, Any]) -> str:
    """The smallest clearance, red when negative (penetration), with the closest pair when known."""
    c = clearance(r)
    if c is None:
        return "–"
    text = _num(c, ".3g")
    pair = r.get("closest_pair") if r.get("min_collision_distance") == c else None  # a monitor's has no pair
    if c < 0:
        text = f"[red]{text}[/red]"
    return text + (f"\n[dim]{escape(str(pair))}[/dim]" if pair else "")


def summary_table(summary: dict[str, Any]) -> Table:
    """One row per run: resolver, task errors, subtask values, median step time, limit violations (steps and the
    largest), the smallest clearance (a column when any run has a collision world or a clearance monitor), damping."""
    unit = summary.get("length_unit", "m")
    runs = summary["runs"]
    with_clearance = any(clearance(r) is not None for r in runs.values())
    table = Table(
        title=f"{summary['task']}: {summary['robot']}, dt = {summary['dt']} s, {summary['steps']} steps",
        title_justify="left",
        padding=(0, 1),
    )
    table.add_column("run\n(resolver)", no_wrap=True)
    table.add_column(escape(f"error [{unit}]") + "\nmax / final", justify="right", no_wrap=True)
    table.add_column("subtasks\ninitial → final", min_width=12, ratio=1)
    table.add_column("µs/step\nmedian", justify="right", no_wrap=True)
    table.add_column("limit viol.\nsteps", justify="right", no_wrap=True)
    if with_clearance:
        table.add_column(escape(f"min clear. [{unit}]") + "\n(< 0: hit)", justify="right", no_wrap=True)
    table.add_column("damped", justify="right", no_wrap=True)
    for name, r in runs.items():
        items = [f"{k} {_num(v['initial'])} → {_num(v['final'])}" for k, v in r["subtasks"].items() if "initial" in v]
        for k, v in r["subtasks"].items():
            if "waypoints" in v:  # a round trip short of a waypoint is flagged
                wp = v["waypoints"]
                note = f"{escape(k)}: {wp['reached']}/{len(wp['values'])} waypoints reached"
                items.append(note if wp["reached"] == len(wp["values"]) else f"[yellow]{note}[/yellow]")
        if "trace_JWJT" in r:
            items.append(f"tr(JWJᵀ) {_num(r['trace_JWJT']['initial'])} → {_num(r['trace_JWJT']['final'])}")
        if "plant" in r:  # a run through a simulated plant: the kinematic run's error and the actuator effort
            effort = max(r.get("actuator_effort", {}).get("max_abs", {}).values(), default=None)
            items.append(f"{r['plant']} plant; kinematic max {_num(r.get('kinematic_max_task_error'), '.2g')}")
            items.append(f"max |τ| {_num(effort)} N·m")
        alarms = [f"{r['fallbacks']} fb"] if r.get("fallbacks") else []
        alarms += [f"{r['relaxed_steps']} relaxed"] if r.get("relaxed_steps") else []
        damped = str(r.get("damped_steps", 0)) + (f" ({', '.join(alarms)})" if alarms else "")
        cells = [
            f"[bold]{name}[/bold]\n[dim]({r['resolver']})[/dim]",
            f"{_num(r['max_task_error'], '.2g')} / {_num(r['final_task_error'], '.2g')}",
            "; ".join(items) or "–",
            f"{r['step_time_us']['median']:.0f}",
            _limit_cell(r),
            *([_clearance_cell(r)] if with_clearance else []),
            damped,
        ]
        table.add_row(*cells)
    return table


def print_summary(summary: dict[str, Any], console: Console | None = None) -> None:
    """Print :func:`summary_table`."""
    (console or Console()).print(summary_table(summary))
