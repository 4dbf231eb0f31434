"""Incremental parsing of simpleFoam's output: iterations, initial residuals, the state, the outcome.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

The parser is fed raw chunks of the solver's stdout+stderr as they arrive (partial lines are kept
until their newline), so parsing costs O(new output) per step, never a re-read of the whole log.

What it recognises (OpenFOAM v1912 wording):

- ``Time = 123``: iteration 123 starts.
- ``<solver>:  Solving for Ux, Initial residual = 0.01, Final residual = ..., No Iterations 2``: the
  first solve of a field in an iteration gives its initial residual (as simpleFoam's residualControl
  judges it); every solve's ``No Iterations`` adds to ``linear_iterations``.
- ``ExecutionTime = 1.14 s``: the iteration is complete; the solver's CPU seconds so far.
- ``volFieldValue <cells> write:`` / ``surfaceFieldValue <inlet> write:`` followed by
  ``    average(...) of <field> = 1953.64``: the two terms of the paper's state.
- ``SIMPLE solution converged in 418 iterations``: simpleFoam's own residualControl was met.
- ``runTimeControl <name> output:`` ... ``    Stopping calculation``: the case's own runTimeControl
  function object (``satisfiedAction end``) ended the run after the iteration just completed; printed
  whatever its ``log`` setting, then ``    Writing fields`` (the fields of that iteration are written).
- ``Re-reading object fvSolution from file ...``: printed (and flushed) before every re-read of
  fvSolution, i.e. before the solver opens the relaxation FIFO again; counted in ``fvsolution_rereads``.
- ``--> FOAM FATAL (IO) ERROR`` (+ its message line), the sigFpe/sigSegv stack traces: crash causes.
- NaN/Inf or an initial residual above ``divergence_threshold``, or a state term that is not finite or
  above ``state_limit``: divergence. The parser then freezes: it ignores the rest of the output, so
  everything it reports (``failed_at``, residuals, history, state) is that of the first bad iteration
  however far the solver ran on before it was stopped and however the output was chunked.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["LOG_FILE", "STATE_LIMIT", "VECTOR_COMPONENTS", "CpuClock", "LogParser", "SolverCost",
           "field_residual", "read_solver_cost", "solved_field_names", "solver_cost"]

_TIME = re.compile(r"^Time = (\S+)\s*$")
_SOLVE = re.compile(r"Solving for (\w+), Initial residual = (\S+), Final residual = (\S+),"
                    r"(?: No Iterations (\d+))?")
_EXECUTION = re.compile(r"^ExecutionTime = (\S+)")
_FUNCTION_HEADER = re.compile(r"^(?:volFieldValue|surfaceFieldValue) (\S+) write:")
_FUNCTION_VALUE = re.compile(r"^\s+\w+\(.*\) of \S+ = (\S+)\s*$")
_CONVERGED = re.compile(r"solution converged in (\S+) iterations")
_RUN_TIME_CONTROL = re.compile(r"^runTimeControl (\S+) output:")
_STOPPING = re.compile(r"^\s+Stopping calculation\s*$")
_REREAD = re.compile(r"Re-reading object fvSolution\b")
#: Crash markers -> the cause recorded (a FOAM FATAL error also records its next message line).
_ERRORS = {"sigFpe::sigHandler": "floating point exception (SIGFPE)",
           "sigSegv::sigHandler": "segmentation fault (SIGSEGV)",
           "FOAM FATAL": "FOAM FATAL ERROR", "std::bad_alloc": "out of memory (std::bad_alloc)"}
#: Default bound of a state term (|U|^2 in m^2/s^2) above which the solution has blown up; the env
#: sets a much tighter, inlet-relative one (FoamEnvConfig.state_divergence_ratio).
STATE_LIMIT = 1e30
VECTOR_COMPONENTS = ("x", "y", "z")


def field_residual(residuals: dict[str, float], name: str) -> float | None:
    """Initial residual of a field: its own entry, or the largest of its vector components."""
    if name in residuals:
        return residuals[name]
    parts = [residuals[name + c] for c in VECTOR_COMPONENTS if name + c in residuals]
    if not parts:
        return None
    return max(parts, key=lambda v: v if math.isfinite(v) else math.inf)


def criterion_distance(residuals: Mapping[str, float], criterion: Mapping[str, float]) -> float:
    """Decades above ``criterion`` ({field: threshold}) of the worst field in ``residuals`` (<= 0: every
    field meets it; a non-finite residual is infinitely far); NaN if no criterion field is there."""
    found = [math.log10(max(residuals[name], 1e-300) / threshold) if math.isfinite(residuals[name])
             else math.inf for name, threshold in criterion.items() if name in residuals]
    return max(found) if found else math.nan


def solved_field_names(solved: tuple[str, ...]) -> list[str]:
    """Field names of simpleFoam's solved equations: ``Ux``/``Uy``(/``Uz``) -> ``U``, in solve order."""
    names: list[str] = []
    for name in solved:
        base = name[:-1]
        components = {base + c for c in VECTOR_COMPONENTS}
        field = base if base and name in components and len(components & set(solved)) > 1 else name
        if field not in names:
            names.append(field)
    return names


