"""Load robots from URDF files, including the ones shipped offline by ``example-robot-data``."""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pinocchio as pin

from redundik.errors import ModelError, short_repr
from redundik.kinematics.model import MAX_NV, RobotModel

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


#: Largest URDF file parsed [bytes] (TALOS's is 0.11 MB; meshes live in their own files).
MAX_URDF_BYTES = 16 * 1024 * 1024
#: Most ``<link>`` / ``<joint>`` elements a URDF may declare (TALOS: 60 / 59). Pinocchio's URDF reader recurses once
#: per link of a chain, so a chain of 7 000 links overflows its stack (a segfault) before ``MAX_NV`` could refuse the
#: model: the file is counted here, by a streaming XML pass, before any C++ library sees it.
MAX_URDF_LINKS = 1024
MAX_URDF_JOINTS = 1024
#: Longest chain of joints from the root link to a leaf (``MAX_NV`` moving joints, plus fixed ones).
MAX_URDF_DEPTH = 512
#: Deepest nesting of XML elements (a URDF nests about 4: robot / link / visual / geometry / mesh).
MAX_URDF_NESTING = 32


def _check_urdf_structure(p: Path) -> None:
    """Count a URDF's links, joints, XML nesting and chain depth in one streaming pass (expat, no C++ model), and
    refuse it before Pinocchio parses it when any is beyond its bound.

    Raises:
        ModelError: names the file, what is too large, and the bound.
    """
    import xml.etree.ElementTree as ET

    counts = {"link": 0, "joint": 0}
    bound = {"link": MAX_URDF_LINKS, "joint": MAX_URDF_JOINTS}
    parent_of: dict[str, str] = {}  # child link -> parent link
    nesting = 0
    pending: tuple[str, str] = ("", "")  # the current joint's (parent, child) links
    try:
        for event, elem in ET.iterparse(str(p), events=("start", "end")):
            if event == "start":
                nesting += 1
                if nesting > MAX_URDF_NESTING:
                    raise ModelError(f"URDF '{p}': XML elements nested deeper than {MAX_URDF_NESTING} levels")
                if nesting == 2 and elem.tag in counts:
                    counts[elem.tag] += 1
                    if counts[elem.tag] > bound[elem.tag]:
                        raise ModelError(
                            f"URDF '{p}': more than {bound[elem.tag]} <{elem.tag}> elements: refused before parsing "
                            f"(redundik models at most {MAX_NV} joints)"
                        )
                    pending = ("", "")
                elif nesting == 3 and elem.tag in ("parent", "child"):
                    link = elem.get("link", "")
                    pending = (link, pending[1]) if elem.tag == "parent" else (pending[0], link)
                continue
            nesting -= 1
            if nesting == 1:
                if elem.tag == "joint" and pending[0] and pending[1]:
                    parent_of[pending[1]] = pending[0]
                elem.clear()  # keep memory flat: the elements are not needed after they are counted
    except ET.ParseError as exc:
        raise ModelError(f"could not parse URDF '{p}': {exc}") from None
    deepest = 0
    depth_of: dict[str, int] = {}
    for link in parent_of:
        chain: list[str] = []
        seen: set[str] = set()
        node = link
        while node in parent_of and node not in depth_of and len(chain) <= MAX_URDF_DEPTH:
            if node in seen:
                raise ModelError(f"URDF '{p}': the joints form a loop through link '{node[:80]}' (a tree is expected)")
            seen.add(node)
            chain.append(node)
            node = parent_of[node]
        if len(chain) > MAX_URDF_DEPTH:
            deepest = len(chain)
            break
        base = depth_of.get(node, 0)
        for k, name in enumerate(reversed(chain), start=1):
            depth_of[name] = base + k
        deepest = max(deepest, depth_of.get(link, 0))
    if deepest > MAX_URDF_DEPTH:
        raise ModelError(
            f"URDF '{p}': a chain of more than {MAX_URDF_DEPTH} joints from the root link: refused before parsing "
            f"(redundik models at most {MAX_NV} joints)"
        )


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
        ModelError: if the file is missing, larger than ``MAX_URDF_BYTES``, declares more than ``MAX_URDF_LINKS``
            links or ``MAX_URDF_JOINTS`` joints, has a chain deeper than ``MAX_URDF_DEPTH``, or Pinocchio cannot
            parse it.
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
    _check_urdf_structure(p)
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
    if not isinstance(name, str) or name not in EXAMPLE_ROBOTS:
        raise ModelError(f"unknown example robot {short_repr(name)}; known: {sorted(EXAMPLE_ROBOTS)}")
    rel, free_flyer = EXAMPLE_ROBOTS[name]
    path = example_robot_data_dir() / rel
    if not path.is_file():
        raise ModelError(f"example robot '{name}': URDF '{path}' is not in the installed example-robot-data")
    return from_urdf(path, free_flyer=free_flyer, name=name)
