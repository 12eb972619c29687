"""MuJoCo models of redundik robots: from the same URDF, or built from the Pinocchio model (D-H robots).

The MuJoCo plant (:mod:`redundik.simulation.mujoco_plant`) loads the robot's URDF through :func:`strip_urdf`; the
mink interop (``redundik.peers``) and the benchmark build their MuJoCo models here too.

MuJoCo cannot open the URDFs' ``package://`` meshes, so :func:`mujoco_from_urdf` strips every ``<visual>`` and
``<collision>`` element (kinematics only). MuJoCo's URDF import fuses links attached by fixed joints into their
parents (the Panda's ``panda_hand`` disappears into ``panda_link7``), so every frame a task needs becomes a
**site** named after the frame, placed on the MuJoCo body that carries it at the frame's fixed placement (taken
from the redundik model at the neutral configuration). Use ``frame_type="site"`` in mink tasks.

A MuJoCo body frame is its URDF link frame; ``tests/test_peers.py`` checks that every site's pose equals the
Pinocchio frame pose at random configurations.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from redundik._optional import require_extra
from redundik.errors import ModelError
from redundik.kinematics.model import RobotModel

#: Pinocchio joint short names → (MuJoCo joint type name, axis).
_AXIS_JOINTS: dict[str, tuple[str, tuple[float, float, float]]] = {
    "JointModelRX": ("hinge", (1.0, 0.0, 0.0)),
    "JointModelRY": ("hinge", (0.0, 1.0, 0.0)),
    "JointModelRZ": ("hinge", (0.0, 0.0, 1.0)),
    "JointModelPX": ("slide", (1.0, 0.0, 0.0)),
    "JointModelPY": ("slide", (0.0, 1.0, 0.0)),
    "JointModelPZ": ("slide", (0.0, 0.0, 1.0)),
}


def _wxyz(rotation: np.ndarray) -> list[float]:
    quat = pin.Quaternion(rotation).coeffs()  # (x, y, z, w)
    return [float(quat[3]), float(quat[0]), float(quat[1]), float(quat[2])]


def strip_urdf(path: str | os.PathLike[str]) -> str:
    """The URDF text without visual/collision/gazebo/transmission elements (kinematics and inertia only).

    Raises:
        ModelError: if the file is missing or not XML.
    """
    p = Path(path)
    if not p.is_file():
        raise ModelError(f"URDF file '{p}' does not exist")
    try:
        root = ET.parse(p).getroot()
    except ET.ParseError as exc:
        raise ModelError(f"could not parse URDF '{p}': {exc}") from exc
    for link in root.iter("link"):
        for tag in ("visual", "collision"):
            for elem in link.findall(tag):
                link.remove(elem)
    for tag in ("gazebo", "transmission", "mujoco"):
        for elem in root.findall(tag):
            root.remove(elem)
    mj = ET.SubElement(root, "mujoco")
    ET.SubElement(mj, "compiler", {"discardvisual": "true", "balanceinertia": "true"})
    return ET.tostring(root, encoding="unicode")


def _host_body(robot: RobotModel, frame_id: int, bodies: set[str]) -> int:
    """The nearest frame at or above ``frame_id`` (through fixed frames) that is a MuJoCo body; its frame id."""
    model = robot.model
    fid = frame_id
    for _ in range(len(model.frames)):
        fr = model.frames[fid]
        if fr.name in bodies:
            return fid
        if fr.type == pin.FrameType.JOINT or fid == 0:
            break
        fid = fr.parentFrame
    raise ModelError(
        f"robot '{robot.name}': frame '{model.frames[frame_id].name}' is not attached (through fixed joints) to a "
        "body of the MuJoCo model"
    )


def add_frame_sites(spec: Any, robot: RobotModel, frames: Sequence[str]) -> None:
    """Add one site per redundik frame, on the MuJoCo body carrying it (see the module docstring)."""
    bodies = {b.name for b in spec.bodies}
    q0 = robot.neutral()
    robot.update(q0)
    for name in frames:
        fid = robot.frame_id(name)
        host = _host_body(robot, fid, bodies)
        rel = robot.frame_pose(host).actInv(robot.frame_pose(fid))  # host frame → frame, constant
        body = spec.body(robot.model.frames[host].name)
        body.add_site(name=name, pos=np.asarray(rel.translation), quat=_wxyz(rel.rotation))


def mujoco_from_urdf(
    path: str | os.PathLike[str],
    robot: RobotModel,
    frames: Sequence[str] = (),
    *,
    free_flyer: bool = False,
) -> Any:
    """Load a URDF into MuJoCo (kinematics only) with a site per task frame; returns a ``mujoco.MjModel``.

    Args:
        path: The URDF the redundik ``robot`` was built from.
        robot: The redundik model of the same URDF (site placements are read from it).
        frames: Frame names that become sites (e.g. ``["panda_hand"]``).
        free_flyer: Give the root body a free joint (as redundik's ``free_flyer=True``).

    Raises:
        ExtraImportError: MuJoCo is not installed (``pip install 'redundik[sim]'``).
        ModelError: unreadable URDF or a frame MuJoCo cannot carry.
    """
    mujoco = require_extra("mujoco", "sim")
    text = strip_urdf(path)
    try:
        spec = mujoco.MjSpec.from_string(text)
    except Exception as exc:  # mujoco raises ValueError with its parser message
        raise ModelError(f"MuJoCo could not load URDF '{path}': {exc}") from exc
    if free_flyer:
        root = spec.worldbody.first_body()
        if root is None:
            raise ModelError(f"URDF '{path}' has no body to attach a free flyer to")
        root.add_freejoint()
    add_frame_sites(spec, robot, frames)
    return _compile(spec, str(path))


def mujoco_from_robot(robot: RobotModel, frames: Sequence[str] = ()) -> Any:
    """Build a MuJoCo model joint by joint from the redundik (Pinocchio) model, e.g. for a D-H robot.

    Every Pinocchio joint becomes a body at the joint placement with a hinge/slide joint on the same axis and
    the same limits (a free flyer becomes a free joint); bodies get a unit mass (MuJoCo needs one; kinematics do
    not depend on it). Joint and site names are the redundik joint and frame names.

    Raises:
        ExtraImportError: MuJoCo is not installed (``pip install 'redundik[sim]'``).
        ModelError: a joint type MuJoCo has no counterpart for.
    """
    mujoco = require_extra("mujoco", "sim")
    model = robot.model
    spec = mujoco.MjSpec()
    spec.modelname = robot.name
    spec.compiler.degree = False  # joint ranges below are in radians
    bodies: dict[int, Any] = {0: spec.worldbody}
    for j in range(1, model.njoints):
        jm, name = model.joints[j], model.names[j]
        short = jm.shortname()
        placement = model.jointPlacements[j]
        body = bodies[model.parents[j]].add_body(
            name=f"{name}_body",
            pos=np.asarray(placement.translation),
            quat=_wxyz(placement.rotation),
            mass=1.0,
            inertia=[1e-3, 1e-3, 1e-3],
        )
        bodies[j] = body
        if short == "JointModelFreeFlyer":
            body.add_freejoint(name=name)
            continue
        if short in _AXIS_JOINTS:
            kind, axis = _AXIS_JOINTS[short]
        elif short in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
            kind = "hinge" if "Revolute" in short else "slide"
            ax = [float(a) for a in jm.extract().axis]
            axis = (ax[0], ax[1], ax[2])
        else:
            raise ModelError(f"robot '{robot.name}': joint '{name}' ({short}) has no MuJoCo counterpart here")
        iq = jm.idx_q
        lo, hi = float(model.lowerPositionLimit[iq]), float(model.upperPositionLimit[iq])
        limited = np.isfinite(lo) and np.isfinite(hi) and hi - lo < 1e9
        body.add_joint(
            name=name,
            type=mujoco.mjtJoint.mjJNT_HINGE if kind == "hinge" else mujoco.mjtJoint.mjJNT_SLIDE,
            axis=list(axis),
            range=[lo, hi] if limited else [0.0, 0.0],
            limited=mujoco.mjtLimited.mjLIMITED_TRUE if limited else mujoco.mjtLimited.mjLIMITED_FALSE,
        )
    for name in frames:
        fid = robot.frame_id(name)
        fr = model.frames[fid]
        body = bodies[fr.parentJoint]
        body.add_site(name=name, pos=np.asarray(fr.placement.translation), quat=_wxyz(fr.placement.rotation))
    return _compile(spec, robot.name)


def _compile(spec: Any, where: str) -> Any:
    try:
        return spec.compile()
    except Exception as exc:
        raise ModelError(f"MuJoCo could not compile the model of '{where}': {exc}") from exc
