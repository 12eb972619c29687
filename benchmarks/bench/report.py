"""Write a benchmark run as a Markdown table, a JSON file and a plot (matplotlib, Agg, imported lazily)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from benchmarks.bench.harness import BATCH_METHODS, METHODS, PEERS, BenchResult


def _num(x: float, digits: int = 1) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "–"
    return f"{x:.{digits}f}"


def _sci(x: float) -> str:
    return "–" if x is None or math.isnan(x) else f"{x:.2e}"


def to_json(result: BenchResult) -> dict[str, Any]:
    """The JSON document: ``{"cases": [...], "ratios": [...], "targets": [...], "skipped": [...], "meta": {...}}``."""
    return {
        "cases": [c.as_json() for c in result.cases],
        "ratios": result.ratios(),
        "targets": result.targets(),
        "skipped": result.skipped,
        "cold_start": result.cold_start,
        "meta": result.meta,
    }


def write_json(result: BenchResult, path: str | Path) -> Path:
    """Write :func:`to_json` to ``path`` (parents created)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(json.dumps(to_json(result), indent=2, allow_nan=False, default=_json_default))
    return p


def _json_default(obj: object) -> object:
    if hasattr(obj, "item"):
        return obj.item()  # numpy scalars
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def markdown(result: BenchResult, command: str = "") -> str:
    """The Markdown report: main table, ratios to the faster peer, targets, per-stage profile, skipped cases."""
    order = {m: i for i, m in enumerate(METHODS)}
    robots = list(result.meta["robots"])
    cases = sorted(result.cases, key=lambda c: (robots.index(c.robot), order[c.method]))
    lines: list[str] = []
    if command:
        lines += [f"Command: `{command}`", ""]
    m = result.meta
    lines += [
        f"{m['steps']} timed steps per case after {m['warmup']} warm-up steps (fewer on the slow snakes; the batch "
        f"case {m.get('batch_steps', '–')} calls of its problems), round-robin in chunks of {m['chunk']}; "
        f"Python {m['python']} on {m['platform']} ({m['processor']}); wall time {m['wall_time_s']:.0f} s.",
        "",
        "| robot | method | backend | median µs | p90 µs | × faster peer | max task error | subtask (final) "
        "| limit viol. | fallbacks | path | status |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|---|",
    ]
    for c in cases:
        if c.method in BATCH_METHODS:
            continue
        peer = result.faster_peer(c.robot)
        ratio = "–" if peer is None or not c.ok else _num(c.median_us / peer.median_us, 2)
        star = " (default)" if c.default_backend else ""
        lines.append(
            f"| {c.robot} | {c.method} | {c.backend}{star} | {_num(c.median_us)} | {_num(c.p90_us)} | {ratio} "
            f"| {_sci(c.max_task_error)} | {c.subtask_label} = {c.subtask_final:.4g} | {c.limit_violations}"
            f"{'' if not c.limit_violations else f' (max {c.max_violation:.1e})'} | {c.fallback_steps + c.failures} "
            f"| {_path(c)} | {_status(c.status)} |"
        )
    lines += user_table(result)
    lines += cold_start_table(result)
    lines += batch_table(result)
    lines += placo_table(result)
    lines += snake_table(result)
    lines += qp_split_table(result)
    lines += ["", "Targets (issues 11 and 31, measured in this run):", ""]
    lines += targets_table(result)
    prof = [c for c in cases if c.stages_us]
    if prof:
        lines += [
            "",
            "Per-stage profile of redundik's methods (median µs per step, separate probed run):",
            "",
            "| robot | method | backend | kinematics | tasks | build | solve | other | total | QP called |",
            "|---|---|---|---:|---:|---:|---:|---:|---:|---:|",
        ]
        for c in prof:
            s = c.stages_us or {}
            lines.append(
                f"| {c.robot} | {c.method} | {c.backend} | "
                + " | ".join(_num(s.get(k, float("nan"))) for k in ("kinematics", "tasks", "build", "solve", "other"))
                + f" | {_num(s.get('total', float('nan')))} | "
                + ("–" if c.qp_fraction is None else f"{100 * c.qp_fraction:.0f} %")
                + " |"
            )
    fails = [c for c in cases if c.first_failure]
    if fails:
        lines += ["", "First failure per case:", ""]
        lines += [f"- {c.robot}/{c.method}/{c.backend}: {c.first_failure}" for c in fails]
    if result.skipped:
        lines += ["", "Skipped:", ""] + [f"- {s}" for s in result.skipped]
    return "\n".join(lines) + "\n"


