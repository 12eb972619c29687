"""Package hygiene: public names exist, the math never imports matplotlib, the console script runs."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import redundik.parallel as parallel

CONFIGS = Path(__file__).resolve().parents[2] / "configs"


def test_every_public_name_is_defined() -> None:
    missing = [name for name in parallel.__all__ if not hasattr(parallel, name)]
    assert not missing


def test_math_does_not_import_matplotlib() -> None:
    code = (
        "import sys, redundik.parallel, redundik.config.parallel, redundik.cli.parallel_cmds; "
        "print('matplotlib' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


def test_console_script() -> None:
    exe = Path(sys.executable).with_name("redundik")
    res = subprocess.run(
        [str(exe), "mobility", str(CONFIGS / "mobility_stewart.yaml"), "--json"], capture_output=True, text=True
    )
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout)["F"] == 36
    res = subprocess.run(
        [
            str(exe),
            "stewart",
            "fk",
            str(CONFIGS / "stewart33.yaml"),
            "--legs",
            "0.1",
            "0.1",
            "0.1",
            "0.1",
            "0.1",
            "0.1",
            "--method",
            "grid",
        ],
        capture_output=True,
        text=True,
    )
    assert res.returncode == 3
    assert res.stderr.strip().startswith("error: legs 1 and 2") and len(res.stderr.strip().splitlines()) == 1
