"""Replaying running episodes into a new foam batch: the half of FoamBatchCore that a resume needs.

A batch's solvers do not survive its process, but the solver is deterministic: an episode is its reset
seed and the actions taken since. So a snapshot keeps, per env, that seed and those actions (with K,
the return and the last observation, to check the replay) and the env's seed stream; the replay resets
each env with its seed, steps the same actions, checks, and restores the streams.
BatchedFoamEnv (lock-step) and foam_bridge._async_batch.AsyncFoamEnv both build their snapshot/replay
on :class:`EpisodeReplay`; the asynchronous batch also keeps the results in flight
(:func:`json_ready`, :func:`from_json`).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from foam_bridge._backends import WORKER_DIED

__all__ = ["EpisodeReplay", "from_json", "json_ready"]


class EpisodeReplay:
    """Snapshot and replay of the running episodes, mixed into FoamBatchCore (it uses the batch's
    ``_tallies``, ``_streams``, ``run_resets`` and ``run_steps``)."""

    def _episode_entry(self, env_id: int) -> dict[str, Any]:
        """Env ``env_id``'s running episode as JSON-ready data: its reset seed, the actions taken, K,
        return and last observation, whether it has one ("running"), and the env's seed stream."""
        tally = self._tallies[env_id]
        return {"seed": tally.seed, "actions": [list(pair) for pair in tally.actions],
                "iterations": tally.iterations, "return": tally.episode_return,
                "obs": [float(v) for v in tally.obs], "running": tally.seed is not None
                and not tally.reset_failure, "stream": json.dumps(self._streams[env_id].bit_generator.state)}

    def _replay_episodes(self, entries: dict[int, dict[str, Any]]) -> str:
        """Bring the envs of ``entries`` (env -> :meth:`_episode_entry`) to their episodes: reset, step,
        check. Returns "" when every one matches, else why not."""
        if not entries:
            return ""
        return self._replay_resets(entries) or self._replay_steps(entries) or self._replay_differs(entries)

    def _restore_streams(self, entries: list[dict[str, Any]]) -> None:
        for stream, entry in zip(self._streams, entries, strict=True):
            stream.bit_generator.state = json.loads(entry["stream"])

    def _replay_resets(self, entries: dict[int, dict[str, Any]]) -> str:
        _, failures = self.run_resets({i: int(entry["seed"]) for i, entry in entries.items()}, {})
        if not failures:
            return ""
        env_id = min(failures)
        return f"env {env_id}: reset failed: {failures[env_id].error or WORKER_DIED}"

    def _replay_steps(self, entries: dict[int, dict[str, Any]]) -> str:
        for step in range(max(len(entry["actions"]) for entry in entries.values())):
            due = {i: np.asarray(e["actions"][step], np.float64) for i, e in entries.items()
                   if len(e["actions"]) > step}
            results, _ = self.run_steps(due)
            for env_id, (_, _, terminated, truncated, _) in sorted(results.items()):
                if terminated or truncated:
                    return f"env {env_id}: its episode ended at replayed step {step + 1}"
        return ""

    def _replay_differs(self, entries: dict[int, dict[str, Any]]) -> str:
        for i, entry in entries.items():
            tally = self._tallies[i]
            expected = (entry["iterations"], entry["return"], np.float32(entry["obs"]).tolist())
            if (tally.iterations, tally.episode_return, tally.obs.tolist()) != expected:
                return (f"env {i}: the replayed episode differs (K {tally.iterations}, snapshot "
                        f"{entry['iterations']})")
        return ""


def json_ready(value: Any) -> Any:
    """``value`` (infos, observations) with numpy arrays as lists and numpy scalars as Python ones."""
    if isinstance(value, dict):
        return {str(key): json_ready(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(item) for item in value]
    if isinstance(value, np.ndarray):
        return json_ready(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


def from_json(info: dict[str, Any]) -> dict[str, Any]:
    """A :func:`json_ready` info back in the shape the batch made it: ``final_obs`` a float32 array."""
    if "final_obs" not in info:
        return info
    return {**info, "final_obs": np.asarray(info["final_obs"], np.float32)}
