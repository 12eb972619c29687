"""Headless Chromium for the viewer tests: screenshots and the DOM after load, and pixel comparisons.

The tests skip only when no Chromium is installed; with ``REDUNDIK_REQUIRE_BROWSER=1`` (set by ``.ci/run``, which
also installs Debian's ``chromium``) a missing browser is a failure instead.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

from redundik.viewer.snapshot import CHROMIUM_FLAGS

FLAGS = list(CHROMIUM_FLAGS)  # the flags the product uses for its own screenshots (one list)


def chromium() -> str:
    """The Chromium executable; skips the test if there is none (fails instead under REDUNDIK_REQUIRE_BROWSER=1)."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    if os.environ.get("REDUNDIK_REQUIRE_BROWSER") == "1":
        pytest.fail("Chromium is required (REDUNDIK_REQUIRE_BROWSER=1) but not installed: apt-get install chromium")
    pytest.skip("Chromium is not installed (apt-get install chromium)")


def _run(args: list[str], timeout: float) -> subprocess.CompletedProcess[str]:
    with tempfile.TemporaryDirectory(prefix="redundik-chromium-") as profile:
        return subprocess.run(
            [chromium(), *FLAGS, f"--user-data-dir={profile}", *args],
            capture_output=True,
            text=True,
            timeout=timeout,
            check=False,
        )


def screenshot(url: str, path: Path, size: tuple[int, int] = (800, 600), budget_ms: int | None = 5000) -> np.ndarray:
    """Load ``url``, save a PNG screenshot at ``path`` and return it as an (H, W, 3) uint8 array."""
    from PIL import Image

    extra = [f"--virtual-time-budget={budget_ms}"] if budget_ms else []
    proc = _run([*extra, f"--screenshot={path}", f"--window-size={size[0]},{size[1]}", url], timeout=60)
    assert path.is_file(), f"no screenshot of {url}: {proc.stderr[-2000:]}"
    return np.asarray(Image.open(path).convert("RGB"))


def dump_dom(url: str, budget_ms: int = 5000) -> str:
    """The serialised DOM of ``url`` after its scripts ran."""
    proc = _run([f"--virtual-time-budget={budget_ms}", "--dump-dom", url], timeout=60)
    return proc.stdout


def changed(a: np.ndarray, b: np.ndarray, threshold: int = 40) -> np.ndarray:
    """Pixels whose colour differs by more than ``threshold`` (sum over channels) between two images, (H, W) bool."""
    return np.abs(a.astype(int) - b.astype(int)).sum(axis=2) > threshold


def non_background(img: np.ndarray, threshold: int = 60) -> np.ndarray:
    """Pixels far from the image's most common colour (the background), (H, W) bool."""
    flat = img.reshape(-1, 3)
    colours, counts = np.unique(flat, axis=0, return_counts=True)
    bg = colours[np.argmax(counts)].astype(int)
    return np.abs(img.astype(int) - bg).sum(axis=2) > threshold
