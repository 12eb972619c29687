"""Collision geometry and avoidance: link shapes fitted from the URDF, obstacles, distances, barriers, potentials."""

from redundik.collision.avoidance import CollisionAvoidance, CollisionReport
from redundik.collision.geometry import APPROXIMATIONS, approximate, fit_capsule, fit_sphere, load_collision_model
from redundik.collision.world import (
    OBSTACLE_KINDS,
    CollisionWorld,
    Distances,
    Motion,
    Obstacle,
    default_srdf,
    make_shape,
    read_srdf_pairs,
)

__all__ = [
    "APPROXIMATIONS",
    "OBSTACLE_KINDS",
    "CollisionAvoidance",
    "CollisionReport",
    "CollisionWorld",
    "Distances",
    "Motion",
    "Obstacle",
    "approximate",
    "default_srdf",
    "fit_capsule",
    "fit_sphere",
    "load_collision_model",
    "make_shape",
    "read_srdf_pairs",
]
