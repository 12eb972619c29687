"""Load robots from URDF files, including the ones shipped offline by ``example-robot-data``."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pinocchio as pin

from redundik.errors import ModelError
from redundik.kinematics.model import RobotModel

#: URDF paths (relative to the example-robot-data ``robots`` folder) of the robots known to load offline.
EXAMPLE_ROBOTS: dict[str, tuple[str, bool]] = {
    "panda": ("panda_description/urdf/panda.urdf", False),
    "ur5": ("ur_description/urdf/ur5_robot.urdf", False),
    "ur10": ("ur_description/urdf/ur10_robot.urdf", False),
    "talos": ("talos_data/robots/talos_reduced.urdf", True),
    "talos_full": ("talos_data/robots/talos_full_v2.urdf", True),
    "g1": ("g1_description/urdf/g1_29dof_rev_1_0.urdf", True),
    "xarm7": ("xarm_description/urdf/xarm7.urdf", False),
    "z1": ("z1_description/urdf/z1.urdf", False),
}


def example_robot_data_dir() -> Path:
    """The ``robots`` folder of the installed ``example-robot-data`` package.

    Raises:
        ModelError: if the package is not installed.
    """
    candidates = [Path(p) / "cmeel.prefix/share/example-robot-data/robots" for p in sys.path if p]
    candidates.append(Path(sys.prefix) / "share/example-robot-data/robots")
    env = os.environ.get("EXAMPLE_ROBOT_DATA_MODEL_DIR")
    if env:
        candidates.insert(0, Path(env))
    for c in candidates:
        if c.is_dir():
            return c
    raise ModelError(
        "example-robot-data is not installed (its URDFs were not found); install it with "
        "`pip install example-robot-data`"
    )


def from_urdf(path: str | os.PathLike[str], *, free_flyer: bool = False, name: str | None = None) -> RobotModel:
    """Build a robot from a URDF file (kinematics only: meshes are not loaded).

    Args:
        path: Path to the URDF file.
        free_flyer: Add a floating base (6 unactuated velocity coordinates first).
        name: Robot name for reports; the URDF's robot name if ``None``.

    Raises:
        ModelError: if the file is missing or Pinocchio cannot parse it.
    """
    p = Path(path)
    if not p.is_file():
        raise ModelError(f"URDF file '{p}' does not exist")
    try:
        if free_flyer:
            model = pin.buildModelFromUrdf(str(p), pin.JointModelFreeFlyer())
        else:
            model = pin.buildModelFromUrdf(str(p))
    except Exception as exc:  # pinocchio raises ValueError / RuntimeError with C++ messages
        raise ModelError(f"could not parse URDF '{p}': {exc}") from exc
    return RobotModel(model, name=name or model.name, length_unit="m")


def load_example_robot(name: str) -> RobotModel:
    """Load a robot shipped by ``example-robot-data`` by its short name (``panda``, ``talos``, ``g1``, ...).

    Humanoids (talos, g1) get a free-flyer base, as in their upstream loaders.

    Raises:
        ModelError: unknown name (lists the known ones) or missing data package.
    """
    if name not in EXAMPLE_ROBOTS:
        raise ModelError(f"unknown example robot '{name}'; known: {sorted(EXAMPLE_ROBOTS)}")
    rel, free_flyer = EXAMPLE_ROBOTS[name]
    path = example_robot_data_dir() / rel
    if not path.is_file():
        raise ModelError(f"example robot '{name}': URDF '{path}' is not in the installed example-robot-data")
    return from_urdf(path, free_flyer=free_flyer, name=name)
