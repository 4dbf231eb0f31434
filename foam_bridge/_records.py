"""EpisodeRecord: what one finished episode of a foam env was, and its one codec.

A FoamCaseEnv builds it when an episode ends; a BatchedFoamEnv builds it for an episode its env could
not report (a worker that died, a reset that failed). Both hand it out as ``info["episode"]``, a plain
dict (:meth:`EpisodeRecord.to_json`: gymnasium batches infos key by key, and the dict travels between
processes as is); :meth:`EpisodeRecord.from_info` reads it back from an episode's final info.

The same record is one row of a training run's episodes.csv (:data:`COLUMNS`; :meth:`EpisodeRecord.row`
gives the typed row, :func:`parse_row` and :func:`rows_to_csv` read and write the text):

    index, env, update, seed, inlet_velocity, steps, iterations, linear_iterations, solver_time_s, return,
    outcome, cause, wall_time_s, solver_idle_s, actions, node, step_height

``index``, ``env`` and ``update`` say where the row sits in a run (the trainer's numbering); ``actions``
is the JSON list of the factors taken, rounded to 6 decimals. A number the episode has not got (the
step height of a user's case, the costs of an episode whose worker died) is NaN, an empty cell in the
file; files written before ``linear_iterations``, ``solver_time_s``, ``step_height`` and ``node``
existed read as NaN (or "") there.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

COLUMNS = ("index", "env", "update", "seed", "inlet_velocity", "steps", "iterations", "linear_iterations",
           "solver_time_s", "return", "outcome", "cause", "wall_time_s", "solver_idle_s", "actions", "node",
           "step_height", "case")
#: Float columns; an empty cell reads as NaN.
_FLOATS = ("inlet_velocity", "linear_iterations", "solver_time_s", "return", "wall_time_s", "solver_idle_s",
           "step_height")
#: Columns that files of older versions lack (read as NaN there).
_ADDED_LATER = ("linear_iterations", "solver_time_s", "step_height")


@dataclass
class EpisodeRecord:
    """One finished episode (see the module docstring). ``linear_iterations`` and ``solver_time_s`` are
    the solver's other costs (what its log says; NaN where it said nothing); ``wall_time_s`` and
    ``solver_idle_s`` its time in all and waiting on the bridge. ``env_id``, ``node`` and
    ``confirmations`` are only known in some places; None leaves them out of the JSON."""

    outcome: str = ""
    cause: str = ""
    iterations: int = 0
    seed: int | None = None
    inlet_velocity: float = math.nan
    step_height: float = math.nan
    actions: list[list[float]] = field(default_factory=list)
    episode_return: float = math.nan
    linear_iterations: float = math.nan
    solver_time_s: float = math.nan
    wall_time_s: float = math.nan
    solver_idle_s: float = 0.0
    residuals: dict[str, float] = field(default_factory=dict)
    env_id: int | None = None
    node: str | None = None
    confirmations: list[dict[str, Any]] | None = None
    case: str | None = None  # which case of a family (foam_bridge._family_env)

    @property
    def steps(self) -> int:
        """Actions taken (one per step)."""
        return len(self.actions)

    # ---- JSON: info["episode"] --------------------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        """The record as ``info["episode"]`` (the optional entries only where known)."""
        out: dict[str, Any] = {
            "outcome": self.outcome, "cause": self.cause, "iterations": int(self.iterations),
            "seed": self.seed, "inlet_velocity": float(self.inlet_velocity),
            "step_height": float(self.step_height), "actions": [list(a) for a in self.actions],
            "return": float(self.episode_return), "steps": self.steps,
            # floats always (a solver's count is an int): batched infos type a key by its first env
            "linear_iterations": float(self.linear_iterations), "solver_time_s": float(self.solver_time_s),
            "wall_time_s": float(self.wall_time_s), "solver_idle_s": float(self.solver_idle_s),
            "residuals": dict(self.residuals)}
        for name in ("env_id", "node", "confirmations", "case"):
            if getattr(self, name) is not None:
                out[name] = getattr(self, name)
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> EpisodeRecord:
        """The record of an ``info["episode"]`` dict; what it lacks takes the defaults."""
        names = ("outcome", "cause", "iterations", "seed", "inlet_velocity", "step_height",
                 "linear_iterations", "solver_time_s", "wall_time_s", "solver_idle_s", "residuals", "env_id",
                 "node", "confirmations", "case")
        values = {name: data[name] for name in names if data.get(name) is not None}
        return cls(**values, actions=[list(a) for a in data.get("actions", [])],
                   episode_return=_number(data.get("return")))

    @classmethod
    def from_info(cls, info: Mapping[str, Any]) -> EpisodeRecord:
        """The record of an episode's final info: its ``"episode"`` entry, else (a host batch without
        records) what the info itself says of the end."""
        record = info.get("episode")
        if isinstance(record, Mapping):
            return cls.from_json(record)
        return cls(outcome=str(info.get("outcome", "")), cause=str(info.get("cause", "")),
                   iterations=int(info.get("iterations", 0)))

    # ---- episodes.csv ------------------------------------------------------------------------------
    def row(self, env: int, update: int, index: int | None = None) -> dict[str, Any]:
        """The typed episodes.csv row of this episode (``index`` is set when the row joins a file)."""
        actions = [[round(float(a), 6) for a in pair] for pair in self.actions]
        row = {"env": int(env), "update": int(update), "seed": self.seed,
               "inlet_velocity": _number(self.inlet_velocity), "steps": len(actions),
               "step_height": _number(self.step_height), "iterations": int(self.iterations),
               "linear_iterations": _number(self.linear_iterations),
               "solver_time_s": _number(self.solver_time_s), "return": _number(self.episode_return),
               "outcome": str(self.outcome), "cause": str(self.cause),
               "wall_time_s": _number(self.wall_time_s), "solver_idle_s": _number(self.solver_idle_s),
               "actions": actions, "node": str(self.node or ""), "case": str(self.case or "")}
        return row if index is None else {"index": int(index), **row}

    @classmethod
    def from_row(cls, row: Mapping[str, Any]) -> EpisodeRecord:
        """The record of a typed row (:func:`parse_row`); the residuals are not in the file."""
        return cls(outcome=row["outcome"], cause=row["cause"], iterations=row["iterations"], seed=row["seed"],
                   inlet_velocity=row["inlet_velocity"], step_height=row["step_height"],
                   actions=[list(a) for a in row["actions"]], episode_return=row["return"],
                   linear_iterations=row["linear_iterations"], solver_time_s=row["solver_time_s"],
                   wall_time_s=row["wall_time_s"], solver_idle_s=row["solver_idle_s"], node=row["node"],
                   case=row.get("case") or None)


def parse_row(raw: Mapping[str, str]) -> dict[str, Any] | None:
    """The typed row of one csv.DictReader row; None if it is garbled (a torn or foreign line)."""
    try:
        row: dict[str, Any] = {"index": int(raw["index"]), "env": int(raw["env"]),
                               "update": int(raw["update"]),
                               "seed": int(raw["seed"]) if raw["seed"] not in ("", "None") else None,
                               "steps": int(raw["steps"]), "iterations": int(raw["iterations"]),
                               "outcome": raw["outcome"], "cause": raw["cause"],
                               "actions": json.loads(raw["actions"]),
                               "node": raw.get("node") or "",  # older files lack it
                               "case": raw.get("case") or ""}  # and this
        for name in _FLOATS:
            text = raw.get(name, "") if name in _ADDED_LATER else raw[name]
            row[name] = float(text) if text != "" else math.nan  # a short row's None: TypeError, dropped
    except (KeyError, TypeError, ValueError):
        return None
    return row


def rows_to_csv(rows: Iterable[Mapping[str, Any]]) -> str:
    """The text of an episodes.csv holding ``rows`` (typed rows with their index)."""
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


def read_rows(text: str) -> list[dict[str, Any]]:
    """The typed rows of an episodes.csv's text, garbled ones dropped."""
    rows = (parse_row(raw) for raw in csv.DictReader(io.StringIO(text)))
    return [row for row in rows if row is not None]


def _number(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan
