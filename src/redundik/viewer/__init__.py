"""See a run: an offline HTML replay (:func:`write_html`, needs nothing beyond the core) and a live meshcat viewer
(:class:`LiveViewer`, :func:`replay_meshcat`; optional extra ``viewer``: ``pip install redundik[viewer]``).

Submodules are imported lazily so ``import redundik.viewer`` costs little and never needs meshcat.
"""

from __future__ import annotations

from typing import Any

__all__ = ["LiveViewer", "build_task_replay", "replay_meshcat", "write_html"]


def __getattr__(name: str) -> Any:
    if name in ("write_html", "build_task_replay"):
        from redundik.viewer import html

        return getattr(html, name)
    if name in ("LiveViewer", "replay_meshcat"):
        from redundik.viewer import live

        return getattr(live, name)
    raise AttributeError(f"module 'redundik.viewer' has no attribute {name!r}")
