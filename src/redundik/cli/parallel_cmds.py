"""``redundik stewart | hybrid33 | delta | mobility`` — parallel mechanisms of chapter section 5.4.

Every command reads a YAML configuration (see ``configs/stewart*.yaml`` etc.), prints a rich table, or with
``--json`` one JSON object on stdout. Orientation options: ``--rpy R P Y`` in degrees with
R = Rz(Y)·Ry(P)·Rx(R), or ``--R`` with nine numbers row by row; without either, the identity. Lengths are in the
configuration's unit. Errors are :class:`~redundik.errors.RedundikError` (one line, exit code 2 via ``main``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from redundik.cli._params import path_value

if TYPE_CHECKING:
    import numpy as np

from redundik.errors import ConfigError, MechanismError, short_repr
from redundik.reporting.paths import safe_path

stewart_app = typer.Typer(
    help="Stewart platforms (3-3, 6-3, 6-6): IK, FK, Jacobian, statics, drawings.", no_args_is_help=True
)
hybrid_app = typer.Typer(help="The 3+3 UPR + RRR hybrid arm: IK, FK, computer project 2.", no_args_is_help=True)
delta_app = typer.Typer(help="Delta (3-URR) legs from the equivalent UPR platform.", no_args_is_help=True)

ConfigArg = Annotated[Path, typer.Argument(help="YAML configuration file.")]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object instead of a table.")]
PosOpt = Annotated[tuple[float, float, float], typer.Option("--p", help="Position X Y Z [config unit].")]
RpyOpt = Annotated[
    tuple[float, float, float] | None,
    typer.Option("--rpy", help="Roll pitch yaw [deg], R = Rz(Y)·Ry(P)·Rx(R)."),
]
ROpt = Annotated[
    tuple[float, float, float, float, float, float, float, float, float] | None,
    typer.Option("--R", help="Rotation matrix, 9 numbers row by row (within 1e-3 of SO(3); projected onto it)."),
]


# ---------------------------------------------------------------------------------------------- helpers
def _load(path: Path, kind: str) -> Any:
    from redundik.config.parallel import load_config

    cfg = load_config(path)
    if cfg.kind != kind:
        raise ConfigError(f"{path} describes a {cfg.kind!r} mechanism, this command needs {kind!r}", path="kind")
    return cfg


def _rotation(rpy: tuple[float, float, float] | None, rot: tuple[float, ...] | None) -> np.ndarray:
    import numpy as np

    from redundik.parallel._linalg import as_rotation, rpy_matrix

    if rpy is not None and rot is not None:
        raise MechanismError("give either --rpy or --R, not both")
    if rot is not None:
        # a matrix printed with 4 digits is within ~1e-4 of SO(3): accept up to 1e-3 and project onto SO(3)
        approx = as_rotation(np.reshape(rot, (3, 3)), "--R", tol=1e-3)
        from scipy.spatial.transform import Rotation

        return Rotation.from_matrix(approx).as_matrix()
    if rpy is not None:
        if not np.all(np.isfinite(rpy)) or np.any(np.abs(rpy) > MAX_INPUT):
            raise MechanismError(f"--rpy: expected finite angles of at most {MAX_INPUT:g} [deg], got {list(rpy)}")
        return rpy_matrix(*rpy)
    return np.eye(3)


def _out_file(out: Path, suffix: str) -> Path:
    """``--out FILE``: a safe file name ending in ``suffix`` (the format written), its resolved path in its folder.

    Without the check, a folder (``--out out/``) or a name without the suffix was written as ``NAME.png`` *beside*
    the path given (matplotlib appends the suffix), and another suffix was an internal error or a GIF in a PNG.
    """
    if out.suffix.lower() != suffix:
        raise MechanismError(
            f"--out: expected a {suffix} file name (this command writes {suffix[1:].upper()}), got "
            f"{short_repr(str(out), 120)}"
        )
    target = safe_path(out.parent, out.name)
    if target.is_dir():
        raise MechanismError(f"--out: {short_repr(str(out), 120)} is a folder; give a {suffix} file name")
    return target


#: Largest magnitude of a number given on the command line (as |x| ≤ 1e6 in the YAML files): beyond it the
#: mechanism's arithmetic overflows to inf/NaN.
MAX_INPUT = 1e6


def _vec(values: tuple[float, ...], name: str) -> np.ndarray:
    import numpy as np

    arr = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise MechanismError(f"{name}: non-finite value {arr.tolist()}")
    if np.any(np.abs(arr) > MAX_INPUT):
        raise MechanismError(f"{name}: values must be at most {MAX_INPUT:g} in magnitude, got {arr.tolist()}")
    return arr


def _non_finite(node: Any, path: str = "") -> str | None:
    """The key path of the first non-finite number in a result, or ``None``."""
    import math

    if isinstance(node, float):
        return None if math.isfinite(node) else path or "result"
    if isinstance(node, dict):
        for key, value in node.items():
            found = _non_finite(value, f"{path}.{key}" if path else str(key))
            if found:
                return found
    elif isinstance(node, (list, tuple)):
        for i, value in enumerate(node):
            found = _non_finite(value, f"{path}[{i}]")
            if found:
                return found
    return None


def _emit(payload: dict[str, Any], as_json: bool, title: str, rows: list[tuple[str, str]]) -> None:
    bad = _non_finite(payload)
    if bad is not None:  # never print inf/NaN (nor write "Infinity" into a JSON document) as an answer
        raise MechanismError(f"{title}: the result is not finite at '{bad}' (the inputs overflow the computation)")
    if as_json:
        typer.echo(json.dumps(payload))
        return
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    table = Table(title=escape(title))
    table.add_column("quantity")
    table.add_column("value")
    for key, value in rows:
        table.add_row(escape(key), escape(value))
    Console().print(table)


def _fmt(values: Any, digits: int = 6) -> str:
    import numpy as np

    arr = np.asarray(values, dtype=float)
    if arr.ndim == 2:
        return "\n".join(_fmt(row, digits) for row in arr)
    return "  ".join(f"{v:.{digits}f}" for v in np.atleast_1d(arr))


# ---------------------------------------------------------------------------------------------- stewart
@stewart_app.command("ik")
def stewart_ik(config: ConfigArg, p: PosOpt, rpy: RpyOpt = None, rot: ROpt = None, as_json: JsonOpt = False) -> None:
    """Leg lengths and unit vectors for a top pose (5.18)/(5.25)."""
    platform = _load(config, "stewart").build()
    legs = platform.inverse_kinematics(_vec(p, "--p"), _rotation(rpy, rot))
    payload = {"lengths": legs.lengths.tolist(), "units": legs.units.tolist(), "vectors": legs.vectors.tolist()}
    rows = [("lengths", _fmt(legs.lengths)), ("units", _fmt(legs.units))]
    _emit(payload, as_json, f"{platform.kind} Stewart IK [{platform.unit}]", rows)


@stewart_app.command("fk")
def stewart_fk(
    config: ConfigArg,
    legs: Annotated[tuple[float, float, float, float, float, float], typer.Option("--legs", help="Six leg lengths.")],
    method: Annotated[
        str, typer.Option("--method", help="exact (least squares) or grid (the book's search).")
    ] = "exact",
    starts: Annotated[int, typer.Option("--starts", min=1, max=10_000, help="Initial poses of the exact solver.")] = 48,
    half_space: Annotated[str, typer.Option("--half-space", help="above, below or any.")] = "above",
    as_json: JsonOpt = False,
) -> None:
    """Every top pose for six leg lengths (exact solver), or the book's grid-search answer."""
    from redundik.parallel.stewart_fk import forward_kinematics, grid_search_fk

    platform = _load(config, "stewart").build()
    q = _vec(legs, "--legs")
    if method == "grid":
        sols = [grid_search_fk(platform, q)]
    elif method == "exact":
        if half_space not in ("above", "below", "any"):
            raise MechanismError(f"--half-space must be one of ['above', 'below', 'any'], got {half_space!r}")
        sols = forward_kinematics(platform, q, starts=starts, half_space=half_space)  # type: ignore[arg-type]
    else:
        raise MechanismError(f"--method must be one of ['exact', 'grid'], got {method!r}")
    payload = {
        "method": method,
        "solutions": [
            {"p": s.p.tolist(), "R": s.R.tolist(), "residual": s.residual}
            | ({"theta_deg": s.theta.tolist()} if s.theta is not None else {})
            for s in sols
        ],
    }
    rows = []
    for k, s in enumerate(sols):
        rows += [(f"#{k + 1} p", _fmt(s.p)), (f"#{k + 1} R", _fmt(s.R)), (f"#{k + 1} residual", f"{s.residual:.3e}")]
    _emit(payload, as_json, f"{platform.kind} Stewart FK ({method}): {len(sols)} solution(s)", rows)


