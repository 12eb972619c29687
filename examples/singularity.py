"""Near a singularity: the joint-speed cap and the singularity guard, on the chapter's planar 3R arm.

The tip's target moves out of reach (the arm stretches out: a singularity), stays there, and comes back. Each
resolver runs the sweep three times: with neither cap nor guard (what ``pinv`` did before: hundreds of rad/s,
unflagged), with the default cap only, and with the guard. The states the guard went through are printed along the
sweep, then one line per run: the largest |q̇| [rad/s], the steps where the cap or the guard acted, and the final
tip error [m].

Run: ``python examples/singularity.py`` (a few seconds).
"""

from __future__ import annotations

import numpy as np

import redundik as rk
from redundik.resolvers import SingularityGuard

DT = 0.01  # [s]


def planar3r() -> rk.RobotModel:
    """The chapter's 3R planar arm: three revolute joints, links of 1 m, no velocity limits."""
    return rk.from_dh([rk.DHRow(str(i + 1), a=1.0) for i in range(3)], name="planar3r")


def targets(start: np.ndarray, far: np.ndarray, n: int = 120, hold: int = 60) -> list[np.ndarray]:
    """From ``start`` out to ``far`` (outside the 3 m reach), held, and back."""
    out = [start + (far - start) * min(1.0, k / n) for k in range(n + hold)]
    return out + [far + (start - far) * min(1.0, k / n) for k in range(n + hold)]


def sweep(name: str, show: bool = False, **options: object) -> str:
    """Run the sweep under resolver ``name`` with ``options``; returns the summary line."""
    robot = planar3r()
    q = np.array([0.3, 0.4, 0.3])
    robot.update(q)
    task = rk.FrameTask("3", axes="planar", gain=10.0)
    stack = rk.TaskStack([task])
    resolver = rk.make_resolver(name, **options)
    path = targets(robot.frame_position("3"), np.array([4.0, 0.5, 0.0]))
    fastest, capped, guarded, last_state = 0.0, 0, 0, None
    res = None
    for k, p in enumerate(path):
        task.set_target(p)
        res = resolver.step(robot, stack, q, k * DT, DT)
        fastest = max(fastest, float(np.abs(res.dq).max()))
        capped += "max_joint_speed" in res.relaxed
        guarded += "singularity" in res.relaxed
        state = res.info.get("singularity")
        if show and state != last_state:
            print(
                f"  t = {k * DT:5.2f} s  {state:<10}  κ = {res.info['condition']:8.1f}  "
                f"w = {res.info['manipulability']:.3f}  |q̇| = {np.abs(res.dq).max():.2f} rad/s"
            )
            last_state = state
        q = robot.integrate(q, res.dq, DT)
    assert res is not None
    label = "guard" if "singularity" in options else "no cap" if "max_joint_speed" in options else "default cap"
    return (
        f"{name:<8} {label:<11} max |q̇| = {fastest:8.2f} rad/s   capped {capped:3d}   guarded {guarded:3d}   "
        f"final error {res.task_error:.3f} m"
    )


def main() -> int:
    print("guard states along the sweep (pinv, SingularityGuard()):")
    sweep("pinv", show=True, singularity=SingularityGuard())
    print()
    for name in ("pinv", "feedback", "wqp", "hqp"):
        print(sweep(name, max_joint_speed=None))
        print(sweep(name))
        print(sweep(name, singularity=SingularityGuard(slow_at=40, halt_at=120, release_at=30)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
