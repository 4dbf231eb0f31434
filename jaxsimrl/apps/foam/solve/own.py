"""The case run as its user would run it: ``simpleFoam`` on a copy, its own settings (or constant factors).

It is ``solve``'s comparison (``--compare``) and its last line of defence (jaxsimrl.apps.foam.solve.watchdog):
the result of such a run is exactly the user's own. The run happens in a spawned process (the driver has JAX
loaded; forking it may deadlock), which dies with the driver (PR_SET_PDEATHSIG), and simpleFoam dies with
it (foam_bridge._solver.run_to_end starts it so): a killed ``solve`` leaves no solver behind.
"""

from __future__ import annotations

import ctypes
import multiprocessing as mp
import os
import signal
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from foam_bridge import (
    AnswerMonitor,
    LogParser,
    SettleRule,
    copy_case,
    decompose,
    find_openfoam,
    reconstruct,
    restore_case,
    run_application,
    run_to_end,
)
from jaxsimrl.apps.foam.solve.criterion import write_criterion

#: Fields whose factor a constant comparison sets (as the bridge names them in relaxationFactors).
CONSTANT_FIELDS = ("U", "p", "turbulence")


@dataclass(frozen=True)
class OwnRun:
    """One plain run: its case directory, whether it converged (simpleFoam's residualControl stopped it,
    or the case's own runTimeControl, named in ``stopped_by``), the iterations, simpleFoam's wall and
    CPU seconds, the exit code, the per-iteration residuals, and an error text (empty when it ran)."""

    case: str
    label: str
    converged: bool
    iterations: int
    wall_time_s: float
    cpu_time_s: float
    exit_code: int | None
    history: list[dict[str, float]] = field(default_factory=list)
    error: str = ""
    stopped_by: str | None = None
    answer: dict[str, Any] | None = None  # the answer monitor's report (settle runs only)

    @property
    def settled(self) -> str | None:
        """"settled" or "oscillating" where the answer monitor stopped the run, else None."""
        return None if self.answer is None else self.answer.get("outcome")


@dataclass(frozen=True)
class Settle:
    """A run stopped on its answer (foam_bridge's answer monitor): the tolerance and the fields it samples."""

    tolerance: float
    fields: tuple[str, ...]


def run_own(source: Path, dest: Path, label: str, timeout_s: float, factors: Sequence[float] | None = None,
            flat: bool = False, criterion: Mapping[str, float] | None = None, start_time: int = 0,
            ranks: int = 1, settle: Settle | None = None, budget: int | None = None) -> OwnRun:
    """Copy ``source`` to ``dest`` (mesh it if needed) and run simpleFoam once to its end; ``factors``:
    constant (alpha_u, alpha_p[, turbulence]) merged into its relaxationFactors (else its own);
    ``criterion``: its SIMPLE.residualControl instead of its own (solve's ``--residual``);
    ``start_time``: the time directory it starts from (``startFrom latestTime`` with only 0 and that one
    copied), iterations counted from there; ``ranks`` > 1: decomposed, run under mpirun and its latest
    fields reconstructed, as the user would run it; ``settle``: the answer monitor watches the run and
    stops it once its answer has settled (foam_bridge's AnswerMonitor; None: the plain run); ``budget``:
    its iterations at most (``--max-iterations``; None: its own endTime)."""
    openfoam = find_openfoam()
    copy_case(source, dest, start_time=start_time)
    if start_time:
        with open(dest / "system" / "controlDict", "a") as out:
            out.write("\n// ----- jaxsimrl solve: from the time copied -----\nstartFrom latestTime;\n")
    if budget is not None:
        with open(dest / "system" / "controlDict", "a") as out:
            out.write(f"\n// ----- jaxsimrl solve --max-iterations -----\nendTime {start_time + budget};\n")
    if not (dest / "constant" / "polyMesh" / "boundary").is_file():
        run_application(openfoam, "blockMesh", dest)
    if criterion is not None:
        write_criterion(dest, criterion)
    if factors is not None:
        with open(dest / "system" / "fvSolution", "a") as out:
            out.write("\n// ----- constant factors of jaxsimrl solve --compare-constant -----\n"
                      + constant_relaxation(factors, flat))
    parser = LogParser("", "", start=start_time)
    monitor = None if settle is None else AnswerMonitor(dest, settle.fields, start_time,
                                                        SettleRule(settle.tolerance), ranks=ranks)
    try:
        if monitor is not None:
            monitor.install()
        if ranks > 1:
            decompose(dest, openfoam, ranks)
        code, wall = run_to_end(dest, openfoam, parser, timeout_s, ranks, _watch(monitor))
        if monitor is not None:
            monitor.poll(parser.iteration, ended=True)
            restore_case(dest, ranks)
        if ranks > 1 and code == 0:
            reconstruct(dest, openfoam)
    except Exception as err:  # noqa: BLE001 - a timeout or a broken case is this run's outcome
        return OwnRun(str(dest), label, False, parser.completed, 0.0, parser.execution_time, None,
                      parser.history, f"{type(err).__name__}: {err}")
    error = "" if code == 0 else f"simpleFoam exited with code {code}: {parser.error or 'no message'}"
    ended = parser.converged_at or parser.stopped_at  # residualControl, or the case's runTimeControl
    return OwnRun(str(dest), label, ended is not None and code == 0, ended or parser.completed, wall,
                  parser.execution_time, code, parser.history, error,
                  parser.stopped_by if parser.converged_at is None else None,
                  None if monitor is None else monitor.report())


