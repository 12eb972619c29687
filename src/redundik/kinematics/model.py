"""The robot model every resolver works on: a thin, stateful wrapper around a ``pinocchio.Model``.

A :class:`RobotModel` owns one ``pinocchio.Data``. :meth:`RobotModel.update` runs forward kinematics and the joint
Jacobians once per control tick; tasks and potentials then read frame poses and Jacobians from that cached state,
so several tasks on the same tick share one kinematics pass. State lives on this object, never on ``pin.Model``.

Jacobians are *base-aligned* (Pinocchio's ``LOCAL_WORLD_ALIGNED``): the linear rows are the velocity of the frame
origin and the angular rows the angular velocity, both expressed in the world (base) frame, i.e. the J_b of the
chapter's eq. (4.15) as used in (5.6): V = (v, ω) = J q̇.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
import pinocchio as pin

from redundik._names import did_you_mean
from redundik.errors import ModelError, short_repr
from redundik.kinematics.memory import se3_vector_view
from redundik.kinematics.values import finite_real as _finite_real
from redundik.kinematics.values import reals as _reals

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
WORLD = pin.ReferenceFrame.WORLD

_REVOLUTE = {"JointModelRX", "JointModelRY", "JointModelRZ"}
_PRISMATIC = {"JointModelPX", "JointModelPY", "JointModelPZ"}

#: Row indices of a base-aligned 6×n Jacobian by axis name.
AXES: dict[str, int] = {"x": 0, "y": 1, "z": 2, "rx": 3, "ry": 4, "rz": 5}


#: Most velocity coordinates a robot may have: Pinocchio's data holds nv³ second-order derivative tensors (0.5 GB at
#: nv = 200, 4 GB at 400); a larger model is refused with a ModelError instead of a MemoryError or a swap storm.
MAX_NV = 256


#: How far a configuration's quaternion (free-flyer base, spherical joint) may be from unit norm and still be
#: accepted: | ‖q_quat‖ − 1 | ≤ 1e-3 is rounding or a float32 round trip, normalised silently; anything farther (a
#: zero, tiny or scaled quaternion) is a ModelError naming the joint (it was a rotation scaled by ‖q‖², silently).
QUATERNION_TOLERANCE = 1e-3
#: A quaternion norm this close to 1 is taken as unit (4 units in the last place: ``integrate`` gives ≤ 1).
_UNIT_ROUNDOFF = 4 * 2.220446049250313e-16


def _float_vectors(model: pin.Model) -> dict[str, np.ndarray]:
    """Copies of the model's float vectors (limits, armature, friction, ...) by attribute name; the names differ
    between Pinocchio versions, so they are found on the model."""
    vectors: dict[str, np.ndarray] = {}
    for name in dir(model):
        if not name.startswith("_"):
            value = getattr(model, name)
            if isinstance(value, np.ndarray) and value.dtype.kind == "f":
                vectors[name] = np.array(value, dtype=float)
    return vectors


@dataclass(frozen=True)
class JointInfo:
    """One actuated degree of freedom as the user sees it.

    Attributes:
        name: Joint name (D-H row name or URDF joint name).
        idx_q: Index into the configuration vector q.
        idx_v: Index into the velocity vector q̇.
        kind: ``"revolute"`` [rad], ``"prismatic"`` [m or the model's length unit], or ``"other"``.
        lower: Lower position limit (``-inf`` if none).
        upper: Upper position limit (``+inf`` if none).
        velocity: Velocity limit (``inf`` if none).
    """

    name: str
    idx_q: int
    idx_v: int
    kind: str
    lower: float
    upper: float
    velocity: float


@dataclass
class RobotModel:
    """A kinematic model backed by Pinocchio, with a cached kinematic state.

    Build one with :func:`redundik.kinematics.from_dh`, :func:`redundik.kinematics.from_urdf` or
    :func:`redundik.kinematics.load_example_robot`, or wrap an existing ``pin.Model`` directly.

    Args:
        model: The Pinocchio model (kinematic tree, joint limits, operational frames).
        name: A human-readable robot name used in reports.
        length_unit: Unit of lengths in this model, e.g. ``"m"`` or ``"dm"``; informational.
    """

    model: pin.Model
    name: str = "robot"
    length_unit: str = "m"
    data: pin.Data = field(init=False, repr=False)
    joints: tuple[JointInfo, ...] = field(init=False, repr=False)
    _q: np.ndarray | None = field(init=False, default=None, repr=False)
    _support: np.ndarray | None = field(init=False, default=None, repr=False)
    _nq: int = field(init=False, default=0, repr=False)
    _nv: int = field(init=False, default=0, repr=False)
    #: (joint name, index of the quaternion's first coordinate in q) of every free-flyer / spherical joint
    _quaternions: tuple[tuple[str, int], ...] = field(init=False, default=(), repr=False)
    #: (model, its frame count, name → first frame id): :meth:`frame_id`'s table, made again when either changes
    _frame_ids: tuple[pin.Model, int, dict[str, int]] | None = field(init=False, default=None, repr=False)
    #: (data, a (nframes, 3) view on its frames' origins or None: not verified): :meth:`frame_position`'s
    _placements: tuple[pin.Data, np.ndarray | None] | None = field(init=False, default=None, repr=False)
    #: (joints, name → first JointInfo, the (3, nv) rows lower, upper, velocity): made once per ``joints``
    _joint_table: tuple[Any, dict[str, JointInfo], np.ndarray] | None = field(init=False, default=None, repr=False)

    def __post_init__(self) -> None:
        if int(self.model.nv) > MAX_NV:
            raise ModelError(
                f"robot '{self.name}': {int(self.model.nv)} velocity coordinates, more than {MAX_NV}: Pinocchio's data "
                "holds nv³ second-order derivative tensors (0.5 GB at nv = 200) and is refused before its "
                "memory is taken"
            )
        self.data = self.model.createData()
        self._nq, self._nv = int(self.model.nq), int(self.model.nv)
        joints: list[JointInfo] = []
        for jid in range(1, self.model.njoints):
            jmodel = self.model.joints[jid]
            jname = self.model.names[jid]
            short = jmodel.shortname()
            # Pinocchio names axis-aligned joints RX/RY/RZ and PX/PY/PZ (D-H joints, most URDF joints);
            # unaligned ones RevoluteUnaligned / PrismaticUnaligned; unbounded revolute ones RUBX... (nq = 2).
            if short in _REVOLUTE or ("Revolute" in short and "Unbounded" not in short):
                kind = "revolute"
            elif short in _PRISMATIC or "Prismatic" in short:
                kind = "prismatic"
            else:
                kind = "other"
            if jmodel.nq == 1 and jmodel.nv == 1:  # (name, idx_q, idx_v, kind, lower, upper, velocity)
                iq, iv = jmodel.idx_q, jmodel.idx_v
                limits = float(self.model.lowerPositionLimit[iq]), float(self.model.upperPositionLimit[iq])
                joints.append(JointInfo(jname, iq, iv, kind, *limits, float(self.model.velocityLimit[iv])))
            else:
                for k in range(jmodel.nv):
                    iq, iv = jmodel.idx_q + k if jmodel.nq == jmodel.nv else -1, jmodel.idx_v + k
                    velocity = float(self.model.velocityLimit[iv])
                    joints.append(JointInfo(f"{jname}.{k}", iq, iv, "other", -np.inf, np.inf, velocity))
        self.joints = tuple(joints)
        first = {"JointModelFreeFlyer": 3, "JointModelSpherical": 0}  # the quaternion's offset in the joint's q
        joints_q = [(self.model.names[j], self.model.joints[j]) for j in range(1, self.model.njoints)]
        self._quaternions = tuple((n, jm.idx_q + first[s]) for n, jm in joints_q if (s := jm.shortname()) in first)
        self._check_model()

    def __getstate__(self) -> dict[str, object]:
        """The state for a pickle or a deep copy, with a copy of the model whose non-finite entries are set to 0.

        Pinocchio before 4 pickles a ``pin.Model`` through a Boost text archive that writes ``inf`` and cannot read
        it back (``input stream error``), and an unlimited joint has infinite limits: the entries are recorded
        beside the model and put back by :meth:`__setstate__`. The model in use is not touched.
        """
        state = dict(self.__dict__)
        model = pin.Model(self.model)
        nonfinite: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for name, value in _float_vectors(model).items():
            bad = ~np.isfinite(value)
            if bad.any():
                nonfinite[name] = (np.flatnonzero(bad), value[bad])
                value[bad] = 0.0
                setattr(model, name, value)
        state["model"] = model
        state["_nonfinite"] = nonfinite
        # Pinocchio's data is not part of the state: the copy makes its own and computes it again at its q. Objects
        # that keep views of this robot's data (a frame task's live pose, a fused plan's Jacobians) recognise it by
        # identity; a data object copied beside the robot would pass that test while its views stayed frozen copies
        # (a copied stack silently followed a pose that no longer moved).
        del state["data"]
        state["_frame_ids"] = state["_placements"] = state["_joint_table"] = None  # (made again for the copy)
        return state

    def __setstate__(self, state: dict[str, object]) -> None:
        """Restore a pickled or copied robot: the model's non-finite entries go back where they were."""
        state = dict(state)
        nonfinite = cast("dict[str, tuple[np.ndarray, np.ndarray]]", state.pop("_nonfinite", {}))
        model = state["model"]
        for name, (index, value) in nonfinite.items():
            vector = np.array(getattr(model, name), dtype=float)
            vector[index] = value
            setattr(model, name, vector)
        self.__dict__.update(state)
        self.data = self.model.createData()
        if self._q is not None:
            self._update_checked(self._q)

    def _check_model(self) -> None:
        """Refuse a model no resolver could use: no moving joint, a NaN or inverted limit, a zero joint axis.

        Raises:
            ModelError: names the robot and the joint.
        """
        if self.model.nv == 0:
            raise ModelError(f"robot '{self.name}' has no moving joint (nv = 0): nothing to resolve")
        for j in self.joints:
            if math.isnan(j.lower) or math.isnan(j.upper) or j.lower > j.upper:
                raise ModelError(
                    f"robot '{self.name}': joint '{j.name}': limits must satisfy lower ≤ upper, got "
                    f"[{j.lower:g}, {j.upper:g}]"
                )
            if j.lower == math.inf or j.upper == -math.inf:
                raise ModelError(
                    f"robot '{self.name}': joint '{j.name}': limits [{j.lower:g}, {j.upper:g}] leave no position "
                    "(-inf / inf mean no limit only as lower / upper)"
                )
            if math.isnan(j.velocity) or j.velocity < 0:
                raise ModelError(
                    f"robot '{self.name}': joint '{j.name}': velocity limit must be ≥ 0 (inf: none), got {j.velocity}"
                )
        for jid in range(1, self.model.njoints):
            axis = getattr(self.model.joints[jid].extract(), "axis", None)
            if axis is not None and not float(np.linalg.norm(axis)) > 1e-12:
                raise ModelError(f"robot '{self.name}': joint '{self.model.names[jid]}' has a zero axis")

    # ------------------------------------------------------------------ sizes and names
    @property
    def nq(self) -> int:
        """Size of the configuration vector q."""
        return self._nq

    @property
    def nv(self) -> int:
        """Size of the velocity vector q̇ (the number of joints n of the chapter)."""
        return self._nv

    @property
    def has_quaternions(self) -> bool:
        """A joint's coordinates include a unit quaternion (a free flyer, a spherical joint): a configuration is
        checked and normalised there by :meth:`check_configuration`."""
        return bool(self._quaternions)

    @property
    def joint_names(self) -> list[str]:
        """Names of the velocity coordinates, in q̇ order."""
        return [j.name for j in self.joints]

    @property
    def frame_names(self) -> list[str]:
        """Names of every frame in the model (D-H frames, URDF links, joints)."""
        return [f.name for f in self.model.frames]

    def frame_id(self, name: str) -> int:
        """Index of the frame called ``name`` (the first one of that name, as Pinocchio's ``getFrameId``), from a
        table made once per model (a task that looks its frame up by name at every tick pays a dictionary lookup).

        Raises:
            ModelError: if no such frame exists (the message lists close matches), or ``name`` is not a str.
        """
        table = self._frame_ids
        model = self.model
        if table is not None and table[0] is model and type(name) is str:  # (a known name: one lookup; a frame
            fid = table[2].get(name)  # added since cannot change a known name's first index)
            if fid is not None:
                return fid
        if table is None or table[0] is not model or table[1] != model.nframes:
            ids: dict[str, int] = {}
            for i, frame in enumerate(model.frames):
                ids.setdefault(frame.name, i)
            table = self._frame_ids = (model, model.nframes, ids)
        fid = table[2].get(name) if type(name) is str else None
        if fid is not None:
            return fid
        if not isinstance(name, str):  # (Boost.Python's ArgumentError otherwise)
            raise ModelError(
                f"robot '{self.name}': a frame name (str) was expected, got {type(name).__name__} {short_repr(name)}"
            )
        if not self.model.existFrame(name):
            raise ModelError(
                f"frame '{name}' does not exist in robot '{self.name}'; {did_you_mean(name, self.frame_names)}"
                f"available: {_listing(self.frame_names)}"
            )
        return int(self.model.getFrameId(name))

    def joint(self, name: str) -> JointInfo:
        """The joint called ``name``.

        Raises:
            ModelError: if no such joint exists; the message lists the valid names.
        """
        info = self._joints_table()[1].get(name) if type(name) is str else None
        if info is not None:
            return info
        raise ModelError(
            f"joint '{name}' does not exist in robot '{self.name}'; {did_you_mean(name, self.joint_names)}"
            f"available: {self.joint_names}"
        )

    # ------------------------------------------------------------------ configurations
    def neutral(self) -> np.ndarray:
        """The neutral configuration (zeros for a D-H chain)."""
        return np.asarray(pin.neutral(self.model), dtype=float)

    def random_configuration(self, rng: np.random.Generator | int | None = None) -> np.ndarray:
        """A configuration drawn uniformly within the joint limits (±π for unlimited revolute joints), with ``rng``: a
        ``numpy.random.Generator``, an int seed ≥ 0 (``np.random.default_rng(seed)``) or ``None`` (fresh entropy);
        anything else is a :class:`ModelError`."""
        if rng is None or (isinstance(rng, (int, np.integer)) and not isinstance(rng, bool) and rng >= 0):
            rng = np.random.default_rng(None if rng is None else int(rng))
        elif not isinstance(rng, np.random.Generator):
            raise ModelError(
                f"robot '{self.name}': random_configuration(rng): expected a numpy Generator "
                f"(np.random.default_rng(...)), an int seed ≥ 0 or None, got {type(rng).__name__} {short_repr(rng)}"
            )
        lo = np.array(self.model.lowerPositionLimit, dtype=float)
        hi = np.array(self.model.upperPositionLimit, dtype=float)
        lo = np.where(np.isfinite(lo) & (lo > -1e10), lo, -np.pi)
        hi = np.where(np.isfinite(hi) & (hi < 1e10), hi, np.pi)
        q = self.neutral()
        for jid in range(1, self.model.njoints):
            jm = self.model.joints[jid]
            if jm.nq == 1:
                q[jm.idx_q] = rng.uniform(lo[jm.idx_q], hi[jm.idx_q])
            elif jm.nq == 2 and jm.nv == 1:  # unbounded revolute stored as (cos, sin)
                a = rng.uniform(-np.pi, np.pi)
                q[jm.idx_q : jm.idx_q + 2] = (np.cos(a), np.sin(a))
        return q

    def integrate(self, q: np.ndarray, dq: np.ndarray, dt: float) -> np.ndarray:
        """q ⊕ q̇·dt on the configuration manifold (plain q + q̇·dt for a D-H chain).

        This is the chapter's first-order update q_new = q + q̇·dt.

        Raises:
            ModelError: a q that :meth:`update` refuses (a quaternion far from unit norm), a dq that is not nv real
                numbers, a dt that is not a finite number, or a non-finite result (NaN in q or dq).
        """
        nv = self._nv
        v = dq
        if not (type(dq) is np.ndarray and dq.dtype == np.float64 and dq.shape == (nv,)):
            v = _reals(dq, f"integrate: dq must be {nv} real numbers for robot '{self.name}'")
            if v.size != nv:
                raise ModelError(f"integrate: dq has {v.size} entries, robot '{self.name}' has nv = {nv}")
        if type(dt) is not float or not math.isfinite(dt):
            dt = _finite_real(dt, "integrate: dt")
        if not (type(q) is np.ndarray and q.dtype == np.float64 and q.shape == (self._nq,)):
            q = self.check_configuration(q, f"integrate: q must be {self._nq} real numbers for robot '{self.name}'")
        elif self._quaternions:  # (a zero quaternion gave a zero quaternion back, which update refuses)
            q = self._unit_quaternions(q, f"integrate: q for robot '{self.name}'")
        out = np.asarray(pin.integrate(self.model, q, v * dt), dtype=float)
        if not math.isfinite(float(out @ out)) and not np.isfinite(out).all():
            bad = "q" if not np.isfinite(q).all() else "dq"
            raise ModelError(f"integrate: the result is not finite ({bad} contains NaN or infinite values)")
        return out

    def difference(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """The velocity that goes from q0 to q1 in unit time (q1 ⊖ q0).

        Raises:
            ModelError: q0 or q1 refused by :meth:`check_configuration` (size, NaN, a quaternion far from unit).
        """
        q0, q1 = self._checked(q0, "difference(q0)"), self._checked(q1, "difference(q1)")
        return np.asarray(pin.difference(self.model, q0, q1), dtype=float)

    def _checked(self, q: Any, what: str) -> np.ndarray:
        """:meth:`check_configuration`, in a few operations for a finite (one reduction) float64 array (nq,)."""
        fast = type(q) is np.ndarray and q.dtype == np.float64 and q.shape == (self._nq,)
        if fast and math.isfinite(np.add.reduce(q)):
            return self._unit_quaternions(q, f"robot '{self.name}': {what}") if self._quaternions else q
        return self.check_configuration(q, f"robot '{self.name}': {what}")

    def check_configuration(self, q: Sequence[float] | np.ndarray, where: str = "q") -> np.ndarray:
        """Return ``q`` as a float array after checking its size and finiteness.

        Raises:
            ModelError: wrong length or non-finite entries; names ``where`` and the expected size.
        """
        arr = _reals(q, f"{where}: expected {self.nq} real numbers for robot '{self.name}'")
        if arr.shape[0] != self.nq:
            raise ModelError(f"{where}: expected {self.nq} values for robot '{self.name}', got {arr.shape[0]}")
        if not np.all(np.isfinite(arr)):
            raise ModelError(f"{where}: contains NaN or infinite values: {arr.tolist()}")
        return self._unit_quaternions(arr, where) if self._quaternions else arr

    def _unit_quaternions(self, q: np.ndarray, where: str | None) -> np.ndarray:
        """``q`` with its quaternions normalised (a copy when one is changed), if each is within
        :data:`QUATERNION_TOLERANCE` of unit norm. A norm within :data:`_UNIT_ROUNDOFF` of 1 (a few units in the last
        place: what ``integrate`` returns) is left as it is: dividing by it would change q by less than its own
        round-off. ``where``: what the error names (``None``: the robot's q).

        Raises:
            ModelError: a quaternion farther from unit norm; names the joint and its coordinates.
        """
        out = q
        for name, i in self._quaternions:
            x, y, z, w = q[i : i + 4].tolist()
            norm = math.sqrt(x * x + y * y + z * z + w * w)
            if abs(norm - 1.0) <= _UNIT_ROUNDOFF:
                continue
            if not abs(norm - 1.0) <= QUATERNION_TOLERANCE:
                where = f"robot '{self.name}': q" if where is None else where
                raise ModelError(
                    f"{where}: joint '{name}': the quaternion (x, y, z, w) = q[{i}:{i + 4}] = "
                    f"{[round(v, 6) for v in (x, y, z, w)]} has norm {norm:.3g}; expected a unit quaternion (norm "
                    f"within {QUATERNION_TOLERANCE:g} of 1, e.g. (0, 0, 0, 1) for no rotation)"
                )
            if out is q:
                out = q.copy()
            out[i : i + 4] /= norm
        return out

    # ------------------------------------------------------------------ limits
    def _joints_table(self) -> tuple[Any, dict[str, JointInfo], np.ndarray]:
        """:attr:`_joint_table` for the current ``joints`` (made again if they were replaced)."""
        table = self._joint_table
        joints = self.joints
        if table is None or table[0] is not joints:
            by_name: dict[str, JointInfo] = {}
            for j in joints:
                by_name.setdefault(j.name, j)
            rows = np.array([[j.lower for j in joints], [j.upper for j in joints], [j.velocity for j in joints]])
            rows.setflags(write=False)
            table = self._joint_table = (joints, by_name, rows.reshape(3, len(joints)))
        return table

    @property
    def lower_limits(self) -> np.ndarray:
        """Lower position limits per velocity coordinate (``-inf`` where unlimited); a copy."""
        return self._joints_table()[2][0].copy()

    @property
    def upper_limits(self) -> np.ndarray:
        """Upper position limits per velocity coordinate (``+inf`` where unlimited); a copy."""
        return self._joints_table()[2][1].copy()

    @property
    def velocity_limits(self) -> np.ndarray:
        """Velocity limits per velocity coordinate (``inf`` where unlimited); a copy."""
        return self._joints_table()[2][2].copy()

    def limit_violation(self, q: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """Per-joint amount by which q is outside its position limits (0 inside, and below ``tol``), in q̇ order;
        a q that :meth:`check_configuration` refuses or a tol that is not a finite number ≥ 0 is a ModelError."""
        q = self._checked(q, "limit_violation(q)")
        if not (type(tol) is float and 0.0 <= tol < math.inf):
            tol = _finite_real(tol, f"robot '{self.name}': limit_violation: tol", low=0.0)
        out = np.zeros(len(self.joints))
        for k, j in enumerate(self.joints):
            if j.idx_q < 0:
                continue
            v = q[j.idx_q]
            out[k] = max(j.lower - v, v - j.upper, 0.0)
        out[out < tol] = 0.0
        return out

    # ------------------------------------------------------------------ kinematics state
    def update(self, q: np.ndarray) -> None:
        """Compute forward kinematics, frame placements and joint Jacobians at ``q`` (once per tick)."""
        if not (type(q) is np.ndarray and q.dtype == np.float64 and q.shape == (self._nq,)):
            q = self.check_configuration(q, f"robot '{self.name}': update(q)")
        elif not math.isfinite(float(np.add.reduce(q))) and not np.isfinite(q).all():  # the sum first: one call
            raise ModelError(f"robot '{self.name}': update(q): q contains NaN or infinite values: {q.tolist()[:8]}")
        self._update_checked(q)

    def _update_checked(self, q: np.ndarray) -> None:
        """:meth:`update` for a q already checked (float64, shape (nq,), finite): a resolver's step checks it once.
        A model with quaternions has them checked and normalised here (a few operations per quaternion)."""
        if self._quaternions:
            q = self._unit_quaternions(q, None)
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        self._q = q.copy()

    @property
    def q(self) -> np.ndarray:
        """The configuration of the last :meth:`update`.

        Raises:
            ModelError: if :meth:`update` was never called.
        """
        if self._q is None:
            raise ModelError(f"robot '{self.name}': call update(q) before querying kinematics")
        return self._q

    def frame_pose(self, frame: str | int) -> pin.SE3:
        """Pose of a frame in the world (base) frame at the last :meth:`update`: a copy, the caller's to keep (a
        "home" pose stored in a loop does not follow the robot)."""
        return self.frame_pose_view(frame).copy()

    def frame_pose_view(self, frame: str | int) -> pin.SE3:
        """:meth:`frame_pose` as a live view on the kinematic data, for internal hot paths (a task that reads its
        frame every tick): it changes at every :meth:`update`, and writing to it corrupts the model's state until
        the next one. Use :meth:`frame_pose` to keep a pose."""
        fid = self._frame_index(frame)
        if self._q is None:
            self.q  # noqa: B018 - raises: update() was never called
        return self.data.oMf[fid]

    def frame_position(self, frame: str | int) -> np.ndarray:
        """Origin of a frame in the world frame, shape (3,) (a copy)."""
        placements = self._placements
        data = self.data
        if placements is None or placements[0] is not data:
            view = se3_vector_view(data.oMf)
            placements = self._placements = (data, None if view is None else view[:, 9:12])
        fid = self._frame_index(frame)
        origins = placements[1]  # (nframes, 3): each frame's origin, a verified view of data.oMf
        if origins is None or self._q is None:
            return np.array(self.frame_pose_view(fid).translation)  # (its error; a view not verified)
        return origins[fid].copy()

    def _frame_index(self, frame: str | int) -> int:
        """The frame id of a name or an index.

        Raises:
            ModelError: an unknown name, an index outside [0, nframes), or neither a name nor an integer.
        """
        if type(frame) is str:
            table = self._frame_ids  # (frame_id's first test, inlined: a known name costs one lookup)
            if table is not None and table[0] is self.model:
                fid = table[2].get(frame)
                if fid is not None:
                    return fid
            return self.frame_id(frame)
        if type(frame) is int and 0 <= frame < self.model.nframes:  # (an id, as a task keeps it: two tests)
            return frame
        if isinstance(frame, (int, np.integer)) and not isinstance(frame, bool):
            fid = int(frame)
            if 0 <= fid < self.model.nframes:
                return fid
            raise ModelError(f"robot '{self.name}': frame index {fid} is outside [0, {self.model.nframes})")
        if isinstance(frame, str):  # (a str subclass: numpy's str_)
            return self.frame_id(str(frame))
        raise ModelError(
            f"robot '{self.name}': a frame is given by its name or its index, got {type(frame).__name__} {frame!r}"
        )

    def frame_jacobian(self, frame: str | int) -> np.ndarray:
        """Base-aligned 6×nv Jacobian of a frame: rows (v_x, v_y, v_z, ω_x, ω_y, ω_z), eq. (5.6)."""
        fid = self._frame_index(frame)
        if self._q is None:
            self.q  # noqa: B018 - raises: update() was never called
        J = np.asarray(pin.getFrameJacobian(self.model, self.data, fid, LWA))
        return J if J.ndim == 2 else J.reshape(6, self._nv)  # the bindings return a 6×1 matrix as shape (6,)

    def frame_jacobian_derivatives(self, frame: str | int) -> np.ndarray:
        """∂J/∂q_k of the base-aligned frame Jacobian, shape (6, nv, nv): ``H[:, :, k] = ∂J/∂q_k``.

        Exact, from the spatial (WORLD) Jacobian J^s of the frame's joint: for columns j, k where joint(k) supports
        joint(j) (is an ancestor of it, or the same joint), ∂J^s_j/∂q_k = ad(J^s_k) J^s_j, with
        ad(v, ω)·(v', ω') = (ω × v' + v × ω', ω × ω'); otherwise 0. The base-aligned Jacobian at the frame origin p is
        J = X(p) J^s with X(p) = [[I, −[p]×], [0, I]], hence ∂J/∂q_k = X(p) ∂J^s/∂q_k + [[0, −[∂p/∂q_k]×], [0, 0]] J^s,
        with ∂p/∂q_k the k-th linear column of J. Derivatives are along the velocity coordinates (q ⊕ ε e_k).
        """
        fid = self._frame_index(frame)
        self.q  # noqa: B018 - raises if update() was never called
        fr = self.model.frames[fid]
        js = np.asarray(pin.getJointJacobian(self.model, self.data, fr.parentJoint, WORLD))  # (6, nv)
        v, w = js[:3].T, js[3:].T  # (nv, 3) each
        # pairs [j, k]: ad(J_k) J_j = (ω_k × v_j + v_k × ω_j, ω_k × ω_j)
        hv = np.cross(w[None, :, :], v[:, None, :]) + np.cross(v[None, :, :], w[:, None, :])  # (j, k, 3)
        hw = np.cross(w[None, :, :], w[:, None, :])
        mask = self.support_mask()[:, :, None]  # [j, k]: joint(k) supports joint(j)
        hv *= mask
        hw *= mask
        p = np.array(self.data.oMf[fid].translation)
        jl = v + np.cross(w, p)  # ∂p/∂q_k = v_k + ω_k × p, (nv, 3)
        out = np.empty((6, self.nv, self.nv))
        out[3:] = hw.transpose(2, 0, 1)
        # X(p): linear part v + ω × p  ->  hv + hw × p, plus ω_j × ∂p/∂q_k
        out[:3] = (hv + np.cross(hw, p) + np.cross(w[:, None, :], jl[None, :, :])).transpose(2, 0, 1)
        return out

    def support_mask(self) -> np.ndarray:
        """Boolean (nv, nv) matrix M[j, k] = joint of velocity k is joint of velocity j or one of its ancestors."""
        if self._support is None:
            owner = np.empty(self.nv, dtype=int)
            for jid in range(1, self.model.njoints):
                jm = self.model.joints[jid]
                owner[jm.idx_v : jm.idx_v + jm.nv] = jid
            mask = np.zeros((self.nv, self.nv))
            for j in range(self.nv):
                mask[j] = np.isin(owner, list(self.model.supports[int(owner[j])]))
            self._support = mask
        return self._support


def _listing(names: Sequence[str], limit: int = 40) -> str:
    names = [n for n in names if n != "universe"]
    if len(names) <= limit:
        return ", ".join(names)
    return ", ".join(names[:limit]) + f", ... ({len(names)} in all)"
