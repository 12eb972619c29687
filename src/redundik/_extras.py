"""Optional dependencies: which extra provides each module, and one actionable error when it is missing.

The core (kinematics, tasks, resolvers, simulation) needs numpy, scipy, pin, qpsolvers and daqp only; everything
else comes from an extra of ``pyproject.toml`` and is imported at the point of use through :func:`require`.
"""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType

from redundik.errors import MissingDependencyError

#: Importable module → (pip distribution, extra of redundik that installs it).
PROVIDERS: dict[str, tuple[str, str]] = {
    "typer": ("typer", "cli"),
    "rich": ("rich", "cli"),
    "pydantic": ("pydantic", "cli"),
    "yaml": ("PyYAML", "cli"),
    "matplotlib": ("matplotlib", "plots"),
    "PIL": ("pillow", "plots"),
    "example_robot_data": ("example-robot-data", "robots"),
    "osqp": ("osqp", "backends"),
    "proxsuite": ("proxsuite", "backends"),
    "quadprog": ("quadprog", "backends"),
    "mink": ("mink", "peers"),
    "pink": ("pin-pink", "peers"),
    "mujoco": ("mujoco", "sim"),
    "meshcat": ("meshcat", "viewer"),
    "dask": ("dask", "sweep"),
    "distributed": ("distributed", "sweep"),
    "pyarrow": ("pyarrow", "sweep"),
}


def install_hint(module: str) -> str:
    """``pip install 'redundik[EXTRA]'`` (or the plain distribution) for ``module``."""
    dist, extra = PROVIDERS.get(module.split(".")[0], (module, ""))
    return f"pip install 'redundik[{extra}]'" if extra else f"pip install {dist}"


def missing(module: str, purpose: str) -> MissingDependencyError:
    """The error to raise when ``module`` is needed for ``purpose`` and cannot be imported."""
    dist, _ = PROVIDERS.get(module.split(".")[0], (module, ""))
    return MissingDependencyError(f"{purpose} needs {dist}, which is not installed: {install_hint(module)}")


def is_installed(module: str) -> bool:
    """True if ``module`` can be found (without importing it)."""
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def require(module: str, purpose: str) -> ModuleType:
    """Import ``module`` for ``purpose`` (``"plotting"``, ``"the redundik command"``, ...).

    Raises:
        MissingDependencyError: it is not installed; the message says which extra to install.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise missing(module, purpose) from exc
