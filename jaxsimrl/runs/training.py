"""The chunked training loop over a run directory: train a chunk, record it, checkpoint it, repeat.

Any trainer with ``run_chunk(state) -> (state, metrics)`` and ``num_updates`` works (see
:mod:`jaxsimrl.agents.ppo`). After every chunk, in this order and with Ctrl-C held back from the start
of the chunk until all three are on disk: the metrics rows, the checkpoint (named by the number of
updates done) and summary.json. A run interrupted anywhere therefore resumes from a checkpoint whose
updates all have metrics rows, and :meth:`MetricsLog.load` drops the rows of a chunk whose checkpoint
never landed.
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import jax
import numpy as np

from jaxsimrl.runs.checkpoint import Checkpoints
from jaxsimrl.runs.run_dir import MetricsLog, Row, RunDir, rows_with_episodes, summarise
from jaxsimrl.runs.signals import STOP_SIGNALS, interrupt_for

ChunkHook = Callable[[int], None]
StopTest = Callable[[], bool]
#: Called at once with the number of stop signals (Ctrl-C, SIGTERM) received during a chunk (1, 2, ...)
#: and the signal; see interrupts_deferred.
InterruptHook = Callable[[int, int], None]


@contextlib.contextmanager
def interrupts_deferred(on_interrupt: InterruptHook | None = None) -> Iterator[None]:
    """Hold SIGINT and SIGTERM back until the block is done, then raise KeyboardInterrupt (Terminated
    if one was SIGTERM: jaxsimrl.runs.signals); main thread only.

    ``on_interrupt(count, signum)`` is called at once for every such signal, from a thread of its own:
    the main thread may be inside a jitted call, where Python runs no signal handler until the call returns
    (the signal's byte arrives through ``signal.set_wakeup_fd``). It may end the process there (a host
    env whose solvers must not run on to the end of the chunk)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []
    previous = {signum: signal.signal(signum, lambda signum, frame: received.append(signum))
                for signum in STOP_SIGNALS}
    try:
        with _interrupt_watcher(on_interrupt):
            yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    if received:
        raise interrupt_for(received)


@contextlib.contextmanager
def _interrupt_watcher(on_interrupt: InterruptHook | None) -> Iterator[None]:
    """A thread that calls ``on_interrupt`` as soon as the C-level signal handler writes a stop signal's
    byte to the wakeup pipe (nothing without a hook)."""
    if on_interrupt is None:
        yield
        return
    read_fd, write_fd = os.pipe()
    os.set_blocking(write_fd, False)  # the signal handler must never block on it

    def watch() -> None:
        count = 0
        while data := os.read(read_fd, 64):  # b"" once write_fd is closed
            for signum in data:
                if signum in STOP_SIGNALS:
                    count += 1
                    on_interrupt(count, signum)

    watcher = threading.Thread(target=watch, name="interrupt-watcher", daemon=True)
    watcher.start()
    old_fd = signal.set_wakeup_fd(write_fd, warn_on_full_buffer=False)
    try:
        yield
    finally:
        signal.set_wakeup_fd(old_fd)
        os.close(write_fd)
        watcher.join(timeout=5)
        os.close(read_fd)


def chunk_rows(metrics: dict[str, Any], first_update: int, count: int, steps_before: int,
               wall_before: float, chunk_time: float) -> list[Row]:
    """One row per update of a chunk. The chunk runs as one jitted call, so its time is shared evenly
    between its updates: ``wall_time_s`` is interpolated and ``steps_per_s`` is the chunk's rate."""
    host = {name: np.asarray(value)[:count] for name, value in metrics.items()}
    rate = (int(host["env_steps"][-1]) - steps_before) / chunk_time if chunk_time > 0 else math.nan
    rows = []
    for i in range(count):
        row: Row = {"update": first_update + i, "env_steps": int(host["env_steps"][i]),
                    "wall_time_s": wall_before + chunk_time * (i + 1) / count, "steps_per_s": rate}
        row.update({name: _scalar(values[i]) for name, values in host.items() if name != "env_steps"})
        rows.append(row)
    return rows


def agent_chunk_rows(metrics: dict[str, Any], first_update: int, count: int, steps_before: int,
                     wall_before: float, chunk_time: float) -> list[Row]:
    """The rows of a batch of agents' chunk (metrics shaped (updates, agents)): :func:`chunk_rows` of each
    agent with an ``agent`` column, ordered by update, then agent."""
    host = {name: np.asarray(value) for name, value in metrics.items()}
    agents = range(host["env_steps"].shape[1])
    per_agent = [chunk_rows({name: values[:, agent] for name, values in host.items()}, first_update, count,
                            steps_before, wall_before, chunk_time) for agent in agents]
    return [{"update": row["update"], "agent": agent, **row}
            for update_rows in zip(*per_agent, strict=True) for agent, row in enumerate(update_rows)]


