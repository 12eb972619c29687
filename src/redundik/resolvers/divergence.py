"""A divergence watch on the control loop: geometric growth of ‖q̇‖ or of the task error is flagged, never silent.

A first-order loop e ← (1 − K dt) e is stable for K·dt < 2 (``Resolver.step`` refuses more), but a loop can still
diverge for reasons no single step sees — the plant integrated with a longer step than the ``dt`` the resolver was
given, a reference that runs away, a wrong sign in a custom task. The watch flags a step when either

* the main-task error has grown by at least :data:`ERROR_GROWTH` per step for :data:`ERROR_STREAK` steps in a row
  (×8.9) while ‖q̇‖ grew too (×2 at least over the streak) — the signature of e ← (1 − K dt) e with |1 − K dt| > 1
  (a reference moving away from rest grows the error as t or t², by (1 + 1/n)^k per step, under 1.2 after 12
  steps for k ≤ 2); or
* ‖q̇‖ has grown by at least :data:`GROWTH` per step for :data:`STREAK` steps in a row (×17).

A flagged step carries ``StepResult.info["diverging"]`` (the growth factor of the streak) and a
:class:`DivergenceWarning` is issued once per streak.
"""

from __future__ import annotations

import math
import warnings

#: Smallest per-step growth of ‖q̇‖ counted towards a q̇ streak.
GROWTH = 1.1
#: Consecutive growing steps of ‖q̇‖ that make a divergence.
STREAK = 30
#: Smallest per-step growth of the task error counted towards an error streak.
ERROR_GROWTH = 1.2
#: Consecutive growing steps of the task error (with ‖q̇‖ growing too) that make a divergence.
ERROR_STREAK = 12
#: Values below which nothing is counted (a loop at rest) [rad/s or m/s; unit of the error].
FLOOR = 1e-9


class DivergenceWarning(RuntimeWarning):
    """‖q̇‖ or the task error grows geometrically over consecutive control steps: the loop diverges."""


class _Streak:
    """A run of consecutive steps where a value grew by at least ``growth`` (advanced by the watch's update)."""

    def __init__(self, growth: float) -> None:
        self.growth, self.last, self.count, self.start = growth, math.nan, 0, math.nan


class DivergenceWatch:
    """Counts consecutive growing steps of ‖q̇‖ and of the task error; see the module docstring."""

    def __init__(self) -> None:
        self.dq = _Streak(GROWTH)
        self.error = _Streak(ERROR_GROWTH)
        self.dq_at_error_start = math.nan
        self.warned = False

    def update(self, norm: float, error: float = 0.0) -> float | None:
        """Feed ‖q̇‖ and the task error of a step; returns the growth factor of a streak that is a divergence.

        A value extends its streak when it and the previous one are ≥ ``FLOOR`` (1e-9) and it grew by the streak's
        factor; otherwise the streak restarts (written out once here: this runs on every control tick)."""
        err, dqs = self.error, self.dq
        if not (error >= err.growth * err.last or norm >= dqs.growth * dqs.last or self.warned):
            # the common tick, decided in one test: neither value grew by its streak's factor (or one is NaN), so
            # both streaks restart, as the branches below would conclude
            err.count = dqs.count = 0
            err.last, dqs.last = error, norm
            return None
        before, last = err.count, err.last
        if error >= FLOOR and last >= FLOOR and error >= err.growth * last:
            if before == 0:
                err.start = last
            err.count = before + 1
        else:
            err.count = 0
        err.last = error
        if err.count and not before:
            self.dq_at_error_start = dqs.last
        last = dqs.last
        if norm >= FLOOR and last >= FLOOR and norm >= dqs.growth * last:
            if dqs.count == 0:
                dqs.start = last
            dqs.count += 1
        else:
            dqs.count = 0
        dqs.last = norm
        if err.count >= ERROR_STREAK and norm >= 2.0 * self.dq_at_error_start:
            return error / err.start
        if dqs.count >= STREAK:
            return norm / dqs.start
        if self.warned and not (err.count or dqs.count):
            self.warned = False
        return None

    def flag(self, who: str, norm: float, factor: float, info: dict[str, object]) -> None:
        """Record a divergence in ``info`` and warn (once per streak)."""
        info["diverging"] = factor
        if not self.warned:
            self.warned = True
            warnings.warn(
                f"{who}: the control loop diverges (growth ×{factor:.3g} over consecutive steps, |q̇| now "
                f"{norm:.3g}): is the plant integrated with the dt given to step()? K·dt must be < 2",
                DivergenceWarning,
                stacklevel=3,
            )
