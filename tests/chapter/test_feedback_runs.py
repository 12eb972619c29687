"""State-feedback run of the 17-joint dual arm: each controlled subtask follows p_d + (p0 − p_d) e^(−Kt)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from redundik.config import load_task
from redundik.config.runner import run_task

ROOT = Path(__file__).resolve().parents[2]


def test_dualarm_feedback_subtasks_converge_exponentially_while_hands_track() -> None:
    plan = load_task(ROOT / "tasks/dualarm17.yaml")
    plan.steps = 150  # 3 s
    res = run_task(plan, ["independent_rank", "independent_feedback"])
    r = res["independent_feedback"]
    t = r.log.t
    for name, target in (("centering", 6.0), ("elbow_left", 0.8)):
        p = r.log.potentials[name]
        ideal = target + (p[0] - target) * np.exp(-1.0 * t)  # ṗ = K (p_d − p), K = 1 /s
        assert np.abs(p - ideal).max() < 0.06 * abs(p[0] - target), name
        # without the law the rank solution goes elsewhere (centering grows, sin²θ7 stays near 1)
        assert abs(res["independent_rank"].log.potentials[name][-1] - target) > 5 * abs(p[-1] - target), name
    assert r.summary["max_task_error"] < 5e-3
    assert r.summary["limit_violations"] == 0
