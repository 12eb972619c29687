"""Safe file names and the one gate every output file goes through.

**Every file a run or a command writes must get its path from :func:`safe_path`** (summary.json, CSVs, figures,
GIFs, and any writer added later: HTML replays, sweeps). It refuses names that are not safe file names and any
path that would land outside the output folder once resolved (``..``, absolute paths, symlinks pointing out).

Names that become file names (task names, run names, output names) follow :data:`NAME_PATTERN`: 1 to 64
characters from ``A-Z a-z 0-9 _ . -``, starting with a letter or digit, without ``..``. The same check is done at
validation time (:func:`check_name`), so a bad name is a one-line :class:`~redundik.errors.ConfigError` with its
YAML key path before anything runs.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from redundik.errors import ConfigError, RedundikError, short_repr

#: Safe file-name pattern of task, run and output names (``..`` is refused separately).
NAME_PATTERN = r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}"
_NAME_RE = re.compile(NAME_PATTERN)
#: Human-readable description used in error messages.
NAME_RULE = "1-64 characters from A-Z a-z 0-9 _ . -, starting with a letter or digit, no '..'"


class OutputPathError(RedundikError):
    """An output file name is unsafe or its path would leave the output folder."""


def name_problem(name: object) -> str | None:
    """Why ``name`` is not a safe file name, or ``None`` if it is."""
    if not isinstance(name, str):
        return f"expected a name (a string), got {short_repr(name)}"
    if not _NAME_RE.fullmatch(name) or ".." in name:
        return f"{short_repr(name)} is not a safe name ({NAME_RULE})"
    return None


def check_name(name: object, path: str | None = None) -> str:
    """Return ``name`` if it is a safe file name.

    Raises:
        ConfigError: otherwise, at the key path ``path``.
    """
    problem = name_problem(name)
    if problem is not None:
        raise ConfigError(problem, path)
    assert isinstance(name, str)
    return name


def check_output_folder(out_dir: str | os.PathLike[str]) -> Path:
    """``out_dir`` as a path, if it can be an output folder: refuses an existing path that is not a folder.

    Call it before a long job, so a bad ``--out`` is refused before the work rather than after it.

    Raises:
        OutputPathError: ``out_dir`` (or one of its parents) exists and is not a folder, or ``out_dir`` is the
            file-system root (``--out /``: the run's files would be strewn over ``/``).
    """
    folder = Path(out_dir)
    try:
        is_root = folder.resolve() == Path(folder.resolve().anchor)
    except (OSError, ValueError, RuntimeError):  # a loop of symlinks, an embedded NUL: the writes will say
        is_root = False
    if is_root:
        raise OutputPathError(
            f"refusing to use the file-system root {short_repr(str(folder), 200)} as the output folder: give a "
            "folder of its own (e.g. out/NAME)"
        )
    for part in (folder, *folder.parents):
        if part.exists() and not part.is_dir():
            raise OutputPathError(
                f"cannot use output folder {short_repr(str(folder), 200)}: {short_repr(str(part), 200)} exists and "
                "is not a folder"
            )
        if part.exists():
            break
    return folder


def safe_path(out_dir: str | os.PathLike[str], name: str) -> Path:
    """The path of output file ``name`` inside ``out_dir``, checked; the folder is created if needed.

    ``name`` must be a safe file name (:data:`NAME_PATTERN`, e.g. ``"summary.json"``, ``"rank_null.csv"``); the
    resolved path (symlinks followed, also an existing file that is a symlink) must be inside the resolved
    ``out_dir``. Call this for every file you write.

    Raises:
        OutputPathError: an unsafe name, or a path that resolves outside ``out_dir``.
    """
    problem = name_problem(name)
    if problem is not None:
        raise OutputPathError(f"refusing to write output file: {problem}")
    folder = Path(out_dir)
    check_output_folder(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        root = folder.resolve(strict=True)
        target = (root / name).resolve()
    except OSError as exc:
        raise OutputPathError(
            f"cannot use output folder {short_repr(str(folder), 200)}: {exc.strerror or exc}"
        ) from None
    if target.parent != root:
        raise OutputPathError(
            f"refusing to write '{name}': it resolves to '{target}', outside the output folder {root}"
        )
    return target
