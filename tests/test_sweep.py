"""``redundik sweep``: the same table in-process and on a Dask LocalCluster, convergence, outputs, bad sweep files."""

from __future__ import annotations

import copy
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from redundik.errors import ConfigError
from redundik.sweep import MAX_PROBLEMS, load_sweep, run_chunk, run_sweep
from redundik.sweep.output import read_table
from tests.conftest import ROOT

PANDA = str(ROOT / "configs" / "panda.yaml")
TOL = 1e-4

SMALL: dict[str, Any] = {
    "name": "small",
    "robot": PANDA,
    "task": {"frame": "panda_hand_tcp", "axes": "position", "gain": 1.0, "posture": {"gain": 0.2}},
    "targets": {
        "grid": {"x": {"start": -0.9, "stop": 0.9, "num": 5}, "y": 0.1, "z": {"start": 0.0, "stop": 1.2, "num": 4}}
    },
    "starts": {"home": True, "random": {"count": 2, "seed": 7, "margin": 0.1}},
    "resolver": {"name": "wqp"},
    "convergence": {"dt": 1.0, "tol": TOL, "max_iterations": 40, "stall": {"window": 8, "min_decrease": 1e-5}},
    "chunk_size": 16,
}


def _small(**changes: Any) -> dict[str, Any]:
    data = copy.deepcopy(SMALL)
    data.update(changes)
    return data


