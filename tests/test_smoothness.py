"""The smoothness metrics (:mod:`redundik.reporting.smoothness`) against sequences computed by hand, and their place in
a run's ``summary.json`` and CSV."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from redundik.reporting import smoothness as sm

# one joint, dt = 0.5 s: q̇ = 1, 1, 0, 2 (from rest: q̇ = 0 before)
DQ = np.array([[1.0], [1.0], [0.0], [2.0]])
DT = 0.5


def test_accelerations_and_jerks_by_hand() -> None:
    # from rest: q̈ = (1−0, 1−1, 0−1, 2−0)/0.5 = 2, 0, −2, 4; jerk = (2−0, 0−2, −2−0, 4+2)/0.5 = 4, −4, −4, 12
    np.testing.assert_allclose(sm.accelerations(DQ, DT)[:, 0], [2.0, 0.0, -2.0, 4.0])
    np.testing.assert_allclose(sm.jerks(DQ, DT)[:, 0], [4.0, -4.0, -4.0, 12.0])
    # not from rest: q̈ = 0, −2, 4 and jerk = −4, 12
    np.testing.assert_allclose(sm.accelerations(DQ, DT, from_rest=False)[:, 0], [0.0, -2.0, 4.0])
    np.testing.assert_allclose(sm.jerks(DQ, DT, from_rest=False)[:, 0], [-4.0, 12.0])


def test_chatter_counts_sign_changes_per_second() -> None:
    # q̈ = 2, 0, −2, 4: signs +, (0 skipped), −, + → 2 changes in M·dt = 2 s → 1 /s
    assert sm.chatter(DQ, DT)[0] == pytest.approx(1.0)
    # not from rest: q̈ = 0, −2, 4 → 1 change in 2 s
    assert sm.chatter(DQ, DT, from_rest=False)[0] == pytest.approx(0.5)
    # alternating q̇ = 1, −1, 1, −1 at dt = 0.1: q̈ = 10, −20, 20, −20 → 3 changes in 0.4 s
    alt = np.array([[1.0], [-1.0], [1.0], [-1.0]])
    assert sm.chatter(alt, 0.1)[0] == pytest.approx(7.5)


def test_the_dead_band_ignores_rounding_noise() -> None:
    # q̈ = 1, 1e-12, −1e-12, 1 (dt = 1): the noise lies in the band max(1e-9, 1e-6·1) → no change
    dq = np.array([[1.0], [1.0 + 1e-12], [1.0], [2.0]])
    assert sm.chatter(dq, 1.0)[0] == 0.0
    # without a band the noise flips twice: +, +, −, +
    assert sm.chatter(dq, 1.0, atol=0.0, rtol=0.0)[0] == pytest.approx(2 / 4)


def test_summary_and_columns_by_hand() -> None:
    dq = np.hstack([DQ, np.zeros((4, 1))])  # a second joint at rest
    s = sm.summary(dq, DT, ["a", "b"])
    assert s["max_abs_ddq"] == 4.0 and s["max_abs_jerk"] == 12.0
    assert s["chatter_per_s"] == {"max": 1.0, "mean": 0.5, "joint": "a"}
    assert s["chatter_by_joint"] == {"a": 1.0, "b": 0.0} and s["from_rest"] is True
    cols = dict(sm.columns(dq, DT, samples=5))
    np.testing.assert_array_equal(cols["max_abs_ddq"], [2.0, 0.0, 2.0, 4.0, np.nan])
    np.testing.assert_array_equal(cols["max_abs_jerk"], [4.0, 4.0, 4.0, 12.0, np.nan])
    np.testing.assert_array_equal(cols["ddq_sign_changes"], [0.0, 0.0, 1.0, 1.0, np.nan])


def test_an_empty_run_and_a_bad_shape() -> None:
    s = sm.summary(np.zeros((0, 2)), 0.1, ["a", "b"])
    assert s["max_abs_ddq"] == 0.0 and s["max_abs_jerk"] == 0.0 and s["chatter_per_s"]["max"] == 0.0
    with pytest.raises(ValueError, match=r"\(M, nv\)"):
        sm.accelerations(np.zeros(3), 0.1)


def test_a_run_reports_smoothness_in_its_summary_and_csv(tmp_path: Path) -> None:
    from redundik.config import load_task
    from redundik.config.runner import run_task
    from redundik.reporting.outputs import write_outputs
    from tests.hostile import TASK

    text = TASK.replace("steps: 500", "steps: 60").replace(
        "    resolver: wqp\n", "    resolver: wqp\n    options: {limits: {acceleration: 5.0, jerk: 100.0}}\n", 1
    )
    path = tmp_path / "t.yaml"
    path.write_text(text, encoding="utf-8")
    plan = load_task(path)
    results = run_task(plan, ["rank_only", "wqp"])
    summary = write_outputs(plan, results, tmp_path / "out")
    for name, result in results.items():
        smooth = summary["runs"][name]["smoothness"]
        acc = np.diff(np.vstack([np.zeros((1, 3)), result.log.dq[:-1]]), axis=0) / plan.dt
        assert smooth["max_abs_ddq"] == pytest.approx(float(np.max(np.abs(acc))))
        header = (tmp_path / "out" / f"{name}.csv").read_text().splitlines()[0].split(",")
        for col in ("max_abs_ddq", "max_abs_jerk", "ddq_sign_changes"):
            assert col in header
    # the jerk-limited run keeps |q̈| ≤ 5 and |jerk| ≤ 100 (1e-9 relative); the unlimited one jumps from rest
    assert summary["runs"]["wqp"]["smoothness"]["max_abs_jerk"] <= 100.0 * (1 + 1e-9)
    assert summary["runs"]["wqp"]["smoothness"]["max_abs_ddq"] <= 5.0 * (1 + 1e-9)
    assert summary["runs"]["rank_only"]["smoothness"]["max_abs_jerk"] > 1e3
