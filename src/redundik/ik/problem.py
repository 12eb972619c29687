"""Inputs of :func:`redundik.solve_ik` checked and laid out for the iteration: frames, targets, bounds, buffers.

Every check raises a :class:`~redundik.errors.RedundikError` subclass naming the argument: ``ModelError`` for an
unknown frame or a bad ``q0`` (:meth:`RobotModel.frame_id`, :meth:`RobotModel.check_configuration`), ``TaskError``
for a target (the frame task's own validation, ``tasks.frame._as_pose``), ``ResolverError`` for the options.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from redundik.errors import ModelError, ResolverError, TaskError
from redundik.ik import kernels as K
from redundik.kinematics.model import RobotModel
from redundik.tasks.conform import MAX_COORDINATE
from redundik.tasks.frame import _as_pose

#: What a target may be, per frame.
Target = Any  # pin.SE3 | np.ndarray (4, 4) | np.ndarray (3,) | nested sequences of numbers


def positive(value: object, what: str, unit: str, *, allow_none: bool = False) -> float | None:
    """``value`` as a float when it is a finite real number > 0, else a :class:`ResolverError` naming ``what``."""
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ResolverError(f"solve_ik: {what} must be a number > 0 [{unit}], got {value!r:.60}")
    try:
        x = float(value)
    except OverflowError:  # an int beyond the float range (10**400): out of range, refused below
        x = math.inf
    if not (math.isfinite(x) and x > 0):
        raise ResolverError(
            f"solve_ik: {what} must be finite and > 0 [{unit}] (within the float range), got {value!r:.60}"
        )
    return x


def count(value: object, what: str, minimum: int, *, allow_none: bool = False) -> int | None:
    """``value`` as an int ≥ ``minimum`` (``None`` allowed when ``allow_none``), else a :class:`ResolverError`."""
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ResolverError(f"solve_ik: {what} must be an integer ≥ {minimum}, got {value!r:.60}")
    return int(value)


def frames_and_targets(frame: object, target: object) -> tuple[list[str], list[Target]]:
    """Pair the frame names with their targets: one name and one target, a list of names and as many targets, or a
    mapping name → target (``target`` then omitted)."""
    if isinstance(frame, Mapping):
        if target is not None:
            raise TaskError("solve_ik: give the targets either in the frame → target mapping or as target, not both")
        names, targets = list(frame.keys()), list(frame.values())
    elif isinstance(frame, str):
        names, targets = [frame], [target]
    elif isinstance(frame, Sequence):
        names = list(frame)
        if isinstance(target, (np.ndarray, pin.SE3)) or not isinstance(target, Sequence):
            raise TaskError(f"solve_ik: {len(names)} frames need a list of {len(names)} targets, got {target!r:.60}")
        targets = list(target)
    else:
        raise TaskError(f"solve_ik: frame must be a frame name, a list of names or a mapping, got {frame!r:.60}")
    if not names:
        raise TaskError("solve_ik: no frame given")
    if len(targets) != len(names):
        raise TaskError(f"solve_ik: {len(names)} frames but {len(targets)} targets")
    bad = [n for n in names if not isinstance(n, str)]
    if bad:
        raise TaskError(f"solve_ik: frame names must be strings, got {bad[0]!r:.60}")
    if len(set(names)) != len(names):
        raise TaskError(f"solve_ik: a frame is listed twice in {names}")
    return names, targets


def target_arrays(names: list[str], targets: list[Target]) -> tuple[np.ndarray, np.ndarray]:
    """(T (4k, 4), mode (k,)): each target as a homogeneous matrix (rows 4k … 4k + 3; position targets: identity
    rotation) and its mode (0 pose, 1 position); validated by the frame task's rules (an SE3 or a float 4×4 array
    that passes the compiled check ``rigid_transform`` skips their slower route)."""
    T = np.zeros((4 * len(names), 4))
    mode = np.zeros(len(names), dtype=np.int64)
    for k, (name, tgt) in enumerate(zip(names, targets, strict=True)):
        H = tgt.homogeneous if isinstance(tgt, pin.SE3) else tgt
        if isinstance(H, np.ndarray) and H.shape == (4, 4) and H.dtype == np.float64 and K.rigid_transform(
            H, MAX_COORDINATE
        ):  # fmt: skip
            T[4 * k : 4 * k + 4] = H
            continue
        pose = _as_pose(tgt, f"solve_ik: target of frame '{name}'")
        if isinstance(pose, pin.SE3):
            T[4 * k : 4 * k + 4] = pose.homogeneous
        else:
            T[4 * k : 4 * k + 4] = np.eye(4)
            T[4 * k : 4 * k + 3, 3] = pose
            mode[k] = 1
    return T, mode


@dataclass
class Problem:
    """One robot, a set of frames and what the iteration needs about them (built once, reused over targets).

    Attributes:
        robot: The robot.
        names: Frame names; ``fids`` their ids.
        qmap: Per velocity coordinate, its index in q (−1: none, e.g. a free-flyer's).
        lo, hi: Position bounds per velocity coordinate (±inf where none) [rad or m].
        additive: q ⊕ Δ = q + Δ for this model (every joint has one coordinate), else ``pin.integrate``.
        rand_q: q indices drawn at a restart (bounded or revolute coordinates of joints that move a frame);
            ``rand_lo``/``rand_hi`` their ranges; ``rand_angle``: first indices of unbounded revolute (cos, sin)
            pairs that move a frame.
        q_lo, q_hi: Bounds per q coordinate (±inf where none: quaternions, (cos, sin) pairs) [rad or m].
        q_mid: The default start: the neutral configuration with every bounded coordinate mid-range.
    """

    robot: RobotModel
    names: list[str]
    fids: list[int]
    qmap: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    additive: bool
    rand_q: np.ndarray
    rand_lo: np.ndarray
    rand_hi: np.ndarray
    rand_angle: np.ndarray
    q_lo: np.ndarray
    q_hi: np.ndarray
    q_mid: np.ndarray


def build_problem(robot: RobotModel, names: list[str]) -> Problem:
    """The :class:`Problem` of ``names`` on ``robot``.

    Raises:
        ModelError: not a RobotModel, an unknown frame (the valid names listed), or a frame no joint moves.
    """
    if not isinstance(robot, RobotModel):
        raise ModelError(f"solve_ik: robot must be a RobotModel (rk.load_example_robot, rk.from_urdf, ...), got "
                         f"{type(robot).__name__}")  # fmt: skip
    model = robot.model
    fids = [robot.frame_id(n) for n in names]
    support = np.zeros(model.njoints, dtype=bool)
    for n, f in zip(names, fids, strict=True):
        parent = model.frames[f].parentJoint
        if parent == 0:
            raise ModelError(f"solve_ik: frame '{n}' is fixed to the world (no joint moves it)")
        support[list(model.supports[parent])] = True
    nv = robot.nv
    qmap = np.full(nv, -1, dtype=np.int64)
    lo, hi = np.full(nv, -np.inf), np.full(nv, np.inf)
    for j in robot.joints:
        if j.idx_q >= 0:
            qmap[j.idx_v] = j.idx_q
            lo[j.idx_v], hi[j.idx_v] = j.lower, j.upper
    rand_q, rand_lo, rand_hi, rand_angle = [], [], [], []
    for jid in range(1, model.njoints):
        jm = model.joints[jid]
        if not support[jid]:
            continue
        if jm.nq == 1 and jm.nv == 1:
            low, high = float(model.lowerPositionLimit[jm.idx_q]), float(model.upperPositionLimit[jm.idx_q])
            short = jm.shortname()
            revolute = short in ("JointModelRX", "JointModelRY", "JointModelRZ") or "Revolute" in short
            if not (math.isfinite(low) and math.isfinite(high) and high - low < 1e10):
                if not revolute:
                    continue  # an unbounded prismatic joint: kept where it starts
                low, high = -math.pi, math.pi
            rand_q.append(jm.idx_q)
            rand_lo.append(low)
            rand_hi.append(high)
        elif jm.nq == 2 and jm.nv == 1:
            rand_angle.append(jm.idx_q)
    additive = all(model.joints[j].nq == 1 and model.joints[j].nv == 1 for j in range(1, model.njoints))
    q_lo = np.array(model.lowerPositionLimit, dtype=float)
    q_hi = np.array(model.upperPositionLimit, dtype=float)
    unbounded = np.ones(robot.nq, dtype=bool)
    unbounded[qmap[qmap >= 0]] = False
    q_lo[unbounded], q_hi[unbounded] = -np.inf, np.inf  # quaternions, (cos, sin) pairs: not clipped
    q_mid = robot.neutral()
    mid = np.isfinite(q_lo) & np.isfinite(q_hi) & (q_hi - q_lo < 1e10)
    q_mid[mid] = 0.5 * (q_lo[mid] + q_hi[mid])
    q_mid = np.minimum(np.maximum(q_mid, q_lo), q_hi)
    return Problem(
        robot, names, fids, qmap, lo, hi, additive, np.array(rand_q, dtype=np.int64), np.array(rand_lo),
        np.array(rand_hi), np.array(rand_angle, dtype=np.int64), q_lo, q_hi, q_mid,
    )  # fmt: skip


def start_configuration(problem: Problem, q0: object) -> np.ndarray:
    """The first attempt's start: ``q0`` clipped into the limits, or (``None``) the neutral configuration with every
    bounded coordinate at the middle of its range.

    Raises:
        ModelError: ``q0`` of the wrong size or with NaN / infinite values.
    """
    if q0 is None:
        return problem.q_mid.copy()
    q = problem.robot.check_configuration(q0, "solve_ik: q0")  # type: ignore[arg-type]
    return np.minimum(np.maximum(q, problem.q_lo), problem.q_hi)


def restart_configuration(problem: Problem, q_start: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A configuration drawn uniformly within the limits for the joints that move a frame (±π for an unbounded
    revolute joint), the other coordinates as in ``q_start``."""
    q = q_start.copy()
    q[problem.rand_q] = rng.uniform(problem.rand_lo, problem.rand_hi)
    if problem.rand_angle.size:
        a = rng.uniform(-math.pi, math.pi, problem.rand_angle.size)
        q[problem.rand_angle] = np.cos(a)
        q[problem.rand_angle + 1] = np.sin(a)
    return q
