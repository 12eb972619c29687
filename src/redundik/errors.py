"""One exception root for redundik; every error a user can cause derives from it."""

from __future__ import annotations


class RedundikError(Exception):
    """Root of every error redundik raises on purpose."""


class ModelError(RedundikError):
    """A robot model could not be built or queried (bad D-H table, unknown frame or joint, bad URDF)."""


class TaskError(RedundikError):
    """A task or subtask is ill-defined (wrong dimension, unknown frame, bad parameter)."""


class ResolverError(RedundikError):
    """A resolver cannot handle the task stack it was given (e.g. more subtasks than null-space dimension)."""


class SolverError(ResolverError):
    """A QP backend failed or is not installed; carries the problem for inspection when available."""

    def __init__(self, message: str, problem: object | None = None) -> None:
        super().__init__(message)
        self.problem = problem


class NonFiniteRows(ResolverError):
    """A subtask's rows hold NaN or infinite values at a step (its barrier or potential could not be evaluated
    there): the resolver does not solve without them, it stops (q̇ = 0, clipped to the limits by a QP resolver) and
    its result's ``fallback`` names the subtask; raised inside a step, never out of ``Resolver.step``."""

    def __init__(self, subtask: str) -> None:
        super().__init__(f"non-finite rows from subtask '{subtask}'")
        self.subtask = subtask


class ConfigError(RedundikError):
    """A configuration file is invalid; the message names the YAML key path and what was expected."""

    def __init__(self, message: str, path: str | None = None) -> None:
        super().__init__(f"{path}: {message}" if path else message)
        self.path = path


class MechanismError(RedundikError):
    """A parallel mechanism has bad geometry or cannot be assembled for the given inputs."""


class MissingDependencyError(RedundikError, ImportError):
    """An optional dependency is not installed; the message names the extra that provides it (``pip install ...``)."""


class SimulationError(RedundikError):
    """A run could not be continued: a non-finite joint velocity or configuration (overflow, a huge gain)."""


def short_repr(value: object, limit: int = 60) -> str:
    """A bounded ``repr`` for error messages: never formats more than a few levels / items of ``value``.

    ``repr()`` of a parsed alias bomb or of a deeply nested list would take unbounded time and memory; this one
    looks at no more than ~6 items per level and 3 levels, then truncates to ``limit`` characters.
    """
    import reprlib

    r = reprlib.Repr()
    r.maxlevel, r.maxlist, r.maxtuple, r.maxdict, r.maxset = 3, 6, 6, 6, 6
    r.maxstring, r.maxother, r.maxlong = limit, limit, 40
    try:
        text = r.repr(value)
    except Exception:  # a hostile __repr__: say what it is, not what it contains
        text = f"<{type(value).__name__}>"
    text = text.replace("\n", " ")
    return text if len(text) <= limit else text[: limit - 3] + "..."
