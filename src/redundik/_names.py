""" "Did you mean" for unknown names (frames, joints, resolvers, QP backends): the close matches of a typo.

Standard library only, so every layer (kinematics, resolvers, the CLI) can use it.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable


def close_matches(name: object, choices: Iterable[str], n: int = 3) -> list[str]:
    """Up to ``n`` of ``choices`` closest to ``name`` (``difflib``'s ratio ≥ 0.6; case ignored), best first."""
    if not isinstance(name, str) or not name:
        return []
    options = [c for c in choices if isinstance(c, str)]
    by_lower: dict[str, str] = {}
    for c in options:
        by_lower.setdefault(c.lower(), c)
    found = difflib.get_close_matches(name[:200].lower(), list(by_lower), n=n, cutoff=0.6)
    return [by_lower[f] for f in found]


def did_you_mean(name: object, choices: Iterable[str]) -> str:
    """``"did you mean 'a' or 'b'? "`` for the close matches of ``name``, or ``""`` when there is none."""
    close = close_matches(name, choices)
    return f"did you mean {' or '.join(repr(c) for c in close)}? " if close else ""
