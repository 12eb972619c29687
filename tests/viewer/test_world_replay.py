"""Headless Chromium draws panda_shelf's collision world in the HTML replay: the shelf and the post, the robot's
collision capsules behind a toggle, and the closest pair named with its distance (issue 32, item 9)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import TASKS
from tests.viewer.browser import dump_dom, screenshot

SIZE = (800, 600)


@pytest.fixture(scope="module")
def shelf_page(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from redundik.cli.main import main

    out = tmp_path_factory.mktemp("shelf_html")
    args = ["run", str(TASKS / "panda_shelf.yaml"), "--html", "--no-figures", "--quiet", "--out", str(out)]
    assert main([*args, "--runs", "no_avoidance"]) == 0
    return out / "panda_shelf.html"


def _view(img: np.ndarray) -> np.ndarray:
    h, w, _ = img.shape
    return img[int(0.1 * h) : int(0.92 * h), int(0.1 * w) : int(0.9 * w)].astype(int)


def _reddish(img: np.ndarray) -> int:
    v = _view(img)
    return int(np.count_nonzero((v[..., 0] - v[..., 1] > 50) & (v[..., 0] - v[..., 2] > 50)))


def _bluish(img: np.ndarray) -> int:
    v = _view(img)
    return int(np.count_nonzero((v[..., 2] - v[..., 0] > 50) & (v[..., 2] > 150)))


def test_chromium_draws_the_obstacles_and_the_capsule_toggle(shelf_page: Path, tmp_path: Path) -> None:
    url = shelf_page.as_uri()
    world = screenshot(f"{url}?t=2.5&robot=0&paths=0", tmp_path / "world.png", SIZE)
    assert _reddish(world) > 2000, "the shelf boards and the post are not drawn"
    caps = screenshot(f"{url}?t=2.5&robot=0&paths=0&capsules=1", tmp_path / "caps.png", SIZE)
    assert _bluish(caps) > _bluish(world) + 2000, "capsules=1 does not show the collision capsules"


def test_page_names_the_closest_pair_and_its_distance(shelf_page: Path) -> None:
    dom = dump_dom(f"{shelf_page.as_uri()}#t=2.5")
    body = re.search(r"<body[^>]*>", dom)
    assert body is not None, dom[:500]
    closest = re.search(r'data-closest="([^"]*)"', body.group(0))
    assert closest is not None, body.group(0)
    assert closest.group(1).startswith("panda_link5|post -") and "mm (penetration)" in closest.group(1)
    assert 'data-capsules="hidden"' in body.group(0)
    assert re.search(r'<button id="capsules"[^>]*>capsules</button>', dom)  # the toggle is offered
