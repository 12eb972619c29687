"""Inverse kinematics to convergence within the joint limits: :func:`solve_ik` and its batch form."""

from __future__ import annotations

from redundik.ik.solve import IKResult, solve_ik

__all__ = ["IKResult", "solve_ik"]
