"""The offline HTML replay: ``redundik run tasks/panda_circle.yaml --html`` writes one self-contained page, and
headless Chromium shows the Panda in it, moving between two instants."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import TASKS
from tests.viewer.browser import changed, dump_dom, non_background, screenshot

SIZE = (800, 600)


@pytest.fixture(scope="module")
def replay(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The HTML written by ``redundik run tasks/panda_circle.yaml --html --no-figures``."""
    from redundik.cli.main import main

    out = tmp_path_factory.mktemp("panda_html")
    assert main(["run", str(TASKS / "panda_circle.yaml"), "--html", "--no-figures", "--quiet", "--out", str(out)]) == 0
    pages = list(out.glob("*.html"))
    assert [p.name for p in pages] == ["panda_circle.html"]
    return pages[0]


def _doc(page: Path) -> dict:
    text = page.read_text(encoding="utf-8")
    m = re.search(r'<script id="replay-data" type="application/json">(.*?)</script>', text, re.S)
    assert m is not None
    return json.loads(m.group(1))


def test_page_is_self_contained_and_holds_every_run(replay: Path) -> None:
    text = replay.read_text(encoding="utf-8")
    assert not re.search(r"<script[^>]*\ssrc=|<link\b|<img\b|\bimport\s*\(|fetch\(|XMLHttpRequest", text)
    assert replay.stat().st_size < 2_000_000
    doc = _doc(replay)
    assert [r["name"] for r in doc["runs"]] == ["pinv", "wqp", "hqp"]
    assert len(doc["parts"]) >= 10  # the Panda's visual meshes (links 0-7, hand, two fingers)
    run = doc["runs"][0]
    assert run["t"][0] == 0.0 and run["t"][-1] == pytest.approx(4.0)
    assert [p["name"] for p in run["paths"]] == ["tcp"]


def test_desired_path_is_the_5cm_circle(replay: Path) -> None:
    import base64

    run = _doc(replay)["runs"][1]
    desired = np.frombuffer(base64.b64decode(run["paths"][0]["desired"]), dtype="<f4").reshape(-1, 3)
    actual = np.frombuffer(base64.b64decode(run["paths"][0]["actual"]), dtype="<f4").reshape(-1, 3)
    assert np.ptp(desired[:, 0]) < 1e-6  # the circle lies in the y-z plane
    assert np.ptp(desired[:, 1]) == pytest.approx(0.10, abs=2e-3)
    assert np.ptp(desired[:, 2]) == pytest.approx(0.10, abs=2e-3)
    assert np.max(np.linalg.norm(desired - actual, axis=1)) < 2e-3


def test_chromium_draws_the_panda_and_playback_moves_it(replay: Path, tmp_path: Path) -> None:
    url = replay.as_uri()
    at0 = screenshot(f"{url}?t=0", tmp_path / "t0.png", SIZE)
    at1 = screenshot(f"{url}?t=1.0", tmp_path / "t1.png", SIZE)
    empty = screenshot(f"{url}?t=0&robot=0", tmp_path / "empty.png", SIZE)
    h, w, _ = at0.shape
    view = (slice(int(0.1 * h), int(0.92 * h)), slice(int(0.15 * w), int(0.85 * w)))  # below the bar, above legend
    robot = changed(at0, empty)[view]
    assert robot.mean() > 0.04, f"robot covers only {robot.mean():.1%} of the view"
    assert non_background(at0)[view][robot].mean() > 0.9  # drawn pixels, not background-coloured ones
    moved = changed(at0, at1)[view]
    assert moved.sum() > 300, f"only {moved.sum()} pixels changed between t = 0 and t = 1 s"
    assert moved.sum() < robot.sum()  # the arm moves a little (a 5 cm circle), it does not vanish


def test_page_reads_run_and_time_from_the_hash(replay: Path) -> None:
    dom = dump_dom(f"{replay.as_uri()}#run=hqp&t=2.0")
    body = re.search(r"<body[^>]*>", dom)
    assert body is not None, dom[:500]
    assert 'data-status="drawn"' in body.group(0)
    assert 'data-run="hqp"' in body.group(0)
    frame = int(re.search(r'data-frame="(\d+)"', body.group(0)).group(1))  # type: ignore[union-attr]
    assert frame == 100  # 200 drawn samples over 4 s: t = 2 s is sample 100
