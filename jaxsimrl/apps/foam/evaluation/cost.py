"""Moved: a simpleFoam run's linear-solver cost is read by foam_bridge.logparse (solver_cost,
read_solver_cost, SolverCost), beside the env's own log parser; these names stay importable from here."""

from __future__ import annotations

from foam_bridge.logparse import LOG_FILE, SolverCost, read_solver_cost, solver_cost

__all__ = ["LOG_FILE", "SolverCost", "read_solver_cost", "solver_cost"]