def _to_float(text: str) -> float:
    try:
        return float(text.rstrip(","))
    except ValueError:
        return math.nan


@dataclass
class CpuClock:
    """A run's CPU seconds from its ``ExecutionTime`` lines, fed in order with :meth:`add`.

    A solver restarted from the run's fields (foam_bridge._confirm) counts from 0 again, so a value
    below the last one starts a new process: ``total`` is its time plus the last time of every
    earlier process.
    """

    total: float = 0.0
    _earlier: float = 0.0
    _last: float = 0.0

    def add(self, seconds: float) -> float:
        """Count one ExecutionTime value; returns the total so far."""
        if seconds < self._last:
            self._earlier += self._last
        self._last = seconds
        self.total = self._earlier + seconds
        return self.total


@dataclass
class LogParser:
    """Feed it the solver's output chunk by chunk; read the latest facts from its attributes.

    Attributes: ``iteration`` (last ``Time =`` seen), ``completed`` (last finished iteration),
    ``residuals`` (raw initial residuals of the last finished iteration, e.g. {"Ux": .., "p": ..}),
    ``history`` (one residual dict per finished iteration, in order), ``cells_state`` /
    ``inlet_state`` / ``state_iteration`` (latest state terms and the iteration they belong to),
    ``linear_iterations`` (inner iterations of every linear solve so far, all fields), ``execution_time``
    (the solver's CPU seconds at the last finished iteration, summed over the processes of a run
    restarted from its fields: their counts start from 0 again),
    ``converged_at``, ``stopped_at`` and ``stopped_by`` (the iteration after which the case's own
    runTimeControl ended the run, and its name), ``fvsolution_rereads``, ``error`` (first crash line),
    ``diverged`` (cause text). Iterations are counted from ``start`` (a run restarted from that time
    directory: its ``Time = start + K`` is iteration K).
    and ``failed_at`` (the iteration in which divergence was detected; the parser ignores all output
    after that line).
    """

    cells_function: str
    inlet_function: str
    divergence_threshold: float = 1e3
    state_limit: float = STATE_LIMIT
    iteration: int = 0
    completed: int = 0
    residuals: dict[str, float] = field(default_factory=dict)
    history: list[dict[str, float]] = field(default_factory=list)
    linear_iterations: int = 0
    execution_time: float = 0.0
    cells_state: float | None = None
    inlet_state: float | None = None
    state_iteration: int = 0
    converged_at: int | None = None
    stopped_at: int | None = None
    stopped_by: str | None = None
    fvsolution_rereads: int = 0
    error: str | None = None
    diverged: str | None = None
    failed_at: int | None = None
    start: int = 0
    _current: dict[str, float] = field(default_factory=dict)
    _clock: CpuClock = field(default_factory=CpuClock)
    _pending_function: str | None = None
    _pending_error: bool = False
    _run_time_control: str | None = None
    _partial: str = ""

    def feed(self, chunk: bytes | str) -> None:
        """Parse a chunk of output; an unfinished last line waits for the next chunk."""
        text = chunk.decode(errors="replace") if isinstance(chunk, bytes) else chunk
        lines = (self._partial + text).split("\n")
        self._partial = lines.pop()
        for line in lines:
            self._line(line)

    def finish(self) -> None:
        """Parse the unfinished last line (call when the stream has ended)."""
        if self._partial:
            self._line(self._partial)
            self._partial = ""

    def _line(self, line: str) -> None:
        if self.diverged is not None:
            return  # frozen at the first bad iteration (see the module docstring)
        if self._pending_error and line.strip():
            self.error = f"{self.error}: {line.strip()}"
            self._pending_error = False
        if match := _TIME.match(line):
            self.iteration = int(round(_to_float(match.group(1)))) - self.start
            self._current = {}
        elif match := _SOLVE.search(line):
            self.linear_iterations += int(match.group(4) or 0)
            self._residual(match.group(1), _to_float(match.group(2)))
        elif match := _EXECUTION.match(line):
            seconds = _to_float(match.group(1))
            if math.isfinite(seconds):
                self.execution_time = self._clock.add(seconds)
            self.completed = self.iteration
            self.residuals = self._current
            self.history.append(self._current)
        elif match := _FUNCTION_HEADER.match(line):
            self._pending_function = match.group(1)
        elif self._pending_function and (match := _FUNCTION_VALUE.match(line)):
            self._state_term(self._pending_function, _to_float(match.group(1)))
            self._pending_function = None
        elif _REREAD.search(line):
            self.fvsolution_rereads += 1
        elif match := _CONVERGED.search(line):
            self.converged_at = int(round(_to_float(match.group(1)))) - self.start  # it prints the time
        elif match := _RUN_TIME_CONTROL.match(line):
            self._run_time_control = match.group(1)
        elif _STOPPING.match(line) and self._run_time_control is not None:
            self.stopped_at, self.stopped_by = self.completed, self._run_time_control
        elif self.error is None:
            self._error(line)

    def _error(self, line: str) -> None:
        for marker, cause in _ERRORS.items():
            if marker in line:
                self.error = cause
                self._pending_error = marker == "FOAM FATAL"
                return

    def _residual(self, name: str, value: float) -> None:
        if name in self._current:
            return  # only the first solve of a field per iteration counts (as residualControl)
        self._current[name] = value
        if not (math.isfinite(value) and value <= self.divergence_threshold):
            self._diverge(f"initial residual of {name} = {value}")

    def _state_term(self, function: str, value: float) -> None:
        if function == self.cells_function:
            self.cells_state = value
        elif function == self.inlet_function:
            self.inlet_state = value
        else:
            return
        self.state_iteration = self.iteration
        if not (math.isfinite(value) and abs(value) <= self.state_limit):
            self._diverge(f"state term {function} = {value} (limit {self.state_limit:.6g})")

    def _diverge(self, what: str) -> None:
        self.failed_at = self.iteration
        self.diverged = f"{what} at iteration {self.iteration}"


