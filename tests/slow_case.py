"""A case whose steps last far longer than a stop may take, for stop and kill tests that can fail.

OpenFOAM's pitzDaily tutorial with its pressure solver made slow on purpose: 3000 unpreconditioned
PBiCGStab sweeps every SIMPLE iteration (tolerance 0, so always all of them), about 0.7 s an iteration
here instead of 10 ms, so a step of 100 iterations lasts over a minute. A solver that ran on to the end
of its step after a stop would still be running long after the 5 s a test allows, where on the plain
tutorial (a step in about a second) it would have ended anyway. (A ``systemCall`` sleep would slow it
without CPU, but OpenFOAM refuses system calls as root.)
"""

from __future__ import annotations

import re
import shutil
import time
from collections.abc import Callable
from pathlib import Path

import pytest

TUTORIALS = Path("/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam")
#: What a stop may take before a test calls it late: the issue's bound.
STOP_LIMIT_S = 5.0
SLOW_PRESSURE = """p
    {
        solver          PBiCGStab;
        preconditioner  none;
        tolerance       0;
        relTol          0;
        maxIter         3000;
    }"""


def slow_pitz_daily(dest: Path) -> Path:
    """pitzDaily copied to ``dest`` with its pressure solver slowed (see the module docstring)."""
    if not (TUTORIALS / "pitzDaily").is_dir():
        pytest.skip("openfoam-examples not installed")
    shutil.copytree(TUTORIALS / "pitzDaily", dest)
    solution = dest / "system" / "fvSolution"
    text, count = re.subn(r"\bp\s*\{[^}]*\}", SLOW_PRESSURE, solution.read_text(), count=1)
    assert count == 1, "pitzDaily's fvSolution has no p solver entry"
    solution.write_text(text)
    return dest


def iterations_in(log: Path) -> int:
    """The SIMPLE iterations a simpleFoam log has started so far (0 if there is no log yet)."""
    try:
        return log.read_text(errors="replace").count("\nTime = ")
    except FileNotFoundError:
        return 0


def episode_progress(root: Path) -> list[int]:
    """The iterations each episode's solver under ``root`` has started (the case checks' one-iteration dry
    runs left out); a scratch directory that vanishes during the walk (a check's) is skipped."""
    try:
        logs = [log for log in root.rglob("log.simpleFoam") if "episode" in log.parts]
    except FileNotFoundError:
        return []
    return [iterations_in(log) for log in logs]


def all_into_a_step(root: Path, solvers: int, iterations: int = 3) -> bool:
    """Whether ``solvers`` episode solvers run under ``root``, each ``iterations`` into its first step."""
    progress = episode_progress(root)
    return len(progress) == solvers and min(progress) >= iterations


def wait_until(condition: Callable[[], bool], timeout_s: float, what: str) -> None:
    """Poll ``condition`` every 0.1 s; fail the test naming ``what`` after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.1)


def seconds_until(condition: Callable[[], bool], timeout_s: float) -> float:
    """Seconds until ``condition`` holds (polled every 0.05 s), or ``timeout_s`` if it never does."""
    start = time.monotonic()
    while not condition():
        if time.monotonic() - start >= timeout_s:
            return timeout_s
        time.sleep(0.05)
    return time.monotonic() - start
