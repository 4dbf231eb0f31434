"""A stand-in for simpleFoam: an env whose steps take as long as measured episodes did, asleep.

It measures what a batch's shape costs (lock-step barriers, resets, the rest of a step after a mid-step
convergence) at pool sizes this machine cannot run: the stand-in's "solver" is a sleep, so 128 of them
cost no CPU. It runs through the same bridge as the real solver; only the env a worker builds changes:

    profile = Profile.from_csv("experiments/foam/train-mesh05/episodes.csv")
    batch = BatchedFoamEnv(cfg, num_envs=8, pool=8, seed=0, make_env=StandIn(profile))

The time model, fitted to a run's episodes.csv (``Profile.from_csv``): each episode draws one measured
episode (a bootstrap of the rows, so an episode's length and its solver speed stay paired): K
iterations at ``busy / K`` seconds per iteration, busy = ``wall_time_s - solver_idle_s`` (the solver's
own time: its start-up, amortised, included; the trainer's ``pool_utilisation`` counts the same).
Most of the spread of that speed over a run is the machine's load changing over time, which every
env of a batch feels alike (in train-mesh05, episodes that ran side by side have speeds correlated
0.93; the speed's CV is 0.41 over the run, 0.13 within 11 consecutive episodes). Drawn independently
per env it would make the envs of a batch far more unequal than they are, so ``detrend`` (episodes)
divides each speed by the running median of its neighbours (times the run's median): what is left is
the spread between envs that run at the same time, the one a lock-step barrier waits for. A
step sleeps ``interval`` iterations' worth, the last one ``K mod interval`` (the episode converged
mid-step); a reset sleeps ``reset_s`` (the case copy: 0.08-0.09 s at mesh 0.5-1.0, foam_bridge._env).
``time_scale`` shrinks every sleep alike (utilisation is a ratio of times, so it holds as long as the
host's own per-step work stays small against a step).

Its episode records look like the real ones: ``wall_time_s`` from the end of the reset, ``solver_idle_s``
the time between a step's end and the next step's start (waiting on the bridge), and ``solver_time_s``
the seconds it slept computing (the stand-in's exact busy time). The observation is the fraction of the
episode left, the reward minus the iterations run (as the real env's); actions are ignored.

A utilisation measurement wraps it (or the real env) in ``foam_bridge._timing.TimedSteps``.
"""

from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from foam_bridge._records import EpisodeRecord

__all__ = ["DETREND", "RESET_S", "Profile", "StandIn", "StandInEnv"]

#: Seconds a reset takes (case copy; foam_bridge._env's measurement at mesh 0.5-1.0).
RESET_S = 0.09
#: Episodes in the running median that takes the machine's changing load out of the speeds.
DETREND = 11


def _detrended(rates: tuple[float, ...], window: int) -> tuple[float, ...]:
    """``rates`` over the running median of ``window`` neighbours, times their overall median."""
    if window <= 1:
        return tuple(rates)
    values, half = np.asarray(rates), window // 2
    local = np.array([np.median(values[max(0, i - half):i + half + 1]) for i in range(len(values))])
    return tuple(float(v) for v in values / local * np.median(values))