# ---- a finished run's cost, from its whole log ----------------------------------------------------
# Relaxation changes what one SIMPLE iteration costs: the linear solvers' inner iterations (the pressure
# equation's above all) grow or shrink with the factors. These read a whole log once, after a run (the
# episode pool after an episode's last step); LogParser above is the incremental reader the env uses.
# ExecutionTime is the solver's CPU time: it does not grow while the solver sits paused between env
# steps, nor with a busy pool.

#: The log a FoamCaseEnv episode's solver writes in its case directory.
LOG_FILE = "log.simpleFoam"
_COST_SOLVE = re.compile(r"Solving for (\w+), Initial residual = \S+, Final residual = \S+, "
                         r"No Iterations (\d+)")
_COST_EXECUTION = re.compile(r"^ExecutionTime = (\S+) s", re.MULTILINE)
_COMPONENT = re.compile(r"^(\w+?)[xyz]$")


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
    """The cost in a simpleFoam log's text: the inner iterations of every solve per field (the
    components ``Ux``, ``Uy``, ``Uz`` of ``vector_fields`` summed under the field's name) and the last
    ExecutionTime (summed over the processes of a restarted run, :class:`CpuClock`)."""
    counts: dict[str, int] = {}
    for match in _COST_SOLVE.finditer(log_text):
        name = _cost_field(match.group(1), vector_fields)
        counts[name] = counts.get(name, 0) + int(match.group(2))
    times = _COST_EXECUTION.findall(log_text)
    clock = CpuClock()
    for seconds in times:
        clock.add(float(seconds))
    return SolverCost(counts, clock.total if times else None)


def read_solver_cost(case_dir: str | Path, vector_fields: tuple[str, ...] = ("U",)) -> SolverCost | None:
    """The cost recorded in ``case_dir/log.simpleFoam``, or None if there is no such log."""
    try:
        text = (Path(case_dir) / LOG_FILE).read_bytes().decode(errors="replace")
    except OSError:
        return None
    return solver_cost(text, vector_fields)


def _cost_field(solved: str, vector_fields: tuple[str, ...]) -> str:
    match = _COMPONENT.match(solved)
    if match and match.group(1) in vector_fields:
        return match.group(1)
    return solved
