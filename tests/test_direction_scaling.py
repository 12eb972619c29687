"""``scaling="direction"`` of ``wqp`` and ``hqp`` (issue 33 item 1): the largest α ∈ [0, 1] with J q̇ = αV under
every hard limit, then the lower levels in what is left.

The reference is a linear program of its own, over the full (q̇, α) — maximise α subject to J q̇ − αV = 0, the
step's joint-limit box as bounds on q̇ and the hard rows — solved by scipy's HiGHS without the null-space
reduction, the margins or the second stage of the implementation. The box comes from ``JointLimits.box`` (the
limits' own module, tested on its own in ``tests/test_limits.py``)."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import linprog

import redundik as rk
from redundik.errors import ResolverError
from redundik.resolvers import BatchResolver
from redundik.tasks.base import Barrier, BarrierTerm

TOOL = "panda_hand_tcp"
DT = 0.01
GAIN = 20.0  # [1/s]
STATES = 200


@pytest.fixture(scope="module")
def panda() -> rk.RobotModel:
    return rk.load_example_robot("panda")


def reference_alpha(
    J: np.ndarray,
    V: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    G: np.ndarray | None = None,
    h: np.ndarray | None = None,
) -> float:
    """max α over (q̇, α): J q̇ = αV, lb ≤ q̇ ≤ ub, G q̇ ≤ h, 0 ≤ α ≤ 1 (``nan`` when infeasible)."""
    n = J.shape[1]
    cost = np.zeros(n + 1)
    cost[-1] = -1.0
    A_eq = np.hstack([J, -V[:, None]])
    bounds = [(a if math.isfinite(a) else None, b if math.isfinite(b) else None) for a, b in zip(lb, ub, strict=True)]
    bounds.append((0.0, 1.0))
    A_ub = b_ub = None
    if G is not None and G.shape[0]:
        A_ub, b_ub = np.hstack([G, np.zeros((G.shape[0], 1))]), h
    opts = {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10}
    res = linprog(cost, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=np.zeros(J.shape[0]), bounds=bounds, options=opts)
    return float(res.x[-1]) if res.status == 0 else math.nan


def angle(a: np.ndarray, b: np.ndarray) -> float:
    """The angle between two vectors [rad]."""
    c = float(a @ b) / (np.linalg.norm(a) * np.linalg.norm(b))
    return math.acos(min(1.0, max(-1.0, c)))


def random_state(robot: rk.RobotModel, rng: np.random.Generator, tool: rk.FrameTask) -> np.ndarray:
    """A configuration inside the limits (a third of them near a limit) and a tool target 0.1–0.6 m away, in a
    random orientation offset: V = K e far beyond what the velocity limits allow in dt."""
    lo, hi = robot.lower_limits, robot.upper_limits
    u = rng.uniform(0.02, 0.98, size=robot.nq)
    if rng.uniform() < 0.3:
        k = rng.integers(0, 7)
        u[k] = rng.choice([1e-4, 1.0 - 1e-4])
    q = lo + (hi - lo) * u
    robot.update(q)
    pose = robot.frame_pose(TOOL).copy()
    rot = pin.exp3(rng.normal(size=3) * 0.3)
    tool.set_target(pin.SE3(rot @ pose.rotation, pose.translation + rng.normal(size=3) * rng.uniform(0.1, 0.6)))
    return q


def _check_state(
    resolver: rk.Resolver, robot: rk.RobotModel, stack: rk.TaskStack, q: np.ndarray, prev: np.ndarray | None
) -> tuple[float, float, float]:
    """(α, α_ref, angle) of one step; asserts the hard limits hold, and that a step the reference finds no α for
    (a rate window that J q̇ = αV cannot meet for any α) says so: α = 0, stuck, a fallback note."""
    res = resolver.step(robot, stack, q, 0.0, DT)
    term = res.terms[0]
    box = resolver.limits.box(robot, q, DT, prev)  # type: ignore[attr-defined]
    assert (res.dq >= box.lb).all() and (res.dq <= box.ub).all()
    ref = reference_alpha(term.J, term.v, box.lb, box.ub)
    w = term.J @ res.dq
    ang = angle(w, term.v) if res.scale > 0 and np.linalg.norm(w) > 0 else 0.0
    assert res.stuck == (res.scale < resolver.stuck_below)  # type: ignore[attr-defined]
    assert res.info["scale"] == res.scale
    if not math.isfinite(ref):
        assert res.scale == 0.0 and res.stuck and res.info["direction"] == "unreachable"
        assert res.fallback is not None and "no q̇ within the hard limits" in res.fallback
    return res.scale, ref, ang


@pytest.mark.parametrize("name", ["wqp", "hqp"])
@pytest.mark.parametrize("acceleration", [None, 30.0])
def test_alpha_and_direction_match_the_reference(panda: rk.RobotModel, name: str, acceleration: float | None) -> None:
    """On 200 random Panda states whose limits bind (velocity, position, and a rate window when ``acceleration``):
    α equals the reference LP's to 1e-6 and J q̇ is along V within 1e-6 rad whenever α > 0."""
    rng = np.random.default_rng(33 if acceleration is None else 34)
    tool = rk.FrameTask(TOOL, gain=GAIN)
    stack = rk.TaskStack([tool, rk.PostureTask(gain=1.0)])
    resolver = rk.make_resolver(name, scaling="direction", limits={"acceleration": acceleration})
    scaled = unreachable = 0
    worst_alpha = worst_angle = 0.0
    for _ in range(STATES):
        q = random_state(panda, rng, tool)
        resolver.reset()
        prev = None
        if acceleration is not None:  # a previous q̇: a rate window around it
            prev = rng.normal(size=panda.nv) * 0.1
            resolver._dq_prev = prev.copy()  # type: ignore[attr-defined]
        alpha, ref, ang = _check_state(resolver, panda, stack, q, prev)
        if not math.isfinite(ref):
            unreachable += 1
            continue
        worst_alpha = max(worst_alpha, abs(alpha - ref))
        if alpha > 0:
            worst_angle = max(worst_angle, ang)
        scaled += alpha < 1.0
    assert worst_alpha <= 1e-6
    assert worst_angle <= 1e-6
    assert scaled >= STATES * 0.8  # the limits bind on (nearly) every state
    assert unreachable <= STATES * 0.1


