"""The cost of a simpleFoam run beyond its SIMPLE iterations, read from its ``log.simpleFoam``.

Relaxation changes what one SIMPLE iteration costs: the linear solvers' inner iterations (the
pressure equation's above all) grow or shrink with the factors. simpleFoam (v1912) prints one line per
linear solve, e.g.

    GAMG:  Solving for p, Initial residual = 0.0019, Final residual = 0.0001, No Iterations 1

and after every SIMPLE iteration ``ExecutionTime = 1.14 s  ClockTime = 1 s`` (ExecutionTime is the
solver's CPU time: it does not grow while the solver sits paused between env steps, nor with a busy
pool). :func:`solver_cost` sums the inner iterations of every solve in the log per field (the
components Ux, Uy, Uz count as U) and takes the last ExecutionTime (summed over the processes of a
restarted run). foam_bridge.logparse reads the
same lines for residuals only; this module is separate so that the env's parser stays as it is.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from foam_bridge.logparse import CpuClock

_SOLVE = re.compile(r"Solving for (\w+), Initial residual = \S+, Final residual = \S+, No Iterations (\d+)")
_EXECUTION = re.compile(r"^ExecutionTime = (\S+) s", re.MULTILINE)
_COMPONENT = re.compile(r"^(\w+?)[xyz]$")
LOG_FILE = "log.simpleFoam"


@dataclass(frozen=True)
class SolverCost:
    """Linear-solver iterations per field (``{"U": .., "p": .., "k": .., "omega": ..}``) and the
    solver's CPU seconds (None if the log has no ExecutionTime line)."""

    linear_iterations: dict[str, int]
    cpu_time_s: float | None

    @property
    def total(self) -> int:
        """Inner iterations of every linear solve in the run."""
        return sum(self.linear_iterations.values())

    def of(self, name: str) -> int:
        """Inner iterations of one field's solves (0 if it was never solved)."""
        return self.linear_iterations.get(name, 0)


def solver_cost(log_text: str, vector_fields: tuple[str, ...] = ("U",)) -> SolverCost:
    """The cost in a simpleFoam log's text; ``vector_fields`` are the fields whose components
    (``Ux``, ``Uy``, ``Uz``) are summed under the field's name."""
    counts: dict[str, int] = {}
    for match in _SOLVE.finditer(log_text):
        name = _field_of(match.group(1), vector_fields)
        counts[name] = counts.get(name, 0) + int(match.group(2))
    times = _EXECUTION.findall(log_text)
    clock = CpuClock()
    for seconds in times:
        clock.add(float(seconds))
    return SolverCost(counts, clock.total if times else None)


def read_solver_cost(case_dir: str | Path, vector_fields: tuple[str, ...] = ("U",)) -> SolverCost | None:
    """The cost recorded in ``case_dir/log.simpleFoam``, or None if there is no such log."""
    path = Path(case_dir) / LOG_FILE
    try:
        text = path.read_bytes().decode(errors="replace")
    except OSError:
        return None
    return solver_cost(text, vector_fields)


def _field_of(solved: str, vector_fields: tuple[str, ...]) -> str:
    match = _COMPONENT.match(solved)
    if match and match.group(1) in vector_fields:
        return match.group(1)
    return solved
