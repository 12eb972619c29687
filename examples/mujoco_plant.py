"""redundik driving a MuJoCo plant: the IK runs at the control rate, MuJoCo simulates the Panda's dynamics.

The Panda's URDF is loaded into MuJoCo with joint position servos (kp, kv), gravity, the URDF masses and inertias,
gravity compensation through the actuators and the URDF effort limits; MuJoCo steps at 1 kHz, the resolver at
200 Hz. Each tick reads the simulated joint positions (the "encoders"), solves for q̇ and sends it to the plant.
The tool draws the 5 cm circle of ``tasks/panda_circle.yaml``; the script prints the tracking error under the
plant next to the same loop with a perfect integrator, and the peak actuator torques.

Run: ``python examples/mujoco_plant.py`` (needs ``pip install 'redundik[sim]'``); add ``--view`` to watch it in
meshcat (``pip install 'redundik[viewer]'``).
"""

from __future__ import annotations

import sys
import time

import numpy as np

import redundik as rk
from redundik.kinematics import EXAMPLE_ROBOTS, example_robot_data_dir
from redundik.simulation.mujoco_plant import MujocoPlant
from redundik.simulation.plant import PlantOptions

DT = 0.005  # control period [s]
TICKS = 800  # 4 s: two turns
TOOL = "panda_hand_tcp"
Q0 = np.array([0.0, -0.785398, 0.0, -2.356194, 0.0, 1.570796, 0.785398, 0.02, 0.02])


def run(plant: MujocoPlant | None, viewer: object | None = None) -> tuple[float, float]:
    """One loop; returns (max position error [m], median tick time [s])."""
    robot = rk.load_example_robot("panda")
    stack = rk.TaskStack(
        [rk.FrameTask(TOOL, rk.Circle(0.05, np.pi, plane=("y", "z")), axes="pose", gain=10.0)],
        [rk.GradientSubtask(rk.JointCentering(center=Q0), gain=-1.0)],  # descend ½‖q − q0‖² in the null space
    )
    resolver = rk.make_resolver("pinv")
    q = Q0.copy() if plant is None else plant.reset(Q0)
    robot.update(q)
    stack.reset(robot)
    worst, ticks = 0.0, []
    for k in range(TICKS + 1):
        t0 = time.perf_counter()
        result = resolver.step(robot, stack, q, k * DT, DT)
        worst = max(worst, float(np.linalg.norm(result.terms[0].error[:3])))
        if k == TICKS:
            break
        q = robot.integrate(q, result.dq, DT) if plant is None else plant.step(result.dq, DT)
        if viewer is not None:
            viewer.update(q, k * DT)  # type: ignore[attr-defined]
        ticks.append(time.perf_counter() - t0)
    return worst, float(np.median(ticks))


def main(argv: list[str]) -> int:
    robot = rk.load_example_robot("panda")
    urdf = example_robot_data_dir() / EXAMPLE_ROBOTS["panda"][0]
    spec = PlantOptions(type="mujoco", actuator="position", kp=2000.0, kv=100.0, sim_dt=0.001)
    plant = MujocoPlant(robot, urdf, spec, control_dt=DT)
    viewer = None
    if "--view" in argv:
        from redundik.viewer import LiveViewer

        viewer = LiveViewer(robot, urdf, rate_hz=30.0, open_browser=True)
        print(f"meshcat: {viewer.url}")
    kinematic, _ = run(None)
    dynamic, tick = run(plant, viewer)
    effort = plant.summary()["actuator_effort"]["max_abs"]
    print(f"max position error: kinematic {1e3 * kinematic:.3f} mm, MuJoCo plant {1e3 * dynamic:.3f} mm")
    peaks = ", ".join(f"{n[-6:]} {v:.1f}" for n, v in effort.items() if "finger" not in n)
    print(f"peak actuator torque [N·m]: {peaks}")
    print(f"median control tick incl. {plant.substeps} MuJoCo steps: {1e6 * tick:.0f} µs")
    ok = dynamic < 0.02 and kinematic < 1e-3
    print("OK" if ok else "FAILED: the plant does not track the circle within 2 cm")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
