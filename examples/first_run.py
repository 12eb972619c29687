"""Tutorial 1, your first task run: run ``tasks/planar3r_line.yaml`` with the ``redundik`` command, read summary.json.

The chapter's 3R arm draws a straight line with its tip; the file holds six runs of the same task (rank solution
only, rank plus null-space gradient of p = sin²θ3, the state-feedback law, a closed-loop variant, ``wqp``, ``hqp``).
This script runs the command a shell user would type, into a temporary folder, and reads the summary it writes.

Run: ``python examples/first_run.py``; the last line checks the book's result (θ3 → −90° with the null-space term).
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

TASK = Path(__file__).resolve().parents[1] / "tasks" / "planar3r_line.yaml"


def redundik_command() -> list[str]:
    """The ``redundik`` console script of this interpreter's environment (found even when it is not on PATH)."""
    beside = Path(sys.executable).with_name("redundik")
    if beside.is_file():
        return [str(beside)]
    found = shutil.which("redundik")
    if found is None:
        raise SystemExit("the `redundik` command is not installed: pip install -e . (or pip install redundik)")
    return [found]


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "planar3r_line"
        # the shell command: redundik run tasks/planar3r_line.yaml --out DIR --no-figures --quiet
        cmd = [*redundik_command(), "run", str(TASK), "--out", str(out), "--no-figures", "--quiet"]
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if proc.returncode != 0:
            print(proc.stdout, proc.stderr, sep="\n")
            return 1
        print("written:", ", ".join(sorted(p.name for p in out.iterdir())))
        summary = json.loads((out / "summary.json").read_text())

    print(f"task {summary['task']!r}: {summary['steps']} steps of dt = {summary['dt']} s, joints {summary['joints']}")
    print(f"{'run':12} {'resolver':9} {'θ3 final [deg]':>15} {'max tip error [mm]':>19} {'sin²θ3 final':>13} fallbacks")
    for name, run in summary["runs"].items():
        theta3 = math.degrees(run["final_q"][2])
        sin2 = run["potentials"]["sin2_q3"]["final"]
        print(
            f"{name:12} {run['resolver']:9} {theta3:15.1f} {1e3 * run['max_task_error']:19.3f} {sin2:13.4f} "
            f"{run['fallbacks']}"
        )

    runs = summary["runs"]
    theta3_null = math.degrees(runs["rank_null"]["final_q"][2])
    ok = -90.0 < theta3_null < -85.0 and runs["rank_null"]["max_task_error"] < 5e-3
    ok = ok and all(run["fallbacks"] == 0 for run in runs.values())
    verdict = "OK" if ok else "FAIL"
    print(f"check: rank_null ends at θ3 = {theta3_null:.1f}° (the book: → −90°), tip within 5 mm: {verdict}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