@pytest.mark.parametrize("name", ["wqp", "hqp"])
def test_lower_levels_resolved_in_what_is_left(panda: rk.RobotModel, name: str) -> None:
    """q̇ is the lower levels' optimum on {J q̇ = αV} within the box: for wqp its own objective ½q̇ᵀPq̇ + gᵀq̇, for
    hqp the posture's ½‖q̇ − z‖² — each solved by quadprog on the full q̇ with α the step's; agreement to 1e-6 on 200
    random states (the median is ~1e-10; the worst sit on ill-conditioned vertices of the box)."""
    qpsolvers = pytest.importorskip("qpsolvers")
    pytest.importorskip("quadprog")
    rng = np.random.default_rng(35)
    tool = rk.FrameTask(TOOL, gain=GAIN)
    stack = rk.TaskStack([tool, rk.PostureTask(gain=1.0)])
    resolver = rk.make_resolver(name, scaling="direction")
    plain = rk.make_resolver(name)
    worst = 0.0
    for _ in range(STATES):
        q = random_state(panda, rng, tool)
        resolver.reset()
        res = resolver.step(panda, stack, q, 0.0, DT)
        built = plain.build(panda, stack, 0.0, DT)  # type: ignore[attr-defined]
        if name == "wqp":
            P, g = built.problem.P, built.problem.q
        else:
            P, g = np.eye(panda.nv), -built.rows.z
        box = resolver.limits.box(panda, q, DT)  # type: ignore[attr-defined]
        term = res.terms[0]
        x = qpsolvers.solve_qp(P, g, A=term.J, b=res.scale * term.v, lb=box.lb, ub=box.ub, solver="quadprog")
        assert x is not None
        worst = max(worst, float(np.max(np.abs(x - res.dq))))
    assert worst <= 1e-6


