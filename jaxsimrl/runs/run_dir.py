"""The layout of a training run directory and the files in it (everything but the checkpoints).

    RUN_DIR/
      config.json     resolved config: {"env", "seed", "ppo": PPOConfig dict, "jax_version", "devices", ...}
      metrics.jsonl   one JSON object per PPO update (non-finite numbers written as null)
      metrics.csv     the same rows as CSV (non-finite numbers left empty)
      summary.json    totals of the run, rewritten after every chunk
      checkpoints/    orbax checkpoints, one per chunk (see :mod:`jaxsimrl.runs.checkpoint`)

Every write is atomic. The metrics files are rewritten whole after every chunk, *before* the chunk's
checkpoint is saved: a crash in between leaves rows past the last checkpoint, which
:meth:`MetricsLog.load` drops on resume, so the files never miss an update that the checkpoint has.
"""

from __future__ import annotations

import csv
import io
import json
import math
import statistics
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from jaxsimrl.runs.atomic import atomic_write_json, atomic_write_text

CONFIG_FILE = "config.json"
METRICS_JSONL = "metrics.jsonl"
METRICS_CSV = "metrics.csv"
SUMMARY_FILE = "summary.json"
CHECKPOINT_DIR = "checkpoints"
# final_mean_return averages the episodes that ended in this many last updates that had any.
FINAL_RETURN_UPDATES = 5

Row = dict[str, Any]


@dataclass(frozen=True)
class RunDir:
    """Paths of one run directory."""

    path: Path

    @property
    def config(self) -> Path:
        return self.path / CONFIG_FILE

    @property
    def metrics_jsonl(self) -> Path:
        return self.path / METRICS_JSONL

    @property
    def metrics_csv(self) -> Path:
        return self.path / METRICS_CSV

    @property
    def summary(self) -> Path:
        return self.path / SUMMARY_FILE

    @property
    def checkpoints(self) -> Path:
        return self.path / CHECKPOINT_DIR

    @staticmethod
    def check_new(path: str | Path) -> None:
        """Refuse a path for a fresh run that is a file or a non-empty directory (it may hold another
        run); creates nothing."""
        path = Path(path)
        if path.exists() and not path.is_dir():
            raise ValueError(f"--out {path} exists and is not a directory")
        if path.is_dir() and any(path.iterdir()):
            raise ValueError(f"--out {path} is not empty (continue that run with --resume {path})")

    @classmethod
    def create(cls, path: str | Path) -> RunDir:
        """Make a fresh run directory (see :meth:`check_new`)."""
        run = cls(Path(path))
        cls.check_new(run.path)
        try:
            run.path.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise ValueError(f"cannot create --out {run.path}: {err.strerror}") from None
        return run

    @classmethod
    def existing(cls, path: str | Path) -> RunDir:
        """An existing run directory with a readable config.json."""
        run = cls(Path(path))
        if not run.path.exists():
            raise ValueError(f"run directory {run.path} does not exist")
        if not run.path.is_dir():
            raise ValueError(f"run directory {run.path} is not a directory")
        if not run.config.is_file():
            raise ValueError(f"{run.path} is not a run directory (no {CONFIG_FILE})")
        return run

    def write_config(self, record: dict[str, Any]) -> None:
        atomic_write_json(self.config, record)

    def read_config(self) -> dict[str, Any]:
        record = read_json(self.config)
        if not isinstance(record, dict) or not isinstance(record.get("ppo"), dict):
            raise ValueError(f"{self.config} has no 'ppo' section: not a jaxsimrl run config")
        if not isinstance(record.get("seed", 0), int):
            raise ValueError(f"{self.config}: seed must be an integer, got {record['seed']!r}")
        seeds = record.get("seeds", [0])
        if not isinstance(seeds, list) or not seeds or not all(isinstance(seed, int) for seed in seeds):
            raise ValueError(f"{self.config}: seeds must be a non-empty list of integers, got {seeds!r}")
        return record

    def checkpoint_steps(self) -> list[int]:
        """Steps of the checkpoints on disk, oldest first, read without orbax: orbax names a
        checkpoint directory by its step only once the checkpoint is complete."""
        if not self.checkpoints.is_dir():
            return []
        return sorted(int(p.name) for p in self.checkpoints.iterdir() if p.name.isdigit() and p.is_dir())

    def write_summary(self, summary: dict[str, Any]) -> None:
        atomic_write_json(self.summary, _json_safe(summary))


class MetricsLog:
    """The per-update metrics rows of a run, mirrored to metrics.jsonl and metrics.csv."""

    def __init__(self, run: RunDir, rows: Sequence[Row] = ()) -> None:
        self.run = run
        self.rows: list[Row] = [dict(row) for row in rows]

    @classmethod
    def load(cls, run: RunDir, up_to_update: int) -> MetricsLog:
        """Rows of updates 1..``up_to_update`` from metrics.jsonl (later rows and torn or garbled lines are
        dropped)."""
        rows: list[Row] = []
        if run.metrics_jsonl.exists():
            for line in run.metrics_jsonl.read_text(errors="replace").splitlines():
                try:
                    row = json.loads(line)
                except json.JSONDecodeError:
                    continue
                if isinstance(row, dict) and row.get("update", math.inf) <= up_to_update:
                    rows.append({k: math.nan if v is None else v for k, v in row.items()})
        return cls(run, rows)

    def extend(self, rows: Iterable[Row]) -> None:
        """Add rows and rewrite both files atomically."""
        self.rows.extend(dict(row) for row in rows)
        self.write()

    def write(self) -> None:
        safe_rows = [_json_safe(row) for row in self.rows]
        atomic_write_text(self.run.metrics_jsonl, "".join(json.dumps(r) + "\n" for r in safe_rows))
        atomic_write_text(self.run.metrics_csv, _to_csv(safe_rows))

    @property
    def wall_time_s(self) -> float:
        """Training time of the run so far (carried over across resumes)."""
        return float(self.rows[-1]["wall_time_s"]) if self.rows else 0.0

    @property
    def env_steps(self) -> int:
        return int(self.rows[-1]["env_steps"]) if self.rows else 0


