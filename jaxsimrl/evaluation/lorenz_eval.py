"""Evaluate a trained Lorenz agent against the uncontrolled system (Pawar & Maulik, fig. "results_lorenz").

Two measurements, in one batched rollout per policy (episode 0 is the paper's, 1..N the random ones):
- the paper's trajectory: from (1, 12, 9) with (sigma, rho, beta) = (10, 20, 8/3), one full episode,
  controlled vs uncontrolled (plotted by :mod:`jaxsimrl.evaluation.plots`);
- statistics over N episodes from random initial states (the env's own sampler: uniform in
  [-40, 40]^3): return per episode and the fraction of steps with |velocity| > V_th. The uncontrolled
  baseline runs from the same initial states.
Actions are the policy's mean (deterministic) unless ``stochastic``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxsimrl.agents.ppo.evaluate import ActFn, scan_episodes
from jaxsimrl.envs.lorenz import P_MINUS, Lorenz, LorenzParams
from jaxsimrl.runs.atomic import atomic_write_json

EVAL_FILE = "eval.json"
PLOT_FILE = "eval_trajectory.png"


class Rollout(NamedTuple):
    """Arrays of a batch of full episodes: B episodes, T steps."""

    xyz: np.ndarray  # (B, T + 1, 3) positions, initial state first
    speed: np.ndarray  # (B, T) |velocity| after each step
    reward: np.ndarray  # (B, T) step rewards (terminal penalty included at the last step)


def initial_states(env: Lorenz, params: LorenzParams, key: jax.Array, episodes: int) -> tuple[jax.Array, Any]:
    """Episode 0 starts from ``params.init_state`` (the paper's (1, 12, 9)); episodes 1..N from the
    env's random initial states drawn with ``key``. Returns batched (obs, env state)."""

    @jax.jit  # one compiled call instead of many small eager ones
    def draw(key: jax.Array, params: LorenzParams) -> tuple[jax.Array, Any]:
        fixed = env.reset(key, params.replace(random_init=False))
        keys = jax.random.split(key, episodes)
        random = jax.vmap(env.reset, in_axes=(0, None))(keys, params.replace(random_init=True))
        return jax.tree.map(lambda first, rest: jnp.concatenate([first[None], rest]), fixed, random)

    return draw(key, params)


def rollout(env: Lorenz, params: LorenzParams, act: ActFn, carry: Any, start: tuple[jax.Array, Any],
            key: jax.Array) -> Rollout:
    """Run every episode of ``start`` for ``params.horizon`` steps under ``act`` (jitted)."""

    def run(carry: Any, start: tuple[jax.Array, Any], key: jax.Array) -> tuple[jax.Array, ...]:
        xyz, speed, reward = scan_episodes(env, params, act, carry, start, key, params.horizon,
                                           lambda out: (out.state.xyz, out.info["speed"], out.reward))
        xyz = jnp.concatenate([start[1].xyz[None], xyz])
        return jnp.swapaxes(xyz, 0, 1), speed.T, reward.T

    xyz, speed, reward = jax.device_get(jax.jit(run)(carry, start, key))
    return Rollout(np.asarray(xyz), np.asarray(speed), np.asarray(reward))


def uncontrolled(obs: jax.Array, carry: Any, starts: jax.Array, key: jax.Array) -> tuple[jax.Array, Any]:
    """The uncontrolled system: no perturbation of (sigma, rho, beta)."""
    return jnp.zeros((obs.shape[0], Lorenz.action_dim), obs.dtype), carry


def episode_stats(returns: np.ndarray, speed: np.ndarray, v_threshold: float) -> dict[str, float]:
    """Return statistics of a batch of episodes and the fraction of their steps above ``v_threshold``."""
    return {"mean_return": float(np.mean(returns)), "std_return": float(np.std(returns)),
            "min_return": float(np.min(returns)), "max_return": float(np.max(returns)),
            "fraction_above_threshold": float(np.mean(speed > v_threshold))}


def compare(env: Lorenz, params: LorenzParams, act: ActFn, carry: Any, episodes: int, seed: int
            ) -> tuple[dict[str, Any], Rollout, Rollout]:
    """Controlled (``act``) vs uncontrolled rollouts from the same initial states; returns the report
    and the two rollouts (episode 0 = the paper's initial state, not counted in the statistics)."""
    start_key, act_key = jax.random.split(jax.random.PRNGKey(seed))
    start = initial_states(env, params, start_key, episodes)
    agent = rollout(env, params, act, carry, start, act_key)
    base = rollout(env, params, uncontrolled, (), start, act_key)
    v_th = float(params.v_threshold)
    report: dict[str, Any] = {"episodes": episodes, "episode_steps": params.horizon, "seed": seed,
                              "v_threshold": v_th}
    report.update(episode_stats(agent.reward[1:].sum(axis=1), agent.speed[1:], v_th))
    report["uncontrolled"] = episode_stats(base.reward[1:].sum(axis=1), base.speed[1:], v_th)
    report["paper_initial_state"] = {"xyz": [float(v) for v in agent.xyz[0, 0]]}
    for name, run in (("controlled", agent), ("uncontrolled", base)):
        report["paper_initial_state"][name] = {
            "return": float(run.reward[0].sum()), "final_xyz": [float(v) for v in run.xyz[0, -1]],
            "fraction_above_threshold": float(np.mean(run.speed[0] > v_th))}
    return report, agent, base


def evaluate_run(run_path: Path, episodes: int = 32, stochastic: bool = False, seed: int = 0
                 ) -> dict[str, Any]:
    """eval-lorenz: write RUN_DIR/eval.json and RUN_DIR/eval_trajectory.png; return the report."""
    from jaxsimrl.evaluation.plots import plot_trajectories
    from jaxsimrl.introspect.loading import load_policy

    loaded = load_policy(run_path)
    policy = loaded.policy

    def act(obs: jax.Array, carry: Any, starts: jax.Array, key: jax.Array) -> tuple[jax.Array, Any]:
        return policy.act(loaded.params, obs, carry, starts, key, deterministic=not stochastic)

    env, params = Lorenz(), LorenzParams()
    report, agent, base = compare(env, params, act, policy.initial_carry(episodes + 1), episodes, seed)
    report.update(stochastic=stochastic, checkpoint_update=loaded.update, trained_env_steps=loaded.env_steps)
    plot_trajectories(Path(run_path) / PLOT_FILE, agent.xyz[0], base.xyz[0], agent.speed[0], base.speed[0],
                      dt=float(params.dt), v_threshold=float(params.v_threshold), fixed_point=P_MINUS)
    atomic_write_json(Path(run_path) / EVAL_FILE, report)
    return report
