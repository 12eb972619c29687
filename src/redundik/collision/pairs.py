"""A collision world's candidate pairs: every pair of geometries except those on the same or adjacent joints, both
fixed to the world, or disabled (by the user or an SRDF's ``<disable_collisions>``: MoveIt's "Adjacent", "Never",
"Default" pairs; example-robot-data ships one beside the Panda's and TALOS's URDF)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Collection
from pathlib import Path

import pinocchio as pin

from redundik.errors import ModelError


def read_srdf_pairs(path: str | Path) -> list[tuple[str, str]]:
    """The ``<disable_collisions link1= link2=>`` pairs of an SRDF file.

    Raises:
        ModelError: a missing or malformed file.
    """
    p = Path(path)
    if not p.is_file():
        raise ModelError(f"SRDF file '{p}' does not exist")
    try:
        root = ET.parse(p).getroot()
    except ET.ParseError as exc:
        raise ModelError(f"SRDF file '{p}' is not valid XML: {exc}") from exc
    return [(e.get("link1", ""), e.get("link2", "")) for e in root.iter("disable_collisions")]


def default_srdf(urdf: str | Path) -> Path | None:
    """The SRDF example-robot-data ships beside a URDF (``../srdf/*.srdf``), or ``None``."""
    folder = Path(urdf).resolve().parent.parent / "srdf"
    if not folder.is_dir():
        return None
    files = sorted(folder.glob("*.srdf"))
    stem = Path(urdf).stem.split("_")[0]
    for f in files:
        if f.stem == stem:
            return f
    return files[0] if files else None


def candidate_pairs(
    model: pin.Model,
    geometry: pin.GeometryModel,
    n_links: int,
    *,
    self_collision: bool,
    disabled: Collection[frozenset[str]],
    obstacle_links: Collection[str] | None,
) -> list[tuple[int, int]]:
    """The geometry index pairs (i, j), i < j, a collision world checks: the robot's first ``n_links`` geometries
    against each other (``self_collision``; not on the same or adjacent joints, not both fixed to the world, not in
    ``disabled``, a set of link-name pairs), then every moving link (of ``obstacle_links`` when given) against each
    obstacle (the geometries after the links)."""
    objs = geometry.geometryObjects
    names = [go.name for go in objs]
    parents = model.parents
    pairs: list[tuple[int, int]] = []
    if self_collision:
        for i in range(n_links):
            for j in range(i + 1, n_links):
                ji, jj = objs[i].parentJoint, objs[j].parentJoint
                if ji == jj or parents[ji] == jj or parents[jj] == ji or (ji == 0 and jj == 0):
                    continue
                if frozenset((names[i], names[j])) in disabled:
                    continue
                pairs.append((i, j))
    for i in range(n_links):
        if objs[i].parentJoint == 0 or (obstacle_links is not None and names[i] not in obstacle_links):
            continue
        for k in range(n_links, len(objs)):
            pairs.append((i, k))
    return pairs