@pytest.mark.parametrize("name", ["wqp", "hqp"])
def test_unscaled_mode_swerves(panda: rk.RobotModel, name: str) -> None:
    """The contrast: without the mode the same states bend J q̇ away from V (degrees, not micro-radians), and
    ``scale`` stays 1.0."""
    rng = np.random.default_rng(33)
    tool = rk.FrameTask(TOOL, gain=GAIN)
    stack = rk.TaskStack([tool, rk.PostureTask(gain=1.0)])
    resolver = rk.make_resolver(name)
    angles = []
    for _ in range(30):
        q = random_state(panda, rng, tool)
        resolver.reset()
        res = resolver.step(panda, stack, q, 0.0, DT)
        assert res.scale == 1.0 and not res.stuck
        angles.append(angle(res.terms[0].J @ res.dq, res.terms[0].v))
    assert np.median(angles) > math.radians(1.0)


def _free_state(robot: rk.RobotModel, tool: rk.FrameTask) -> np.ndarray:
    q = np.array([0.1, -0.6, 0.2, -2.2, 0.1, 1.7, 0.6, 0.02, 0.02])
    robot.update(q)
    pose = robot.frame_pose(TOOL).copy()
    tool.set_target(pin.SE3(pose.rotation, pose.translation + np.array([0.002, -0.001, 0.001])))
    return q


def test_hqp_free_step_is_the_unscaled_one(panda: rk.RobotModel) -> None:
    """No limit binds: α = 1 and q̇ identical (bit for bit) to the unscaled hqp's."""
    tool = rk.FrameTask(TOOL, gain=GAIN)
    stack = rk.TaskStack([tool, rk.PostureTask(gain=1.0)])
    q = _free_state(panda, tool)
    plain = rk.make_resolver("hqp").step(panda, stack, q, 0.0, DT)
    scaled = rk.make_resolver("hqp", scaling="direction").step(panda, stack, q, 0.0, DT)
    assert plain.info["qp"] == 0
    assert scaled.scale == 1.0 and not scaled.stuck and scaled.info["direction"] == "free"
    assert np.array_equal(scaled.dq, plain.dq)


def test_wqp_free_step_meets_v_exactly(panda: rk.RobotModel) -> None:
    """No limit binds: α = 1; q̇ minimises wqp's own objective on J q̇ = V (checked against a KKT solve), within
    O(level_ratio) of the unscaled wqp's q̇, whose J q̇ is off V's direction where the direction mode's is not."""
    tool = rk.FrameTask(TOOL, gain=GAIN)
    stack = rk.TaskStack([tool, rk.PostureTask(gain=1.0)])
    q = _free_state(panda, tool)
    wqp = rk.WeightedQPResolver()
    plain = wqp.step(panda, stack, q, 0.0, DT)
    built = wqp.build(panda, stack, 0.0, DT)
    scaled = rk.make_resolver("wqp", scaling="direction").step(panda, stack, q, 0.0, DT)
    assert plain.info["qp"] == 0
    assert scaled.scale == 1.0 and scaled.info["direction"] == "free"
    J, V = scaled.terms[0].J, scaled.terms[0].v
    P, g = built.problem.P, built.problem.q
    n, m = P.shape[0], J.shape[0]
    kkt = np.block([[P, J.T], [J, np.zeros((m, m))]])
    ref = np.linalg.solve(kkt, np.concatenate([-g, V]))[:n]
    assert np.allclose(scaled.dq, ref, atol=1e-9)
    assert np.linalg.norm(J @ scaled.dq - V) <= 1e-9 * np.linalg.norm(V)
    assert np.linalg.norm(scaled.dq - plain.dq) <= 1e-2 * np.linalg.norm(plain.dq)