def _watch(monitor: AnswerMonitor | None) -> Any:
    """run_to_end's ``watch``: read the monitor's samples as the log grows and stop the run once the
    verdict says so (None without a monitor: the plain run)."""
    if monitor is None:
        return None

    def watch(parser: LogParser) -> None:
        if monitor.poll(parser.iteration) is not None:
            monitor.request_stop()

    return watch


def constant_relaxation(factors: Sequence[float], flat: bool = False) -> str:
    """A relaxationFactors entry for constant (alpha_u, alpha_p[, every other equation])."""
    equations = {"U": float(factors[0])}
    if len(factors) > 2:
        equations['"(k|epsilon|omega|nuTilda|f|v2)"'] = float(factors[2])
    fields = {"p": float(factors[1])}
    body = {**fields, **equations} if flat else {"fields": fields, "equations": equations}
    return "relaxationFactors\n{\n" + _entries(body, 1) + "}\n"


def _entries(tree: dict[str, Any], depth: int) -> str:
    pad = "    " * depth
    text = ""
    for key, value in tree.items():
        if isinstance(value, dict):
            text += f"{pad}{key}\n{pad}{{\n{_entries(value, depth + 1)}{pad}}}\n"
        else:
            text += f"{pad}{key} {value!r};\n"
    return text


class OwnProcess:
    """:func:`run_own` in a spawned process that dies with this one; ``result()`` waits for it."""

    def __init__(self, *args: Any) -> None:
        ctx = mp.get_context("spawn")
        self._queue = ctx.SimpleQueue()
        self._process = ctx.Process(target=_serve, args=(os.getpid(), self._queue, args), daemon=True,
                                    name="solve-own-run")
        self._process.start()
        self._result: OwnRun | None = None

    def result(self, timeout_s: float) -> OwnRun:
        if self._result is not None:
            return self._result
        deadline = time.monotonic() + timeout_s
        while self._queue.empty():
            if not self._process.is_alive() and self._queue.empty():
                raise RuntimeError(f"the run with the case's own settings died (exit "
                                   f"{self._process.exitcode})")
            if time.monotonic() > deadline:
                self.stop()
                raise RuntimeError(f"the run with the case's own settings took more than {timeout_s:g} s")
            time.sleep(0.05)
        self._result = self._queue.get()
        return self._result

    def stop(self) -> None:
        """Kill the process (its simpleFoam dies with it) and reap it."""
        if self._process.is_alive():
            self._process.kill()
        self._process.join(10)


def _serve(parent: int, queue: Any, args: tuple[Any, ...]) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the driver's; it stops us
    ctypes.CDLL(None).prctl(1, int(signal.SIGKILL), 0, 0, 0)  # PR_SET_PDEATHSIG: die with the driver
    if os.getppid() != parent:
        os._exit(1)
    queue.put(run_own(*args))
