"""Sweep files → a :class:`SweepPlan`: the robot, the task template, every problem's target and start.

The problems are targets × starts, numbered p = i_target · n_starts + i_start; they are generated once from the
file (grids in order, random samples from their seeds with NumPy's PCG64), so problem p is the same problem whatever
the chunking or the engine. The whole file is checked before anything runs (shape by pydantic, then the frame,
configurations, resolver options, gains and the method's keys against the robot, then the number of problems ≤
:data:`~redundik.sweep.schema.MAX_PROBLEMS`); every problem is a one-line :class:`~redundik.errors.ConfigError`
with the YAML key path.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from redundik.config.anyfile import detect_kind
from redundik.config.builders import check_axes
from redundik.config.options import check_resolver_options
from redundik.config.robot import LoadedRobot, angle_scale, configuration_from_file, load_robot, rpy_matrix
from redundik.config.yamlio import join_path, read_yaml, validate
from redundik.errors import ConfigError, RedundikError
from redundik.resolvers import make_resolver
from redundik.resolvers.batch import BatchResolver
from redundik.sweep.schema import MAX_PROBLEMS, MAX_WORK, GridSpec, IKSpec, RangeSpec, SweepFileSpec


@dataclass
class SweepPlan:
    """A validated sweep file, ready to run (see the module docstring).

    Attributes:
        spec: The validated file.
        robot: The robot and what its config added.
        axes: Frame-task rows.
        home: The robot's home configuration [rad, length unit].
        posture_target: q_ref of the null-space posture [rad, length unit].
        target_positions: Target positions of the frame, shape (n_targets, 3) [m].
        target_rotation: Target orientation of the frame (one for all targets), shape (3, 3).
        starts: Start configurations, shape (n_starts, nq) [rad, length unit].
        payload: What a remote worker needs to rebuild this plan (the file's data and its folder).
    """

    spec: SweepFileSpec
    robot: LoadedRobot
    axes: tuple[str, ...]
    home: np.ndarray
    posture_target: np.ndarray
    target_positions: np.ndarray
    target_rotation: np.ndarray
    starts: np.ndarray
    payload: dict[str, Any]

    @property
    def ik_options(self) -> IKSpec:
        """The options of ``method: solve_ik`` (the file's ``ik``, or the defaults)."""
        return self.spec.ik if self.spec.ik is not None else IKSpec()

    @property
    def name(self) -> str:
        """The sweep's name (also its output files' stem)."""
        return self.spec.name

    @property
    def n_targets(self) -> int:
        """Number of targets."""
        return int(self.target_positions.shape[0])

    @property
    def n_starts(self) -> int:
        """Number of start configurations per target."""
        return int(self.starts.shape[0])

    @property
    def n_problems(self) -> int:
        """Number of problems, targets × starts."""
        return self.n_targets * self.n_starts

    @property
    def key(self) -> str:
        """A digest of :attr:`payload` (workers cache plans by it)."""
        text = json.dumps(self.payload, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def batch_resolver(self) -> BatchResolver:
        """A fresh :class:`~redundik.resolvers.batch.BatchResolver` of the task template (one per chunk)."""
        r = self.spec.resolver
        t = self.spec.task
        return BatchResolver(
            make_resolver(r.name, **r.options),
            self.robot.model,
            t.frame,
            axes=self.axes,
            gain=t.gain,
            posture_gain=t.posture.gain,
            posture_target=self.posture_target,
        )

    def problems(self, start: int, stop: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Problems ``start`` … ``stop − 1``: (target index (n,), start index (n,), q (n, nq), targets (n, 4, 4))."""
        p = np.arange(start, stop, dtype=np.int64)
        ti, si = p // self.n_starts, p % self.n_starts
        T = np.zeros((p.size, 4, 4))
        T[:, :3, :3] = self.target_rotation
        T[:, :3, 3] = self.target_positions[ti]
        T[:, 3, 3] = 1.0
        return ti, si, self.starts[si].copy(), T


def _axis_values(axis: float | RangeSpec) -> np.ndarray:
    if isinstance(axis, RangeSpec):
        return np.linspace(axis.start, axis.stop, axis.num)
    return np.array([float(axis)])


def _grid_size(grid: GridSpec) -> int:
    n = 1
    for axis in (grid.x, grid.y, grid.z):
        n *= axis.num if isinstance(axis, RangeSpec) else 1
    return n


def _count(spec: SweepFileSpec) -> tuple[int, int]:
    """(n_targets, n_starts) from the file alone, before anything is allocated."""
    t = spec.targets
    if t.grid is not None:
        n_t = _grid_size(t.grid)
    elif t.random is not None:
        n_t = t.random.count
    else:
        assert t.points is not None
        n_t = len(t.points)
    s = spec.starts
    n_s = int(s.home) + len(s.configurations) + (s.random.count if s.random is not None else 0)
    return n_t, n_s


def _targets(spec: SweepFileSpec) -> np.ndarray:
    t = spec.targets
    if t.grid is not None:
        axes = [_axis_values(a) for a in (t.grid.x, t.grid.y, t.grid.z)]
        mesh = np.meshgrid(*axes, indexing="ij")
        return np.stack([m.reshape(-1) for m in mesh], axis=1)
    if t.random is not None:
        rng = np.random.default_rng(t.random.seed)
        return rng.uniform(np.array(t.random.low), np.array(t.random.high), size=(t.random.count, 3))
    assert t.points is not None
    return np.array(t.points, dtype=float).reshape(-1, 3)


def _check_within_limits(model: Any, q: np.ndarray, where: str, what: str, hint: str) -> None:
    """Refuse a configuration outside the joint limits (the iteration would start, or be pulled, outside them)."""
    bad = np.flatnonzero(model.limit_violation(q, tol=1e-9) > 0)
    if bad.size:
        j = model.joints[int(bad[0])]
        raise ConfigError(
            f"{what} is outside the joint limits ({j.name} = {q[j.idx_q]:.4g} not in [{j.lower:.4g}, {j.upper:.4g}]); "
            + hint,
            where,
        )


#: What to do about a home configuration outside the limits.
_HOME_HINT = "give 'q0' (or a robot config with q0, e.g. configs/panda.yaml) or list start configurations"


def _starts(spec: SweepFileSpec, robot: LoadedRobot, home: np.ndarray) -> np.ndarray:
    model = robot.model
    out: list[np.ndarray] = []
    s = spec.starts
    if s.home:
        out.append(home[None, :])
    for i, values in enumerate(s.configurations):
        where = join_path("starts.configurations", i)
        q = configuration_from_file(values, model, spec.angle_unit, where)
        _check_within_limits(model, q, where, "this start configuration", "give one within the limits")
        out.append(q[None, :])
    if s.random is not None:
        if model.nq != model.nv:
            raise ConfigError(
                f"random starts need a robot whose configuration is a vector space (nq = nv); this one has "
                f"nq = {model.nq}, nv = {model.nv}: list the configurations instead",
                "starts.random",
            )
        lo = np.array(model.model.lowerPositionLimit, dtype=float)
        hi = np.array(model.model.upperPositionLimit, dtype=float)
        lo = np.where(np.isfinite(lo) & (lo > -1e10), lo, -np.pi)
        hi = np.where(np.isfinite(hi) & (hi < 1e10), hi, np.pi)
        m = s.random.margin * (hi - lo)
        rng = np.random.default_rng(s.random.seed)
        out.append(rng.uniform(lo + m, hi - m, size=(s.random.count, model.nq)))
    return np.concatenate(out, axis=0)


def _read(source: str | Path | dict[str, Any], base_dir: Path | None) -> tuple[dict[str, Any], Path]:
    """The file's data and the folder its relative paths are resolved from; a task or robot file is refused."""
    if isinstance(source, dict):
        return source, (base_dir or Path.cwd()).resolve()
    path = Path(source)
    data = read_yaml(path, "sweep file")
    base = (base_dir or path.resolve().parent).resolve()
    if "runs" in data:
        raise ConfigError(f"{path.name} is a task file, not a sweep file: run it with `redundik run {path}`")
    kind = detect_kind(data)
    if kind in ("robot", "mechanism"):
        what = {"robot": "a sweep file names it under 'robot:'", "mechanism": "sweeps are of serial robots"}[kind]
        raise ConfigError(
            f"{path.name} is a {kind} config, not a sweep file: {what} (`redundik validate` checks any file)"
        )
    return data, base


def _check_size(spec: SweepFileSpec) -> None:
    """At least one start, at most :data:`MAX_PROBLEMS` problems and :data:`MAX_WORK` problem-steps."""
    n_t, n_s = _count(spec)
    if n_s == 0:
        raise ConfigError("no start configuration: set 'home: true', list 'configurations' or draw 'random'", "starts")
    if n_t * n_s > MAX_PROBLEMS:
        raise ConfigError(
            f"{n_t} targets × {n_s} starts = {n_t * n_s} problems; at most {MAX_PROBLEMS} are allowed "
            "(split the sweep into several files)",
            "targets",
        )
    conv, ik = spec.convergence, spec.ik
    attempts = 1 if spec.method == "differential" or ik is None or ik.max_restarts is None else 1 + ik.max_restarts
    work = n_t * n_s * conv.max_iterations * attempts
    if work > MAX_WORK:
        per = f"{conv.max_iterations} iterations" + (f" × {attempts} attempts" if attempts > 1 else "")
        raise ConfigError(
            f"{n_t * n_s} problems × {per} = {work:.3g} steps at most; a sweep may take at most {MAX_WORK:.0e} "
            "problem-steps (hours of work otherwise): lower max_iterations or split the sweep into several files",
            "convergence.max_iterations" if attempts == 1 else "ik.max_restarts",
        )


def _check_method(spec: SweepFileSpec, axes: tuple[str, ...]) -> None:
    """The method's own keys: ``dt`` for ``differential``; position or pose axes, and a bound on each problem's
    work, for ``solve_ik``; no ``ik`` block for ``differential``."""
    if spec.method == "differential":
        if spec.ik is not None:
            raise ConfigError(
                "'ik' holds the options of method: solve_ik, but method is differential (the default); set "
                "method: solve_ik, or leave 'ik' out",
                "ik",
            )
        if spec.convergence.dt is None:
            raise ConfigError(
                "required key is missing: method: differential iterates q ← q ⊕ q̇·dt (dt [s], e.g. 1.0)",
                "convergence.dt",
            )
        return
    if set(axes) not in ({"x", "y", "z"}, {"x", "y", "z", "rx", "ry", "rz"}) or len(axes) not in (3, 6):
        raise ConfigError(
            f"method: solve_ik solves position or pose targets; task.axes {list(axes)} is neither: use axes: "
            "position or axes: pose (or method: differential)",
            "task.axes",
        )
    ik = spec.ik
    if ik is not None and ik.max_restarts is None and ik.timeout is None:
        raise ConfigError(
            "give max_restarts or timeout [s] (or both): with neither a problem could run forever", "ik.max_restarts"
        )


def _check_frame(spec: SweepFileSpec, model: Any) -> tuple[tuple[str, ...], int]:
    """(task axes, frame id), checked: a frame on a moving link, an orientation only with rotation axes, and
    gain × dt ≤ 2."""
    task = spec.task
    axes = check_axes(task.axes, "task.axes")
    if spec.targets.orientation is not None and not any(a in ("rx", "ry", "rz") for a in axes):
        raise ConfigError(
            f"a target orientation is given but task.axes {list(axes)} has no rotation axis, so it would be ignored; "
            "use axes: pose (or add rx, ry, rz), or leave 'orientation' out",
            "targets.orientation",
        )
    try:
        fid = model.frame_id(task.frame)
    except RedundikError as exc:
        raise ConfigError(str(exc), "task.frame") from None
    if model.model.frames[fid].parentJoint == 0:
        raise ConfigError(
            f"frame '{task.frame}' is fixed to the world (no joint moves it): no target could ever be reached; "
            "choose a frame on a moving link",
            "task.frame",
        )
    _check_method(spec, axes)
    dt = spec.convergence.dt
    for key, gain in (("task.gain", task.gain), ("task.posture.gain", task.posture.gain)):
        if dt is not None and gain * dt > 2.0:
            raise ConfigError(
                f"gain × dt = {gain:g} × {dt:g} = {gain * dt:g} > 2: the iteration would diverge; lower the gain or dt",
                key,
            )
    return axes, fid


def _check_resolver(plan: SweepPlan) -> None:
    """The resolver's options, and its limit overrides bound to the robot now, not in a worker."""
    spec = plan.spec
    check_resolver_options(spec.resolver.name, spec.resolver.options, "resolver.options")
    try:
        limits = getattr(plan.batch_resolver().resolver, "limits", None)
        if limits is not None:
            limits.bind(plan.robot.model)
    except RedundikError as exc:
        msg, name = str(exc), spec.resolver.name
        if not msg.startswith((f"resolver '{name}'", f"{name}:")):
            msg = f"resolver '{name}': {msg}"
        raise ConfigError(msg, "resolver.options") from None
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"resolver '{spec.resolver.name}': bad options: {exc}", "resolver.options") from None


def load_sweep(source: str | Path | dict[str, Any], base_dir: Path | None = None) -> SweepPlan:
    """Read, validate and assemble a sweep file without running it.

    Args:
        source: Path of a YAML sweep file (read by :func:`redundik.config.yamlio.read_yaml`), or its content.
        base_dir: Folder relative paths (the robot config) are resolved from (the file's folder; cwd for a mapping).

    Raises:
        ConfigError: the first problem found, with its YAML key path.
    """
    data, base = _read(source, base_dir)
    spec: SweepFileSpec = validate(SweepFileSpec, data)
    _check_size(spec)
    robot = load_robot(spec.robot, base, "robot")
    model = robot.model
    axes, fid = _check_frame(spec, model)
    if spec.q0 is not None:
        home = configuration_from_file(spec.q0, model, spec.angle_unit, "q0")
    else:
        home = robot.q0 if robot.q0 is not None else model.neutral()
    if spec.starts.home or spec.task.posture.target == "home":
        where = "q0" if spec.q0 is not None else "starts.home" if spec.starts.home else "task.posture.target"
        _check_within_limits(model, home, where, "the home configuration", _HOME_HINT)
    if spec.task.posture.target == "home":
        posture = home.copy()
    else:
        posture = configuration_from_file(spec.task.posture.target, model, spec.angle_unit, "task.posture.target")
    if spec.targets.orientation is not None:
        R = rpy_matrix(np.array(spec.targets.orientation) * angle_scale(spec.angle_unit))
    else:
        data_ = model.model.createData()
        pin.framesForwardKinematics(model.model, data_, home)
        R = np.array(data_.oMf[fid].rotation)
    plan = SweepPlan(
        spec=spec,
        robot=robot,
        axes=axes,
        home=home,
        posture_target=posture,
        target_positions=_targets(spec),
        target_rotation=R,
        starts=_starts(spec, robot, home),
        payload={"data": data, "base_dir": str(base)},
    )
    _check_resolver(plan)
    return plan
