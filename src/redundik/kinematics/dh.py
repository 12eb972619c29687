"""Build a :class:`RobotModel` from a standard Denavit–Hartenberg table.

Standard D-H (the chapter's convention): the one-step transform from frame i−1 to frame i is

    A_{i-1}^i = Rz(θ_i) · Tz(d_i) · Tx(a_i) · Rx(α_i),

with θ_i the variable of a revolute joint and d_i that of a prismatic one. Joint i therefore moves about (or
along) z_{i−1}: in Pinocchio it is a ``JointModelRZ`` / ``JointModelPZ`` placed at frame i−1, and frame i is an
operational frame fixed on joint i at Rz(θ_off)·Tz(d)·Tx(a)·Rx(α) (revolute) or Rz(θ)·Tz(d_off)·Tx(a)·Rx(α)
(prismatic). Frame 0 sits at the base transform (A_b^0 of eq. 5.13) in the world frame b.

Tree-shaped chains: a row may start from any earlier frame (``parent``), so two arms can branch off a shared
torso; a row may also *reuse* the variable of an earlier row's joint (``joint``) with its own θ offset, which
expresses couplings such as the dual arm's θ3r = θ3l + β (Table 5.1) exactly: both rows then rotate about the same
axis z_2, and their frames are fixed on the same Pinocchio joint.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from redundik.errors import ModelError, short_repr
from redundik.kinematics.model import MAX_NV, RobotModel


@dataclass(frozen=True)
class DHRow:
    """One row of a standard D-H table.

    Attributes:
        name: Name of the frame this row ends in (frame i); also the joint name unless ``joint`` is given.
        theta: θ_i [rad]; for a revolute joint, the offset added to the joint variable.
        d: d_i [length unit]; for a prismatic joint, the offset added to the joint variable.
        a: a_i [length unit].
        alpha: α_i [rad].
        kind: ``"revolute"``, ``"prismatic"`` or ``"fixed"`` (a constant transform, no joint).
        lower: Lower joint limit [rad or length]; ``-inf`` if none.
        upper: Upper joint limit [rad or length]; ``inf`` if none.
        velocity: Joint velocity limit [rad/s or length/s]; ``inf`` if none.
        parent: Name of frame i−1; ``None`` means the previous row's frame (or the base frame for the first row).
        joint: Name of an earlier row whose joint variable this row shares (coupled joints); ``None`` for a new
            joint. The shared row must start from the same parent frame.
    """

    name: str
    theta: float = 0.0
    d: float = 0.0
    a: float = 0.0
    alpha: float = 0.0
    kind: str = "revolute"
    lower: float = -np.inf
    upper: float = np.inf
    velocity: float = np.inf
    parent: str | None = None
    joint: str | None = None

    def transform(self, value: float = 0.0) -> np.ndarray:
        """The 4×4 homogeneous matrix A_{i-1}^i for a joint value (θ or d added to the offset)."""
        theta = self.theta + (value if self.kind == "revolute" else 0.0)
        d = self.d + (value if self.kind == "prismatic" else 0.0)
        return dh_matrix(theta, d, self.a, self.alpha)


def dh_matrix(theta: float, d: float, a: float, alpha: float) -> np.ndarray:
    """Standard D-H homogeneous transform Rz(θ)·Tz(d)·Tx(a)·Rx(α) (the chapter's A matrices).

    Args:
        theta: θ [rad]. d: d [length unit]. a: a [length unit]. alpha: α [rad].

    Raises:
        ModelError: a parameter that is not a finite real number (names it).
    """
    for key, value in (("theta", theta), ("d", d), ("a", a), ("alpha", alpha)):
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float, np.integer, np.floating))
            or not math.isfinite(value)
        ):
            raise ModelError(f"dh_matrix: {key} must be a finite real number, got {short_repr(value)}")
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def _se3(matrix: np.ndarray) -> pin.SE3:
    return pin.SE3(np.asarray(matrix[:3, :3]), np.asarray(matrix[:3, 3]))


#: Largest |θ|, |d|, |a|, |α| of a D-H row (as in robot config files): larger ones overflow the kinematics.
MAX_DH_VALUE = 1e6


#: Names Pinocchio gives the world's joint and frame: a row (or ``base_frame``) of that name would make every frame
#: lookup by name ambiguous.
RESERVED_NAMES = frozenset({"universe"})
#: Most joint rows a table may have (``RobotModel``'s ``MAX_NV``: Pinocchio's data grows as nv³).
MAX_DH_JOINTS = MAX_NV


def _check_row(row: object, i: int, robot: str) -> None:
    """Refuse a row that is not a :class:`DHRow`, an empty or non-string name, or numbers that are not numbers."""
    if not isinstance(row, DHRow):
        raise ModelError(f"robot '{robot}': row {i + 1}: expected a DHRow, got {type(row).__name__}")
    if not isinstance(row.name, str) or not row.name.strip():
        raise ModelError(f"robot '{robot}': row {i + 1}: name must be a non-empty string, got {row.name!r}")
    if row.name in RESERVED_NAMES or (isinstance(row.joint, str) and row.joint in RESERVED_NAMES):
        raise ModelError(
            f"robot '{robot}': row {i + 1}: {row.name!r} is Pinocchio's name of the world frame and joint; give the "
            "row another name"
        )
    for key in ("parent", "joint"):
        value = getattr(row, key)
        if value is not None and not isinstance(value, str):
            raise ModelError(f"robot '{robot}': row {i + 1} ('{row.name}'): {key} must be a frame name or None")
    for key in ("theta", "d", "a", "alpha", "lower", "upper", "velocity"):
        value = getattr(row, key)
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise ModelError(
                f"robot '{robot}': row {i + 1} ('{row.name}'): {key} must be a number, got {type(value).__name__}"
            )
        if key in ("theta", "d", "a", "alpha") and abs(value) > MAX_DH_VALUE:
            raise ModelError(
                f"robot '{robot}': row {i + 1} ('{row.name}'): {key} = {value:g} is larger than {MAX_DH_VALUE:g} in "
                "magnitude (the kinematics would overflow)"
            )
    if np.isnan(row.velocity) or row.velocity < 0:
        raise ModelError(
            f"robot '{robot}': row {i + 1} ('{row.name}'): velocity limit must be ≥ 0 (inf: none), got {row.velocity}"
        )
    if row.lower == np.inf or row.upper == -np.inf:
        raise ModelError(
            f"robot '{robot}': row {i + 1} ('{row.name}'): limits [{row.lower}, {row.upper}] leave no position "
            "(-inf / inf mean no limit only as lower / upper)"
        )


def _check_table(rows: Sequence[DHRow], name: str, base_frame: str) -> None:
    """Raise :class:`ModelError` unless ``rows`` is a non-empty list of at most :data:`MAX_DH_JOINTS` joint rows and
    ``base_frame`` a usable frame name."""
    if isinstance(rows, (str, bytes)) or not isinstance(rows, Sequence):
        raise ModelError(f"robot '{name}': rows must be a list of DHRow, got {type(rows).__name__}")
    if len(rows) == 0:
        raise ModelError(f"robot '{name}': the D-H table has no rows")
    if len(rows) > MAX_DH_JOINTS and sum(getattr(r, "kind", "revolute") != "fixed" for r in rows) > MAX_DH_JOINTS:
        raise ModelError(
            f"robot '{name}': the D-H table has more than {MAX_DH_JOINTS} joint rows ({len(rows)} rows): Pinocchio's "
            "data grows as nv³ (0.5 GB at 200 joints)"
        )
    if not isinstance(base_frame, str) or not base_frame.strip() or base_frame in RESERVED_NAMES:
        raise ModelError(
            f"robot '{name}': base_frame must be a non-empty name other than 'universe' (Pinocchio's world frame), "
            f"got {base_frame!r}"
        )


def _checked_base(base: np.ndarray | None, name: str) -> np.ndarray:
    """The base transform as a float 4×4 matrix (identity for ``None``); :class:`ModelError` unless it is a finite
    homogeneous transform with a proper rotation."""
    raw = np.eye(4) if base is None else base if isinstance(base, np.ndarray) else np.asarray(base, dtype=object)
    if raw.shape != (4, 4) or raw.dtype.kind not in "fiuO":
        raise ModelError(f"robot '{name}': base must be a finite 4×4 homogeneous matrix, got {short_repr(base)}")
    try:
        base_m = np.asarray(raw, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"robot '{name}': base must be a 4×4 matrix of real numbers, got {short_repr(base)}") from None
    if not np.all(np.isfinite(base_m)):
        raise ModelError(f"robot '{name}': base must be a finite 4×4 homogeneous matrix")
    rot = base_m[:3, :3]
    if not np.allclose(rot @ rot.T, np.eye(3), atol=1e-9) or np.linalg.det(rot) < 0:
        raise ModelError(f"robot '{name}': base rotation is not a proper rotation matrix")
    if not np.allclose(base_m[3], (0.0, 0.0, 0.0, 1.0), rtol=0.0, atol=1e-12):
        raise ModelError(f"robot '{name}': base must be homogeneous: its last row must be (0, 0, 0, 1)")
    return base_m


def _check_row_values(row: DHRow, where: str, name: str) -> None:
    """Raise :class:`ModelError` on a row's unknown kind, non-finite θ, d, a, α or inverted limits."""
    if row.kind not in ("revolute", "prismatic", "fixed"):
        raise ModelError(f"robot '{name}': {where}: kind must be revolute, prismatic or fixed, got {row.kind!r}")
    nums = (row.theta, row.d, row.a, row.alpha)
    if not all(np.isfinite(v) for v in nums):
        raise ModelError(f"robot '{name}': {where}: θ, d, a, α must be finite numbers, got {nums}")
    if np.isnan(row.lower) or np.isnan(row.upper) or row.lower > row.upper:
        raise ModelError(f"robot '{name}': {where}: joint limits must satisfy lower ≤ upper")


def _add_joint(model: pin.Model, parent_joint: int, parent_placement: np.ndarray, row: DHRow) -> int:
    """Add the joint of a revolute (about z) or prismatic (along z) row at ``parent_placement`` in ``parent_joint``,
    with the row's limits and a massless body; its joint id."""
    jmodel = pin.JointModelRZ() if row.kind == "revolute" else pin.JointModelPZ()
    jid = model.addJoint(
        parent_joint,
        jmodel,
        _se3(parent_placement),
        row.name,
        np.array([np.inf]),
        np.array([np.inf if np.isinf(row.velocity) else row.velocity]),
        np.array([row.lower]),
        np.array([row.upper]),
    )
    model.appendBodyToJoint(jid, pin.Inertia.Zero(), pin.SE3.Identity())
    return int(jid)


def from_dh(
    rows: Sequence[DHRow],
    *,
    base: np.ndarray | None = None,
    base_frame: str = "0",
    name: str = "dh_robot",
    length_unit: str = "m",
) -> RobotModel:
    """Build a Pinocchio-backed robot from a standard D-H table.

    Args:
        rows: The D-H rows in order; every row's ``parent`` must name an earlier frame.
        base: 4×4 transform of frame 0 in the world base frame b (A_b^0 of eq. 5.13); identity if ``None``.
        base_frame: Name of frame 0.
        name: Robot name for reports.
        length_unit: Unit of d and a (e.g. ``"m"``, ``"dm"``).

    Returns:
        A :class:`RobotModel` whose operational frames are named after the rows (plus ``base_frame``).

    Raises:
        ModelError: on duplicate names, unknown parents or coupled joints, bad kinds, non-finite numbers or
            inverted limits; the message names the row.
    """
    _check_table(rows, name, base_frame)
    base_m = _checked_base(base, name)

    model = pin.Model()
    model.name = name
    universe = 0
    model.addFrame(pin.Frame(base_frame, universe, 0, _se3(base_m), pin.FrameType.OP_FRAME))

    # frame name -> (parent joint id, placement of that frame in the joint)
    frames: dict[str, tuple[int, np.ndarray]] = {base_frame: (universe, base_m)}
    # row name -> (pin joint id, the row, its parent frame name)
    joint_rows: dict[str, tuple[int, DHRow, str]] = {}
    previous = base_frame
    for i, row in enumerate(rows):
        _check_row(row, i, name)
        where = f"row {i + 1} ('{row.name}')"
        if row.name in frames:
            raise ModelError(f"robot '{name}': {where}: duplicate frame name")
        _check_row_values(row, where, name)
        parent = row.parent if row.parent is not None else previous
        if parent not in frames:
            raise ModelError(
                f"robot '{name}': {where}: parent frame '{parent}' is not defined before this row; "
                f"defined so far: {list(frames)}"
            )
        parent_joint, parent_placement = frames[parent]
        # Constant part after the joint motion, in the moving joint's frame. Rz(q+θ)·Tz(d)… = Rz(q)·A(θ, d, a, α)
        # and Rz(θ)·Tz(q+d)… = Tz(q)·A(θ, d, a, α), because Rz and Tz commute: one formula for both kinds.
        const = dh_matrix(row.theta, row.d, row.a, row.alpha)
        if row.kind == "fixed":
            frames[row.name] = (parent_joint, parent_placement @ const)
            model.addFrame(pin.Frame(row.name, parent_joint, 0, _se3(parent_placement @ const), pin.FrameType.OP_FRAME))
            previous = row.name
            continue
        if row.joint is not None:
            if row.joint not in joint_rows:
                raise ModelError(
                    f"robot '{name}': {where}: coupled joint '{row.joint}' is not an earlier joint row; "
                    f"joints so far: {list(joint_rows)}"
                )
            jid, shared, shared_parent = joint_rows[row.joint]
            if shared_parent != parent or shared.kind != row.kind:
                raise ModelError(
                    f"robot '{name}': {where}: a coupled row must start from the same frame "
                    f"('{shared_parent}') and be of the same kind ({shared.kind}) as row '{row.joint}'"
                )
        else:
            jid = _add_joint(model, parent_joint, parent_placement, row)
            joint_rows[row.name] = (jid, row, parent)
        frames[row.name] = (jid, const)
        model.addFrame(pin.Frame(row.name, jid, 0, _se3(const), pin.FrameType.OP_FRAME))
        previous = row.name
    return RobotModel(model, name=name, length_unit=length_unit)
