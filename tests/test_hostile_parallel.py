"""Hostile input to the parallel-mechanism commands (``stewart``, ``hybrid33``): never an inf or NaN printed,
bounded counts, a bad previous θ₆ named, a non-finite result refused."""

from __future__ import annotations

import math

import pytest

from tests.conftest import CONFIGS
from tests.hostile import Cli, _one_line_error


@pytest.mark.parametrize(
    ("value", "expected"), [("nan", "non-finite value"), ("1e308", "values must be at most 1e+06")]
)
def test_hybrid_book_ik_names_a_bad_previous_theta6(cli: Cli, value: str, expected: str) -> None:
    """``--theta6-prev nan`` was reported as "top point: contains a non-finite value"; 1e308 was accepted."""
    args = ["hybrid33", "ik", CONFIGS / "hybrid33_rect.yaml", "--p", "0", "0", "1", "--method", "book"]
    code, out, err = cli(*args, "--theta6-prev", value, "--json")
    _one_line_error(code, err)
    assert err.startswith(f"error: --theta6-prev: {expected}"), err
    assert out == ""


_FK = ["stewart", "fk", str(CONFIGS / "stewart33.yaml"), "--legs", *(["1.861", "1.5044"] * 3), "--method", "exact"]


_STATICS = ["stewart", "statics", str(CONFIGS / "stewart66.yaml"), "--p", "0", "0", "1", "--wrench"]


_ANIMATE = ["stewart", "animate", str(CONFIGS / "stewart33.yaml"), "--p", "0", "0", "1.5", "--to-p", "0", "0", "1.6"]


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["stewart", "ik", CONFIGS / "stewart33.yaml", "--p", "0", "0", "1e308", "--json"], "--p: values must be"),
        (["stewart", "ik", CONFIGS / "stewart33.yaml", "--p", "0", "0", "1", "--rpy", "0", "0", "1e308"], "--rpy"),
        ([*_STATICS, "0", "0", "1e308", "0", "0", "1e308", "--json"], "--wrench: values must be"),
        (["delta", "ik", CONFIGS / "delta.yaml", "--top", "0", "0", "1e300"], "--top: values must be"),
        (["hybrid33", "ik", CONFIGS / "hybrid33_rect.yaml", "--p", "0", "0", "1e308", "--json"], "--p"),
    ],
)
def test_parallel_commands_never_print_inf_or_nan(cli: Cli, args: list[object], expected: str) -> None:
    code, out, err = cli(*args)
    _one_line_error(code, err)
    assert expected in err and out == ""  # no "Infinity" / "NaN" in a JSON document on stdout


def test_a_non_finite_parallel_result_is_refused_not_printed() -> None:
    from redundik.cli import parallel_cmds
    from redundik.errors import MechanismError

    with pytest.raises(MechanismError, match=r"not finite at 'lengths\[1\]'"):
        parallel_cmds._emit({"lengths": [1.0, math.inf]}, True, "IK", [])


@pytest.mark.parametrize(
    "args",
    [
        [*_FK, "--starts", "-5"],
        [*_FK, "--starts", "100000000"],
        [*_ANIMATE, "--frames", "100000000", "--out", "x.gif"],
    ],
)
def test_parallel_counts_are_bounded(cli: Cli, args: list[object]) -> None:
    code, _, err = cli(*args)
    assert code == 2 and ("--starts" in err or "--frames" in err), err  # a usage error, before any work
