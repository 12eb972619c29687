"""Load robots from URDF files, including the ones shipped offline by ``example-robot-data``."""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from collections.abc import Iterator
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
        MissingDependencyError: the package is not installed (``pip install 'redundik[robots]'``).
    """
    candidates = [Path(p) / "cmeel.prefix/share/example-robot-data/robots" for p in sys.path if p]
    candidates.append(Path(sys.prefix) / "share/example-robot-data/robots")
    env = os.environ.get("EXAMPLE_ROBOT_DATA_MODEL_DIR")
    if env:
        candidates.insert(0, Path(env))
    for c in candidates:
        if c.is_dir():
            return c
    from redundik._extras import missing

    raise missing("example_robot_data", "loading an example robot (its URDFs were not found)")


#: Largest URDF file parsed [bytes].
MAX_URDF_BYTES = 64 * 1024 * 1024


@contextlib.contextmanager
def _captured_stderr() -> Iterator[list[str]]:
    """Redirect file descriptor 2 (where urdfdom's C++ code prints) into a buffer for the duration.

    Yields a list that receives the captured text after the block, so an error can quote its first line instead
    of the parser's chatter reaching the terminal ahead of redundik's own one-line message.
    """
    out: list[str] = []
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no usable fd 2 (embedded interpreter): nothing to redirect
        yield out
        return
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield out
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            out.append(tmp.read(4096).decode("utf-8", "replace"))


def _first_line(text: str) -> str:
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    return lines[0][:160] if lines else ""


def from_urdf(path: str | os.PathLike[str], *, free_flyer: bool = False, name: str | None = None) -> RobotModel:
    """Build a robot from a URDF file (kinematics only: meshes are not loaded).

    Args:
        path: Path to the URDF file.
        free_flyer: Add a floating base (6 unactuated velocity coordinates first).
        name: Robot name for reports; the URDF's robot name if ``None``.

    Raises:
        ModelError: if the file is missing or Pinocchio cannot parse it.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise ModelError(f"URDF path must be a file path (str or Path), got {type(path).__name__}")
    if not str(path).strip():
        raise ModelError("URDF path is an empty string: give the path of a .urdf file")
    p = Path(path)
    try:
        exists = p.is_file()
        size = p.stat().st_size if exists else 0
    except (OSError, ValueError) as exc:  # a name too long, an embedded NUL, ...
        raise ModelError(
            f"URDF file '{str(p)[:120]}' cannot be read: {getattr(exc, 'strerror', None) or exc}"
        ) from None
    if not exists:
        if p.is_dir():
            raise ModelError(f"URDF path '{str(p)[:200]}' is a folder, not a file: give the path of a .urdf file")
        if p.exists():
            raise ModelError(f"URDF path '{str(p)[:200]}' is not a regular file (a device, a pipe?)")
        raise ModelError(f"URDF file '{str(p)[:200]}' does not exist")
    if size > MAX_URDF_BYTES:
        raise ModelError(f"URDF file '{p}' is larger than {MAX_URDF_BYTES // (1024 * 1024)} MiB")
    chatter: list[str] = []
    try:
        with _captured_stderr() as chatter:
            if free_flyer:
                model = pin.buildModelFromUrdf(str(p), pin.JointModelFreeFlyer())
            else:
                model = pin.buildModelFromUrdf(str(p))
    except Exception as exc:  # pinocchio raises ValueError / RuntimeError with C++ messages
        detail = _first_line(str(exc)) or type(exc).__name__
        said = _first_line("".join(chatter))
        raise ModelError(
            f"could not parse URDF '{p}': {detail}" + (f" (urdfdom: {said})" if said and said not in detail else "")
        ) from None
    return RobotModel(model, name=name or model.name, length_unit="m")


def load_example_robot(name: str) -> RobotModel:
    """Load a robot shipped by ``example-robot-data`` by its short name (``panda``, ``talos``, ``g1``, ...).

    Humanoids (talos, g1) get a free-flyer base, as in their upstream loaders.

    Raises:
        ModelError: unknown name (lists the known ones).
        MissingDependencyError: example-robot-data is not installed (`pip install 'redundik[robots]'`).
    """
    if name not in EXAMPLE_ROBOTS:
        raise ModelError(f"unknown example robot '{name}'; known: {sorted(EXAMPLE_ROBOTS)}")
    rel, free_flyer = EXAMPLE_ROBOTS[name]
    path = example_robot_data_dir() / rel
    if not path.is_file():
        raise ModelError(f"example robot '{name}': URDF '{path}' is not in the installed example-robot-data")
    return from_urdf(path, free_flyer=free_flyer, name=name)
