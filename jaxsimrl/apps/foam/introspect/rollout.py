"""Roll a train-foam policy out on real simpleFoam episodes, one tidy row per step.

The episodes run on foam_bridge's episode pool (:func:`foam_bridge._episodes.run_episodes`: simpleFoam
workers, one episode per slot, each reset at its own inlet velocity and seeded by its index) with a
:class:`jaxsimrl.apps.foam.evaluation.controllers.LearnedController` on a :class:`jaxsimrl.policy.BatchActor`:
the policy's mean action (as eval-foam's learned_deterministic), or a sample keyed by (seed, episode
index, step), so a sampled episode does not depend on the pool size or on the other episodes.

The record is a dict of numpy arrays with one entry per step of every episode, in episode order
(``pandas.DataFrame`` takes the 1-D ones as they are; episodes have different lengths):

- ``episode``, ``velocity`` (inlet m/s), ``step`` (0, 1, ...);
- ``obs`` (rows, obs_dim): the raw observation acted on; ``action`` (rows, 2): (alpha_u, alpha_p);
- ``value``: the critic's value of ``obs`` in reward units (about minus the iterations still to go);
- ``iterations_before`` and ``iterations``: the SIMPLE iteration count K when the action took over and
  after the step; ``reward`` = -(K_after - K_before), or the failure reward (NaN if the worker died);
- ``residual.<field>``: simpleFoam's latest initial residual of each convergence field after the step;
- ``outcome`` (str): "running", then how the episode ended on its last row.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from foam_bridge import EpisodeJob, FoamEnvConfig, run_episodes
from jaxsimrl.apps.foam.evaluation.controllers import LearnedController
from jaxsimrl.policy import BatchActor

#: The controller name the rollout's episodes run under.
CONTROLLER = "policy"


def foam_rollout(policy: Any, env_params: FoamEnvConfig | None = None, steps: int | None = None,
                 episodes: int = 1, seed: int = 0, deterministic: bool = True,
                 velocities: Sequence[float] = (50.0,), pool: int = 1) -> dict[str, np.ndarray]:
    """``episodes`` episodes per inlet velocity of ``policy`` (a LoadedPolicy of a train-foam run) on
    ``env_params`` (default: the run's FoamEnvConfig; e.g. ``dataclasses.replace(policy.env_params,
    mesh_scale=0.4)``), on ``pool`` workers. The policy acts in its training box whatever the config's."""
    cfg = _check(policy, env_params, steps, episodes, velocities, pool)
    plan = [(v, sample) for v in _velocities(velocities) for sample in range(episodes)]
    controller = _controller(policy, min(pool, len(plan)), deterministic, seed)
    jobs = [EpisodeJob(uid, controller, seed=uid, options={"inlet_velocity": v}, tag=v)
            for uid, (v, _) in enumerate(plan)]
    results = run_episodes(cfg, jobs, pool, prefix="foam_eval_")
    return _record(policy, results, tuple(cfg.convergence))


def _check(policy: Any, env_params: Any, steps: Any, episodes: Any, velocities: Any, pool: Any
           ) -> FoamEnvConfig:
    cfg = policy.env_params if env_params is None else env_params
    if not isinstance(cfg, FoamEnvConfig):
        raise ValueError(f"env_params must be a FoamEnvConfig, got {type(cfg).__name__}")
    if steps is not None:
        raise ValueError("steps: a foam episode runs until it converges, fails or reaches max_iterations; "
                         "set env_params.max_iterations to shorten it")
    for name, value in (("episodes", episodes), ("pool", pool)):
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
    speeds = _velocities(velocities)
    if len(set(speeds)) != len(speeds):
        raise ValueError(f"velocities must be distinct, got {speeds}")
    if cfg.observation_size != policy.obs_dim:
        raise ValueError(f"env_params gives observations of size {cfg.observation_size}, the policy takes "
                         f"{policy.obs_dim} (keep residual_features and convergence as trained)")
    return cfg.validate()


def _controller(policy: Any, batch: int, deterministic: bool, seed: int) -> Any:
    """eval-foam's learned controller, on the loaded parameters and the training action box."""
    return LearnedController(CONTROLLER, BatchActor(policy, batch), deterministic, seed)


def _record(policy: Any, results: Sequence[Any], fields: tuple[str, ...]) -> dict[str, np.ndarray]:
    rows: list[dict[str, Any]] = []
    for episode, result in enumerate(results):
        before = 0
        values = _values(policy, [step.obs for step in result.trace])
        for t, step in enumerate(result.trace):
            row = {"episode": episode, "velocity": result.job.tag, "step": t, "obs": step.obs,
                   "action": step.action, "value": values[t], "iterations_before": before,
                   "iterations": step.iterations, "reward": step.reward, "outcome": step.outcome}
            row.update({f"residual.{name}": step.residuals.get(name, np.nan) for name in fields})
            rows.append(row)
            before = step.iterations
    keys = ("episode", "velocity", "step", "obs", "action", "value", "iterations_before", "iterations",
            "reward", *(f"residual.{name}" for name in fields), "outcome")
    return {key: _column(key, [row[key] for row in rows], policy) for key in keys}


def _values(policy: Any, obs: list[np.ndarray]) -> np.ndarray:
    """The critic's values along one episode, from the carry each step started with (as acting did)."""
    if not obs:
        return np.zeros(0)
    if not policy.recurrent:
        return np.atleast_1d(policy.value(np.stack(obs)))
    values, state = [], None
    for row in obs:
        values.append(float(policy.value(row, state)))
        state = policy.act(row, state)[1]
    return np.asarray(values)


def _column(key: str, values: list[Any], policy: Any) -> np.ndarray:
    if key == "outcome":
        return np.asarray(values, dtype=str)
    if key in ("obs", "action"):
        width = policy.obs_dim if key == "obs" else policy.action_dim
        return np.asarray(values, np.float64).reshape(len(values), width)
    kind = np.int64 if key in ("episode", "step", "iterations_before", "iterations") else np.float64
    return np.asarray(values, kind)


def _velocities(velocities: Any) -> list[float]:
    """``velocities`` (one number, a sequence or an array) as a list of floats > 0; ValueError if not."""
    try:
        speeds = np.atleast_1d(np.asarray(velocities, np.float64))
    except (TypeError, ValueError):
        speeds = np.array([np.nan])
    if speeds.ndim != 1 or not speeds.size or not np.all(np.isfinite(speeds) & (speeds > 0)):
        raise ValueError(f"velocities must be inlet velocities > 0 in m/s, got {velocities!r}")
    return [float(v) for v in speeds]
