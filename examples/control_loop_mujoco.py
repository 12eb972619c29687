"""``rk.ControlLoop`` driving the MuJoCo Panda at 200 Hz in real time, with a streamed target and the watchdog.

The Panda's URDF runs in MuJoCo under joint position servos (1 kHz physics, gravity, compensation); redundik's
``wqp`` resolves a position task on the tool plus a posture at 200 Hz, with a rate limit of 5 rad/s² on every joint.
The script plays a teleoperation session:

* 0 – 2.5 s: a target streamed every tick, moving on a 6 cm circle;
* 2.5 – 3.5 s: the stream stops; after ``command_timeout`` = 0.05 s the watchdog brings the arm to rest within the rate
  limit (``result.info["watchdog"]``: "stopping", then "stopped");
* 3.5 – 4.5 s: a new target is streamed: the watchdog resumes control within the same limit.

It prints the deadline statistics (step time p50/p99/p99.9/max, overruns) and the commanded motion's smoothness
(max |q̈|, max |q⃛|, sign changes of q̈ per joint per second); with ``--out DIR`` it writes the figure
``control_loop_mujoco.png`` (step-time distribution, q̇ and q̈ over time) into DIR, and nothing anywhere else.

Run: ``python examples/control_loop_mujoco.py [--out DIR]`` (needs ``pip install 'redundik[sim]'``; headless).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import redundik as rk
from redundik.kinematics import EXAMPLE_ROBOTS, example_robot_data_dir
from redundik.simulation.mujoco_plant import MujocoPlant
from redundik.simulation.plant import PlantOptions

PERIOD = 0.005  # control period [s]
ACCEL = 5.0  # rate limit a_max [rad/s²]: the resolver's, and the watchdog's deceleration
TIMEOUT = 0.05  # command_timeout [s]
STREAM_END, RESUME, END = 2.5, 3.5, 4.5  # [s]
TOOL = "panda_hand_tcp"
Q0 = np.array([0.0, -0.785398, 0.0, -2.356194, 0.0, 1.570796, 0.785398, 0.02, 0.02])


def run() -> dict[str, np.ndarray | rk.DeadlineStats | list[str] | float]:
    """The session; returns the per-tick records and the loop's statistics."""
    robot = rk.load_example_robot("panda")
    urdf = example_robot_data_dir() / EXAMPLE_ROBOTS["panda"][0]
    spec = PlantOptions(type="mujoco", actuator="position", kp=2000.0, kv=100.0, sim_dt=0.001)
    plant = MujocoPlant(robot, urdf, spec, control_dt=PERIOD)
    state = {"q": plant.reset(Q0)}
    tool = rk.FrameTask(TOOL, axes="position", gain=10.0)
    stack = rk.TaskStack([tool, rk.PostureTask(Q0, gain=1.0)])
    resolver = rk.make_resolver("wqp", limits={"acceleration": ACCEL})

    def write(dq: np.ndarray) -> None:
        state["q"] = plant.step(dq, PERIOD)

    loop = rk.ControlLoop(
        robot, stack, resolver, period=PERIOD, read=lambda: state["q"], write=write, command_timeout=TIMEOUT
    )
    robot.update(Q0)
    home = robot.frame_pose(TOOL).translation.copy()
    ts, dqs, errors, states = [], [], [], []
    for tick in loop.ticks(duration=END):
        t = tick.t
        ts.append(t)
        dqs.append(tick.result.dq.copy())  # (valid until the next tick: copied)
        states.append(str(tick.result.info["watchdog"]))
        target = None
        if t < STREAM_END:  # the operator's hand, on a circle in the y-z plane
            w = 2 * np.pi / 2.5
            target = home + 0.06 * np.array([0.0, np.sin(w * t), 1.0 - np.cos(w * t)])
        elif t >= RESUME:  # a new, fixed target, streamed again
            target = home + np.array([0.05, -0.05, 0.0])
        if target is not None:
            tool.set_target(target)
        errors.append(float(np.linalg.norm(tick.result.terms[0].error)))
    return {
        "t": np.array(ts),
        "dq": np.array(dqs),
        "error": np.array(errors),
        "states": states,
        "stats": loop.stats,
        "steps": loop.step_times,
    }


def smoothness(t: np.ndarray, dq: np.ndarray) -> tuple[float, float, float]:
    """(max |q̈| [rad/s²], max |q⃛| [rad/s³], sign changes of q̈ per joint per second) of the commanded q̇ at the tick
    times ``t`` [s] (a skipped slot makes a step two periods long)."""
    ddq = np.diff(dq, axis=0) / np.diff(t)[:, None]
    jerk = np.diff(ddq, axis=0) / np.diff(t)[1:, None]
    signs = np.sign(np.where(np.abs(ddq) > 1e-9, ddq, 0.0))
    changes = np.sum((signs[1:] * signs[:-1]) < 0)
    return float(np.abs(ddq).max()), float(np.abs(jerk).max()), float(changes / dq.shape[1] / (t[-1] - t[0]))