@stewart_app.command("jacobian")
def stewart_jacobian(
    config: ConfigArg, p: PosOpt, rpy: RpyOpt = None, rot: ROpt = None, as_json: JsonOpt = False
) -> None:
    """The Jacobian J0 (5.28) with q̇ = J0ᵀ V0 (5.29)."""
    platform = _load(config, "stewart").build()
    J0 = platform.jacobian(_vec(p, "--p"), _rotation(rpy, rot))
    _emit({"J0": J0.tolist()}, as_json, "J0 (5.28)", [("J0", _fmt(J0, 4))])


@stewart_app.command("statics")
def stewart_statics(
    config: ConfigArg,
    p: PosOpt,
    wrench: Annotated[
        tuple[float, float, float, float, float, float],
        typer.Option("--wrench", help="fx fy fz mx my mz on the top disc, base frame, moment about frame 6 origin."),
    ],
    rpy: RpyOpt = None,
    rot: ROpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Leg forces τ = J0⁻¹ F0 balancing a wrench on the top disc (5.30)."""
    platform = _load(config, "stewart").build()
    tau = platform.leg_forces(_vec(p, "--p"), _rotation(rpy, rot), _vec(wrench, "--wrench"))
    _emit(
        {"forces": tau.tolist(), "sum": float(tau.sum())},
        as_json,
        "leg forces [N]",
        [("forces", _fmt(tau, 4)), ("sum", f"{tau.sum():.4f}")],
    )


@stewart_app.command("draw")
def stewart_draw(
    config: ConfigArg,
    p: PosOpt,
    out: Annotated[Path, typer.Option("--out", parser=path_value, help="PNG file to write.")],
    rpy: RpyOpt = None,
    rot: ROpt = None,
) -> None:
    """3-D drawing of a platform pose (PNG)."""
    from redundik.reporting.parallel_plots import draw_stewart

    platform = _load(config, "stewart").build()
    target = _out_file(out, ".png")
    draw_stewart(platform, _vec(p, "--p"), _rotation(rpy, rot), target)
    typer.echo(str(target))


@stewart_app.command("animate")
def stewart_animate(
    config: ConfigArg,
    p: PosOpt,
    to_p: Annotated[tuple[float, float, float], typer.Option("--to-p", help="Final position X Y Z.")],
    out: Annotated[Path, typer.Option("--out", parser=path_value, help="GIF file to write.")],
    rpy: RpyOpt = None,
    to_rpy: Annotated[tuple[float, float, float] | None, typer.Option("--to-rpy", help="Final rpy [deg].")] = None,
    frames: Annotated[int, typer.Option("--frames", min=2, max=1000, help="Number of frames.")] = 20,
) -> None:
    """GIF of a straight-line move between two poses (orientation by slerp)."""
    from redundik.parallel.hybrid33 import linear_path
    from redundik.reporting.parallel_plots import animate_stewart

    platform = _load(config, "stewart").build()
    ps, Rs = linear_path(_vec(p, "--p"), _rotation(rpy, None), _vec(to_p, "--to-p"), _rotation(to_rpy, None), frames)
    target = _out_file(out, ".gif")
    animate_stewart(platform, list(zip(ps, Rs, strict=True)), target)
    typer.echo(str(target))


# ---------------------------------------------------------------------------------------------- hybrid33
def _hybrid_payload(sol: Any) -> dict[str, Any]:
    import numpy as np

    return {
        "lengths": sol.lengths.tolist(),
        "theta": sol.theta.tolist(),
        "theta_deg": np.degrees(sol.theta).tolist(),
        "R03": sol.R03.tolist(),
        "o3": sol.o3.tolist(),
        "top": sol.top.tolist(),
        "theta6_used": sol.theta6_used,
        "lag": sol.lag,
        "orientation_residual": sol.orientation_residual,
    }


@hybrid_app.command("ik")
def hybrid_ik(
    config: ConfigArg,
    p: PosOpt,
    rot: ROpt = None,
    rpy: RpyOpt = None,
    method: Annotated[str, typer.Option("--method", help="exact (self-consistent θ6) or book (lagged).")] = "exact",
    theta6_prev: Annotated[float, typer.Option("--theta6-prev", help="Book scheme: previous θ6 [deg].")] = 0.0,
    branch: Annotated[int, typer.Option("--branch", help="Wrist branch: 1 (sin θ5 > 0) or -1.")] = 0,
    as_json: JsonOpt = False,
) -> None:
    """Leg lengths, wrist angles θ4..θ6 [rad] and the passive R03 for a tool pose."""
    import numpy as np

    cfg = _load(config, "hybrid33")
    arm = cfg.build()
    b = branch or cfg.branch
    if b not in (1, -1):
        raise MechanismError(f"--branch must be 1 or -1, got {branch}")
    pos, R = _vec(p, "--p"), _rotation(rpy, rot)
    if method == "exact":
        sol = arm.ik_exact(pos, R, b)
    elif method == "book":
        prev = float(_vec((theta6_prev,), "--theta6-prev")[0])
        sol = arm.ik_book(pos, R, np.radians(prev), b)
    else:
        raise MechanismError(f"--method must be one of ['exact', 'book'], got {method!r}")
    payload = _hybrid_payload(sol)
    rows = [
        ("lengths", _fmt(sol.lengths)),
        ("theta [deg]", _fmt(np.degrees(sol.theta), 4)),
        ("R03", _fmt(sol.R03)),
        ("θ6 lag [deg]", f"{np.degrees(sol.lag):.6f}"),
    ]
    _emit(payload, as_json, f"3+3 hybrid IK ({method})", rows)


@hybrid_app.command("fk")
def hybrid_fk(
    config: ConfigArg,
    legs: Annotated[tuple[float, float, float], typer.Option("--legs", help="l1 l2 l3.")],
    theta: Annotated[tuple[float, float, float], typer.Option("--theta", help="θ4 θ5 θ6 [deg].")],
    as_json: JsonOpt = False,
) -> None:
    """Every tool pose for leg lengths and wrist angles (platform FK, then the wrist)."""
    import numpy as np

    arm = _load(config, "hybrid33").build()
    poses = arm.forward_kinematics(_vec(legs, "--legs"), np.radians(_vec(theta, "--theta")))
    payload = {
        "solutions": [
            {"p": a.p.tolist(), "R": a.R.tolist(), "R03": a.R03.tolist(), "residual": a.residual} for a in poses
        ]
    }
    rows = []
    for k, a in enumerate(poses):
        rows += [(f"#{k + 1} p", _fmt(a.p)), (f"#{k + 1} R", _fmt(a.R)), (f"#{k + 1} residual", f"{a.residual:.2e}")]
    _emit(payload, as_json, f"3+3 hybrid FK: {len(poses)} solution(s)", rows)


@hybrid_app.command("path")
def hybrid_path(
    config: ConfigArg,
    out: Annotated[
        Path, typer.Option("--out", parser=path_value, help="Directory for joint_profiles.png and roundtrip.json.")
    ],
    as_json: JsonOpt = False,
) -> None:
    """Computer project 2: home → destination, book (lagged) and exact joint profiles and round-trip errors."""
    import numpy as np

    from redundik.parallel.hybrid33 import run_path
    from redundik.reporting.parallel_plots import plot_joint_profiles

    cfg = _load(config, "hybrid33")
    if cfg.home is None or cfg.destination is None:
        raise ConfigError("the path command needs 'home' and 'destination' poses", path="home")
    arm = cfg.build()
    res = run_path(
        arm,
        cfg.home.p,
        cfg.home.R,
        cfg.destination.p,
        cfg.destination.R,
        cfg.path.n,
        cfg.path.dt,
        np.radians(cfg.home.theta6),
        cfg.branch,
    )
    profiles, roundtrip = safe_path(out, "joint_profiles.png"), safe_path(out, "roundtrip.json")
    plot_joint_profiles(res, profiles)
    payload: dict[str, Any] = res.summary() | {
        "n": len(res.t),
        "dt": cfg.path.dt,
        "home_book": _hybrid_payload(res.home_book),
        "home_exact": _hybrid_payload(res.home_exact),
        "roundtrip_position_book": res.roundtrip_book.tolist(),
        "roundtrip_position_exact": res.roundtrip_exact.tolist(),
        "roundtrip_angle_book": res.roundtrip_book_angle.tolist(),
        "roundtrip_angle_exact": res.roundtrip_exact_angle.tolist(),
        "files": [str(profiles), str(roundtrip)],
    }
    roundtrip.write_text(json.dumps(payload, indent=1), encoding="utf-8")
    rows = [(k, f"{v:.3e}") for k, v in res.summary().items()] + [("written", str(out))]
    _emit({k: payload[k] for k in (*res.summary(), "files")}, as_json, "project 2 round trips", rows)


# ---------------------------------------------------------------------------------------------- delta
@delta_app.command("ik")
def delta_ik(
    config: ConfigArg,
    top: Annotated[tuple[float, float, float], typer.Option("--top", help="Top point X Y Z.")],
    as_json: JsonOpt = False,
) -> None:
    """URR leg angles (θ1, θ2) [rad], knee points and leg frames for a Top point."""
    import numpy as np

    delta = _load(config, "delta").build()
    res = delta.inverse_kinematics(_vec(top, "--top"))
    payload = {
        "theta": res.theta.tolist(),
        "theta_deg": np.degrees(res.theta).tolist(),
        "lengths": res.lengths.tolist(),
        "knees": res.knees.tolist(),
        "frames": res.frames.tolist(),
    }
    rows = [
        ("theta [deg]", _fmt(np.degrees(res.theta), 4)),
        ("UPR lengths", _fmt(res.lengths)),
        ("knees", _fmt(res.knees)),
    ]
    _emit(payload, as_json, "Delta IK", rows)


# ---------------------------------------------------------------------------------------------- mobility
def mobility_cmd(config: ConfigArg, as_json: JsonOpt = False) -> None:
    """Net degrees of freedom by Grübler's formula (5.16)."""
    cfg = _load(config, "mobility")
    mob = cfg.build()
    payload = {"m": mob.m, "F": mob.F, "D": mob.D, "links": mob.links, "joints": mob.joints, "passive": mob.passive}
    _emit(payload, as_json, f"mobility of {cfg.name}", [(k, str(v)) for k, v in payload.items()])


def register(app: typer.Typer) -> None:
    """Add the ``stewart``, ``hybrid33`` and ``delta`` groups and the ``mobility`` command to ``app``."""
    app.add_typer(stewart_app, name="stewart")
    app.add_typer(hybrid_app, name="hybrid33")
    app.add_typer(delta_app, name="delta")
    app.command("mobility")(mobility_cmd)
