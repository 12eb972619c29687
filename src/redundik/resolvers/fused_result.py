"""The result of a fused step (:mod:`redundik.resolvers.fused`): q̇ from the compiled call, the task terms built when
first read."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from redundik.resolvers.base import LazyStepResult
from redundik.tasks.base import TaskTerm


class FusedStepResult(LazyStepResult):
    """A ``LazyStepResult`` of a fused step: ``terms`` built on first read, ``task_error`` computed in the step."""

    @classmethod
    def fused(
        cls,
        dq: np.ndarray,
        make_terms: Callable[[], list[TaskTerm]],
        task_error: float,
        info: dict[str, object],
        build_time: float,
        solve_time: float,
        main: list[int],
        pending: Callable[[], tuple[float, bool, dict[str, object]]],
        dq_rank: np.ndarray | None = None,
        dq_null: np.ndarray | None = None,
        dq_norm: float | None = None,
        fallback: str | None = None,
        cap_ratio: float = -1.0,
    ) -> FusedStepResult:
        """The result; ``make_terms()`` builds the terms when they are first read. ``dq_norm`` and ``cap_ratio``
        (max_i |q̇_i| / c_i, −1 when not computed): what the compiled call computed of q̇ for ``Resolver.step``."""
        res = cls.__new__(cls)
        res.__dict__ = {
            "dq": dq,
            "dq_rank": dq_rank,
            "dq_null": dq_null,
            "gains": None,
            "damping": 0.0,
            "fallback": fallback,
            "_info": info,
            "build_time": build_time,
            "solve_time": solve_time,
            "main": main,
            "pending": pending,
            "_make_terms": make_terms,
            "_task_error": task_error,
            "_dq_norm": dq_norm,  # ‖q̇‖ from the compiled call (the divergence watch reads it)
            "_cap_ratio": cap_ratio,  # (the joint-speed cap's test, when the compiled call made it)
        }
        return res

    @property
    def terms(self) -> list[TaskTerm]:
        d = self.__dict__
        terms = d.get("_terms")
        if terms is None:
            terms = d["_terms"] = self._build_terms()
        return terms

    @terms.setter
    def terms(self, value: list[TaskTerm]) -> None:
        self.__dict__["_terms"] = value

    def _build_terms(self) -> list[TaskTerm]:
        """The step's terms, built on their first read (``terms`` keeps them): from the ``make_terms`` callable the
        result was made with; a subclass builds them from its step's record."""
        terms: list[TaskTerm] = self.__dict__["_make_terms"]()
        return terms

    @property
    def task_error(self) -> float:
        return self.__dict__["_task_error"]
