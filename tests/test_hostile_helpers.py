"""Every public function of ``redundik`` on hostile arguments (NaN, inf, strings, wrong shapes, empty arrays): a
RedundikError subclass naming what was wrong, never a numba TypingError, a bare TypeError or a NaN output."""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np
import pytest

import redundik as rk

HOSTILE: list[Any] = [
    math.nan,
    math.inf,
    -math.inf,
    "a",
    None,
    True,
    [1.0, 2.0],
    np.array([]),
    np.zeros((0, 3)),
    np.array([1.0, 2.0, 3.0]),
    np.full((2, 3), np.nan),
    np.full((2, 3), np.inf),
    np.array([["a", "b"]]),
    np.zeros((2, 3), dtype=complex),
    np.zeros((2, 2, 2)),
    {"x": 1},
    object(),
]


def _no_nan(value: object) -> None:
    arrays = [value] if isinstance(value, np.ndarray) else []
    for attr in ("pinv", "null_projector"):
        if hasattr(value, attr):
            arrays.append(getattr(value, attr))
    for arr in arrays:
        assert np.isfinite(np.asarray(arr, dtype=float)).all(), value


@pytest.mark.parametrize("bad", HOSTILE, ids=repr)
def test_pseudo_inverse_refuses_hostile_matrices(bad: Any) -> None:
    try:
        out = rk.pseudo_inverse(bad)
    except rk.RedundikError:
        return
    _no_nan(out)


@pytest.mark.parametrize("key", ["epsilon", "max_damping", "rcond"])
@pytest.mark.parametrize("bad", [math.nan, math.inf, -1.0, "a", None, [1.0]], ids=repr)
def test_pseudo_inverse_refuses_hostile_options(key: str, bad: Any) -> None:
    with pytest.raises(rk.ResolverError, match=key):
        rk.pseudo_inverse(np.eye(2), **{key: bad})


def test_pseudo_inverse_solve_and_project_refuse_wrong_shapes() -> None:
    pi = rk.pseudo_inverse(np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))
    np.testing.assert_allclose(pi.solve(np.array([1.0, 2.0])), [1.0, 2.0, 0.0], atol=1e-12)
    for bad in (np.zeros(3), np.array([np.nan, 0.0]), "ab", np.zeros((2, 2))):
        with pytest.raises(rk.ResolverError, match="rhs"):
            pi.solve(bad)
    for bad in (np.zeros(2), np.array([np.inf, 0.0, 0.0]), None):
        with pytest.raises(rk.ResolverError, match="z"):
            pi.null_project(bad)


@pytest.mark.parametrize("position", range(4))
@pytest.mark.parametrize("bad", [math.nan, math.inf, "a", None, True, [1.0], np.array([1.0, 2.0])], ids=repr)
def test_dh_matrix_refuses_hostile_parameters(position: int, bad: Any) -> None:
    args: list[Any] = [0.1, 0.2, 0.3, 0.4]
    args[position] = bad
    with pytest.raises(rk.ModelError, match=("theta", "d", "a", "alpha")[position]):
        rk.dh_matrix(*args)


def test_dh_matrix_still_takes_numpy_scalars_and_ints() -> None:
    M = rk.dh_matrix(np.float64(0.5), 1, np.int64(2), 0.0)
    assert M.shape == (4, 4) and np.isfinite(M).all()


_CALLS = {
    "from_dh": lambda b: rk.from_dh(b),
    "from_dh_base": lambda b: rk.from_dh([rk.DHRow("1", a=1.0)], base=b),
    "from_urdf": lambda b: rk.from_urdf(b),
    "load_example_robot": lambda b: rk.load_example_robot(b),
    "make_resolver": lambda b: rk.make_resolver(b),
    "DHRow": lambda b: rk.from_dh([rk.DHRow("1", a=b)]),
}


_PAIRS = [(n, b) for n, b in itertools.product(_CALLS, HOSTILE) if not (n == "from_dh_base" and b is None)]


@pytest.mark.parametrize(("name", "bad"), _PAIRS, ids=repr)
def test_public_builders_refuse_hostile_arguments_with_redundik_errors(name: str, bad: Any) -> None:
    with pytest.raises(rk.RedundikError):
        _CALLS[name](bad)
