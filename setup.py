"""Build hook: ship the checkout's ``tasks/``, ``configs/`` and ``sweeps/`` in the wheel, under ``redundik/_data/``.

The files stay where they are in the checkout (``tasks/planar3r_line.yaml`` refers to ``../configs/planar3r.yaml``);
the wheel gets copies with the same relative layout, so ``redundik run planar3r_line``, ``redundik sweep
panda_reach`` and ``redundik examples copy DIR`` work from an installed package. Everything else is in
``pyproject.toml``.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent
#: Folders of the checkout shipped as package data, and the file patterns taken from each (``configs/arm4.urdf``:
#: the tutorials' arm, beside the robot config that names it).
SHIPPED = {"tasks": ("*.yaml",), "configs": ("*.yaml", "*.urdf"), "sweeps": ("*.yaml",)}


class BuildPyWithData(build_py):
    """``build_py`` that also copies the :data:`SHIPPED` files into ``redundik/_data/``."""

    def run(self) -> None:
        super().run()
        for folder, patterns in SHIPPED.items():
            source = ROOT / folder
            if not source.is_dir():  # building from an sdist that lacks them would ship no examples: refuse
                raise SystemExit(f"setup.py: {source} is missing; the wheel must ship the example {folder}")
            target = Path(self.build_lib) / "redundik" / "_data" / folder
            shutil.rmtree(target, ignore_errors=True)  # a file removed from the checkout must not linger in build/
            target.mkdir(parents=True)
            for file in sorted(f for pattern in patterns for f in source.glob(pattern)):
                shutil.copy2(file, target / file.name)


setup(cmdclass={"build_py": BuildPyWithData})
