"""Hostile numbers never print numpy's warning lines ahead of the one-line error (fuzz finding, seed 2)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_huge_radius_gives_one_line_and_no_runtime_warning(tmp_path: Path) -> None:
    text = (ROOT / "configs" / "delta.yaml").read_text(encoding="utf-8")
    assert "base: {radius: 1.0}" in text
    bad = tmp_path / "delta_big.yaml"
    bad.write_text(text.replace("base: {radius: 1.0}", "base: {radius: 1e308}"), encoding="utf-8")
    proc = subprocess.run(
        [sys.executable, "-m", "redundik.cli.main", "delta", "ik", str(bad), "--top", "0", "0", "-1"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode not in (0, 1) and "Traceback" not in proc.stderr
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    assert "RuntimeWarning" not in proc.stderr + proc.stdout