def _assert_same(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> None:
    assert list(a) == list(b)
    for k in a:
        assert a[k].shape == b[k].shape, k
        assert np.array_equal(a[k], b[k]), f"column {k} differs"


@pytest.fixture(scope="module")
def in_process() -> dict[str, np.ndarray]:
    return run_sweep(load_sweep(SMALL)).columns


def test_problems_and_outputs_are_finite_and_mixed(in_process: dict[str, np.ndarray]) -> None:
    c = in_process
    assert c["problem"].tolist() == list(range(60))  # 20 targets × 3 starts, problem order
    assert c["start_index"].tolist() == [0, 1, 2] * 20
    for k, v in c.items():
        if v.dtype.kind == "f":
            assert np.isfinite(v).all(), k
    # the grid spans reachable and unreachable targets: both outcomes occur
    assert 0 < c["converged"].sum() < 60
    conv = c["converged"]
    assert (c["final_error"][conv] < TOL).all()
    assert (c["final_error"][~conv] >= TOL).all()
    assert set(c["status"][conv]) == {"converged"}
    assert (c["limit_margin"] >= -1e-9).all()  # wqp keeps the joints inside their limits


def test_same_table_on_a_local_cluster(in_process: dict[str, np.ndarray]) -> None:
    from redundik.sweep.engine import dask_client

    plan = load_sweep(SMALL)
    with dask_client(local=2, processes=True) as client:
        on_dask = run_sweep(plan, client=client)
    assert on_dask.workers == 2 and on_dask.chunks == 4
    _assert_same(in_process, on_dask.columns)


def test_chunk_size_changes_results_only_by_rounding(in_process: dict[str, np.ndarray]) -> None:
    # bit-identical needs the same chunks (the file fixes chunk_size); other chunk sizes agree to rounding
    other = run_sweep(load_sweep(_small(chunk_size=7))).columns
    for k, v in in_process.items():
        if v.dtype.kind == "f":
            assert np.allclose(v, other[k], rtol=0, atol=1e-9), k
        else:
            assert np.array_equal(v, other[k]), k


def test_reachable_converges_unreachable_is_reported_not_nan() -> None:
    data = _small(targets={"points": [[0.45, 0.1, 0.45], [2.5, 0.0, 0.5]]}, starts={"home": True})
    data["convergence"] = {"dt": 1.0, "tol": TOL, "max_iterations": 60}
    c = run_sweep(load_sweep(data)).columns
    assert c["converged"].tolist() == [True, False]
    assert c["final_error"][0] < TOL
    assert c["status"][1] == "max_iterations" and c["iterations"][1] == 60
    assert np.isfinite(c["final_error"][1]) and c["final_error"][1] > 1.0  # 2.5 m out: well over a metre short
    reached = np.array([c["reached_x"][0], c["reached_y"][0], c["reached_z"][0]])
    assert np.linalg.norm(reached - [0.45, 0.1, 0.45]) < TOL
    for k, v in c.items():
        if v.dtype.kind == "f":
            assert np.isfinite(v).all(), k


@pytest.mark.parametrize("resolver", ["pinv", "wqp"])
def test_batch_iteration_matches_the_one_by_one_loop(resolver: str) -> None:
    plan = load_sweep(_small(resolver={"name": resolver}))
    batch = run_chunk(plan, 0, 60, "batch")
    loop = run_chunk(plan, 0, 60, "loop")
    assert batch["status"].tolist() == loop["status"].tolist()
    assert np.abs(batch["iterations"] - loop["iterations"]).max() <= 1
    q_cols = [k for k in batch if k.startswith("final_q")]
    both = batch["converged"] & loop["converged"]
    assert both.any()
    diff = max(np.abs(batch[k][both] - loop[k][both]).max() for k in q_cols)
    assert diff < 1e-5


def _ik(**ik: Any) -> dict[str, Any]:
    """SMALL solved by method: solve_ik (the same targets and starts)."""
    data = _small(method="solve_ik")
    if ik:
        data["ik"] = ik
    return data


def test_solve_ik_method_converges_within_limits_with_the_same_columns(in_process: dict[str, np.ndarray]) -> None:
    c = run_sweep(load_sweep(_ik(max_restarts=5))).columns
    assert set(in_process) <= set(c) and set(c) - set(in_process) == {"restarts"}  # every column kept, one added
    assert c["problem"].tolist() == list(range(60))
    conv = c["converged"]
    # solve_ik reaches every target the differential iteration reaches, and more (restarts, no posture pull)
    assert (conv | ~in_process["converged"]).all() and conv.sum() > in_process["converged"].sum()
    assert (c["final_error"][conv] <= TOL).all()
    assert set(c["status"][conv]) == {"converged"} and set(c["status"][~conv]) <= {"max_restarts"}
    assert (c["limit_margin"] >= 0.0).all()  # every answer within the limits, converged or not
    assert (c["qp_steps"] == 0).all() and (c["restarts"][~conv] == 5).all()
    for k, v in c.items():
        if v.dtype.kind == "f":
            assert np.isfinite(v).all(), k


def test_solve_ik_method_is_the_same_table_whatever_the_chunks() -> None:
    a = run_sweep(load_sweep(_ik(max_restarts=3))).columns
    b = run_sweep(load_sweep({**_ik(max_restarts=3), "chunk_size": 7})).columns
    _assert_same(a, b)  # problem p is seeded with (seed, p): bit for bit, not only to rounding


def test_solve_ik_method_pose_targets_and_its_summary(tmp_path: Path) -> None:
    from redundik.sweep.output import summary

    data = _ik(orientation_tolerance=1e-3, max_restarts=10)
    data["task"] = {"frame": "panda_hand_tcp", "axes": "pose"}
    data["targets"] = {"points": [[0.45, 0.1, 0.45], [0.3, -0.2, 0.6]], "orientation": [3.14159, 0.0, 0.0]}
    plan = load_sweep(data)
    result = run_sweep(plan)
    c = result.columns
    assert c["converged"].all()
    assert summary(plan, result)["method"] == "solve_ik"
    assert summary(plan, result)["status"]["converged"] == c["problem"].size


@pytest.mark.parametrize(
    ("change", "where"),
    [
        ({"method": "ik"}, "method: expected one of 'differential' or 'solve_ik', got 'ik'"),
        ({"ik": {"max_restarts": 3}}, "ik: 'ik' holds the options of method: solve_ik, but method is differential"),
        ({"method": "solve_ik", "ik": {"max_restarts": -1}}, "ik.max_restarts:"),
        ({"method": "solve_ik", "ik": {"timeout": 0}}, "ik.timeout:"),
        ({"method": "solve_ik", "ik": {"max_restarts": None}}, "ik.max_restarts: give max_restarts or timeout"),
        ({"method": "solve_ik", "ik": {"seeds": 1}}, "ik.seeds: unknown key 'seeds'"),
        ({"method": "solve_ik", "ik": {"orientation_tolerance": "small"}}, "ik.orientation_tolerance:"),
        ({"method": "solve_ik", "task": {"frame": "panda_hand_tcp", "axes": "planar"}}, "task.axes: method: solve_ik"),
        ({"convergence": {"tol": 1e-4}}, "convergence.dt: required key is missing: method: differential"),
        (
            {"method": "solve_ik", "ik": {"max_restarts": 10_000}, "convergence": {"tol": TOL, "max_iterations": 200}},
            "ik.max_restarts: 60 problems × 200 iterations × 10001 attempts = 1.2e+08 steps at most",
        ),
    ],
)
def test_bad_method_keys_are_one_line_errors_with_key_paths(
    change: dict[str, Any], where: str, write_yaml: Callable[..., Path]
) -> None:
    data = _small()
    data.update(change)
    if data.get("method") == "solve_ik" and "ik" in change and "convergence" not in change:
        data["convergence"] = {"tol": TOL, "max_iterations": 40}
    f = write_yaml(data, "bad.yaml")
    with pytest.raises(ConfigError) as info:
        load_sweep(f)
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith(where), msg


def test_cli_writes_parquet_csv_and_figure(tmp_path: Path, write_yaml: Callable[..., Path]) -> None:
    from redundik.cli.main import main

    f = write_yaml(_small(chunk_size=32), "small.yaml")
    assert main(["sweep", str(f), "--out", str(tmp_path / "pq"), "--quiet"]) == 0
    assert main(["sweep", str(f), "--out", str(tmp_path / "csv"), "--format", "csv", "--no-figure", "-q"]) == 0
    pq, cs = read_table(tmp_path / "pq" / "small.parquet"), read_table(tmp_path / "csv" / "small.csv")
    assert (tmp_path / "pq" / "small_map.png").stat().st_size > 5000
    assert not (tmp_path / "csv" / "small_map.png").exists()
    assert (tmp_path / "pq" / "summary.json").is_file()
    _assert_same(pq, cs)
    assert pq["converged"].dtype == bool and pq["status"][0] in ("converged", "stalled", "max_iterations")


def test_shipped_example_validates() -> None:
    plan = load_sweep(ROOT / "sweeps" / "panda_reach.yaml")
    assert plan.n_problems >= 20_000
    assert plan.spec.resolver.name == "wqp"


@pytest.mark.parametrize(
    ("change", "where"),
    [
        ({"chunksize": 3}, "chunksize: unknown key 'chunksize'; allowed keys: name,"),
        ({"task": {"frame": "nope"}}, "task.frame: frame 'nope'"),
        ({"task": {"frame": "panda_hand_tcp", "axes": "sideways"}}, "task.axes: unknown axes 'sideways'"),
        ({"task": {"frame": "panda_hand_tcp", "gain": 5.0}}, "task.gain: gain × dt = 5 × 1 = 5 > 2"),
        ({"resolver": {"name": "hqp"}}, "resolver.name: expected one of 'pinv' or 'wqp', got 'hqp'"),
        ({"resolver": {"name": "wqp", "options": {"dampin": 1}}}, "resolver.options: resolver 'wqp'"),
        ({"convergence": {"dt": 1.0, "tol": -1}}, "convergence.tol: must be > 0"),
        ({"convergence": {"dt": 1.0, "tol": 1e-4, "max_iterations": 10**6}}, "convergence.max_iterations"),
        ({"starts": {"home": False}}, "starts: no start configuration"),
        ({"starts": {"configurations": [[0.0, 1.0]]}}, "starts.configurations[0]: expected 9 values"),
        (
            {"targets": {"random": {"count": 600_000, "seed": 0, "low": [0, 0, 0], "high": [1, 1, 1]}}},
            f"targets: 600000 targets × 3 starts = 1800000 problems; at most {MAX_PROBLEMS}",
        ),
        ({"targets": {"grid": {"x": 0.0, "y": 0.0}}}, "targets.grid.z: required key is missing"),
        ({"targets": {"points": [[0, 0, 0]], "grid": {"x": 0, "y": 0, "z": 0}}}, "targets: give exactly one of"),
        ({"name": "../evil"}, "name: '../evil' is not a safe name"),
        ({"robot": "example-robot-data:panda"}, "starts.home: the home configuration is outside the joint limits"),
        ({"starts": {"home": False, "configurations": [[0.0] * 9]}}, "starts.configurations[0]: this start config"),
        ({"q0": [0.0, 1.0]}, "q0: expected 9 values"),
    ],
)
def test_bad_sweep_files_are_one_line_errors_with_key_paths(
    change: dict[str, Any], where: str, write_yaml: Callable[..., Path]
) -> None:
    f = write_yaml(_small(**change), "bad.yaml")
    with pytest.raises(ConfigError) as info:
        load_sweep(f)
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith(where), msg


def test_bad_engine_and_yaml_errors_through_the_cli(
    write_yaml: Callable[..., Path], capsys: pytest.CaptureFixture[str]
) -> None:
    from redundik.cli.main import main

    f = write_yaml(_small(), "ok.yaml")
    assert main(["sweep", str(f), "--dask", "local:0"]) != 0
    assert "local:N" in capsys.readouterr().err
    bad = write_yaml("name: x\nname: y\n", "dup.yaml")
    assert main(["sweep", str(bad)]) != 0
    err = capsys.readouterr().err.strip()
    assert "duplicate key" in err and len(err.splitlines()) == 1


@pytest.mark.parametrize("address", ["tcp://10.0.0.5:99999", "local:2", "inproc://x", "not an address", 8786])
def test_run_sweep_checks_a_scheduler_address_before_contacting_it(address: object) -> None:
    """From Python as from the CLI: a malformed address is refused at once, saying what was expected (it used to
    wait out the 10 s connect timeout, or reach Dask with an int)."""
    import time

    from redundik.sweep.engine import SweepError

    plan = load_sweep(_small())
    t0 = time.perf_counter()
    with pytest.raises(SweepError, match="scheduler"):
        run_sweep(plan, scheduler=address)  # type: ignore[arg-type]
    assert time.perf_counter() - t0 < 5.0
