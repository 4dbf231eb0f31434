"""episodes.csv: one row per finished episode of a host-env (OpenFOAM) training run, and its statistics.

    index, env, update, seed, inlet_velocity, steps, iterations, linear_iterations, solver_time_s, return,
    outcome, cause, wall_time_s, solver_idle_s, actions, node, step_height

``update`` is the PPO update whose rollout the episode ended in (1-based); ``actions`` is the JSON list of
the factors it took ((alpha_u, alpha_p) pairs, or triples with alpha_t). ``step_height`` is the episode's
step height in m (drawn per episode with a range of heights; empty for a user's case and in files
written before it existed). ``linear_iterations`` (inner iterations of every linear solve) and
``solver_time_s`` (the solver's CPU seconds) are the episode's other costs whatever the run's reward (empty
in files written before they existed). The file is rewritten whole and atomically after every update,
before that update's checkpoint; on resume from checkpoint N the rows of updates after N are dropped (the
same rule as the metrics files), so a run killed anywhere has no torn and no duplicate row. ``node`` is
where the episode ran (foam_bridge's Backend.node_of: the host name, or a Ray node's "IP/NODE"; empty in
files written before it existed, and for an episode no node ran).
"""

from __future__ import annotations

import csv
import io
import json
import math
import statistics
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

from jaxsimrl.runs.atomic import atomic_write_text

EPISODES_FILE = "episodes.csv"
COLUMNS = ("index", "env", "update", "seed", "inlet_velocity", "steps", "iterations", "linear_iterations",
           "solver_time_s", "return", "outcome", "cause", "wall_time_s", "solver_idle_s", "actions", "node",
           "step_height")
#: Float columns; an empty cell reads as NaN.
_FLOATS = ("inlet_velocity", "linear_iterations", "solver_time_s", "return", "wall_time_s", "solver_idle_s",
           "step_height")
#: Columns that files of older versions lack (read as NaN there).
_ADDED_LATER = ("linear_iterations", "solver_time_s", "step_height")
#: The paper plots the moving average of iterations to converge over this many episodes.
MOVING_WINDOW = 100
#: EpisodeLog.systematic_failure needs at least this many episodes (and at least one per env).
SYSTEMATIC_MIN_EPISODES = 3


def episode_row(env_id: int, update: int, info: dict[str, Any]) -> dict[str, Any]:
    """A row from a host batch's final info of an ended episode (its "episode" record)."""
    record = info.get("episode", {})
    actions = [[round(float(a), 6) for a in pair] for pair in record.get("actions", [])]
    return {"env": int(env_id), "update": int(update), "seed": record.get("seed"),
            "inlet_velocity": _number(record.get("inlet_velocity")), "steps": len(actions),
            "step_height": _number(record.get("step_height")),
            "iterations": int(record.get("iterations", info.get("iterations", 0))),
            "linear_iterations": _number(record.get("linear_iterations")),
            "solver_time_s": _number(record.get("solver_time_s")),
            "return": _number(record.get("return")),
            "outcome": str(record.get("outcome", info.get("outcome", ""))),
            "cause": str(record.get("cause", info.get("cause", ""))),
            "wall_time_s": _number(record.get("wall_time_s")),
            "solver_idle_s": _number(record.get("solver_idle_s", 0.0)), "actions": actions,
            "node": str(record.get("node") or "")}


def _number(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


class EpisodeLog:
    """The finished episodes of a run (``rows``) mirrored to ``RUN_DIR/episodes.csv``."""

    def __init__(self, path: Path, rows: list[dict[str, Any]] | None = None) -> None:
        self.path = Path(path)
        self.rows: list[dict[str, Any]] = rows or []
        self.pending: list[dict[str, Any]] = []  # ended since the last flush
        self.on_add: Callable[[], None] | None = None  # told of every episode as it ends (a progress bar)

    @classmethod
    def load(cls, path: Path, up_to_update: int) -> EpisodeLog:
        """The rows of updates 1..``up_to_update`` of an existing file (garbled rows are dropped)."""
        rows = []
        if Path(path).is_file():
            for raw in csv.DictReader(io.StringIO(Path(path).read_text(errors="replace"))):
                row = _parse(raw)
                if row is not None and row["update"] <= up_to_update:
                    rows.append(row)
        return cls(path, rows)

    def add(self, env_id: int, update: int, info: dict[str, Any]) -> None:
        """Record an ended episode (kept in memory until :meth:`flush`)."""
        self.pending.append(episode_row(env_id, update, info))
        if self.on_add is not None:
            self.on_add()

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
        atomic_write_text(self.path, _to_csv(self.rows))
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
        from foam_bridge.env import FAILURES

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
        from foam_bridge.env import FAILURES

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


def _parse(raw: dict[str, str]) -> dict[str, Any] | None:
    try:
        row: dict[str, Any] = {"index": int(raw["index"]), "env": int(raw["env"]),
                               "update": int(raw["update"]),
                               "seed": int(raw["seed"]) if raw["seed"] not in ("", "None") else None,
                               "steps": int(raw["steps"]), "iterations": int(raw["iterations"]),
                               "outcome": raw["outcome"], "cause": raw["cause"],
                               "actions": json.loads(raw["actions"]),
                               "node": raw.get("node") or ""}  # older files lack it
        for name in _FLOATS:
            text = raw.get(name, "") if name in _ADDED_LATER else raw[name]
            row[name] = float(text) if text != "" else math.nan  # a short row's None: TypeError, dropped
    except (KeyError, TypeError, ValueError):
        return None
    return row


def _to_csv(rows: list[dict[str, Any]]) -> str:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=COLUMNS, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        out = {k: "" if isinstance(row[k], float) and not math.isfinite(row[k]) else row[k]
               for k in COLUMNS}
        out["actions"] = json.dumps(row["actions"])
        out["seed"] = "" if row["seed"] is None else row["seed"]
        writer.writerow(out)
    return buffer.getvalue()
