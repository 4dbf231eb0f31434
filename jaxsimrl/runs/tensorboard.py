"""TensorBoard event files of a run's metrics rows, written with tensorboardX (no TensorFlow).

Every numeric, finite column of a metrics row becomes the scalar ``train/<column>`` at the row's
``env_steps``. The files go to RUN_DIR/tensorboard/ (``tensorboard --logdir RUN_DIR``); a resumed run
adds a new event file there, continuing the same curves.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterable, Iterator
from pathlib import Path

from jaxsimrl.runs.run_dir import Row

TENSORBOARD_DIR = "tensorboard"
_STEP_COLUMNS = ("env_steps",)


class TensorBoardWriter:
    """Appends metrics rows to the event files in ``log_dir``."""

    def __init__(self, log_dir: str | Path) -> None:
        from tensorboardX import SummaryWriter  # imported here: only runs given --tensorboard need it

        self.log_dir = Path(log_dir)
        self._writer = SummaryWriter(logdir=str(self.log_dir))

    def write_rows(self, rows: Iterable[Row]) -> None:
        for row in rows:
            step = int(row["env_steps"])
            # a batch's agents share the steps: each gets curves of its own
            prefix = f"train/agent-{row['agent']}" if "agent" in row else "train"
            for name, value in row.items():
                if name not in _STEP_COLUMNS and name != "agent" and _is_scalar(value):
                    self._writer.add_scalar(f"{prefix}/{name}", float(value), global_step=step)
        self._writer.flush()  # a chunk is minutes apart: make it visible now

    def close(self) -> None:
        self._writer.close()


@contextlib.contextmanager
def tensorboard_log(run_path: str | Path, enabled: bool) -> Iterator[TensorBoardWriter | None]:
    """A writer into RUN_DIR/tensorboard/ for the block, or None when not ``enabled``."""
    if not enabled:
        yield None
        return
    writer = TensorBoardWriter(Path(run_path) / TENSORBOARD_DIR)
    try:
        yield writer
    finally:
        writer.close()


def _is_scalar(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