@pytest.mark.parametrize("name", ["wqp", "hqp"])
def test_stuck_when_the_limits_leave_almost_nothing(panda: rk.RobotModel, name: str) -> None:
    """Velocity limits of 1e-5 rad/s against a 0.3 m jump: α ≈ 1e-5 (the reference's), below ``stuck_below``;
    raising ``stuck_below`` to 0 clears the flag on the same step."""
    tool = rk.FrameTask(TOOL, gain=GAIN)
    stack = rk.TaskStack([tool])
    slow = {jn: 1e-5 for jn in panda.joint_names}
    resolver = rk.make_resolver(name, scaling="direction", limits={"velocity_limits": slow})
    q = _free_state(panda, tool)
    pose = panda.frame_pose(TOOL).copy()
    tool.set_target(pin.SE3(pose.rotation, pose.translation + np.array([0.3, 0.0, 0.0])))
    res = resolver.step(panda, stack, q, 0.0, DT)
    box = resolver.limits.box(panda, q, DT)  # type: ignore[attr-defined]
    ref = reference_alpha(res.terms[0].J, res.terms[0].v, box.lb, box.ub)
    assert 0.0 < res.scale < 1e-3 and res.stuck
    assert abs(res.scale - ref) <= 1e-6
    resolver.stuck_below = 0.0  # type: ignore[attr-defined]
    resolver.reset()
    again = resolver.step(panda, stack, q, 0.0, DT)
    assert again.scale == pytest.approx(res.scale, abs=1e-9) and not again.stuck


@pytest.mark.parametrize("name", ["wqp", "hqp"])
def test_rank_deficient_main_task_gives_zero(panda: rk.RobotModel, name: str) -> None:
    """Two main tasks asking the same point to go two ways (J rank-deficient, V outside its range): no α > 0 exists;
    α = 0, stuck, and q̇ leaves both tasks' rows at rest (J q̇ = 0) within the limits."""
    a = rk.FrameTask(TOOL, axes="position", gain=GAIN, name="a")
    b = rk.FrameTask(TOOL, axes="position", gain=GAIN, name="b")
    stack = rk.TaskStack([a, b, rk.PostureTask(gain=1.0)])
    q = _free_state(panda, a)
    p = panda.frame_position(TOOL).copy()
    a.set_target(p + np.array([0.05, 0.0, 0.0]))
    b.set_target(p - np.array([0.05, 0.0, 0.0]))
    resolver = rk.make_resolver(name, scaling="direction")
    res = resolver.step(panda, stack, q, 0.0, DT)
    assert res.scale == 0.0 and res.stuck
    J = np.vstack([res.terms[0].J, res.terms[1].J])
    assert np.linalg.norm(J @ res.dq) <= 1e-9
    box = resolver.limits.box(panda, q, DT)  # type: ignore[attr-defined]
    assert (res.dq >= box.lb).all() and (res.dq <= box.ub).all()


class Floor(Barrier):
    """A safety barrier: the tool's height above a plane, h = z − z₀ ≥ 0 [m]."""

    critical = True

    def __init__(self, z0: float) -> None:
        self.name = "floor"
        self.z0 = z0

    def evaluate(self, robot: rk.RobotModel) -> BarrierTerm:
        z = float(robot.frame_position(TOOL)[2])
        return BarrierTerm(np.array([z - self.z0]), robot.frame_jacobian(TOOL)[2:3].copy(), ["floor"])


@pytest.mark.parametrize("name", ["wqp", "hqp"])
def test_safety_rows_are_hard_limits_of_the_lp(panda: rk.RobotModel, name: str) -> None:
    """A floor 0.5 mm under the tool and a target 0.3 m down and sideways: the damper row ż ≥ −h/dt caps α (the
    reference LP with the same row agrees to 1e-6), J q̇ stays along V, and the row holds."""
    tool = rk.FrameTask(TOOL, axes="position", gain=GAIN)
    q = _free_state(panda, tool)
    z = float(panda.frame_position(TOOL)[2])
    floor = rk.BoundSubtask(Floor(z - 0.0005))
    stack = rk.TaskStack([tool, rk.PostureTask(gain=1.0)], [floor])
    tool.set_target(panda.frame_position(TOOL) + np.array([0.1, 0.0, -0.3]))
    resolver = rk.make_resolver(name, scaling="direction")
    res = resolver.step(panda, stack, q, 0.0, DT)
    C, d, _ = floor.rows(panda, DT)
    box = resolver.limits.box(panda, q, DT)  # type: ignore[attr-defined]
    term = res.terms[0]
    ref = reference_alpha(term.J, term.v, box.lb, box.ub, C, d)
    no_floor = reference_alpha(term.J, term.v, box.lb, box.ub)
    assert ref < no_floor - 1e-3  # the floor, not the box, is what binds
    assert abs(res.scale - ref) <= 1e-6
    assert angle(term.J @ res.dq, term.v) <= 1e-6
    assert (C @ res.dq <= d + 1e-12).all()


