"""Read the D-H rows of a robot config directly (for the chapter's A-matrix computations in :mod:`.jacobians`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from redundik.config.yamlio import read_yaml
from redundik.errors import ConfigError
from redundik.kinematics.dh import DHRow


def read_dh_table(path: str | Path) -> tuple[list[DHRow], np.ndarray, str]:
    """The D-H rows, base transform A_b^0 and base-frame name of a ``configs/*.yaml`` D-H robot.

    Only ``dh``, ``angle_unit``, ``base`` (``matrix`` or ``xyz`` without ``rpy``) and ``base_frame`` are read; the
    full validation is the config loader's job. Angles are converted to radians.

    Raises:
        ConfigError: the file has no ``dh`` table or a base with ``rpy``.
    """
    data = read_yaml(Path(path), "robot config")
    if not isinstance(data, dict) or "dh" not in data:
        raise ConfigError("expected a D-H robot config with a 'dh' table", str(path))
    scale = np.pi / 180.0 if data.get("angle_unit", "rad") == "deg" else 1.0
    rows = []
    for r in data["dh"]:
        kind = r.get("type", "revolute")
        s = scale if kind == "revolute" else 1.0
        rows.append(
            DHRow(
                name=str(r["name"]),
                theta=float(r.get("theta", 0.0)) * scale,
                d=float(r.get("d", 0.0)),
                a=float(r.get("a", 0.0)),
                alpha=float(r.get("alpha", 0.0)) * scale,
                kind=kind,
                lower=float(r["lower"]) * s if r.get("lower") is not None else -np.inf,
                upper=float(r["upper"]) * s if r.get("upper") is not None else np.inf,
                parent=None if r.get("parent") is None else str(r["parent"]),
                joint=None if r.get("joint") is None else str(r["joint"]),
            )
        )
    base = np.eye(4)
    spec = data.get("base") or {}
    if "matrix" in spec:
        base = np.asarray(spec["matrix"], dtype=float)
    else:
        if spec.get("rpy") is not None:
            raise ConfigError("read_dh_table reads base 'matrix' or 'xyz' only", f"{path}: base")
        if spec.get("xyz") is not None:
            base[:3, 3] = spec["xyz"]
    return rows, base, str(data.get("base_frame", "0"))
