"""Guarded imports of the optional peers (mink + MuJoCo, pink): one actionable error when they are missing."""

from __future__ import annotations

import importlib
from types import ModuleType

from redundik.errors import RedundikError

#: pip distribution that provides each importable module of the ``peers`` extra.
_DISTRIBUTIONS: dict[str, str] = {"mink": "mink", "mujoco": "mujoco", "pink": "pin-pink"}


class PeerImportError(RedundikError, ImportError):
    """An optional peer library (mink, MuJoCo, pink) is not installed."""


def require(module: str) -> ModuleType:
    """Import ``module`` (``"mink"``, ``"mujoco"`` or ``"pink"``) or raise an actionable error.

    Raises:
        PeerImportError: if it is not importable; the message says how to install it.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        dist = _DISTRIBUTIONS.get(module, module)
        raise PeerImportError(
            f"the optional peer '{module}' is not installed ({exc}); install redundik[peers] "
            f"(`pip install 'redundik[peers]'`, or `pip install {dist}`)"
        ) from exc


def available(module: str) -> bool:
    """True if ``module`` can be imported (never raises)."""
    try:
        importlib.import_module(module)
    except ImportError:
        return False
    return True
