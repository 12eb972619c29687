"""Griffe extension: read the Sphinx roles in redundik's docstrings as mkdocstrings cross-references.

The docstrings follow the Google style but point at other objects with Sphinx roles (``:class:`TaskTerm```,
``:meth:`~RobotModel.update```). This rewrites each role into an autorefs link before mkdocstrings renders the
docstring, so ``mkdocs build --strict`` fails on a role whose target does not exist. A leading ``~`` shows only the
last component, as in Sphinx; a trailing ``()`` is kept in the text and dropped from the target. Targets in other
packages (``scipy.``, ``numpy.``, ``pinocchio.``: no inventory is fetched) are shown as code without a link.

A module constant documented the Sphinx way, by ``#:`` comment lines just above it, gets them as its docstring.
"""

from __future__ import annotations

import re
from functools import cache
from pathlib import Path
from typing import Any

import griffe

ROLE = re.compile(
    r":(?:py:)?(?:class|meth|mod|data|attr|func|exc|obj):`(?P<tilde>~?)(?P<target>[\w.]+?)(?P<call>\(\))?`"
)
EXTERNAL = ("scipy.", "numpy.", "np.", "pinocchio.", "pin.", "qpsolvers.", "mink.", "pink.", "mujoco.")


def rewrite(text: str) -> str:
    """Every Sphinx role in ``text`` as a Markdown cross-reference ``[`shown`][target]``."""

    def link(match: re.Match[str]) -> str:
        target = match["target"]
        shown = (target.rsplit(".", 1)[-1] if match["tilde"] else target) + (match["call"] or "")
        if target.startswith(EXTERNAL):
            return f"`{shown}`"
        return f"[`{shown}`][{target}]"

    return ROLE.sub(link, text)


@cache
def _source_lines(path: Path) -> list[str]:
    return path.read_text(encoding="utf-8").splitlines()


def comment_docstring(obj: griffe.Object) -> str | None:
    """The ``#:`` comment lines right above an attribute's definition, joined, or ``None``."""
    if not obj.is_attribute or obj.lineno is None or not isinstance(obj.filepath, Path):
        return None
    lines = _source_lines(obj.filepath)
    found: list[str] = []
    index = obj.lineno - 2  # the line above the definition (lineno is 1-based)
    while index >= 0 and lines[index].lstrip().startswith("#:"):
        found.insert(0, lines[index].lstrip()[2:].strip())
        index -= 1
    return " ".join(found) or None


class SphinxRoles(griffe.Extension):
    """Rewrite the roles of every docstring griffe loads; give ``#:``-commented constants their docstring."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        """Rewrite ``obj``'s docstring in place."""
        if obj.docstring is None:
            text = comment_docstring(obj)
            if text is not None:
                obj.docstring = griffe.Docstring(text, parent=obj)
        if obj.docstring is not None and ":`" in obj.docstring.value:
            obj.docstring.value = rewrite(obj.docstring.value)
