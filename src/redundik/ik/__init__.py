"""Inverse kinematics to convergence within the joint limits: :func:`solve_ik` and its batch form."""

from __future__ import annotations

from redundik.ik.batch import IKBatchResult, solve_ik_batch
from redundik.ik.solve import IKResult, solve_ik

__all__ = ["IKBatchResult", "IKResult", "solve_ik", "solve_ik_batch"]
