"""episodes.csv of a train-foam run: one row per finished episode, and its statistics.

The columns and their codec are foam_bridge._records' (:class:`foam_bridge._records.EpisodeRecord`, one row
of the file); this log numbers the rows and keeps the file. ``update`` is the PPO update whose rollout
the episode ended in (1-based). The file is rewritten whole and atomically after every update, before
that update's checkpoint; on resume from checkpoint N the rows of updates after N are dropped (the same
rule as the metrics files), so a run killed anywhere has no torn and no duplicate row. ``node`` is where
the episode ran (foam_bridge's Backend.node_of: the host name, or a Ray node's "IP/NODE"; empty in files
written before it existed, and for an episode no node ran).
"""

from __future__ import annotations

import math
import statistics
from collections import Counter
from pathlib import Path
from typing import Any

from foam_bridge import COLUMNS, FAILURES, EpisodeRecord, read_rows, rows_to_csv
from jaxsimrl.evaluation.curves import MOVING_WINDOW
from jaxsimrl.runs.atomic import atomic_write_text

__all__ = ["COLUMNS", "EPISODES_FILE", "MOVING_WINDOW", "SYSTEMATIC_MIN_EPISODES", "EpisodeLog"]

EPISODES_FILE = "episodes.csv"
#: EpisodeLog.systematic_failure needs at least this many episodes (and at least one per env).
SYSTEMATIC_MIN_EPISODES = 3


class EpisodeLog:
    """The finished episodes of a run (``rows``) mirrored to ``RUN_DIR/episodes.csv``."""

    def __init__(self, path: Path, rows: list[dict[str, Any]] | None = None) -> None:
        self.path = Path(path)
        self.rows: list[dict[str, Any]] = rows or []
        self.pending: list[dict[str, Any]] = []  # ended since the last flush

    @classmethod
    def load(cls, path: Path, up_to_update: int) -> EpisodeLog:
        """The rows of updates 1..``up_to_update`` of an existing file (garbled rows are dropped)."""
        text = Path(path).read_text(errors="replace") if Path(path).is_file() else ""
        return cls(path, [row for row in read_rows(text) if row["update"] <= up_to_update])

    def add(self, env_id: int, update: int, info: dict[str, Any]) -> None:
        """Record an episode that ended in ``update`` from its final info (kept in memory until
        :meth:`flush`)."""
        self.pending.append(EpisodeRecord.from_info(info).row(env_id, update))

    @property
    def count(self) -> int:
        """Episodes ended so far, those of the update in flight included."""
        return len(self.rows) + len(self.pending)

    def flush(self) -> list[dict[str, Any]]:
        """Append the pending episodes and rewrite the file atomically; returns the new rows."""
        new, self.pending = self.pending, []
        for row in new:
            row["index"] = len(self.rows)
            self.rows.append(row)
        atomic_write_text(self.path, rows_to_csv(self.rows))
        return new

    def discard_pending(self) -> None:
        """Forget episodes of an update that will not be saved (its call failed)."""
        self.pending = []

    # ---- statistics -----------------------------------------------------------------------------
    def moving_iterations(self, window: int = MOVING_WINDOW) -> float:
        """Mean iterations of the last ``window`` episodes (NaN before the first)."""
        return self.moving_mean("iterations", window)

    def moving_mean(self, column: str, window: int = MOVING_WINDOW) -> float:
        """Mean of a numeric column over the last ``window`` episodes (NaN before the first, or if a row
        lacks it)."""
        last = self.rows[-window:]
        return statistics.fmean(float(r[column]) for r in last) if last else math.nan

    def outcomes(self) -> dict[str, int]:
        """Episodes per outcome."""
        return dict(Counter(r["outcome"] for r in self.rows))

    def failures(self) -> dict[str, int]:
        """Episodes per failure outcome (foam_bridge's crashed, diverged, hung), in that order."""
        counts = self.outcomes()
        return {name: counts[name] for name in FAILURES if counts.get(name)}

    def systematic_failure(self, num_envs: int) -> str | None:
        """The failure every episode of the run has ended in, if it is one and the same, else None.

        The rule: at least max(num_envs, SYSTEMATIC_MIN_EPISODES) episodes have ended (every env has
        had its chance), no episode ever ended well, and all failed with one outcome and cause at one
        iteration count. A case or setup that cannot run fails that way on every episode whatever the
        actions; a policy that makes the solver blow up does not (its failures come at different
        iterations, and some episodes survive). Returns "at iteration K: <cause>".
        """
        if len(self.rows) < max(num_envs, SYSTEMATIC_MIN_EPISODES):
            return None
        ways = {(r["outcome"], r["iterations"], r["cause"]) for r in self.rows}
        if len(ways) != 1:
            return None
        outcome, iterations, cause = ways.pop()
        return f"at iteration {iterations}: {cause or outcome}" if outcome in FAILURES else None

    def busy_s(self) -> float:
        """Solver-busy seconds of the finished episodes (episode wall time less waiting on the bridge)."""
        return sum(max(r["wall_time_s"] - r["solver_idle_s"], 0.0) for r in self.rows
                   if math.isfinite(r["wall_time_s"]) and math.isfinite(r["solver_idle_s"]))