def _scalar(value: np.ndarray) -> int | float:
    return int(value) if np.issubdtype(value.dtype, np.integer) else float(value)


def latest_return(rows: list[Row]) -> float:
    """The mean episode return of the newest update in which an episode ended (NaN if none); for a batch
    of agents, the mean over the agents with an ending episode in that update."""
    ended = rows_with_episodes(rows)
    if not ended:
        return math.nan
    newest = [float(row["mean_episode_return"]) for row in ended if row["update"] == ended[-1]["update"]]
    return sum(newest) / len(newest)


@dataclass
class Session:
    """Everything a training loop writes to besides the state itself."""

    run: RunDir
    trainer: Any  # has run_chunk(state) -> (state, metrics) and num_updates
    log: MetricsLog
    checkpoints: Checkpoints
    meta: dict[str, Any]  # JSON stored with every checkpoint (the run's config record)
    summary_extra: dict[str, Any] = field(default_factory=dict)  # copied into summary.json
    # Called with the updates done after a chunk's metrics rows are written and before its checkpoint:
    # where other per-update records (a host env's episodes.csv) are written under the same rule.
    before_checkpoint: ChunkHook | None = None
    # Further summary.json entries computed after every chunk (may override "complete").
    summary_hook: Callable[[dict[str, Any]], dict[str, Any]] | None = None
    tensorboard: Any = None  # a TensorBoardWriter (runs/tensorboard.py) that gets the rows too, or None
    # More JSON for each checkpoint's record, computed when it is saved (a host env's running episodes).
    checkpoint_meta: Callable[[], dict[str, Any]] | None = None
    # summary.json from the rows: run_dir.summarise for one agent, run_dir.summarise_agents for a batch.
    summarise_rows: Callable[[list[Row], dict[str, Any]], dict[str, Any]] = summarise

    def write_summary(self) -> dict[str, Any]:
        """Write summary.json from the metrics rows so far and return it."""
        num_updates = self.trainer.num_updates
        summary = self.summarise_rows(self.log.rows, {**self.summary_extra, "num_updates": num_updates})
        summary["complete"] = summary["updates"] >= num_updates
        if self.summary_hook is not None:
            summary.update(self.summary_hook(summary))
        self.run.write_summary(summary)
        return summary


def _run_and_save(session: Session, state: Any, done: int) -> tuple[Any, int, list[Row]]:
    """One chunk: train it, then write its metrics rows, checkpoint and summary."""
    trainer, log = session.trainer, session.log
    started = time.perf_counter()
    state, metrics = trainer.run_chunk(state)
    metrics = jax.device_get(metrics)  # waits for the chunk, so the timing below is honest
    chunk_time = time.perf_counter() - started
    count = min(len(metrics["env_steps"]), trainer.num_updates - done)
    # one agent's metrics are (updates,); a batch's (updates, agents)
    to_rows = chunk_rows if np.ndim(metrics["env_steps"]) == 1 else agent_chunk_rows
    rows = to_rows(metrics, done + 1, count, log.env_steps, log.wall_time_s, chunk_time)
    done += count
    log.extend(rows)
    if session.tensorboard is not None:
        session.tensorboard.write_rows(rows)
    if session.before_checkpoint is not None:
        session.before_checkpoint(done)
    extra = session.checkpoint_meta() if session.checkpoint_meta is not None else {}
    meta = {**session.meta, **extra, "update": done, "env_steps": log.env_steps,
            "wall_time_s": log.wall_time_s}
    session.checkpoints.save(done, state, meta)
    session.write_summary()
    return state, done, rows


def train(session: Session, state: Any, done: int, progress: Any, on_chunk: ChunkHook | None = None,
          until: StopTest | None = None, on_interrupt: InterruptHook | None = None) -> Any:
    """Run chunks from ``done`` updates until ``trainer.num_updates`` (or until ``until()`` is true);
    returns the final state. ``progress`` is a TrainingProgress or anything with its ``update``.

    ``on_chunk(updates_done)`` is called after each chunk is on disk (tests use it to stop a run at a
    chosen point, as a crash would). ``on_interrupt(count, signum)`` is told of each Ctrl-C or SIGTERM
    during a chunk at once (see :func:`interrupts_deferred`).
    """
    trainer, log = session.trainer, session.log
    while done < trainer.num_updates and not (until is not None and until()):
        # Ctrl-C and SIGTERM are held back for the whole chunk: a jitted call cannot be interrupted
        # anyway (the signal waits until it returns), and this way the chunk in flight is saved, not
        # dropped, unless on_interrupt ends the process first.
        with interrupts_deferred(on_interrupt):
            state, done, rows = _run_and_save(session, state, done)
        progress.update(log.env_steps, rows[-1]["steps_per_s"], latest_return(log.rows), done,
                        trainer.num_updates)
        if on_chunk is not None:
            on_chunk(done)
    return state