def _path(c: Any) -> str:
    """``result.info["path"]`` of a redundik case, with the members it ran interpreted (``–`` for the peers)."""
    path = c.extra.get("path")
    if path is None:
        return "–"
    names = c.extra.get("interpreted") or []
    return str(path) + (f" ({', '.join(names)})" if names else "")


def user_table(result: BenchResult) -> list[str]:
    """Issue 31's user cases: median, p90, × their built-in case, × the faster peer, × PlaCo, and the path."""
    rows = [r for r in result.ratios() if r.get("builtin") is not None]
    if not rows:
        return []
    by_key = {(c.robot, c.method, c.backend): c for c in result.cases}
    lines = [
        "",
        "What users run (issue 31; public classes only, same run): each case over its built-in case of the same "
        "method and backend (teleop: the trajectory tick), over the faster peer and PlaCo on the same task set:",
        "",
        "| case | method | backend | median µs | p90 µs | × built-in | built-in | × faster peer | × PlaCo | path |",
        "|---|---|---|---:|---:|---:|---|---:|---:|---|",
    ]
    for r in rows:
        c = by_key[(r["robot"], r["method"], r["backend"])]
        peer = "–" if r["ratio"] is None else f"{r['ratio']:.2f}"
        placo = "–" if r["ratio_placo"] is None else f"{r['ratio_placo']:.2f}"
        lines.append(
            f"| {c.robot} | {c.method} | {c.backend} | {_num(c.median_us)} | {_num(c.p90_us)} | "
            f"{r['ratio_builtin']:.2f} | {r['builtin']} | {peer} | {placo} | {_path(c)} |"
        )
    return lines


def cold_start_table(result: BenchResult) -> list[str]:
    """``cold_start``: the first q̇ of a fresh process on an empty cache and on a warm one, per method."""
    if not result.cold_start:
        return []
    lines = [
        "",
        "Cold start (fresh processes: `import`, set-up and the first step [s]; cold = empty `NUMBA_CACHE_DIR`, warm "
        "= the cache the cold run wrote; the peers compile nothing: one run):",
        "",
        "| method | cold: first q̇ | of it, first step | warm: first q̇ | of it, first step | second step | "
        "first step's path | status |",
        "|---|---:|---:|---:|---:|---:|---|---|",
    ]
    for rec in result.cold_start:
        second = rec.get("warm_second_step_s", rec.get("cold_second_step_s"))
        path = rec.get("cold_path", rec.get("warm_path", "–"))
        names = rec.get("cold_interpreted", rec.get("warm_interpreted")) or []
        lines.append(
            f"| {rec['method']} | {_sec(rec.get('cold_first_dq_s'))} | {_sec(rec.get('cold_first_step_s'))} | "
            f"{_sec(rec.get('warm_first_dq_s'))} | {_sec(rec.get('warm_first_step_s'))} | {_sec(second)} | "
            f"{path}{f' ({chr(44).join(names)})' if names else ''} | {_status(rec['status'])} |"
        )
    return lines


def _sec(x: float | None) -> str:
    return "–" if x is None else (f"{x:.3f}" if x < 10 else f"{x:.1f}")


def targets_table(result: BenchResult) -> list[str]:
    """The targets as Markdown rows: measured value, limit, met (yes / **no** / – not measured), detail."""
    lines = ["| target | measured | limit | met | detail |", "|---|---:|---:|---|---|"]
    for t in result.targets():
        val = "–" if t["value"] is None else f"{t['value']:.3g}"
        lim = ("≤ " if t.get("kind", "max") == "max" else "≥ ") + f"{t['limit']:g}"
        met = {True: "yes", False: "**no**", None: "–"}[t["met"]]
        lines.append(f"| {t['target']} | {val} | {lim} | {met} | {t['detail']} |")
    return lines


def batch_table(result: BenchResult) -> list[str]:
    """The batch case: per method the time per call of all problems, problems/s, the QP fraction, status."""
    cases = [c for c in result.cases if c.method in BATCH_METHODS]
    if not cases:
        return []
    lines = [
        "",
        f"Batch ({cases[0].extra.get('problems', '?')} Panda pose problems per call):",
        "",
        "| method | backend | median µs per call | p90 µs | problems/s | × ordinary steps | QP called "
        "| max task error | vs reset loop | path | status |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---|---|",
    ]
    for c in sorted(cases, key=lambda c: BATCH_METHODS.index(c.method)):
        agree = c.extra.get("loop_agreement")
        steps = result.fastest(c.robot, c.method.split("_")[0] + "_steps")
        speed = "–" if steps is None or not steps.problems_per_s or not c.ok else (
            f"{(c.problems_per_s or 0.0) / steps.problems_per_s:.2f}"
        )  # fmt: skip
        lines.append(
            f"| {c.method} | {c.backend} | {_num(c.median_us, 0)} | {_num(c.p90_us, 0)} | "
            f"{_num(c.problems_per_s or float('nan'), 0)} | {speed} | "
            + ("–" if c.qp_fraction is None else f"{100 * c.qp_fraction:.1f} %")
            + f" | {_sci(c.max_task_error)} | {'–' if agree is None else f'{agree:.1e}'} | {_path(c)} "
            f"| {_status(c.status)} |"
        )
    return lines


