"""An installed package's user (issue 32, item 11): the sweep files ship and resolve by name like the tasks do, and
``--view`` without meshcat is refused with the documented exit code before any work is done."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from redundik.errors import RedundikError
from tests.conftest import ROOT

EXIT_MISSING = 5
SWEEPS = ROOT / "sweeps"


def test_sweep_runs_by_name_from_any_folder(cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:  # type: ignore[no-untyped-def]
    """``redundik sweep panda_reach`` loads the shipped file; the run itself is stopped at its start (20 480 IK)."""
    import redundik.sweep

    seen = {}

    def stop(plan, **_: object) -> None:  # type: ignore[no-untyped-def]
        seen["plan"] = plan
        raise RedundikError("stopped by the test before the sweep ran")

    monkeypatch.setattr(redundik.sweep, "run_sweep", stop)
    monkeypatch.chdir(tmp_path)
    code, _, err = cli("sweep", "panda_reach", "--out", tmp_path / "o", "--quiet")
    assert "stopped by the test" in err, err
    assert code == 3 and seen["plan"].name == "panda_reach" and seen["plan"].n_problems == 160 * 128


def test_an_unknown_sweep_name_lists_the_shipped_ones(cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.chdir(tmp_path)
    code, _, err = cli("sweep", "panda_reech")
    assert code == 3 and "shipped sweep" in err and "panda_reach" in err, err


def test_examples_list_and_copy_include_the_sweeps(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    code, out, _ = cli("examples", "list", "--json")
    names = {(e["kind"], e["name"]) for e in json.loads(out)["examples"]}
    assert code == 0 and {("sweep", p.stem) for p in SWEEPS.glob("*.yaml")} <= names
    code, out, _ = cli("examples", "list")
    assert code == 0 and "redundik sweep NAME" in out and "panda_reach" in out
    code, _, err = cli("examples", "copy", tmp_path / "ex")
    assert code == 0, err
    copied = tmp_path / "ex" / "sweeps" / "panda_reach.yaml"
    assert copied.read_text(encoding="utf-8") == (SWEEPS / "panda_reach.yaml").read_text(encoding="utf-8")
    assert (tmp_path / "ex" / "configs" / "arm4.urdf").is_file()  # the tutorials' URDF, beside its config
    assert cli("validate", copied)[0] == 0  # its ../configs/panda.yaml resolves in the copy
    assert cli("validate", tmp_path / "ex" / "configs" / "arm4.yaml")[0] == 0  # urdf: arm4.urdf resolves


@pytest.fixture
def no_meshcat(monkeypatch: pytest.MonkeyPatch) -> None:
    """meshcat cannot be imported (``None`` in ``sys.modules`` makes ``import meshcat`` raise ImportError)."""
    for name in [m for m in sys.modules if m == "meshcat" or m.startswith("meshcat.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "meshcat", None)


@pytest.mark.usefixtures("no_meshcat")
def test_run_view_without_meshcat_exits_5_before_running(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "out"
    code, _, err = cli("run", "planar3r_line", "--view", "--no-figures", "--out", out, "--runs", "rank_null")
    assert code == EXIT_MISSING, err
    assert "redundik[viewer]" in err and "--view" in err
    assert not out.exists()  # nothing was simulated nor written


@pytest.mark.usefixtures("no_meshcat")
def test_view_live_without_meshcat_exits_5(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    code, _, err = cli("view", tmp_path)
    assert code == EXIT_MISSING and "redundik[viewer]" in err, err
    # the offline replay needs no meshcat: it goes on to read the folder (and says what is missing there)
    code, _, err = cli("view", tmp_path, "--html", tmp_path / "r.html")
    assert code == 3 and "redundik[viewer]" not in err, err


def test_example_urdf_finds_the_shipped_arm_and_names_the_others() -> None:
    from redundik.errors import ConfigError
    from redundik.shipped import example_urdf

    assert example_urdf("arm4").read_text(encoding="utf-8").count("<joint ") == 5
    with pytest.raises(ConfigError, match="shipped: arm4"):
        example_urdf("../tasks/planar3r_line")
