"""The docstrings and comments say what the code does, not the history of its timings (issue 31 item 6: "that
belongs in the changelog"). A timing history is a number, an arrow and a number with a time unit — "660 → 365 µs",
"0.6–2.6 ms → 70–110 µs" — in any module, class or function docstring or ``#`` comment under ``src/redundik``."""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "src" / "redundik"

#: A number or a range of numbers ("300", "0.6–2.6", "2 458").
_NUMBER = r"\d[\d.,]*(?:\s*[–-]\s*\d[\d.,]*)?"
#: A time unit (the micro sign or the Greek mu), ending a word.
_UNIT = r"(?:ns|[µμ]s|us|ms|s)\b"
#: A timing history: a number, an optional unit, an arrow, an optional "~" or "≈", a number and a time unit. The
#: unit after the second number is what tells a timing from the chapter's maths ("q̇ → 0", "dt → 0 s").
HISTORY = re.compile(rf"{_NUMBER}\s*(?:{_UNIT})?\s*(?:→|->)\s*[~≈]?\s*{_NUMBER}\s*{_UNIT}")

_DOCUMENTED = (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)


def _docstrings(tree: ast.Module) -> list[tuple[int, str]]:
    """(first line, raw text) of every module, class and function docstring: uncleaned, so that its lines are the
    file's lines from the first one on."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, _DOCUMENTED):
            text = ast.get_docstring(node, clean=False)
            if text is not None:
                found.append((node.body[0].lineno, text))
    return found


def _comments(source: str) -> list[tuple[int, str]]:
    """(first line, text) of every block of ``#`` comments on consecutive lines, the blocks' lines joined, so that a
    history wrapped over two comment lines is one text."""
    blocks: list[tuple[int, list[str]]] = []
    last = -2
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type != tokenize.COMMENT:
            continue
        line = token.start[0]
        text = token.string.lstrip("#:").strip()
        if line == last + 1 and blocks:
            blocks[-1][1].append(text)
        else:
            blocks.append((line, [text]))
        last = line
    return [(first, "\n".join(lines)) for first, lines in blocks]


def _histories(text: str) -> list[tuple[int, str]]:
    """(line offset in ``text``, matched text) of every timing history in ``text``."""
    return [(text.count("\n", 0, m.start()), " ".join(m.group().split())) for m in HISTORY.finditer(text)]


def test_no_timing_history_in_docstrings_or_comments() -> None:
    """No docstring or comment under src/redundik tells a history of timings (issue 31 item 6): the figures go to
    CHANGELOG.md, the text says what the code does and why. Names every offence as file:line."""
    files = sorted(SOURCE.rglob("*.py"))
    assert len(files) > 50  # (the tree was found)
    offences = []
    for path in files:
        source = path.read_text(encoding="utf-8")
        for first, text in _docstrings(ast.parse(source)) + _comments(source):
            for offset, match in _histories(text):
                offences.append(f"{path.relative_to(ROOT)}:{first + offset}: {match}")
    assert not offences, "timing histories (move them to CHANGELOG.md):\n" + "\n".join(offences)


@pytest.mark.parametrize(
    "text",
    [
        "660 → 365 µs",
        "0.6–2.6 ms → 70–110 µs",
        "72 → ~50 µs",
        "2.5 ms -> 0.16 ms",
        "28 µs → 2–4 µs a step",
        "A QP step of the 10-joint snake 300 →\n72 µs",
        "0.100–0.108 → 0.073–0.074 s",
        "from 45.9 → 43.1 μs",
    ],
)
def test_pattern_finds_timing_histories(text: str) -> None:
    """The pattern finds a before → after timing, with ranges, "~", either mu, an ASCII arrow, a line break."""
    assert HISTORY.search(text), text


@pytest.mark.parametrize(
    "text",
    [
        "q̇ → 0",
        "J⁺ → J^T",
        "dt → 0 s",
        "c → 1/12 as θ → 0",
        "σ_i ≥ ε → 1/σ_i",
        "κ → ∞",
        "3 → 5 samples",
        "`wqp` 22.8 → 32.4×",
        "n = 10 83 → 53 joints",
    ],
)
def test_pattern_leaves_maths_alone(text: str) -> None:
    """Maths and counts with an arrow are not timings: no time unit after the second number."""
    assert not HISTORY.search(text), text