@pytest.mark.parametrize("name", ["wqp", "hqp"])
def test_settings_are_validated(name: str) -> None:
    with pytest.raises(ResolverError, match="scaling must be one of"):
        rk.make_resolver(name, scaling="directional")
    with pytest.raises(ResolverError, match=r"stuck_below must be a number in \[0, 1\]"):
        rk.make_resolver(name, stuck_below=2.0)
    resolver = rk.make_resolver(name)
    assert resolver.scaling == "off" and resolver.stuck_below == 1e-3  # type: ignore[attr-defined]
    with pytest.raises(ResolverError, match="scaling"):
        resolver.scaling = True  # type: ignore[attr-defined]


def test_scaled_run_keeps_every_limit(panda: rk.RobotModel) -> None:
    """A 300-step hqp run toward a far target with a rate limit: every step inside its box (position, velocity,
    rate window), every step along V, α rising to 1 as the target comes within reach."""
    tool = rk.FrameTask(TOOL, gain=GAIN)
    stack = rk.TaskStack([tool, rk.PostureTask(gain=1.0)])
    q = _free_state(panda, tool)
    pose = panda.frame_pose(TOOL).copy()
    tool.set_target(pin.SE3(pose.rotation, pose.translation + np.array([0.25, 0.2, -0.15])))
    resolver = rk.make_resolver("hqp", scaling="direction", limits={"acceleration": 20.0})
    prev = None
    alphas = []
    for k in range(300):
        res = resolver.step(panda, stack, q, k * DT, DT)
        box = resolver.limits.box(panda, q, DT, prev)  # type: ignore[attr-defined]
        assert (res.dq >= box.lb).all() and (res.dq <= box.ub).all()
        if res.scale > 0 and np.linalg.norm(res.terms[0].v) > 1e-9:
            assert angle(res.terms[0].J @ res.dq, res.terms[0].v) <= 1e-6
        alphas.append(res.scale)
        prev = res.dq.copy()
        q = panda.integrate(q, res.dq, DT)
    assert min(alphas) < 0.5 and alphas[-1] == 1.0
    assert panda.limit_violation(q).max() == 0.0


def test_batch_refuses_the_mode(panda: rk.RobotModel) -> None:
    """The batch API has no direction mode: it says so instead of solving the unscaled problems silently."""
    resolver = rk.make_resolver("wqp", scaling="direction")
    with pytest.raises(ResolverError, match="scaling='direction' is not supported in a batch"):
        BatchResolver(resolver, panda, TOOL)


@pytest.mark.parametrize("name", ["wqp", "hqp"])
def test_unreachable_keeps_the_unscaled_step_and_says_so(panda: rk.RobotModel, name: str) -> None:
    """A rate window around 1 rad/s on every joint (the previous q̇) that no q̇ with J q̇ = αV meets for any α (the
    reference LP is infeasible): the step is the unscaled one, α = 0, stuck, and ``fallback`` says why."""
    tool = rk.FrameTask(TOOL, gain=GAIN)
    stack = rk.TaskStack([tool, rk.PostureTask(gain=1.0)])
    q = _free_state(panda, tool)
    prev = np.ones(panda.nv)
    prev[7:] = 0.0
    results = []
    for scaling in ("off", "direction"):
        resolver = rk.make_resolver(name, scaling=scaling, limits={"acceleration": 10.0})
        resolver._dq_prev = prev.copy()  # type: ignore[attr-defined]
        results.append(resolver.step(panda, stack, q, 0.0, DT))
    plain, res = results
    box = resolver.limits.box(panda, q, DT, prev)  # type: ignore[attr-defined]
    assert math.isnan(reference_alpha(res.terms[0].J, res.terms[0].v, box.lb, box.ub))
    assert res.scale == 0.0 and res.stuck and res.info["direction"] == "unreachable"
    assert res.fallback is not None and "no q̇ within the hard limits" in res.fallback
    assert np.array_equal(res.dq, plain.dq)
