"""Small models and numeric helpers shared by the core tests (built in the test, no files)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from redundik.kinematics import DHRow, RobotModel, from_dh


def planar3r(a: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> RobotModel:
    """The chapter's 3R planar arm (Fig. 5.6): all α = 0, d = 0, a_i link lengths."""
    return from_dh([DHRow(str(i + 1), a=a[i]) for i in range(3)], name="planar3r")


def random_dh_robot(rng: np.random.Generator, n: int = 7, with_prismatic: bool = True) -> RobotModel:
    """A random spatial D-H chain with n joints (some prismatic), limits ±π / ±1."""
    rows, base = random_dh_table(rng, n, with_prismatic)
    return from_dh(rows, base=base, name=f"random{n}")


def random_dh_table(
    rng: np.random.Generator, n: int = 7, with_prismatic: bool = True
) -> tuple[list[DHRow], np.ndarray]:
    """Random D-H rows and base transform (see :func:`random_dh_robot`)."""
    rows = []
    for i in range(n):
        kind = "prismatic" if with_prismatic and i in (0, n // 2) else "revolute"
        lim = 1.0 if kind == "prismatic" else np.pi
        rows.append(
            DHRow(
                f"j{i + 1}",
                theta=float(rng.uniform(-np.pi, np.pi)),
                d=float(rng.uniform(-0.5, 0.5)),
                a=float(rng.uniform(0.1, 0.6)),
                alpha=float(rng.choice([-np.pi / 2, 0.0, np.pi / 2]) + rng.uniform(-0.2, 0.2)),
                kind=kind,
                lower=-lim,
                upper=lim,
            )
        )
    base = np.eye(4)
    base[:3, 3] = rng.uniform(-1, 1, 3)
    return rows, base


def fd_gradient(f: Callable[[np.ndarray], float], q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central finite-difference gradient of a scalar function of q (vector-space q)."""
    g = np.zeros(q.size)
    for k in range(q.size):
        e = np.zeros(q.size)
        e[k] = h
        g[k] = (f(q + e) - f(q - e)) / (2 * h)
    return g


def import_every_module() -> list[str]:
    """Import every module of redundik (so that ``__subclasses__`` walks see every class); returns the modules that
    need a third-party package this environment lacks (an optional extra), which are left out. A missing redundik
    module is an error."""
    import importlib
    import pkgutil

    import redundik

    skipped = []
    for info in pkgutil.walk_packages(redundik.__path__, "redundik."):
        try:
            importlib.import_module(info.name)
        except ImportError as exc:
            if (exc.name or "redundik").split(".")[0] == "redundik":
                raise
            skipped.append(info.name)
    return skipped
