"""Guarded imports of the optional extras ``viewer`` (meshcat) and ``sim`` (MuJoCo): one actionable error."""

from __future__ import annotations

import importlib
from types import ModuleType

from redundik.errors import RedundikError


class ExtraImportError(RedundikError, ImportError):
    """A library of an optional extra is not installed."""


def require_extra(module: str, extra: str, dist: str | None = None) -> ModuleType:
    """Import ``module`` or raise an :class:`ExtraImportError` saying ``pip install 'redundik[EXTRA]'``."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise ExtraImportError(
            f"'{module}' is not installed ({exc}); install the '{extra}' extra: "
            f"pip install 'redundik[{extra}]' (or pip install {dist or module})"
        ) from exc