def read_json(path: str | Path) -> Any:
    """The JSON value in ``path``; a one-line ValueError if the file cannot be read or is not JSON."""
    try:
        data = Path(path).read_bytes()
    except OSError as err:
        raise ValueError(f"cannot read {path}: {err.strerror}") from None
    try:
        return json.loads(data)
    except ValueError as err:  # JSONDecodeError, or UnicodeDecodeError for a binary file
        raise ValueError(f"{path} is not valid JSON: {err}") from None


def rows_with_episodes(rows: Sequence[Row]) -> list[Row]:
    """The rows of the updates in which at least one episode ended (a finite mean_episode_return)."""
    return [r for r in rows if r.get("episodes", 0) > 0 and math.isfinite(r["mean_episode_return"])]


def summarise(rows: Sequence[Row], extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """summary.json: totals plus ``final_mean_return``, the episode-weighted mean return over the last
    ``FINAL_RETURN_UPDATES`` updates in which at least one episode ended (NaN if none did)."""
    total_steps = int(rows[-1]["env_steps"]) if rows else 0
    wall = float(rows[-1]["wall_time_s"]) if rows else 0.0
    with_episodes = rows_with_episodes(rows)
    window = with_episodes[-FINAL_RETURN_UPDATES:]
    episodes = sum(int(r["episodes"]) for r in window)
    final = sum(r["mean_episode_return"] * r["episodes"] for r in window) / episodes if episodes else math.nan
    summary = {
        "total_steps": total_steps,
        "updates": int(rows[-1]["update"]) if rows else 0,
        "wall_time_s": wall,
        "steps_per_s": total_steps / wall if wall > 0 else math.nan,
        # Per-chunk rates without the first chunk's compilation dominating: the steady-state speed.
        "median_chunk_steps_per_s": statistics.median(r["steps_per_s"] for r in rows) if rows else math.nan,
        "final_mean_return": final,
        "final_return_episodes": episodes,
        "final_return_updates": [int(r["update"]) for r in window],
        "best_mean_return": max((r["mean_episode_return"] for r in with_episodes), default=math.nan),
    }
    summary.update(extra or {})
    return summary


def agent_rows(rows: Sequence[Row]) -> dict[int, list[Row]]:
    """The rows of a batch run (with an ``agent`` column) split by agent, in agent order."""
    split: dict[int, list[Row]] = {}
    for row in rows:
        split.setdefault(int(row["agent"]), []).append(row)
    return dict(sorted(split.items()))


# Per-agent entries of a batch's summary.json; the other entries are the same for every agent.
_AGENT_KEYS = ("final_mean_return", "final_return_episodes", "final_return_updates", "best_mean_return")


def summarise_agents(rows: Sequence[Row], extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """summary.json of a batch of agents: the totals of :func:`summarise` (shared by the agents; steps are
    per agent, ``all_agents_steps_per_s`` counts them all), ``agents`` with each agent's returns (and its
    seed and swept values, from ``extra["seeds"]`` and ``extra["sweep"]``), and across agents the mean
    of their final and best returns and ``final_mean_return_agents``: count (agents with a finite final
    return), mean, median, min, max."""
    extra = dict(extra or {})
    split = agent_rows(rows)
    seeds = extra.get("seeds") or list(split)
    sweep = extra.get("sweep", {})
    agents = []
    for agent, own in split.items():
        full = summarise(own)
        swept = {name: values[agent] for name, values in sweep.items()}
        returns = {key: full[key] for key in _AGENT_KEYS}
        agents.append({"agent": agent, "seed": seeds[agent], **swept, **returns})
    summary = summarise(next(iter(split.values()), []), extra)
    for key in _AGENT_KEYS[1:3]:
        summary.pop(key)  # no single agent's episodes stand for the batch
    finals = [a["final_mean_return"] for a in agents if math.isfinite(a["final_mean_return"])]
    bests = [a["best_mean_return"] for a in agents if math.isfinite(a["best_mean_return"])]
    summary.update(
        num_agents=len(agents), agents=agents,
        all_agents_steps_per_s=summary["steps_per_s"] * len(agents),
        final_mean_return=statistics.fmean(finals) if finals else math.nan,
        best_mean_return=statistics.fmean(bests) if bests else math.nan,
        final_mean_return_agents=spread(finals))
    return summary


def spread(values: Sequence[float]) -> dict[str, Any]:
    """count, mean, median, min and max of ``values`` (NaN when empty)."""
    if not values:
        return {"count": 0, **dict.fromkeys(("mean", "median", "min", "max"), math.nan)}
    return {"count": len(values), "mean": statistics.fmean(values), "median": statistics.median(values),
            "min": min(values), "max": max(values)}


def _json_safe(value: Any) -> Any:
    """Non-finite floats become null: metrics.jsonl and summary.json stay strict JSON."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    return value


def _to_csv(rows: Sequence[Row]) -> str:
    if not rows:
        return ""
    columns = list(rows[0])
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, lineterminator="\n", extrasaction="ignore")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: "" if row.get(k) is None else row.get(k) for k in columns})
    return buffer.getvalue()
