"""Sweep outputs: the result table (Parquet through pyarrow, or CSV), a map figure and ``summary.json``.

Every file goes through :func:`redundik.reporting.paths.safe_path`. CSV numbers are written with ``repr`` (the
shortest text that reads back to the same double), so a CSV table holds the same values as the Parquet one.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np

from redundik._extras import require
from redundik.reporting.paths import safe_path
from redundik.sweep.engine import SweepResult
from redundik.sweep.plan import SweepPlan
from redundik.sweep.solve import STATUSES

FORMATS = ("parquet", "csv")


def write_table(columns: dict[str, np.ndarray], out_dir: Path, stem: str, fmt: str = "parquet") -> Path:
    """Write the result table as ``STEM.parquet`` or ``STEM.csv`` in ``out_dir``; its path.

    Raises:
        MissingDependencyError: Parquet without pyarrow (extra ``sweep``).
        ValueError: an unknown format.
    """
    if fmt not in FORMATS:
        raise ValueError(f"format must be one of {FORMATS}, got {fmt!r}")
    path = safe_path(out_dir, f"{stem}.{fmt}")
    if fmt == "parquet":
        pa = require("pyarrow", "Parquet output")
        pq = require("pyarrow.parquet", "Parquet output")
        table = pa.table({k: pa.array(list(v) if v.dtype == object else v) for k, v in columns.items()})
        pq.write_table(table, path)
        return path
    names = list(columns)
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(names)
        cols = [columns[k].tolist() for k in names]
        for row in zip(*cols, strict=True):
            w.writerow([repr(v) if isinstance(v, float) else v for v in row])
    return path


def read_table(path: Path) -> dict[str, np.ndarray]:
    """Read a table written by :func:`write_table` back into columns (for checks and notebooks)."""
    path = Path(path)
    if path.suffix == ".parquet":
        pq = require("pyarrow.parquet", "Parquet output")
        table = pq.read_table(path)
        return {
            name: np.array(col.to_pylist(), dtype=object) if col.type == "string" else col.to_numpy()
            for name, col in zip(table.column_names, table.columns, strict=True)
        }
    with path.open(encoding="utf-8", newline="") as fh:
        rows = list(csv.reader(fh))
    header, body = rows[0], rows[1:]
    out: dict[str, np.ndarray] = {}
    for j, name in enumerate(header):
        vals = [r[j] for r in body]
        if name == "status":
            out[name] = np.array(vals, dtype=object)
        elif name == "converged":
            out[name] = np.array([v == "True" for v in vals])
        elif name in ("problem", "target_index", "start_index", "iterations", "qp_steps", "restarts"):
            out[name] = np.array(vals, dtype=np.int64)
        else:
            out[name] = np.array(vals, dtype=float)
    return out


def per_target(plan: SweepPlan, columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Per target: fraction of starts that converged, and the best manipulability among them (NaN: none did)."""
    n_t = plan.n_targets
    ti = columns["target_index"]
    conv = columns["converged"].astype(float)
    frac = np.bincount(ti, weights=conv, minlength=n_t) / plan.n_starts
    best = np.full(n_t, -np.inf)
    m = np.where(columns["converged"], columns["manipulability"], -np.inf)
    np.maximum.at(best, ti, m)
    best[~np.isfinite(best)] = np.nan
    return {"reached_fraction": frac, "best_manipulability": best}


def _plane(plan: SweepPlan) -> tuple[int, int]:
    if plan.spec.figure.plane is not None:
        a, b = plan.spec.figure.plane
        return "xyz".index(a), "xyz".index(b)
    spread = np.ptp(plan.target_positions, axis=0)
    order = np.argsort(-spread, kind="stable")
    return tuple(sorted(int(i) for i in order[:2]))  # type: ignore[return-value]


def write_figure(plan: SweepPlan, columns: dict[str, np.ndarray], out_dir: Path) -> Path:
    """``NAME_map.png``: the targets on a world plane, coloured by reached fraction and by manipulability."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    agg = per_target(plan, columns)
    a, b = _plane(plan)
    P = plan.target_positions
    x, y = P[:, a], P[:, b]
    fig, axs = plt.subplots(1, 2, figsize=(11, 5), constrained_layout=True)
    size = max(2.0, min(60.0, 40000.0 / max(plan.n_targets, 1)))
    s0 = axs[0].scatter(x, y, c=agg["reached_fraction"], s=size, marker="s", cmap="viridis", vmin=0, vmax=1)
    fig.colorbar(s0, ax=axs[0], label="fraction of starts converged")
    ok = np.isfinite(agg["best_manipulability"])
    axs[1].scatter(x[~ok], y[~ok], c="0.85", s=size, marker="s", label="not reached")
    if ok.any():
        s1 = axs[1].scatter(x[ok], y[ok], c=agg["best_manipulability"][ok], s=size, marker="s", cmap="magma")
        fig.colorbar(s1, ax=axs[1], label="manipulability √det(J Jᵀ) at the solution (best start)")
    axs[1].legend(loc="upper right", fontsize=8)
    names = "xyz"
    for ax, title in zip(axs, ("reachability", "manipulability"), strict=True):
        ax.set_xlabel(f"{names[a]} [m]")
        ax.set_ylabel(f"{names[b]} [m]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(f"{plan.name}: {title} of {plan.spec.task.frame}")
    path = safe_path(out_dir, f"{plan.name}_map.png")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def summary(plan: SweepPlan, result: SweepResult) -> dict[str, Any]:
    """Counts by status, iteration statistics and where/how fast it ran."""
    c = result.columns
    conv = c["converged"]
    counts = {s: int(np.count_nonzero(c["status"] == s)) for s in STATUSES}
    return {
        "name": plan.name,
        "problems": result.n_problems,
        "targets": plan.n_targets,
        "starts": plan.n_starts,
        "resolver": plan.spec.resolver.name,
        "method": plan.spec.method,
        "status": counts,
        "converged_fraction": float(np.mean(conv)) if conv.size else 0.0,
        "median_iterations_converged": float(np.median(c["iterations"][conv])) if conv.any() else None,
        "max_final_error_converged": float(np.max(c["final_error"][conv])) if conv.any() else None,
        "qp_steps": int(np.sum(c["qp_steps"])),
        "engine": result.engine,
        "workers": result.workers,
        "chunks": result.chunks,
        "chunk_size": plan.spec.chunk_size,
        "seconds": round(result.seconds, 3),
        "problems_per_s": round(result.n_problems / result.seconds, 1) if result.seconds > 0 else None,
    }


def write_outputs(
    plan: SweepPlan, result: SweepResult, out_dir: Path, fmt: str = "parquet", figure: bool = True
) -> dict[str, Path]:
    """Write the table, the figure (if asked and enabled in the file) and ``summary.json``; their paths by kind."""
    paths = {"table": write_table(result.columns, out_dir, plan.name, fmt)}
    if figure and plan.spec.figure.enabled:
        paths["figure"] = write_figure(plan, result.columns, out_dir)
    p = safe_path(out_dir, "summary.json")
    p.write_text(json.dumps(summary(plan, result), indent=2) + "\n", encoding="utf-8")
    paths["summary"] = p
    return paths
