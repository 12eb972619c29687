"""Interop with the peer IK libraries mink (MuJoCo) and pink (Pinocchio) — the optional ``peers`` extra.

* :mod:`redundik.peers.mink_tasks` / :mod:`redundik.peers.pink_tasks`: the chapter's subtasks they lack
  (manipulability with exact gradient, best posture tr(JWJᵀ), virtual point, state-feedback-driven potentials)
  as their ``Task`` subclasses, to add to existing mink / pink stacks.
* ``mujoco_from_urdf`` / ``mujoco_from_robot`` (from :mod:`redundik.simulation.mujoco_model`): the same robot in
  MuJoCo (from its URDF, or built from a D-H model), with a site per task frame.
* :mod:`redundik.peers.joint_map`: configurations and gradients between redundik's and a peer's coordinates.

Nothing here imports mink, MuJoCo or pink until asked: ``from redundik.peers import MinkPotentialTask`` raises a
:class:`PeerImportError` saying ``install redundik[peers]`` when they are missing.
"""

from __future__ import annotations

from typing import Any

from redundik.peers._deps import PeerImportError, available, require
from redundik.peers.joint_map import JointMap
from redundik.peers.potential_term import PotentialTerm

_LAZY: dict[str, str] = {
    "MinkPotentialTask": "redundik.peers.mink_tasks",
    "MinkManipulabilityTask": "redundik.peers.mink_tasks",
    "MinkBestPostureTask": "redundik.peers.mink_tasks",
    "MinkVirtualPointTask": "redundik.peers.mink_tasks",
    "PinkPotentialTask": "redundik.peers.pink_tasks",
    "PinkManipulabilityTask": "redundik.peers.pink_tasks",
    "PinkBestPostureTask": "redundik.peers.pink_tasks",
    "PinkVirtualPointTask": "redundik.peers.pink_tasks",
    "mujoco_from_urdf": "redundik.simulation.mujoco_model",
    "mujoco_from_robot": "redundik.simulation.mujoco_model",
}

__all__ = ["JointMap", "PeerImportError", "PotentialTerm", "available", "require", *sorted(_LAZY)]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'redundik.peers' has no attribute '{name}'")