def placo_table(result: BenchResult) -> list[str]:
    """redundik's methods over PlaCo's median, per robot where PlaCo ran."""
    rows = [r for r in result.ratios() if r.get("ratio_placo") is not None]
    if not rows:
        return []
    lines = ["", "× PlaCo (its median per step, measured in its own process in the same run):", ""]
    lines += ["| robot | method | backend | × PlaCo |", "|---|---|---|---:|"]
    lines += [f"| {r['robot']} | {r['method']} | {r['backend']} | {r['ratio_placo']:.2f} |" for r in rows]
    return lines


def snake_table(result: BenchResult) -> list[str]:
    """Snake scaling: median and p90/median per n and method, and the fitted growth exponent."""
    fits = [result.snake_fit(m) for m in ("pinv", "wqp", "hqp")]
    sizes = sorted({n for f in fits for n in f["n"]})
    if not sizes:
        return []
    lines = [
        "",
        "Snake scaling (median µs per step, p90/median and the fraction of steps that called the QP backend in "
        "brackets; exponent b of median ∝ nᵇ, and of p90):",
        "",
    ]
    lines += ["| method | " + " | ".join(f"n = {n}" for n in sizes) + " | exponent | exponent of p90 |"]
    lines += ["|---|" + "---:|" * len(sizes) + "---:|---:|"]
    for f in fits:
        cells = []
        for n in sizes:
            if n in f["n"]:
                i = f["n"].index(n)
                qp = f["qp_fraction"][i]
                cells.append(
                    f"{f['median_us'][i]:.0f} ({f['p90_over_median'][i]:.2f}"
                    + ("" if qp is None else f"; QP {100 * qp:.0f} %")
                    + ")"
                )
            else:
                cells.append("–")
        exp = "–" if f["exponent"] is None else f"{f['exponent']:.2f}"
        exp90 = "–" if f["exponent_p90"] is None else f"{f['exponent_p90']:.2f}"
        lines.append(f"| {f['method']} | " + " | ".join(cells) + f" | {exp} | {exp90} |")
    return lines


