"""Training progress on the terminal: a live rich bar on a TTY, one plain line per chunk otherwise.

The bar shows env steps done / total, the steps per second of the last chunk and the latest mean
episode return. Plain lines (logs, CI, pipes) carry the same numbers, so nothing is lost off a TTY.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from typing import Any, TextIO

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Column


class TrainingProgress:
    """Context manager; call :meth:`update` after every chunk."""

    def __init__(self, total_steps: int, done_steps: int = 0, stream: TextIO | None = None,
                 live: bool | None = None) -> None:
        self.stream = stream if stream is not None else sys.stdout
        self.console = Console(file=self.stream, highlight=False)
        self.live = self.console.is_terminal if live is None else live
        self.total_steps = total_steps
        self.done_steps = done_steps
        self._progress: Progress | None = None
        self._task = None

    def __enter__(self) -> TrainingProgress:
        if self.live:
            self._progress = Progress(
                TextColumn("[bold]{task.description}"),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn("env steps  {task.fields[rate]} steps/s  mean return {task.fields[ret]}"),
                TimeElapsedColumn(),
                TimeRemainingColumn(),
                console=self.console,
            )
            self._progress.start()
            # The first chunk includes JAX's compilation, which can take a while: say so.
            self._task = self._progress.add_task("compiling + first chunk", total=self.total_steps,
                                                 completed=self.done_steps, rate="-", ret="-")
        return self

    def __exit__(self, *exc: object) -> None:
        if self._progress is not None:
            self._progress.stop()

    def update(self, env_steps: int, steps_per_s: float, mean_return: float, update: int,
               num_updates: int) -> None:
        """Report the state after a chunk (``mean_return`` NaN when no episode has ended yet)."""
        self.done_steps = env_steps
        rate = f"{steps_per_s:,.0f}"
        ret = "-" if not math.isfinite(mean_return) else f"{mean_return:,.1f}"
        if self._progress is not None:
            self._progress.update(self._task, description="training", completed=env_steps, rate=rate, ret=ret)
        else:
            steps = f"{env_steps:,}/{self.total_steps:,}"
            self.print(f"update {update}/{num_updates}  env steps {steps}  {rate} steps/s  mean return {ret}")

    def print(self, text: str) -> None:
        """A message that does not disturb the live bar."""
        self.console.print(text, soft_wrap=True)


class EpisodeProgress:
    """Progress of a host-env run (a solver's cases on a pool), by episodes: done of the target, the moving
    mean of the iterations to converge over the last 100 episodes (what the paper plots), failures by outcome,
    episodes per hour and the pool's utilisation. A live bar on a TTY, one plain line per update off it.
    The bar counts every episode as it ends (:meth:`episode_ended`, told by the host env), not only
    after each update; the count comes first and the statistics last, so a narrow terminal (80 columns)
    cuts the statistics, never the count."""

    def __init__(self, target: int, episodes: Any, pool: int, metrics: Any, stream: TextIO | None = None,
                 live: bool | None = None, workers: Callable[[], int] | None = None,
                 utilisation: Callable[[], float] | None = None) -> None:
        self.target, self.episodes, self.pool, self.metrics = target, episodes, pool, metrics
        # the pool's live worker count (fewer than ``pool`` once a Ray node is lost for good)
        self.workers = workers or (lambda: pool)
        # the pool's busy share; default: the finished episodes' solver seconds over the run's pool time
        # (an asynchronous batch gives its workers' step seconds: queued steps would count twice here)
        self.utilisation = utilisation or (
            lambda: self.episodes.busy_s() / (self.pool * self.metrics.wall_time_s))
        self.stream = stream if stream is not None else sys.stdout
        self.console = Console(file=self.stream, highlight=False)
        self.live = self.console.is_terminal if live is None else live
        self._progress: Progress | None = None
        self._task = None
        self._ended = 0  # episodes ended since the last update (not in the log yet)

    def __enter__(self) -> EpisodeProgress:
        if self.live:
            self._progress = Progress(
                TextColumn("[bold]{task.description}", table_column=Column(no_wrap=True)),
                MofNCompleteColumn(table_column=Column(no_wrap=True)),
                TextColumn("episodes", table_column=Column(no_wrap=True)), BarColumn(bar_width=16),
                TimeElapsedColumn(), TimeRemainingColumn(),
                TextColumn("{task.fields[stats]}", table_column=Column(no_wrap=True, overflow="ellipsis",
                                                                       ratio=1)),
                console=self.console, expand=True)
            self._progress.start()
            self._task = self._progress.add_task("compiling + first update", total=self.target,
                                                 completed=self.episodes.count, stats="-")
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def stop(self) -> None:
        """End the live bar (idempotent), e.g. before the process leaves on a Ctrl-C."""
        if self._progress is not None:
            self._progress.stop()

    def episode_ended(self) -> None:
        """Count an episode that has just ended (called from the thread that steps the envs); the log
        has it after the update."""
        self._ended += 1
        if self._progress is not None:
            self._progress.update(self._task, description="training",
                                  completed=min(self.episodes.count + self._ended, self.target))

    def stats(self) -> str:
        """The numbers after the episode count, as one short text."""
        wall = self.metrics.wall_time_s
        count = len(self.episodes.rows)
        failed = ", ".join(f"{k} {v}" for k, v in self.episodes.failures().items())
        moving = self.episodes.moving_iterations()
        moving_text = f"{moving:.0f}" if math.isfinite(moving) else "-"
        parts = [f"iterations (last 100) {moving_text}", f"failures: {failed or 'none'}"]
        if (workers := self.workers()) < self.pool:  # first: a narrow terminal cuts the end
            parts.insert(0, f"workers {workers}/{self.pool}")
        if wall > 0:
            parts += [f"{count / wall * 3600:.0f} episodes/h",
                      f"pool {self.utilisation():.0%} busy"]
        return "  ".join(parts)

    def update(self, env_steps: int, steps_per_s: float, mean_return: float, update: int,
               num_updates: int) -> None:
        """Report the state after an update (TrainingProgress's signature; the episode log has the rest)."""
        self._ended = 0  # the update's episodes are in the log now
        count = self.episodes.count
        if self._progress is not None:
            self._progress.update(self._task, description="training", completed=min(count, self.target),
                                  stats=self.stats())
        else:
            self.console.print(f"update {update}  episodes {count}/{self.target}  {self.stats()}",
                               soft_wrap=True)
            self.stream.flush()  # a log file being watched sees every update as it ends
