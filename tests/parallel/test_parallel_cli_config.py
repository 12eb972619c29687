"""YAML configurations and the CLI commands of redundik.parallel (in-process, via typer's CliRunner)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import typer
import yaml
from typer.testing import CliRunner

from redundik.config.parallel import load_config, parse_config
from redundik.errors import ConfigError, MechanismError
from redundik.parallel import StewartPlatform, book_66_pose

CONFIGS = Path(__file__).resolve().parents[2] / "configs"
RUNNER = CliRunner()


@pytest.fixture(scope="module")
def app() -> typer.Typer:
    from redundik.cli import parallel_cmds

    app = typer.Typer()
    parallel_cmds.register(app)
    return app


def _run(app: typer.Typer, *args: str) -> dict:
    res = RUNNER.invoke(app, [*args, "--json"])
    assert res.exit_code == 0, (res.output, res.exception)
    return json.loads(res.output)


def _fail(app: typer.Typer, *args: str) -> BaseException:
    res = RUNNER.invoke(app, list(args))
    assert res.exit_code != 0
    assert res.exception is not None
    return res.exception


# ---------------------------------------------------------------------------------------------- configs
@pytest.mark.parametrize(
    "name",
    sorted(p.name for p in CONFIGS.glob("*.yaml") if p.name.startswith(("stewart", "hybrid33", "delta", "mobility"))),
)
def test_every_parallel_config_loads_and_builds(name: str) -> None:
    load_config(CONFIGS / name).build()


def test_config_66_is_the_book_platform() -> None:
    built = load_config(CONFIGS / "stewart66.yaml").build()
    ref = StewartPlatform.symmetric_66(1.2, 0.8, np.radians(15.0), np.radians(120.0))
    np.testing.assert_allclose(built.base_points, ref.base_points)
    np.testing.assert_allclose(built.top_points, ref.top_points)
    assert built.legs == ref.legs


def _stewart66() -> dict:
    return yaml.safe_load((CONFIGS / "stewart66.yaml").read_text())


@pytest.mark.parametrize(
    ("patch", "message"),
    [
        ({"top": {"radius": -0.8}}, "top.radius: must be > 0.0, got -0.8"),
        ({"top": {"radius": 0.8, "colour": "red"}}, "top.colour: unknown key 'colour'; allowed keys: radius, side"),
        ({"legz": 1}, "legz: unknown key 'legz'; allowed keys: kind, name"),
        ({"layout": "hexagon"}, "layout: expected one of 'symmetric_33'"),
        ({"beta_deg": None}, "beta_deg: required for layout symmetric_66"),
        ({"base": {"radius": float("nan")}}, "base.radius: expected a finite number, got nan"),
        ({"kind": "robot"}, "kind: expected one of"),
        ({"beta_deg": 0.0}, "beta_deg: invalid geometry: top points 0 and 1 coincide"),
    ],
)
def test_config_errors_name_the_key_path(patch: dict, message: str) -> None:
    data = _stewart66() | patch
    with pytest.raises(ConfigError, match=message.replace("(", r"\(")) as info:
        parse_config(data).build()
    assert isinstance(info.value, ConfigError)


def test_config_file_errors(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="cannot read"):
        load_config(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("kind: [stewart\n")
    with pytest.raises(ConfigError, match="invalid YAML"):
        load_config(bad)
    bad.write_text("- 1\n- 2\n")
    with pytest.raises(ConfigError, match="expected a mapping"):
        load_config(bad)
    data = yaml.safe_load((CONFIGS / "hybrid33_rect.yaml").read_text())
    data["d5"] = -0.2
    with pytest.raises(ConfigError, match=r"^d5: must be ≥ 0.0, got -0.2"):
        parse_config(data)
    data["d5"], data["path"] = 0.2, {"n": 1}
    with pytest.raises(ConfigError, match=r"path.n: must be ≥ 2, got 1"):
        parse_config(data)


# ---------------------------------------------------------------------------------------------- CLI
def test_cli_stewart_ik_jacobian_statics_match_the_book(app: typer.Typer) -> None:
    cfg = str(CONFIGS / "stewart66.yaml")
    pose = ["--p", "0", "-0.2", "1", "--rpy", "25", "0", "50"]
    p, R = book_66_pose()
    ref = StewartPlatform.symmetric_66(1.2, 0.8, np.radians(15.0))
    out = _run(app, "stewart", "ik", cfg, *pose)
    np.testing.assert_allclose(out["lengths"], [1.0503, 1.4286, 1.5378, 1.3567, 0.8561, 1.1282], atol=0.5e-4)
    np.testing.assert_allclose(out["units"], ref.inverse_kinematics(p, R).units, atol=1e-12)
    J0 = _run(app, "stewart", "jacobian", cfg, *pose)["J0"]
    np.testing.assert_allclose(J0, ref.jacobian(p, R), atol=1e-12)
    forces = _run(app, "stewart", "statics", cfg, *pose, "--wrench", "0", "0", "-2452.5", "0", "0", "0")["forces"]
    assert sum(forces) == pytest.approx(-2878.8, abs=0.05)
    # --R with the printed 4-digit matrix is accepted (projected onto SO(3))
    printed = ["0.6428", "-0.6943", "0.3237", "0.7660", "0.5826", "-0.2717", "0", "0.4226", "0.9063"]
    out_R = _run(app, "stewart", "ik", cfg, "--p", "0", "-0.2", "1", "--R", *printed)
    np.testing.assert_allclose(out_R["lengths"], out["lengths"], atol=2e-4)


def test_cli_stewart_fk_exact_and_grid(app: typer.Typer) -> None:
    cfg = str(CONFIGS / "stewart33.yaml")
    legs = ["--legs", "1", "0.8", "1.2", "1.1", "0.9", "1"]
    grid = _run(app, "stewart", "fk", cfg, *legs, "--method", "grid")["solutions"]
    assert len(grid) == 1
    np.testing.assert_allclose(grid[0]["p"], [-0.1236, -0.0495, 0.7586], atol=0.5e-4)
    exact = _run(app, "stewart", "fk", cfg, *legs)["solutions"]
    platform = load_config(cfg).build()
    for s in exact:
        np.testing.assert_allclose(
            platform.inverse_kinematics(s["p"], s["R"]).lengths, [float(v) for v in legs[1:]], atol=1e-10
        )
    assert [s["residual"] for s in exact] == sorted(s["residual"] for s in exact) or all(
        s["residual"] < 1e-12 for s in exact
    )


def test_cli_hybrid_ik_and_path(app: typer.Typer, tmp_path: Path) -> None:
    cfg = str(CONFIGS / "hybrid33_rect.yaml")
    out = _run(
        app, "hybrid33", "ik", cfg, "--p", "0.8", "0.4", "2.2", "--R", "1", "0", "0", "0", "1", "0", "0", "0", "1"
    )
    assert set(out) >= {"lengths", "theta", "R03"} and abs(out["lag"]) < 1e-10
    fk = _run(app, "hybrid33", "fk", cfg, "--legs", *map(str, out["lengths"]), "--theta", *map(str, out["theta_deg"]))[
        "solutions"
    ]
    assert min(np.linalg.norm(np.subtract(s["p"], [0.8, 0.4, 2.2])) for s in fk) < 1e-9
    book = _run(app, "hybrid33", "ik", cfg, "--p", "0.8", "0.4", "2.2", "--method", "book")
    assert abs(book["lag"]) > 1.0
    summary = _run(app, "hybrid33", "path", cfg, "--out", str(tmp_path / "p2"))
    assert summary["roundtrip_position_max_exact"] < 1e-9 < summary["roundtrip_position_max_book"]
    written = json.loads((tmp_path / "p2" / "roundtrip.json").read_text())
    assert len(written["roundtrip_position_book"]) == 100
    assert (tmp_path / "p2" / "joint_profiles.png").stat().st_size > 1000


def test_cli_delta_and_mobility(app: typer.Typer) -> None:
    delta = _run(app, "delta", "ik", str(CONFIGS / "delta.yaml"), "--top", "0.05", "0.02", "1.0")
    assert np.shape(delta["theta"]) == (3, 2) and all(t2 < 0 for _, t2 in delta["theta"])
    mob = _run(app, "mobility", str(CONFIGS / "mobility_stewart.yaml"))
    assert (mob["m"], mob["F"]) == (6, 36)
    assert _run(app, "mobility", str(CONFIGS / "mobility_planar_hybrid.yaml"))["m"] == 3
    assert _run(app, "mobility", str(CONFIGS / "mobility_delta.yaml"))["m"] == 3


def test_cli_tables_without_json(app: typer.Typer) -> None:
    res = RUNNER.invoke(app, ["hybrid33", "ik", str(CONFIGS / "hybrid33_rect.yaml"), "--p", "0.8", "0.4", "2.2"])
    assert res.exit_code == 0 and "theta [deg]" in res.output and "R03" in res.output


def test_cli_figures(app: typer.Typer, tmp_path: Path) -> None:
    cfg = str(CONFIGS / "stewart66.yaml")
    png, gif = tmp_path / "pose.png", tmp_path / "move.gif"
    assert RUNNER.invoke(app, ["stewart", "draw", cfg, "--p", "0", "-0.2", "1", "--out", str(png)]).exit_code == 0
    res = RUNNER.invoke(
        app,
        [
            "stewart",
            "animate",
            cfg,
            "--p",
            "0",
            "-0.2",
            "1",
            "--to-p",
            "0.1",
            "0",
            "1.1",
            "--frames",
            "3",
            "--out",
            str(gif),
        ],
    )
    assert res.exit_code == 0, res.exception
    assert png.read_bytes()[:4] == b"\x89PNG" and gif.read_bytes()[:3] == b"GIF"


def test_cli_errors(app: typer.Typer) -> None:
    s33, s66 = str(CONFIGS / "stewart33.yaml"), str(CONFIGS / "stewart66.yaml")
    exc = _fail(app, "stewart", "fk", s33, "--legs", "0.1", "0.1", "0.1", "0.1", "0.1", "0.1", "--starts", "4")
    assert isinstance(exc, MechanismError) and "admit no assembly" in str(exc)
    exc = _fail(app, "stewart", "ik", s66, "--p", "0", "nan", "1")
    assert isinstance(exc, MechanismError) and "non-finite" in str(exc)
    exc = _fail(app, "stewart", "ik", s66, "--p", "0", "0", "1", "--R", "1", "0", "0", "0", "1", "0", "0", "0", "-1")
    assert isinstance(exc, MechanismError) and "not a proper rotation" in str(exc)
    exc = _fail(app, "stewart", "ik", s66, "--p", "0", "0", "1", "--rpy", "0", "0", "0", "--R", *["0"] * 9)
    assert isinstance(exc, MechanismError) and "either --rpy or --R" in str(exc)
    exc = _fail(app, "stewart", "fk", s33, "--legs", *["1"] * 6, "--method", "newton")
    assert "['exact', 'grid']" in str(exc)
    exc = _fail(app, "mobility", s66)
    assert isinstance(exc, ConfigError) and "needs 'mobility'" in str(exc)


def test_main_entry_point_reports_errors_in_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    from redundik.cli import main as main_mod

    code = main_mod.main(["mobility", str(CONFIGS / "mobility_stewart.yaml"), "--json"])
    assert code == 0
    assert json.loads(capsys.readouterr().out)["m"] == 6
    code = main_mod.main(["stewart", "ik", str(CONFIGS / "stewart66.yaml"), "--p", "0", "0", "nan"])
    assert code == 3
    assert capsys.readouterr().err.strip().startswith("error: --p: non-finite value")
