"""PNG screenshots of a replay page with headless Chromium (for the docs gallery: ``redundik view DIR --png``)."""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

from redundik.errors import RedundikError

#: Flags that work headless without a GPU (software WebGL through SwiftShader).
CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--use-gl=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--hide-scrollbars",
)


def chromium_executable() -> str:
    """The Chromium on PATH.

    Raises:
        RedundikError: none is installed (``apt-get install chromium``).
    """
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    raise RedundikError("no Chromium found for screenshots: install it (Debian: apt-get install chromium)")


def screenshot(url: str, png: Path, size: tuple[int, int] = (900, 600), budget_ms: int = 5000) -> Path:
    """Load ``url`` headless and save a screenshot [pixels ``size``] to ``png``; returns it.

    Raises:
        RedundikError: no Chromium, or it wrote no image.
    """
    png = Path(png).resolve()
    png.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="redundik-chromium-") as profile:
        proc = subprocess.run(
            [
                chromium_executable(),
                *CHROMIUM_FLAGS,
                f"--user-data-dir={profile}",
                f"--virtual-time-budget={budget_ms}",
                f"--window-size={size[0]},{size[1]}",
                f"--screenshot={png}",
                url,
            ],
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
    if not png.is_file():
        raise RedundikError(f"Chromium wrote no screenshot of {url}: {proc.stderr.strip()[-300:]}")
    return png
