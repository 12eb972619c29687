"""The example files shipped with redundik: ``tasks/``, ``configs/`` (YAML and the URDFs they name), ``sweeps/``.

An installed wheel carries them under ``redundik/_data/`` (copied there by the build, see ``setup.py``); a source
checkout (editable install) uses the repository's own ``tasks/`` and ``configs/``. Both keep the relative layout
the files refer to each other by (``robot: ../configs/planar3r.yaml``). Standard library only.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

from redundik.errors import ConfigError

#: Folders shipped, in the order they are listed and copied.
FOLDERS = ("tasks", "configs", "sweeps")
#: Files shipped besides the YAML ones (found by pattern in every folder): URDFs a robot config names.
EXTRA_PATTERNS = ("*.urdf",)


def data_dir() -> Path:
    """The folder holding ``tasks/``, ``configs/``, ``sweeps/``: the wheel's ``redundik/_data``, else the checkout.

    Raises:
        ConfigError: neither exists (a broken installation).
    """
    package = Path(__file__).resolve().parent
    for candidate in (package / "_data", package.parents[1]):
        if (candidate / "tasks").is_dir() and (candidate / "configs").is_dir():
            return candidate
    raise ConfigError(f"the shipped examples are missing (no {package / '_data'}): reinstall redundik")


@dataclass(frozen=True)
class Example:
    """One shipped YAML file.

    Attributes:
        name: File name without ``.yaml`` (what ``redundik run NAME`` / ``redundik sweep NAME`` accept).
        folder: ``tasks``, ``configs`` or ``sweeps``.
        path: Where it is.
    """

    name: str
    folder: str
    path: Path

    @property
    def description(self) -> str:
        """The file's ``description:`` (first line), or ``""``; read as text, without a YAML parser."""
        try:
            text = self.path.read_text(encoding="utf-8")
        except OSError:
            return ""
        lines = text.splitlines()
        for i, line in enumerate(lines):
            if line.startswith("description:"):
                value = line.removeprefix("description:").strip()
                if value[:1] in (">", "|"):  # a block scalar: the indented lines that follow
                    block = []
                    for nxt in lines[i + 1 :]:
                        if nxt.strip() and not nxt.startswith((" ", "\t")):
                            break
                        block.append(nxt.strip())
                    value = " ".join(b for b in block if b)
                return value.strip("'\"").strip()
        return ""


def examples(folder: str | None = None) -> list[Example]:
    """Every shipped file (of ``folder`` if given), sorted by folder then name."""
    root = data_dir()
    out: list[Example] = []
    for f in FOLDERS:
        if folder is None or f == folder:
            out += [Example(p.stem, f, p) for p in sorted((root / f).glob("*.yaml"))]
    return out


def find_example(name: str, folder: str = "tasks") -> Path | None:
    """The shipped file ``folder/name.yaml``, or ``None``; ``name`` must be a bare name (no path, no suffix)."""
    if not name or "/" in name or "\\" in name or name.startswith(".") or name.endswith((".yaml", ".yml")):
        return None
    path = data_dir() / folder / f"{name}.yaml"
    return path if path.is_file() else None


def shipped_files() -> list[tuple[str, Path]]:
    """(folder, path) of every shipped file: the YAML examples, then the URDFs the configs name."""
    root = data_dir()
    files = [(ex.folder, ex.path) for ex in examples()]
    for f in FOLDERS:
        files += [(f, p) for pattern in EXTRA_PATTERNS for p in sorted((root / f).glob(pattern))]
    return files


def example_urdf(name: str) -> Path:
    """The shipped URDF ``configs/NAME.urdf``: ``arm4``, the tutorials' 4-joint arm (yaw, shoulder, elbow, wrist).

    Raises:
        ConfigError: no such file (the message lists the shipped URDFs).
    """
    root = data_dir() / "configs"
    path = root / f"{name}.urdf"
    if "/" in name or "\\" in name or name.startswith(".") or not path.is_file():
        shipped = ", ".join(p.stem for p in sorted(root.glob("*.urdf")))
        raise ConfigError(f"no shipped URDF named {name[:60]!r}; shipped: {shipped}")
    return path


def copy_examples(target: Path, overwrite: bool = False) -> list[Path]:
    """Copy ``tasks/``, ``configs/``, ``sweeps/`` into ``target`` (same layout: relative robot paths still resolve).

    Args:
        target: Destination folder (created if missing).
        overwrite: Replace files that already exist (else they are kept and not counted).

    Returns:
        The files written.

    Raises:
        ConfigError: ``target`` exists and is not a folder, or cannot be written.
    """
    if target.exists() and not target.is_dir():
        raise ConfigError(f"'{target}' exists and is not a folder")
    written: list[Path] = []
    try:
        target.mkdir(parents=True, exist_ok=True)
        root = target.resolve(strict=True)
        plan = []
        for folder, path in shipped_files():  # every destination checked before the first write
            dst = target / folder / path.name
            if dst.exists() and not overwrite:
                continue
            if dst.is_symlink() or not dst.resolve().is_relative_to(root):
                # a symlink (a dangling one included) would make copyfile write wherever it points
                raise ConfigError(
                    f"refusing to copy into '{dst}': it is a symlink or resolves outside '{target}' (to "
                    f"'{dst.resolve()}'); remove it or copy into another folder"
                )
            plan.append((path, dst))
        for src, dst in plan:
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(src, dst)
            written.append(dst)
    except OSError as exc:
        raise ConfigError(f"cannot copy the examples into '{target}': {exc.strerror or exc}") from None
    return written
