"""``OUT/solve.png`` while the controlled run goes: rewritten after every step, so a user watching a long
solve sees the residuals and the factors so far (the final report rewrites it with everything).

The drawing (~0.3 s) runs in a thread while the solver runs the next step. A step that ends while the
previous drawing is still running is not queued: the next drawing reads the newer log anyway.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

from foam_bridge import LogParser
from jaxsimrl.apps.foam.solve.report import SOLVE_PNG, plot_png, residual_history
from jaxsimrl.runs.atomic import atomic_write_bytes


class LivePlot:
    """Draws ``out/solve.png`` from the episode's ``log.simpleFoam`` and the steps so far; ``update``
    after each step, ``close`` before the final report (which overwrites the file)."""

    def __init__(self, out: Path, case: Path, criterion: dict[str, float], fields: list[str],
                 log: Path) -> None:
        # criterion: the thresholds drawn (none for a case only its runTimeControl ends); fields: the curves
        self.out, self.case, self.criterion, self.fields, self.log = out, case, dict(criterion), fields, log
        self._latest: tuple[list[dict[str, Any]], list[dict[str, Any]]] | None = None
        self._wake, self._lock, self._closed = threading.Event(), threading.Lock(), False
        self._thread = threading.Thread(target=self._work, name="solve-live-plot", daemon=True)
        self._thread.start()

    def update(self, run: Any) -> None:
        """Draw the run (a jaxsimrl.apps.foam.solve.drive.ControlledRun) as it stands after its latest
        step."""
        with self._lock:
            self._latest = (list(run.steps), list(run.events))
        self._wake.set()

    def close(self) -> None:
        """Stop drawing; waits for a drawing in progress, so that it cannot overwrite the final plot."""
        self._closed = True
        self._wake.set()
        self._thread.join()

    def _work(self) -> None:
        while True:
            self._wake.wait()
            self._wake.clear()
            if self._closed:
                return
            with self._lock:
                latest, self._latest = self._latest, None
            if latest is not None:
                self._draw(*latest)

    def _draw(self, steps: list[dict[str, Any]], events: list[dict[str, Any]]) -> None:
        parser = LogParser("", "")
        try:
            parser.feed(self.log.read_bytes())
        except OSError:  # the episode directory not there yet, or replaced: the next step draws
            return
        data = {"case": str(self.case), "settings": {"criterion": self.criterion}, "steps": steps,
                "fallback": events,
                "residuals": {"controlled": residual_history(parser.history, self.fields)}}
        try:
            atomic_write_bytes(self.out / SOLVE_PNG, plot_png(data))
        except OSError:  # a full disk must not end the solve: the final report says what it can
            return
