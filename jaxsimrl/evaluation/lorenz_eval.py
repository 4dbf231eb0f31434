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
from jaxsimrl.evaluation.aggregate import interval_estimates, plot_performance_profile
from jaxsimrl.policy import load_agents, load_policy
from jaxsimrl.runs.atomic import atomic_write_json
from jaxsimrl.runs.run_dir import spread

EVAL_FILE = "eval.json"
PLOT_FILE = "eval_trajectory.png"
PROFILE_FILE = "eval_profile.png"  # a batch's performance profile across agents


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
    reports, runs, base = compare_agents(env, params, act, carry, episodes, seed, agents=1)
    return reports[0], runs[0], base


def compare_agents(env: Lorenz, params: LorenzParams, act: ActFn, carry: Any, episodes: int, seed: int,
                   agents: int) -> tuple[list[dict[str, Any]], list[Rollout], Rollout]:
    """:func:`compare` for ``agents`` policies in one rollout: ``act`` acts for agent k on episodes
    k * (episodes + 1) ... (k + 1) * (episodes + 1) - 1, every agent from the same initial states."""
    start_key, act_key = jax.random.split(jax.random.PRNGKey(seed))
    start = initial_states(env, params, start_key, episodes)
    tiled = start if agents == 1 else jax.tree.map(lambda leaf: jnp.concatenate([leaf] * agents), start)
    controlled = rollout(env, params, act, carry, tiled, act_key)
    base = rollout(env, params, uncontrolled, (), start, act_key)
    size = episodes + 1
    runs = [Rollout(*(array[k * size:(k + 1) * size] for array in controlled)) for k in range(agents)]
    return [_report(run, base, params, episodes, seed) for run in runs], runs, base


def _report(agent: Rollout, base: Rollout, params: LorenzParams, episodes: int, seed: int) -> dict[str, Any]:
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
    return report


def agents_act(policies: list[Any], stochastic: bool) -> ActFn:
    """One ActFn for the TrainedPolicies ``policies`` (of one run): a single policy acts on the whole
    batch; several act vmapped over their stacked parameters, each on its own block of episodes."""
    policy, count = policies[0].policy, len(policies)
    if count == 1:
        params = policies[0].params

        def act(obs: jax.Array, carry: Any, starts: jax.Array, key: jax.Array) -> tuple[jax.Array, Any]:
            return policy.act(params, obs, carry, starts, key, deterministic=not stochastic)

        return act
    stacked = jax.tree.map(lambda *leaves: jnp.stack(leaves), *[loaded.params for loaded in policies])
    split = lambda leaf: leaf.reshape(count, -1, *leaf.shape[1:])  # noqa: E731
    merge = lambda leaf: leaf.reshape(-1, *leaf.shape[2:])  # noqa: E731

    def act_all(obs: jax.Array, carry: Any, starts: jax.Array, key: jax.Array) -> tuple[jax.Array, Any]:
        def one(params: Any, obs: jax.Array, carry: Any, starts: jax.Array) -> tuple[jax.Array, Any]:
            return policy.act(params, obs, carry, starts, key, deterministic=not stochastic)

        action, carry = jax.vmap(one)(stacked, split(obs), jax.tree.map(split, carry), split(starts))
        return merge(action), jax.tree.map(merge, carry)

    return act_all


def evaluate_run(run_path: Path, episodes: int = 32, stochastic: bool = False, seed: int = 0,
                 agent: int | None = None) -> dict[str, Any]:
    """eval-lorenz: write RUN_DIR/eval.json and RUN_DIR/eval_trajectory.png; return the report. For a
    ``--seeds`` run, every agent is evaluated (from the same initial states) and the report holds each
    agent's statistics and those across agents (see :func:`aggregate_agents`), and their performance
    profile is drawn to RUN_DIR/eval_profile.png; with ``agent=K`` only agent K, into
    eval-agent-K.json and eval_trajectory-agent-K.png."""
    from jaxsimrl.evaluation.plots import plot_trajectories

    policies = load_agents(run_path) if agent is None else [load_policy(run_path, agent=agent)]
    env, params = Lorenz(), LorenzParams()
    carry = policies[0].policy.initial_carry(len(policies) * (episodes + 1))
    reports, runs, base = compare_agents(env, params, agents_act(policies, stochastic), carry, episodes, seed,
                                         len(policies))
    for report, loaded in zip(reports, policies, strict=True):
        report.update(stochastic=stochastic, checkpoint_update=loaded.update,
                      trained_env_steps=loaded.env_steps)
        if loaded.agent is not None:  # which agent: its seed and, of a --sweep, its swept values
            swept = {name: values[loaded.agent] for name, values in loaded.record.get("sweep", {}).items()}
            report.update(agent=loaded.agent, agent_seed=loaded.record["seeds"][loaded.agent], **swept)
    report = reports[0] if len(reports) == 1 else aggregate_agents(reports)
    shown = runs[report.get("plotted_agent", 0)]
    suffix = "" if agent is None else f"-agent-{agent}"
    plot_trajectories(_named(run_path, PLOT_FILE, suffix), shown.xyz[0], base.xyz[0], shown.speed[0],
                      base.speed[0], dt=float(params.dt), v_threshold=float(params.v_threshold),
                      fixed_point=P_MINUS)
    if "aggregate" in report:
        plot_performance_profile(Path(run_path) / PROFILE_FILE, [a["mean_return"] for a in report["agents"]])
        report["profile_plot"] = PROFILE_FILE
    atomic_write_json(_named(run_path, EVAL_FILE, suffix), report)
    return report


# Entries of an agent's report that are the same for every agent of a run.
_SHARED = ("episodes", "episode_steps", "seed", "v_threshold", "stochastic", "checkpoint_update",
           "trained_env_steps", "uncontrolled")


def aggregate_agents(reports: list[dict[str, Any]]) -> dict[str, Any]:
    """The report of a batch of agents: the shared entries, ``mean_return`` and
    ``fraction_above_threshold`` averaged over the agents, ``mean_return_agents`` (count, mean, median,
    min, max across agents), ``aggregate`` (IQM, median and mean of the agents' mean returns with 95 %
    stratified-bootstrap intervals, :func:`jaxsimrl.evaluation.aggregate.interval_estimates`),
    ``agents`` (each agent's own entries) and ``plotted_agent`` (the median agent by mean return, whose
    trajectory is plotted)."""
    means = [report["mean_return"] for report in reports]
    return {**{key: reports[0][key] for key in _SHARED}, "num_agents": len(reports),
            "mean_return": float(np.mean(means)),
            "fraction_above_threshold": float(np.mean([r["fraction_above_threshold"] for r in reports])),
            "mean_return_agents": spread(means),
            "aggregate": {"of": "mean_return", **interval_estimates(means)},
            "plotted_agent": int(np.argsort(means)[len(means) // 2]),
            "agents": [{key: value for key, value in r.items() if key not in _SHARED} for r in reports]}


def _named(run_path: Path, name: str, suffix: str) -> Path:
    """RUN_DIR/name with ``suffix`` before its extension (eval.json -> eval-agent-3.json)."""
    path = Path(run_path) / name
    return path.with_name(path.stem + suffix + path.suffix)
