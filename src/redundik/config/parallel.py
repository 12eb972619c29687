"""YAML configurations of parallel mechanisms (PyYAML + pydantic, unknown keys rejected).

Every file has a ``kind`` (``stewart``, ``hybrid33``, ``delta`` or ``mobility``); :func:`load_config` picks
the model, validates it and converts pydantic's errors into :class:`~redundik.errors.ConfigError` whose message
names the key path (``top.radius: expected a positive number``). ``build()`` turns a validated model into the
mechanism object; geometric problems found there are reported as ``ConfigError`` too, with the file's key.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from redundik.config.yamlio import read_yaml, validate
from redundik.errors import ConfigError, MechanismError, short_repr
from redundik.parallel.delta import DeltaRobot
from redundik.parallel.hybrid33 import Hybrid33Arm
from redundik.parallel.mobility import SPACE_DIM, JointGroup, Mobility, grubler
from redundik.parallel.stewart import StewartPlatform
from redundik.parallel.upr import UPRPlatform

PositiveFloat = Annotated[float, Field(gt=0)]
NonNegativeFloat = Annotated[float, Field(ge=0)]
Vec3 = tuple[float, float, float]
Matrix3 = tuple[Vec3, Vec3, Vec3]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)


class Disc(_Model):
    """Joint points of one disc: a symmetric layout's ``radius`` / ``side`` or explicit ``points``."""

    radius: PositiveFloat | None = None
    side: PositiveFloat | None = None
    points: list[Vec3] | None = None


def _radius(disc: Disc, key: str, allow_side: bool = True) -> float:
    if disc.radius is not None and disc.side is not None:
        raise ConfigError("give either radius or side, not both", path=key)
    if disc.radius is not None:
        return disc.radius
    if allow_side and disc.side is not None:
        return disc.side / np.sqrt(3.0)
    raise ConfigError("expected a positive 'radius'" + (" or 'side'" if allow_side else ""), path=key)


def _points(disc: Disc, key: str) -> list[Vec3]:
    if disc.points is None:
        raise ConfigError("expected a list of [x, y, z] 'points' for layout 'points'", path=key)
    return disc.points


def _array(points: list[Vec3]) -> np.ndarray:
    return np.asarray(points, dtype=float)


def _geometry(build: Any, key: str) -> Any:
    try:
        return build()
    except MechanismError as exc:
        raise ConfigError(f"invalid geometry: {exc}", path=key) from exc


class StewartConfig(_Model):
    """A Stewart platform: ``layout`` symmetric_33 / symmetric_63 / symmetric_66 or explicit ``points``."""

    kind: Literal["stewart"]
    name: str = "stewart"
    unit: str = "m"
    layout: Literal["symmetric_33", "symmetric_63", "symmetric_66", "points"]
    base: Disc
    top: Disc
    beta_deg: float | None = None
    gamma_deg: float = 120.0
    top_offset_deg: float = 120.0
    legs: list[tuple[int, int]] | None = Field(default=None, description="(top index, base index) per leg")

    def build(self) -> StewartPlatform:
        """The :class:`StewartPlatform` described."""
        if self.layout == "symmetric_33":
            r0, r6 = _radius(self.base, "base"), _radius(self.top, "top")
            off = np.radians(self.top_offset_deg)
            return _geometry(
                lambda: StewartPlatform.symmetric_33(r0 * np.sqrt(3), r6 * np.sqrt(3), off, self.unit), "layout"
            )
        if self.layout in ("symmetric_63", "symmetric_66"):
            r0, r6 = _radius(self.base, "base", False), _radius(self.top, "top", False)
            if self.beta_deg is None:
                raise ConfigError(f"required for layout {self.layout}", path="beta_deg")
            beta = np.radians(self.beta_deg)
            if self.layout == "symmetric_63":
                off = np.radians(self.top_offset_deg)
                return _geometry(lambda: StewartPlatform.symmetric_63(r0, r6, beta, off, self.unit), "beta_deg")
            gamma = np.radians(self.gamma_deg)
            return _geometry(lambda: StewartPlatform.symmetric_66(r0, r6, beta, gamma, self.unit), "beta_deg")
        if self.legs is None:
            raise ConfigError("required for layout 'points'", path="legs")
        base, top, legs = _array(_points(self.base, "base")), _array(_points(self.top, "top")), self.legs
        return _geometry(lambda: StewartPlatform(base, top, tuple(legs), self.name, self.unit), "legs")


class PoseConfig(_Model):
    """A tool pose: position ``p`` and rotation ``R`` (rows)."""

    p: Vec3
    R: Matrix3 = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    theta6: float = Field(default=0.0, description="the book's θ6 at this pose [deg] (home only)")


class PathConfig(_Model):
    """Sampling of computer project 2."""

    n: Annotated[int, Field(ge=2, le=100_000)] = 100
    dt: Annotated[float, Field(ge=1e-6, le=1.0)] = 0.01