def qp_split_table(result: BenchResult) -> list[str]:
    """The two kinds of ``wqp``/``hqp`` step, timed apart: the steps that call the QP backend (a constraint is
    active) and the closed-form ones — a step's time is bimodal; the p90 falls among the QP steps past 10 % of them."""
    rows = [
        c
        for c in result.cases
        if c.method in ("wqp", "hqp") and c.default_backend and c.extra.get("qp_step_median_us") is not None
    ]
    if not rows:
        return []
    lines = [
        "",
        "Steps that call the QP backend and the others, timed apart (default backend; median µs per step):",
        "",
        "| robot | method | QP steps | other steps | QP steps' median | others' median | QP / other |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for c in rows:
        qp, free = c.extra["qp_step_median_us"], c.extra.get("free_step_median_us")
        share = 100 * (c.qp_fraction or 0.0)
        ratio = "–" if not free else f"{qp / free:.2f}"
        other = "–" if free is None else f"{free:.1f}"
        lines.append(f"| {c.robot} | {c.method} | {share:.0f} % | {100 - share:.0f} % | {qp:.1f} | {other} | {ratio} |")
    return lines


def _status(status: str) -> str:
    return "ok" if status == "ok" else "**FAILED**: " + status.removeprefix("failed: ")


def readme_table(result: BenchResult) -> str:
    """The README's compact table: per robot and method, the default backend (wqp/hqp) or the fastest (peers),
    median µs, ratio to the faster peer (only for cases that did not fail), max error and status."""
    order = {m: i for i, m in enumerate(METHODS)}
    robots = list(result.meta["robots"])
    lines = [
        "| robot | method | backend | median µs | × faster peer | max task error | path | status |",
        "|---|---|---|---:|---:|---:|---|---|",
    ]
    shown: list[int] = []
    for robot in robots:
        peer = result.faster_peer(robot)
        for method in sorted({c.method for c in result.cases if c.robot == robot}, key=order.__getitem__):
            if method in PEERS:
                c = result.fastest(robot, method) or min(result.find(robot, method), key=lambda c: c.median_us)
            else:
                c = result.default(robot, method) or result.find(robot, method)[0]
            shown.append(id(c))
            ratio = (
                "–" if peer is None or not c.ok or method in BATCH_METHODS else f"{c.median_us / peer.median_us:.2f}"
            )
            pps = "" if c.problems_per_s is None else f" ({c.problems_per_s:.0f} problems/s)"
            lines.append(
                f"| {robot} | {method} | {c.backend} | {_num(c.median_us, 0)}{pps} | {ratio} | "
                f"{_sci(c.max_task_error)} | {_path(c)} | {_status(c.status)} |"
            )
    failed = [c for c in result.cases if not c.ok and id(c) not in shown]
    if failed:
        lines += ["", "Other cases (backends) that FAILED:", ""]
        lines += [f"- {c.robot}/{c.method}/{c.backend}: {c.status.removeprefix('failed: ')}" for c in failed]
    return "\n".join(lines) + "\n"


def ratio_lines(result: BenchResult) -> list[str]:
    """One line per redundik case: its median over the faster peer's; then one line per FAILED case."""
    lines = []
    for r in result.ratios():
        parts = [] if r["ratio"] is None else [f"{r['ratio']:.2f} × {r['peer']}"]
        if r.get("ratio_placo") is not None:
            parts.append(f"{r['ratio_placo']:.2f} × placo")
        if r.get("ratio_builtin") is not None:
            parts.append(f"{r['ratio_builtin']:.2f} × {r['builtin']}")
        path = f"  [{r['path']}]" if r.get("path") else ""
        lines.append(f"{r['robot']:>12} {r['method']:>8}/{r['backend']:<10} = " + ", ".join(parts) + path)
    lines += [f"{c.robot:>9} {c.method:>8}/{c.backend:<10} FAILED: {c.status.removeprefix('failed: ')}"
              for c in result.cases if not c.ok]  # fmt: skip
    return lines


def plot(result: BenchResult, path: str | Path) -> Path:
    """Horizontal bars of the median step time (p90 as whisker), one panel per robot, log scale; PNG."""
    from redundik._extras import require

    matplotlib = require("matplotlib", "plotting")

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    robots = [r for r in result.meta["robots"] if any(c.robot == r and c.median_us > 0 for c in result.cases)]
    order = {m: i for i, m in enumerate(METHODS)}
    fig, axes = plt.subplots(len(robots), 1, figsize=(8, 1.2 + 0.32 * len(result.cases)), squeeze=False)
    colors = {"pinv": "C0", "feedback": "C1", "wqp": "C2", "hqp": "C3", "mink": "C7", "pink": "C8", "placo": "C4"}
    for ax, robot in zip(axes[:, 0], robots, strict=True):
        cs = sorted(
            [c for c in result.cases if c.robot == robot and c.median_us > 0],
            key=lambda c: (order[c.method], c.median_us),
        )
        y = list(range(len(cs)))
        med = [c.median_us for c in cs]
        err = [max(c.p90_us - c.median_us, 0.0) for c in cs]
        ax.barh(y, med, xerr=[[0.0] * len(cs), err], color=[colors.get(c.method.split("_")[0], "C9") for c in cs])
        ax.set_yticks(y, [f"{c.method}/{c.backend}" for c in cs], fontsize=8)
        ax.invert_yaxis()
        ax.set_xscale("log")
        ax.set_title(robot, fontsize=9)
        ax.grid(axis="x", which="both", alpha=0.3)
    axes[-1, 0].set_xlabel("time per IK step [µs] (batch: per call) (median, whisker to p90)")
    fig.tight_layout()
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return p


def write_all(
    result: BenchResult, out_dir: str | Path, command: str = "", json_path: str | Path | None = None
) -> dict[str, Any]:
    """Write ``compare_resolvers.md``, ``.json`` and ``.png`` to ``out_dir`` (and the JSON to ``json_path``)."""
    from redundik.reporting.paths import safe_path

    md = safe_path(out_dir, "compare_resolvers.md")
    md.write_text(markdown(result, command))
    safe_path(out_dir, "readme_table.md").write_text(readme_table(result))
    paths = {"markdown": md, "json": write_json(result, safe_path(out_dir, "compare_resolvers.json")), "plot": None}
    if json_path is not None:
        paths["json_requested"] = write_json(result, json_path)
    if result.cases:
        paths["plot"] = plot(result, safe_path(out_dir, "compare_resolvers.png"))
    return paths
