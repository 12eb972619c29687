"""Robot configs (``configs/*.yaml``, or an inline ``robot:`` mapping) → :class:`~redundik.kinematics.RobotModel`.

A config is either a standard D-H table (``dh:``) or a URDF (``urdf: example-robot-data:panda`` or a path relative
to the config file), plus optional extra operational frames (``frames:``), a home configuration (``q0:``) and
joint-limit overrides (``joint_limits:``). Angles in the file (θ, α, revolute limits and velocities, ``q0``, ``rpy``)
are in the file's ``angle_unit`` (``rad`` by default).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from redundik.config.schema import RobotSpec
from redundik.config.yamlio import join_path, not_a_file, read_yaml, validate
from redundik.errors import ConfigError, ModelError, RedundikError, short_repr
from redundik.kinematics import EXAMPLE_ROBOTS, DHRow, RobotModel, example_robot_data_dir, from_dh, from_urdf

EXAMPLE_PREFIX = "example-robot-data:"
#: Largest magnitude of a configuration entry written in a file [rad, deg or length unit].
MAX_FILE_COORDINATE = 1e6


@dataclass
class LoadedRobot:
    """A robot built from a config, with what the config adds to the model.

    Attributes:
        model: The robot.
        source: Where it came from (config path, ``example-robot-data:NAME`` or ``inline``).
        q0: Home configuration from the config [rad, length unit], or ``None``.
        segments: Links to draw, as (frame, frame) pairs: the D-H rows' parent → child, or the URDF joint tree.
        urdf: The URDF file the model was built from (visual meshes, MuJoCo plant), ``None`` for a D-H robot.
    """

    model: RobotModel
    source: str
    q0: np.ndarray | None = None
    segments: list[tuple[str, str]] = field(default_factory=list)
    urdf: Path | None = None


def rpy_matrix(rpy: list[float] | np.ndarray) -> np.ndarray:
    """R = Rz(yaw)·Ry(pitch)·Rx(roll) for (roll, pitch, yaw) [rad]."""
    return np.asarray(pin.rpy.rpyToMatrix(*[float(v) for v in rpy]))


def angle_scale(unit: str) -> float:
    """Factor from ``unit`` (``deg`` or ``rad``) to radians."""
    return np.pi / 180.0 if unit == "deg" else 1.0


def configuration_from_file(
    values: list[float], robot: RobotModel, unit: str, path: str, size: str = "nq"
) -> np.ndarray:
    """A configuration (or per-joint vector) written in a file, in model units.

    Revolute entries are converted from ``unit`` to radians, prismatic ones are kept (length unit).

    Args:
        values: The numbers of the file.
        robot: The robot (joint kinds and sizes).
        unit: ``deg`` or ``rad``.
        path: Key path for errors.
        size: ``"nq"`` (a configuration) or ``"nv"`` (one value per velocity coordinate).

    Raises:
        ConfigError: wrong length (says the expected one and the joint names), or a quaternion farther than
            ``QUATERNION_TOLERANCE`` from unit norm (names the joint).
    """
    n = robot.nq if size == "nq" else robot.nv
    if len(values) != n:
        names = ", ".join(robot.joint_names)
        raise ConfigError(f"expected {n} values (joints: {names}), got {len(values)}", path)
    arr = np.asarray(values, dtype=float)
    big = np.flatnonzero(~(np.abs(arr) <= MAX_FILE_COORDINATE))
    if big.size:
        i = int(big[0])
        raise ConfigError(f"must be at most {MAX_FILE_COORDINATE:g} in magnitude, got {arr[i]:g}", f"{path}[{i}]")
    scale = angle_scale(unit)
    if scale != 1.0:
        for j in robot.joints:
            idx = j.idx_q if size == "nq" else j.idx_v
            if j.kind == "revolute" and idx >= 0:
                arr[idx] *= scale
    if size == "nq" and robot._quaternions:  # a free-flyer / spherical joint: a unit quaternion (normalised if near)
        try:
            arr = robot._unit_quaternions(arr, path)
        except ModelError as exc:
            raise ConfigError(str(exc)) from None
    return arr


def load_robot(ref: Any, base_dir: Path, path: str = "robot") -> LoadedRobot:
    """Build the robot a task file refers to.

    Args:
        ref: A config path (relative to ``base_dir``), ``example-robot-data:NAME`` or an inline mapping.
        base_dir: Folder of the file that holds ``ref``.
        path: Key path of ``ref`` for errors.

    Raises:
        ConfigError: anything wrong, with the key path (inside the robot file, prefixed by its name).
    """
    if isinstance(ref, str):
        if ref.startswith(EXAMPLE_PREFIX):
            return _example_robot(ref[len(EXAMPLE_PREFIX) :], None, path, ref)
        if not ref.strip():
            raise ConfigError(
                f"expected a robot config path, '{EXAMPLE_PREFIX}NAME' or an inline mapping, got an empty string", path
            )
        try:
            cfg_path = (base_dir / ref).resolve() if not Path(ref).is_absolute() else Path(ref)
            problem = not_a_file(cfg_path)
        except (OSError, ValueError):  # a name too long, an embedded NUL, ...
            raise ConfigError(f"robot config {short_repr(ref)} cannot be read (not a usable path)", path) from None
        if problem == "it does not exist":
            raise ConfigError(f"robot config {short_repr(ref)} does not exist (looked for {cfg_path})", path)
        if problem is not None:
            raise ConfigError(f"robot config {short_repr(ref)} cannot be read: {problem} ({cfg_path})", path)
        data = read_yaml(cfg_path, "robot config")
        prefix = f"{ref}: "
        spec = validate(RobotSpec, data, prefix)
        return build_robot(spec, cfg_path.parent, prefix, str(ref))
    if isinstance(ref, dict):
        spec = validate(RobotSpec, ref, path)
        return build_robot(spec, base_dir, path, "inline")
    raise ConfigError(f"expected a config path, '{EXAMPLE_PREFIX}NAME' or a mapping, got {short_repr(ref)}", path)


def _example_robot(name: str, free_flyer: bool | None, path: str, source: str) -> LoadedRobot:
    if name not in EXAMPLE_ROBOTS:
        raise ConfigError(f"unknown example robot '{name}'; available: {', '.join(sorted(EXAMPLE_ROBOTS))}", path)
    rel, ff_default = EXAMPLE_ROBOTS[name]
    example_robot_data_dir()  # not installed: MissingDependencyError (exit code 5), not an invalid file
    try:
        robot = from_urdf(example_robot_data_dir() / rel, free_flyer=ff_default if free_flyer is None else free_flyer)
    except RedundikError as exc:
        raise ConfigError(str(exc), path) from None
    robot = RobotModel(robot.model, name=name, length_unit="m")
    return LoadedRobot(robot, source, None, _urdf_segments(robot), example_robot_data_dir() / rel)


def build_robot(spec: RobotSpec, base_dir: Path, prefix: str, source: str) -> LoadedRobot:
    """Build a validated :class:`RobotSpec` into a robot (see :func:`load_robot`)."""
    scale = angle_scale(spec.angle_unit)
    if spec.dh is not None:
        loaded = _dh_robot(spec, scale, prefix, source)
    else:
        assert spec.urdf is not None  # guaranteed by RobotSpec's validator
        where = join_path(prefix, "urdf")
        if spec.urdf.startswith(EXAMPLE_PREFIX):
            loaded = _example_robot(spec.urdf[len(EXAMPLE_PREFIX) :], spec.free_flyer, where, source)
        else:
            if not spec.urdf.strip():
                raise ConfigError(f"expected a URDF path or '{EXAMPLE_PREFIX}NAME', got an empty string", where)
            try:
                urdf_path = Path(spec.urdf) if Path(spec.urdf).is_absolute() else (base_dir / spec.urdf).resolve()
                problem = not_a_file(urdf_path)
            except (OSError, ValueError):
                raise ConfigError(f"{short_repr(spec.urdf)} is not a usable URDF path", where) from None
            if problem is not None and problem != "it does not exist":  # a folder, a device: not a URDF file
                raise ConfigError(f"URDF file {short_repr(str(urdf_path), 200)} cannot be read: {problem}", where)
            try:
                robot = from_urdf(urdf_path, free_flyer=bool(spec.free_flyer), name=spec.name)
            except RedundikError as exc:
                raise ConfigError(str(exc), where) from None
            loaded = LoadedRobot(robot, source, None, _urdf_segments(robot), urdf_path)
        if spec.name:
            loaded.model = RobotModel(loaded.model.model, name=spec.name, length_unit=spec.length_unit)
    model = loaded.model.model
    # joint limit overrides
    for jname, lim in spec.joint_limits.items():
        where = join_path(prefix, "joint_limits", jname)
        if not model.existJointName(jname) or model.joints[model.getJointId(jname)].nv != 1:
            names = ", ".join(loaded.model.joint_names)
            raise ConfigError(f"joint '{jname}' does not exist (or is not a 1-dof joint); available: {names}", where)
        jm = model.joints[model.getJointId(jname)]
        s = scale if loaded.model.joint(jname).kind == "revolute" else 1.0
        lo, hi = model.lowerPositionLimit.copy(), model.upperPositionLimit.copy()
        vel = model.velocityLimit.copy()
        if lim.lower is not None:
            lo[jm.idx_q] = lim.lower * s
        if lim.upper is not None:
            hi[jm.idx_q] = lim.upper * s
        if lim.velocity is not None:
            vel[jm.idx_v] = lim.velocity * s
        if lo[jm.idx_q] > hi[jm.idx_q]:
            raise ConfigError("lower limit is above upper limit", where)
        model.lowerPositionLimit, model.upperPositionLimit, model.velocityLimit = lo, hi, vel
    # extra frames
    for fname, fspec in spec.frames.items():
        where = join_path(prefix, "frames", fname)
        if model.existFrame(fname):
            raise ConfigError(f"frame '{fname}' already exists in the robot; choose another name", where)
        if not model.existFrame(fspec.parent):
            raise ConfigError(
                f"parent frame '{fspec.parent}' does not exist; available: {_frames(loaded.model)}",
                join_path(where, "parent"),
            )
        pid = model.getFrameId(fspec.parent)
        parent = model.frames[pid]
        local = pin.SE3(rpy_matrix(np.asarray(fspec.rpy) * scale), np.asarray(fspec.xyz, dtype=float))
        model.addFrame(pin.Frame(fname, parent.parentJoint, pid, parent.placement * local, pin.FrameType.OP_FRAME))
        loaded.segments.append((fspec.parent, fname))
    loaded.model = RobotModel(model, name=loaded.model.name, length_unit=spec.length_unit)
    if spec.q0 is not None:
        loaded.q0 = configuration_from_file(spec.q0, loaded.model, spec.angle_unit, join_path(prefix, "q0"))
    return loaded


def _dh_robot(spec: RobotSpec, scale: float, prefix: str, source: str) -> LoadedRobot:
    assert spec.dh is not None
    rows: list[DHRow] = []
    segments: list[tuple[str, str]] = []
    previous = spec.base_frame
    for i, r in enumerate(spec.dh):
        s = scale if r.type == "revolute" else 1.0
        rows.append(
            DHRow(
                name=r.name,
                theta=r.theta * scale,
                d=r.d,
                a=r.a,
                alpha=r.alpha * scale,
                kind=r.type,
                lower=-np.inf if r.lower is None else r.lower * s,
                upper=np.inf if r.upper is None else r.upper * s,
                velocity=np.inf if r.velocity is None else r.velocity * s,
                parent=r.parent,
                joint=r.joint,
            )
        )
        segments.append((r.parent if r.parent is not None else previous, r.name))
        previous = r.name
        if r.lower is not None and r.upper is not None and r.lower > r.upper:
            raise ConfigError("lower limit is above upper limit", join_path(prefix, "dh", i))
    base = np.eye(4)
    if spec.base is not None:
        if spec.base.matrix is not None:
            base = np.asarray(spec.base.matrix, dtype=float)
        else:
            if spec.base.rpy is not None:
                base[:3, :3] = rpy_matrix(np.asarray(spec.base.rpy) * scale)
            if spec.base.xyz is not None:
                base[:3, 3] = spec.base.xyz
    try:
        robot = from_dh(
            rows, base=base, base_frame=spec.base_frame, name=spec.name or "dh_robot", length_unit=spec.length_unit
        )
    except RedundikError as exc:
        raise ConfigError(str(exc), join_path(prefix, "dh")) from None
    return LoadedRobot(robot, source, None, segments)


def _urdf_segments(robot: RobotModel) -> list[tuple[str, str]]:
    """Links between the origins of consecutive joints of a URDF tree (joint frames carry the joint names)."""
    model = robot.model
    out: list[tuple[str, str]] = []
    for jid in range(1, model.njoints):
        parent = model.parents[jid]
        child = model.names[jid]
        if not model.existFrame(child):
            continue
        if parent > 0 and model.existFrame(model.names[parent]):
            out.append((model.names[parent], child))
        elif parent == 0 and model.joints[jid].nq == 1:
            out.append(("universe", child))
    return out


def _frames(robot: RobotModel) -> str:
    names = [n for n in robot.frame_names if n != "universe"]
    return ", ".join(names) if len(names) <= 40 else ", ".join(names[:40]) + f", ... ({len(names)} in all)"
