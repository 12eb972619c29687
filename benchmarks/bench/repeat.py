"""``--repeat N``: the full comparison run N times (each one interleaved run), summarised per case as the median of
the N runs' figures with their spread (min–max) — the ratios the README quotes.

A ratio is only ever taken inside one run (a case over its peer of the same run); the summary then takes the median
and the range of those per-run ratios, never a ratio of medians from different runs.
"""

from __future__ import annotations

import statistics
from collections.abc import Sequence
from typing import Any

from benchmarks.bench.harness import BenchResult

#: The per-run figures summarised per case (keys of :meth:`BenchResult.ratios` and of the case).
FIGURES: tuple[str, ...] = ("median_us", "p90_us", "ratio", "ratio_placo", "ratio_builtin")


def _spread(values: Sequence[float | None]) -> dict[str, Any] | None:
    vals = [float(v) for v in values if v is not None]
    if not vals:
        return None
    return {"median": statistics.median(vals), "min": min(vals), "max": max(vals), "n": len(vals)}


def summarise_runs(results: Sequence[BenchResult]) -> dict[str, Any]:
    """``{"runs": N, "cases": [...], "targets": [...], "cold_start": [...]}``: per case (robot, method, backend) the
    median, min and max over the runs of each of :data:`FIGURES`, the paths it took and how many runs it passed;
    per target the measured value's spread and in how many runs it was met."""
    keys: list[tuple[str, str, str]] = []
    per: dict[tuple[str, str, str], dict[str, list[Any]]] = {}
    for res in results:
        ratios = {(r["robot"], r["method"], r["backend"]): r for r in res.ratios()}
        for c in res.cases:
            key = (c.robot, c.method, c.backend)
            if key not in per:
                keys.append(key)
                per[key] = {k: [] for k in (*FIGURES, "path", "ok", "builtin")}
            rec = per[key]
            r = ratios.get(key, {})
            rec["median_us"].append(c.median_us if c.ok else None)
            rec["p90_us"].append(c.p90_us if c.ok else None)
            for k in ("ratio", "ratio_placo", "ratio_builtin"):
                rec[k].append(r.get(k))
            rec["path"].append(c.extra.get("path"))
            rec["ok"].append(c.ok)
            rec["builtin"].append(r.get("builtin"))
    cases = []
    for key in keys:
        rec = per[key]
        paths = sorted({str(p) for p in rec["path"] if p is not None})
        builtin = next((b for b in rec["builtin"] if b), None)
        row: dict[str, Any] = {"robot": key[0], "method": key[1], "backend": key[2]}
        row.update({k: _spread(rec[k]) for k in FIGURES})
        row.update({"builtin": builtin, "paths": paths, "ok_runs": sum(rec["ok"]), "runs": len(rec["ok"])})
        cases.append(row)
    targets: dict[str, dict[str, Any]] = {}
    for res in results:
        for t in res.targets():
            rec = targets.setdefault(t["target"], {"target": t["target"], "limit": t["limit"], "kind": t.get("kind"),
                                                   "values": [], "met_runs": 0})  # fmt: skip
            rec["values"].append(t["value"])
            rec["met_runs"] += bool(t["met"])
    for rec in targets.values():
        rec["value"] = _spread(rec.pop("values"))
    cold: dict[str, dict[str, list[Any]]] = {}
    for res in results:
        for c in res.cold_start:
            rec = cold.setdefault(c["method"], {"cold_first_dq_s": [], "warm_first_dq_s": []})
            for k in rec:
                rec[k].append(c.get(k))
    return {
        "runs": len(results),
        "cases": cases,
        "targets": list(targets.values()),
        "cold_start": [{"method": m, **{k: _spread(v) for k, v in rec.items()}} for m, rec in cold.items()],
    }


def _cell(s: dict[str, Any] | None, digits: int = 2) -> str:
    if s is None:
        return "–"
    if s["n"] == 1:
        return f"{s['median']:.{digits}f}"
    return f"{s['median']:.{digits}f} ({s['min']:.{digits}f}–{s['max']:.{digits}f})"


def repeat_markdown(summary: dict[str, Any], command: str = "") -> str:
    """The summary as Markdown: per case the median of the runs' figures and their range, the targets, cold start."""
    n = summary["runs"]
    lines = [f"Command: `{command}`", ""] if command else []
    lines += [
        f"Median over {n} full runs, range (min–max) in brackets; every ratio is taken inside one run (a case over "
        "the faster of mink/pink, PlaCo, or its built-in case of the same run), then summarised. A run whose case "
        "FAILED gives it no figure (`ok runs`).",
        "",
        "| robot | method | backend | median µs | × faster peer | × PlaCo | × built-in | path | ok runs |",
        "|---|---|---|---:|---:|---:|---:|---|---:|",
    ]
    for c in summary["cases"]:
        built = "–" if c["ratio_builtin"] is None else f"{_cell(c['ratio_builtin'])} ({c['builtin']})"
        lines.append(
            f"| {c['robot']} | {c['method']} | {c['backend']} | {_cell(c['median_us'], 1)} | {_cell(c['ratio'])} | "
            f"{_cell(c['ratio_placo'])} | {built} | {' / '.join(c['paths']) or '–'} | {c['ok_runs']}/{c['runs']} |"
        )
    lines += ["", "Targets over the runs:", "", "| target | measured | limit | met in |", "|---|---:|---:|---:|"]
    for t in summary["targets"]:
        lim = ("≤ " if t.get("kind", "max") == "max" else "≥ ") + f"{t['limit']:g}"
        lines.append(f"| {t['target']} | {_cell(t['value'], 3)} | {lim} | {t['met_runs']}/{n} |")
    if summary["cold_start"]:
        lines += ["", "Cold start over the runs [s]:", ""]
        lines += ["| method | cold: first q̇ | warm: first q̇ |", "|---|---:|---:|"]
        for c in summary["cold_start"]:
            lines.append(f"| {c['method']} | {_cell(c['cold_first_dq_s'], 3)} | {_cell(c['warm_first_dq_s'], 3)} |")
    return "\n".join(lines) + "\n"
