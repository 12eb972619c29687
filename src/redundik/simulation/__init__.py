"""Simulated task runs (kinematic, first-order integration)."""

from redundik.simulation.loop import SimulationLog, simulate

__all__ = ["SimulationLog", "simulate"]