def figure(rec: dict[str, object], out: Path) -> Path:
    """The step-time distribution and the commanded q̇, q̈ over time, shaded by the watchdog's state."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, dq, steps = rec["t"], rec["dq"], rec["steps"]
    assert isinstance(t, np.ndarray) and isinstance(dq, np.ndarray) and isinstance(steps, np.ndarray)
    stats = rec["stats"]
    assert isinstance(stats, rk.DeadlineStats)
    fig, (ax0, ax1, ax2) = plt.subplots(3, 1, figsize=(9, 9), constrained_layout=True)
    us = 1e6 * steps
    ax0.hist(us, bins=np.geomspace(max(us.min(), 1.0), us.max() * 1.05, 60), color="tab:blue")
    ax0.set_xscale("log")
    for name, val in (("p50", stats.p50), ("p99", stats.p99), ("p99.9", stats.p999), ("max", stats.max)):
        ax0.axvline(1e6 * val, color="k", lw=0.8, ls="--")
        ax0.annotate(name, (1e6 * val, ax0.get_ylim()[1] * 0.9), rotation=90, fontsize=8, ha="right")
    ax0.set_xlabel("resolver.step time [µs]")
    ax0.set_ylabel("ticks")
    ax0.set_title(f"wqp on the Panda at {1 / PERIOD:g} Hz: {stats.overruns} overruns in {stats.ticks} ticks")
    ddq = np.diff(dq, axis=0) / np.diff(t)[:, None]
    ax1.plot(t, dq, lw=0.9)
    ax2.plot(t[1:], ddq, lw=0.9)
    ax2.axhline(ACCEL, color="k", lw=0.8, ls=":")
    ax2.axhline(-ACCEL, color="k", lw=0.8, ls=":")
    states = rec["states"]
    assert isinstance(states, list)
    for ax in (ax1, ax2):
        for name, color in (("stopping", "tab:orange"), ("stopped", "tab:red"), ("resuming", "tab:green")):
            mask = np.array([s == name for s in states])
            if mask.any():
                ax.fill_between(t, 0, 1, where=mask, color=color, alpha=0.15, transform=ax.get_xaxis_transform())
    ax1.set_ylabel("commanded q̇ [rad/s]")
    ax2.set_ylabel("commanded q̈ [rad/s²]")
    ax2.set_xlabel("t [s] (orange: watchdog stopping, red: stopped, green: resuming)")
    out.mkdir(parents=True, exist_ok=True)
    path = out / "control_loop_mujoco.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None, help="folder for the figure (none written without it)")
    args = parser.parse_args(argv)
    rec = run()
    stats, t, dq, err, states = rec["stats"], rec["t"], rec["dq"], rec["error"], rec["states"]
    assert isinstance(t, np.ndarray) and isinstance(dq, np.ndarray) and isinstance(err, np.ndarray)
    assert isinstance(states, list)
    print(stats)
    acc, jerk, chatter = smoothness(t, dq)
    print(f"commanded motion: max |q̈| {acc:.3f} rad/s² (limit {ACCEL:g}), max |q⃛| {jerk:.0f} rad/s³, "
          f"{chatter:.2f} sign changes of q̈ per joint per second")  # fmt: skip
    stale = [k for k, s in enumerate(states) if s in ("stopping", "stopped")]
    stopped = [k for k, s in enumerate(states) if s == "stopped"]
    streaming = t < STREAM_END
    print(f"watchdog: stale from t = {t[stale[0]]:.3f} s (last target at {t[streaming][-1]:.3f} s), at rest from "
          f"t = {t[stopped[0]]:.3f} s, {states[-1]} at the end")  # fmt: skip
    print(
        f"tool error: max {1e3 * err[streaming][10:].max():.1f} mm while streaming, {1e3 * err[-1]:.2f} mm at the end"
    )
    if args.out is not None:
        print(f"figure: {figure(rec, args.out)}")
    ok = (
        acc <= ACCEL + 1e-9  # the rate limit held through the stop and the resume
        and bool(stopped)
        and not np.any(dq[stopped[0] : stopped[-1] + 1])  # at rest while stopped
        and states[-1] == "armed"
        and err[-1] < 0.01
    )
    print("OK" if ok else "FAILED")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
