"""Progress of a CLI command over planned solver runs: a rich bar on a terminal, one plain line per
finished run otherwise (a log or a pipe shows nothing of a live bar until the command ends)."""

from __future__ import annotations

from typing import Any

#: Columns of the output off a terminal (logs, pipes): rich's default of 80 would wrap result tables.
LOG_WIDTH = 120


class RunProgress:
    """``with RunProgress("grid-foam") as progress: progress.step(text, done, total)``. ``stderr``: write
    there (stdout free for the command's result); ``every_line``: on a terminal too, each run's line stays
    above the bar (solve campaigns: a user reads back which case ended how)."""

    def __init__(self, label: str, stderr: bool = False, every_line: bool = False) -> None:
        from rich.console import Console

        self.label = label
        self.every_line = every_line
        self.console = Console(highlight=False, stderr=stderr)
        if not self.console.is_terminal:
            self.console.width = LOG_WIDTH
        self._progress: Any = None
        self._task: Any = None

    def __enter__(self) -> RunProgress:
        if self.console.is_terminal:
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

            columns = (TextColumn(f"[bold]{self.label}"), BarColumn(), MofNCompleteColumn(),
                       TimeElapsedColumn(), TextColumn("{task.description}"))
            self._progress = Progress(*columns, console=self.console)
            self._progress.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self._progress is not None:
            self._progress.stop()

    def say(self, text: str) -> None:
        self.console.print(text, soft_wrap=True)

    def step(self, text: str, done: int, total: int) -> None:
        """Run ``done`` of ``total`` finished; ``text`` says which and how it ended."""
        if self._progress is None or self.every_line:
            self.say(f"[{done}/{total}] {text}")
        if self._progress is None:
            return
        if self._task is None:
            self._task = self._progress.add_task("", total=total)
        self._progress.update(self._task, completed=done, description=f"last: {text}")
