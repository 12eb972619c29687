"""The divergence watch's one-test fast path decides every tick as its full rules do (a slow reference here)."""

from __future__ import annotations

import math

import numpy as np

from redundik.resolvers.divergence import ERROR_GROWTH, ERROR_STREAK, FLOOR, GROWTH, STREAK, DivergenceWatch


class _Reference:
    """The watch's rules written out without the fast path (the module docstring)."""

    def __init__(self) -> None:
        self.e_last, self.e_count, self.e_start = math.nan, 0, math.nan
        self.d_last, self.d_count, self.d_start = math.nan, 0, math.nan
        self.dq_at_error_start = math.nan
        self.warned = False

    def update(self, norm: float, error: float) -> float | None:
        before = self.e_count
        if error >= FLOOR and self.e_last >= FLOOR and error >= ERROR_GROWTH * self.e_last:
            if before == 0:
                self.e_start = self.e_last
            self.e_count = before + 1
        else:
            self.e_count = 0
        self.e_last = error
        if self.e_count and not before:
            self.dq_at_error_start = self.d_last
        if norm >= FLOOR and self.d_last >= FLOOR and norm >= GROWTH * self.d_last:
            if self.d_count == 0:
                self.d_start = self.d_last
            self.d_count += 1
        else:
            self.d_count = 0
        self.d_last = norm
        if self.e_count >= ERROR_STREAK and norm >= 2.0 * self.dq_at_error_start:
            return error / self.e_start
        if self.d_count >= STREAK:
            return norm / self.d_start
        if self.warned and not (self.e_count or self.d_count):
            self.warned = False
        return None


def test_fast_path_matches_the_full_rules() -> None:
    """Random walks, geometric growth in runs (long enough to flag), values at and below the floor, NaN, inf and 0:
    the same answer and the same streak state on every tick, with the warning state set as ``flag`` sets it."""
    rng = np.random.default_rng(2)
    total = 0
    for _ in range(60):
        watch, ref = DivergenceWatch(), _Reference()
        norm, error = 1.0, 1.0
        flagged = 0
        run = 0
        for _ in range(400):
            if run == 0 and rng.random() < 0.05:
                run = int(rng.integers(5, 45))  # a growth run, long enough to flag when it lasts
            kind = 0 if run else rng.integers(1, 10)
            run = max(run - 1, 0)
            if kind < 4:  # growth: both values grow by more than the streak factors
                norm *= 1.25
                error *= 1.3
            elif kind < 7:
                norm *= float(rng.uniform(0.5, 1.5))
                error *= float(rng.uniform(0.5, 1.5))
            elif kind == 7:
                norm, error = float(rng.choice([0.0, FLOOR / 2, FLOOR, math.nan, math.inf])), 1e-12
            else:
                norm, error = float(rng.uniform(0, 2)), float(rng.uniform(0, 2))
            got, want = watch.update(norm, error), ref.update(norm, error)
            assert (got is None) == (want is None) and (got is None or got == want or (got != got and want != want))
            if got is not None:  # the resolver's flag: warned until both streaks end
                watch.warned = ref.warned = True
                flagged += 1
            assert (watch.error.count, watch.dq.count, watch.warned) == (ref.e_count, ref.d_count, ref.warned)
            assert np.array_equal([watch.error.last, watch.dq.last], [ref.e_last, ref.d_last], equal_nan=True)
        total += flagged
    assert total > 0  # the walks do reach the flagged state
