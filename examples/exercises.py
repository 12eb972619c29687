"""The chapter's exercises 1–3 (section 5.5.2): the one-shot answers at the configurations of their task files.

The task runs ``tasks/exercise{1,2,3}_*.yaml`` simulate the motions (``redundik run exercise1_prrp`` ...); the
answers that are a single evaluation at one configuration are :mod:`redundik.kinematics.analysis`: a minimum-norm
velocity (5.7), the general solution with a subtask gradient (5.8), a null-solution check, the joint torques τ = JᵀF
of a static force. This script loads the shipped task files (geometry chosen in ``configs/prrp_beam.yaml``,
``configs/rrp_bowl.yaml``, ``configs/rpr_lamp.yaml``) and prints them.

Run: ``python examples/exercises.py`` (needs the ``cli`` extra for the YAML layer).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from redundik.config import load_task
from redundik.config.runner import run_task
from redundik.kinematics import analysis
from redundik.shipped import data_dir

GRAVITY = 9.81  # [m/s²]


def answers(root: Path | None = None) -> dict[str, dict[str, np.ndarray | float]]:
    """The one-shot answers of exercises 1–3 at the configurations of their task files.

    Args:
        root: The folder holding ``tasks/`` and ``configs/`` (default: the shipped copies, found installed or not).

    Exercise 2's contact configuration is the final sample of its ``avoid_hqp`` run (w at (0.8, 0)).
    """
    root = root or data_dir()
    out: dict[str, dict[str, np.ndarray | float]] = {}

    p1 = load_task(root / "tasks/exercise1_prrp.yaml")
    r1 = p1.robot.model
    r1.update(p1.runs["min_norm"].q0)
    J1 = analysis.task_jacobian(r1, "4", ("x", "y", "z"))
    v1 = np.array([0.0, 1.0, 0.0])
    theta3 = float(p1.runs["min_norm"].q0[2])
    eta = np.zeros(r1.nv)
    eta[2] = np.sin(2 * theta3)
    out["exercise1"] = {
        "J": J1,
        "qdot_min_norm": analysis.min_norm_velocity(J1, v1),
        "qdot_sing_avoid_k1": analysis.general_velocity(J1, v1, eta, 1.0),
        "det_3col": float(np.linalg.det(J1[:, :3])),
    }

    p2 = load_task(root / "tasks/exercise2_rrp_bowl.yaml")
    res2 = run_task(p2, ["avoid_hqp"])["avoid_hqp"]
    r2 = p2.robot.model
    q2 = res2.log.q[-1]
    r2.update(q2)
    z3 = analysis.frame_axis(r2, "3", "z")
    out["exercise2"] = {
        "q_contact": q2,
        "w_contact": r2.frame_position("3")[:2],
        "tau_press_12N": analysis.static_torques(r2, "3", 12.0 * z3[:2]),
    }

    p3 = load_task(root / "tasks/exercise3_rpr_lamp.yaml")
    r3 = p3.robot.model
    q3 = p3.runs["rank_only"].q0
    r3.update(q3)
    J3 = analysis.task_jacobian(r3, "3", ("x", "y"))
    residual, _, angle = analysis.null_check(J3, np.array([-np.sqrt(3.0), 1.6, -1.5]))
    elbow = r3.frame_position("2")[:2]
    out["exercise3"] = {
        "q0": q3,
        "elbow": elbow,
        "elbow_lamp_distance": float(np.linalg.norm(elbow - [0.4, 1.4])),
        "J": J3,
        "J_qdot_given": residual,
        "angle_to_null_space_deg": float(np.degrees(angle)),
        "tau_2kg": analysis.static_torques(r3, "3", np.array([0.0, 2.0 * GRAVITY])),
    }
    return out


def main() -> int:
    """Print :func:`answers`."""
    np.set_printoptions(precision=4, suppress=True)
    for name, values in answers().items():
        print(name)
        for key, value in values.items():
            print(f"  {key}: {value}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