def _upr(layout: str, base: Disc, top: Disc, axes: list[Vec3] | None, d4: float, unit: str) -> UPRPlatform:
    if layout == "points":
        b, t = _array(_points(base, "base")), _array(_points(top, "top"))
        ax = None if axes is None else _array(axes)
        return _geometry(lambda: UPRPlatform(b, t, ax, d4, unit), "axes" if axes else "top.points")
    rb, rt = _radius(base, "base", False), _radius(top, "top", False)
    return _geometry(lambda: UPRPlatform.book_layout(layout, rb, rt, d4, unit), "layout")  # type: ignore[arg-type]


class Hybrid33Config(_Model):
    """The 3+3 UPR + RRR arm; ``home`` / ``destination`` / ``path`` describe computer project 2."""

    kind: Literal["hybrid33"]
    name: str = "hybrid33"
    unit: str = "m"
    layout: Literal["equilateral", "right_isosceles", "rectangle", "points"]
    base: Disc
    top: Disc
    axes: list[Vec3] | None = None
    d4: NonNegativeFloat
    d5: NonNegativeFloat
    d6: NonNegativeFloat
    branch: Literal[1, -1] = 1
    home: PoseConfig | None = None
    destination: PoseConfig | None = None
    path: PathConfig = PathConfig()

    def build(self) -> Hybrid33Arm:
        """The :class:`Hybrid33Arm` described."""
        platform = _upr(self.layout, self.base, self.top, self.axes, self.d4, self.unit)
        return Hybrid33Arm(platform, self.d5, self.d6)


class DeltaConfig(_Model):
    """A 3-URR Delta: the equivalent UPR platform plus link lengths a1, a2."""

    kind: Literal["delta"]
    name: str = "delta"
    unit: str = "m"
    layout: Literal["equilateral", "right_isosceles", "rectangle", "points"]
    base: Disc
    top: Disc
    axes: list[Vec3] | None = None
    d4: NonNegativeFloat = 0.0
    a1: PositiveFloat
    a2: PositiveFloat

    def build(self) -> DeltaRobot:
        """The :class:`DeltaRobot` described."""
        return DeltaRobot(_upr(self.layout, self.base, self.top, self.axes, self.d4, self.unit), self.a1, self.a2)


class JointConfig(_Model):
    """A group of joints: ``type`` (R, P, C, S = 2 axes, U = 3 axes in the chapter's naming, hooke, ball)."""

    type: str
    count: Annotated[int, Field(ge=1)] = 1
    dof: Annotated[int, Field(ge=1, le=6)] | None = None


class MobilityConfig(_Model):
    """A mechanism for Grübler's formula (5.16): ``space`` (planar/spatial) or ``D``, ``links``, ``joints``."""

    kind: Literal["mobility"]
    name: str = "mechanism"
    space: Literal["planar", "spatial"] | None = None
    D: Literal[3, 6] | None = None
    links: Annotated[int, Field(ge=0)]
    joints: list[JointConfig]

    def build(self) -> Mobility:
        """Evaluate (5.16)."""
        if self.space is None and self.D is None:
            raise ConfigError("give 'space' (planar | spatial) or 'D' (3 | 6)", path="space")
        D = self.D if self.D is not None else SPACE_DIM[self.space or "spatial"]
        if self.space is not None and self.D is not None and SPACE_DIM[self.space] != self.D:
            raise ConfigError(f"space {self.space!r} contradicts D = {self.D}", path="D")
        groups = [JointGroup(j.type, j.count, j.dof) for j in self.joints]
        return _geometry(lambda: grubler(D, self.links, groups), "joints")


AnyConfig = StewartConfig | Hybrid33Config | DeltaConfig | MobilityConfig
MODELS: dict[str, type[BaseModel]] = {
    "stewart": StewartConfig,
    "hybrid33": Hybrid33Config,
    "delta": DeltaConfig,
    "mobility": MobilityConfig,
}


def parse_config(data: Any, source: str = "<config>") -> AnyConfig:
    """Validate already-parsed YAML data.

    Raises:
        ConfigError: not a mapping, unknown ``kind``, or a validation error (first one, with its key path).
    """
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a mapping at the top level")
    kind = data.get("kind")
    if not isinstance(kind, str) or kind not in MODELS:
        raise ConfigError(f"expected one of {sorted(MODELS)}, got {short_repr(kind)}", path="kind")
    # the same validation and one-line key-path messages as task files and robot configs
    config: AnyConfig = validate(MODELS[kind], data)
    return config


def load_config(path: str | Path) -> AnyConfig:
    """Read and validate a YAML configuration file.

    Raises:
        ConfigError: missing, unreadable, binary or non-UTF-8 file, YAML syntax error, duplicate key, alias bomb,
            too deep nesting, or invalid content (one line each).
    """
    data = read_yaml(Path(path), "mechanism config")  # the bounded reader shared by every YAML entry point
    return parse_config(data, str(path))
