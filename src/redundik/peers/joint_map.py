"""Map configurations and gradients between a redundik :class:`RobotModel` and a peer's model of the same robot.

A peer (pink on Pinocchio, mink on MuJoCo) may order the joints differently and, for a floating base, use another
coordinate convention. Joints are matched **by name**, never by position:

* 1-dof joints (revolute, prismatic): q and v entries are copied between the matched indices.
* Pinocchio free flyer ↔ Pinocchio free flyer: the 7 q / 6 v entries are copied as they are.
* Pinocchio free flyer ↔ MuJoCo free joint: MuJoCo stores q = (p, w, x, y, z) and v = (ṗ in the world frame,
  ω in the body frame); Pinocchio q = (p, x, y, z, w) and v = (Rᵀṗ, ω), both in the body frame. So
  v_rk = M v_peer with M = diag(Rᵀ, I), and a gradient maps as η_peer = Mᵀ η_rk = (R η_lin, η_ang).

A gradient η = ∂p/∂q is a co-vector: with v_rk = M v_peer, the chain rule gives η_peer = Mᵀ η_rk.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from redundik.errors import ModelError
from redundik.kinematics.model import RobotModel


@dataclass
class JointMap:
    """Index maps between redundik's (q, v) and a peer's (q, v) for the same robot.

    Build one with :meth:`from_pinocchio` (pink) or :meth:`from_mujoco` (mink).

    Attributes:
        nv_robot: Size of redundik's velocity vector.
        nq_peer: Size of the peer's configuration vector.
        nv_peer: Size of the peer's velocity vector.
        rk_q: redundik q indices of the 1-dof (and copied) coordinates.
        peer_q: Matching peer q indices.
        rk_v: redundik v indices of the 1-dof (and copied) coordinates.
        peer_v: Matching peer v indices.
        free_mujoco: ``(rk_q0, rk_v0, peer_q0, peer_v0)`` of a free flyer mapped to a MuJoCo free joint, or ``None``.
        q_template: redundik configuration the mapped entries are written into (neutral).
    """

    nv_robot: int
    nq_peer: int
    nv_peer: int
    rk_q: np.ndarray
    peer_q: np.ndarray
    rk_v: np.ndarray
    peer_v: np.ndarray
    free_mujoco: tuple[int, int, int, int] | None = None
    q_template: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def is_identity(self) -> bool:
        """True when both sides use the same coordinates in the same order (no copy needed)."""
        n = self.rk_q.shape[0]
        return (
            self.free_mujoco is None
            and n == self.nq_peer == self.q_template.shape[0]
            and bool(np.all(self.rk_q == np.arange(n)) and np.all(self.peer_q == np.arange(n)))
            and self.rk_v.shape[0] == self.nv_peer
            and bool(np.all(self.rk_v == self.peer_v))
        )

    # ------------------------------------------------------------------ conversions
    def to_robot_q(self, q_peer: np.ndarray) -> np.ndarray:
        """The redundik configuration of a peer configuration, shape (robot.nq,)."""
        q = self.q_template.copy()
        q[self.rk_q] = q_peer[self.peer_q]
        if self.free_mujoco is not None:
            iq, _, pq, _ = self.free_mujoco
            q[iq : iq + 3] = q_peer[pq : pq + 3]
            w, x, y, z = q_peer[pq + 3 : pq + 7]
            q[iq + 3 : iq + 7] = (x, y, z, w)
        return q

    def to_peer_q(self, q_robot: np.ndarray, q_peer_template: np.ndarray | None = None) -> np.ndarray:
        """The peer configuration of a redundik configuration, shape (nq_peer,)."""
        q = np.zeros(self.nq_peer) if q_peer_template is None else np.array(q_peer_template, dtype=float)
        q[self.peer_q] = q_robot[self.rk_q]
        if self.free_mujoco is not None:
            iq, _, pq, _ = self.free_mujoco
            q[pq : pq + 3] = q_robot[iq : iq + 3]
            x, y, z, w = q_robot[iq + 3 : iq + 7]
            q[pq + 3 : pq + 7] = (w, x, y, z)
        return q

    def gradient_to_peer(self, eta: np.ndarray, q_robot: np.ndarray) -> np.ndarray:
        """η_peer = Mᵀ η_rk for v_rk = M v_peer (module docstring), shape (nv_peer,).

        Args:
            eta: Gradient in redundik's velocity coordinates, shape (robot.nv,).
            q_robot: The redundik configuration η was taken at (for the floating base rotation).
        """
        out = np.zeros(self.nv_peer)
        out[self.peer_v] = eta[self.rk_v]
        if self.free_mujoco is not None:
            iq, iv, _, pv = self.free_mujoco
            R = pin.Quaternion(q_robot[iq + 6], *q_robot[iq + 3 : iq + 6]).normalized().toRotationMatrix()
            out[pv : pv + 3] = R @ eta[iv : iv + 3]
            out[pv + 3 : pv + 6] = eta[iv + 3 : iv + 6]
        return out

    def velocity_to_robot(self, v_peer: np.ndarray, q_robot: np.ndarray) -> np.ndarray:
        """v_rk = M v_peer, shape (robot.nv,)."""
        out = np.zeros(self.nv_robot)
        out[self.rk_v] = v_peer[self.peer_v]
        if self.free_mujoco is not None:
            iq, iv, _, pv = self.free_mujoco
            R = pin.Quaternion(q_robot[iq + 6], *q_robot[iq + 3 : iq + 6]).normalized().toRotationMatrix()
            out[iv : iv + 3] = R.T @ v_peer[pv : pv + 3]
            out[iv + 3 : iv + 6] = v_peer[pv + 3 : pv + 6]
        return out

    # ------------------------------------------------------------------ builders
    @classmethod
    def from_pinocchio(cls, robot: RobotModel, model: pin.Model) -> JointMap:
        """Match the joints of ``robot`` with those of another Pinocchio model (e.g. pink's) by name.

        Raises:
            ModelError: a joint is missing on either side or has another type; the message names it.
        """
        rk = robot.model
        names_rk = [rk.names[j] for j in range(1, rk.njoints)]
        names_peer = [model.names[j] for j in range(1, model.njoints)]
        _check_same_names(robot.name, names_rk, names_peer, "Pinocchio")
        rk_q: list[int] = []
        peer_q: list[int] = []
        rk_v: list[int] = []
        peer_v: list[int] = []
        for j in range(1, rk.njoints):
            jm = rk.joints[j]
            pj = model.getJointId(rk.names[j])
            pm = model.joints[pj]
            if jm.shortname() != pm.shortname() or jm.nq != pm.nq or jm.nv != pm.nv:
                raise ModelError(
                    f"robot '{robot.name}': joint '{rk.names[j]}' is {jm.shortname()} in redundik but "
                    f"{pm.shortname()} in the peer model"
                )
            rk_q += range(jm.idx_q, jm.idx_q + jm.nq)
            peer_q += range(pm.idx_q, pm.idx_q + pm.nq)
            rk_v += range(jm.idx_v, jm.idx_v + jm.nv)
            peer_v += range(pm.idx_v, pm.idx_v + pm.nv)
        return cls(
            nv_robot=robot.nv,
            nq_peer=int(model.nq),
            nv_peer=int(model.nv),
            rk_q=np.array(rk_q, dtype=int),
            peer_q=np.array(peer_q, dtype=int),
            rk_v=np.array(rk_v, dtype=int),
            peer_v=np.array(peer_v, dtype=int),
            q_template=robot.neutral(),
        )

    @classmethod
    def from_mujoco(cls, robot: RobotModel, model: Any) -> JointMap:
        """Match the joints of ``robot`` with the joints of a ``mujoco.MjModel`` by name (free flyer by type).

        Raises:
            ModelError: a joint is missing on either side or has an unsupported type; the message names it.
        """
        from redundik.peers._deps import require

        mujoco = require("mujoco")
        rk = robot.model
        jt = mujoco.mjtJoint
        mj_joints = {model.joint(i).name: i for i in range(model.njnt)}
        mj_free = [i for i in range(model.njnt) if int(model.jnt_type[i]) == int(jt.mjJNT_FREE)]
        rk_q: list[int] = []
        peer_q: list[int] = []
        rk_v: list[int] = []
        peer_v: list[int] = []
        free: tuple[int, int, int, int] | None = None
        used: set[int] = set()
        for j in range(1, rk.njoints):
            jm, name = rk.joints[j], rk.names[j]
            short = jm.shortname()
            if short == "JointModelFreeFlyer":
                if len(mj_free) != 1:
                    raise ModelError(
                        f"robot '{robot.name}': joint '{name}' is a free flyer; the MuJoCo model has "
                        f"{len(mj_free)} free joints (expected 1)"
                    )
                i = mj_free[0]
                free = (jm.idx_q, jm.idx_v, int(model.jnt_qposadr[i]), int(model.jnt_dofadr[i]))
                used.add(i)
                continue
            if jm.nq != 1 or jm.nv != 1:
                raise ModelError(
                    f"robot '{robot.name}': joint '{name}' ({short}) has no MuJoCo counterpart supported by redundik "
                    "(1-dof revolute/prismatic joints and one free flyer are)"
                )
            if name not in mj_joints:
                raise ModelError(
                    f"robot '{robot.name}': joint '{name}' is not in the MuJoCo model; MuJoCo joints: "
                    f"{sorted(mj_joints)}"
                )
            i = mj_joints[name]
            if int(model.jnt_type[i]) not in (int(jt.mjJNT_HINGE), int(jt.mjJNT_SLIDE)):
                raise ModelError(f"robot '{robot.name}': MuJoCo joint '{name}' is not a hinge or slide joint")
            used.add(i)
            rk_q.append(jm.idx_q)
            rk_v.append(jm.idx_v)
            peer_q.append(int(model.jnt_qposadr[i]))
            peer_v.append(int(model.jnt_dofadr[i]))
        extra = sorted(model.joint(i).name or f"#{i}" for i in range(model.njnt) if i not in used)
        if extra:
            raise ModelError(f"robot '{robot.name}': MuJoCo joints {extra} have no counterpart in the redundik model")
        return cls(
            nv_robot=robot.nv,
            nq_peer=int(model.nq),
            nv_peer=int(model.nv),
            rk_q=np.array(rk_q, dtype=int),
            peer_q=np.array(peer_q, dtype=int),
            rk_v=np.array(rk_v, dtype=int),
            peer_v=np.array(peer_v, dtype=int),
            free_mujoco=free,
            q_template=robot.neutral(),
        )


def _check_same_names(robot: str, names_rk: list[str], names_peer: list[str], what: str) -> None:
    missing = sorted(set(names_rk) - set(names_peer))
    extra = sorted(set(names_peer) - set(names_rk))
    if missing or extra:
        raise ModelError(
            f"robot '{robot}': the {what} model does not have the same joints: missing {missing}, extra {extra}"
        )
