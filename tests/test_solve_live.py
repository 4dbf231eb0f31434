"""solve's live plot (jaxsimrl.apps.foam.solve.live): solve.png redrawn from the episode's log after each
step, in a thread; the real solve's wiring is checked in tests/test_solve_rules.py (solve.png there
mid-run)."""

from __future__ import annotations

import time
from pathlib import Path

from test_foam_logparse import CONVERGED_TAIL

from jaxsimrl.apps.foam.solve.drive import ControlledRun
from jaxsimrl.apps.foam.solve.live import LivePlot


def _run(steps: int) -> ControlledRun:
    return ControlledRun(steps=[{"from_iteration": 100 * i, "to_iteration": 100 * (i + 1),
                                 "action": [0.9, 0.5, 0.9]} for i in range(steps)])


def _drawn(path: Path, after: float, timeout: float = 30.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if path.is_file() and path.stat().st_mtime >= after and path.read_bytes()[:4] == b"\x89PNG":
            return True
        time.sleep(0.05)
    return False


def test_the_live_plot_redraws_after_each_step_and_stops_on_close(tmp_path: Path) -> None:
    log = tmp_path / "log.simpleFoam"
    log.write_text(CONVERGED_TAIL)
    live = LivePlot(tmp_path, tmp_path / "case", {"U": 1e-3, "p": 1e-2}, ["U", "p"], log)
    try:
        live.update(_run(1))
        assert _drawn(tmp_path / "solve.png", 0.0)
        first = (tmp_path / "solve.png").stat().st_mtime
        time.sleep(0.05)
        live.update(_run(2))
        assert _drawn(tmp_path / "solve.png", first + 1e-6)
    finally:
        live.close()
    assert not live._thread.is_alive()
    # after close, an update draws nothing (the final report's plot is never overwritten)
    (tmp_path / "solve.png").unlink()
    live.update(_run(3))
    time.sleep(0.3)
    assert not (tmp_path / "solve.png").exists()


def test_a_missing_log_draws_nothing_and_raises_nothing(tmp_path: Path) -> None:
    live = LivePlot(tmp_path, tmp_path / "case", {}, ["U"], tmp_path / "no" / "log.simpleFoam")
    live.update(_run(1))
    time.sleep(0.3)
    live.close()
    assert not (tmp_path / "solve.png").exists()