@dataclass(frozen=True)
class Profile:
    """The measured episodes a stand-in draws from: K and seconds per iteration, paired by episode."""

    iterations: tuple[int, ...]
    seconds_per_iteration: tuple[float, ...]
    reset_s: float = RESET_S
    interval: int = 100
    time_scale: float = 1.0

    @classmethod
    def from_csv(cls, path: str | Path, first: int | None = None, reset_s: float = RESET_S,
                 interval: int = 100, time_scale: float = 1.0, detrend: int = DETREND) -> Profile:
        """The profile of a run's episodes.csv (its ``first`` rows; None: all) that converged;
        ``detrend``: the running-median window in episodes (0: the speeds as measured)."""
        with open(path, newline="") as handle:
            rows = list(csv.DictReader(handle))[:first]
        pairs = [(int(r["iterations"]), float(r["wall_time_s"]) - float(r["solver_idle_s"] or 0.0))
                 for r in rows if r["outcome"] == "converged" and int(r["iterations"]) > 0]
        pairs = [(k, busy / k) for k, busy in pairs if math.isfinite(busy) and busy > 0]
        if not pairs:
            raise ValueError(f"{path}: no converged episode with a wall time to fit a profile to")
        iterations, rates = zip(*pairs, strict=True)
        return cls(tuple(iterations), _detrended(rates, detrend), reset_s, interval, time_scale)

    def draw(self, rng: np.random.Generator) -> tuple[int, float]:
        """One episode: (K, seconds per iteration, time_scale applied)."""
        pick = int(rng.integers(len(self.iterations)))
        return self.iterations[pick], self.seconds_per_iteration[pick] * self.time_scale

    def describe(self) -> dict[str, float]:
        """Medians and means of the model, in its own (scaled) seconds."""
        k = np.asarray(self.iterations, float)
        rate = np.asarray(self.seconds_per_iteration) * self.time_scale
        partial = np.where(k % self.interval == 0, self.interval, k % self.interval)
        return {"episodes": len(k), "mean_iterations": float(k.mean()),
                "mean_steps": float(np.ceil(k / self.interval).mean()),
                "median_step_s": float(np.median(rate * self.interval)),
                "mean_episode_s": float((k * rate).mean()),
                "mean_last_step_iterations": float(partial.mean()),
                "reset_s": self.reset_s * self.time_scale}


class StandIn:
    """An ``EnvFactory`` (foam_bridge._backends.worker): each worker builds StandInEnvs of ``profile``."""

    def __init__(self, profile: Profile) -> None:
        self.profile = profile

    def __call__(self, cfg: Any, work_dir: Path, env_id: int) -> StandInEnv:
        return StandInEnv(cfg, self.profile, env_id)


class StandInEnv:
    """FoamCaseEnv's interface (reset, step, close, records) with sleeps for the solver."""

    def __init__(self, cfg: Any, profile: Profile, env_id: int = 0) -> None:
        self.cfg, self.profile, self.env_id = cfg, profile, env_id
        self._rng = np.random.default_rng(env_id)
        self._done = True

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        time.sleep(self.profile.reset_s * self.profile.time_scale)
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self._length, self._rate = self.profile.draw(self._rng)
        self._k, self._busy, self._idle, self._seed = 0, 0.0, 0.0, seed
        self._actions: list[list[float]] = []
        self._done = False
        self._started = self._paused = time.monotonic()
        return self._obs(), self._info("running")

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self._done:
            raise RuntimeError("step() on a finished episode: call reset() first")
        begun = time.monotonic()
        if self._k:  # before the first step the solver has not started: nothing waits (as FoamSolver)
            self._idle += begun - self._paused
        run = min(self.profile.interval, self._length - self._k)
        time.sleep(run * self._rate)
        self._paused = time.monotonic()
        self._busy += self._paused - begun
        self._k += run
        self._actions.append([float(a) for a in np.ravel(action)])
        self._done = self._k >= self._length
        info = self._info("converged" if self._done else "running")
        if self._done:
            info["episode"] = EpisodeRecord(
                outcome="converged", iterations=self._k, seed=self._seed, actions=self._actions,
                episode_return=-float(self._k), solver_time_s=self._busy, env_id=self.env_id,
                wall_time_s=self._paused - self._started, solver_idle_s=self._idle).to_json()
        return self._obs(), -float(run), self._done, False, info

    def close(self) -> None:
        self._done = True

    def _obs(self) -> np.ndarray:
        obs = np.zeros(self.cfg.observation_size, np.float32)
        obs[0] = 1.0 - self._k / self._length
        return obs

    def _info(self, outcome: str) -> dict[str, Any]:
        return {"iterations": self._k, "residuals": {}, "outcome": outcome, "cause": "",
                "inlet_velocity": math.nan, "step_height": math.nan}
