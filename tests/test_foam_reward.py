"""The cost-aware rewards (FoamEnvConfig.reward): linear-solver iterations and solver CPU time.

The env's incremental parser counts the costs as the solver prints them; the tests check them against
an independent reading of the whole log (foam_bridge._logparse.read_solver_cost) after real simpleFoam
runs on the coarse mesh (mesh_scale 0.4, a few seconds each).
"""

from __future__ import annotations

from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest
from foam_marks import needs_openfoam

from foam_bridge import _episode_case as episode_case
from foam_bridge._config import U_REF, FoamEnvConfig, cost_per_iteration, failure_reward
from foam_bridge._env import FoamCaseEnv
from foam_bridge._logparse import LogParser, read_solver_cost
from jaxsimrl.agents.ppo.losses import compute_gae

BEST = (0.95, 0.95)

TWO_ITERATIONS = """\
Time = 1

smoothSolver:  Solving for Ux, Initial residual = 1, Final residual = 0.01, No Iterations 3
smoothSolver:  Solving for Uy, Initial residual = 1, Final residual = 0.01, No Iterations 2
GAMG:  Solving for p, Initial residual = 1, Final residual = 0.05, No Iterations 11
GAMG:  Solving for p, Initial residual = 0.3, Final residual = 0.02, No Iterations 4
ExecutionTime = 0.25 s  ClockTime = 0 s

Time = 2

smoothSolver:  Solving for Ux, Initial residual = nan, Final residual = nan, No Iterations 1000
GAMG:  Solving for p, Initial residual = 0.5, Final residual = 0.05, No Iterations 7
ExecutionTime = 0.5 s  ClockTime = 1 s
"""


def test_parser_counts_every_linear_solve_and_the_cpu_time_up_to_the_first_bad_iteration() -> None:
    parser = LogParser("cells", "inlet")
    lines = TWO_ITERATIONS.splitlines(keepends=True)
    parser.feed("".join(lines[:8]))  # iteration 1, in a chunk that ends mid-way through no line
    assert (parser.completed, parser.linear_iterations, parser.execution_time) == (1, 20, 0.25)
    assert parser.residuals["p"] == 1.0  # the residual is the first solve's, the cost counts both
    parser.feed("".join(lines[8:]))
    # iteration 2 diverges at its first solve: that solve counts, nothing after it (the parser froze)
    assert parser.failed_at == 2 and parser.linear_iterations == 1020 and parser.execution_time == 0.25


def test_failure_penalty_is_the_rest_of_the_cap_at_the_episodes_own_rate() -> None:
    iterations = FoamEnvConfig(max_iterations=1000)
    linear = FoamEnvConfig(max_iterations=1000, reward="linear-iterations")
    assert cost_per_iteration(iterations, 5000.0, 400) == 1.0  # SIMPLE iterations cost 1 each
    assert failure_reward(iterations, 400, cost_per_iteration(iterations, 5000.0, 400)) == -600.0
    assert failure_reward(linear, 400, cost_per_iteration(linear, 5000.0, 400)) == -600.0 * 12.5
    assert cost_per_iteration(linear, 0.0, 0) == 1.0  # nothing ran yet
    assert failure_reward(FoamEnvConfig(failure_penalty=-7.0, reward="solver-time"), 400, 3.0) == -7.0
    with pytest.raises(ValueError, match="reward"):
        FoamEnvConfig(reward="wall-clock").validate()


def _episode(tmp_path: Path, name: str, action: tuple[float, float], **overrides) -> tuple[list[float], dict]:
    base = dict(mesh_scale=0.4, interval=50, max_iterations=1000, keep_cases=True, work_dir=tmp_path / name)
    cfg = FoamEnvConfig(**{**base, **overrides})
    with FoamCaseEnv(cfg) as env:
        env.reset(options={"inlet_velocity": U_REF})
        rewards = []
        while True:
            _, reward, terminated, truncated, info = env.step(action)
            rewards.append(reward)
            if terminated or truncated:
                return rewards, {**info["episode"], "log": read_solver_cost(env.case_dir)}


@pytest.mark.slow  # whole runs
@needs_openfoam
def test_linear_iterations_reward_is_the_logs_inner_iteration_count(tmp_path: Path) -> None:
    plain, plain_record = _episode(tmp_path, "plain", BEST)
    rewards, record = _episode(tmp_path, "linear", BEST, reward="linear-iterations")
    assert record["outcome"] == plain_record["outcome"] == "converged"
    # the reward changes what is counted, not the run: same iterations, same inner iterations
    assert record["iterations"] == plain_record["iterations"] == -sum(plain)
    assert record["linear_iterations"] == plain_record["linear_iterations"] == record["log"].total
    assert -sum(rewards) == record["linear_iterations"] == -record["return"]
    assert all(r < 0 for r in rewards) and len(set(rewards[:-1])) > 1  # steps differ in cost
    assert record["linear_iterations"] > 5 * record["iterations"]  # U, p, k, omega: >= 1 each


@pytest.mark.slow  # whole runs
@needs_openfoam
def test_solver_time_reward_is_the_solvers_cpu_seconds(tmp_path: Path) -> None:
    rewards, record = _episode(tmp_path, "time", BEST, reward="solver-time")
    assert record["outcome"] == "converged" and all(r < 0 for r in rewards)
    assert -sum(rewards) == pytest.approx(record["solver_time_s"]) == record["log"].cpu_time_s
    assert 0 < record["solver_time_s"] < record["wall_time_s"]


@needs_openfoam
def test_a_diverged_episode_with_the_linear_reward_costs_more_than_it_ran(tmp_path: Path) -> None:
    rewards, record = _episode(tmp_path, "diverged", BEST, mesh_scale=0.25, reward="linear-iterations")
    assert record["outcome"] == "diverged"
    before = 50 * (len(rewards) - 1)  # SIMPLE iterations of the steps before the failing one
    rate = record["linear_iterations"] / record["iterations"]
    # the last step's penalty is the rest of the cap at the episode's cost per iteration
    assert -rewards[-1] == pytest.approx((1000 - before) * rate, rel=0.05)
    assert -sum(rewards) > record["linear_iterations"]  # failing costs more than the run did


Episode = tuple[list[float], list[bool], list[bool], str]


def _flags(tmp_path: Path, name: str, crash_at: int | None) -> Episode:
    """(rewards, terminated, truncated, outcome) of a real episode of 25-iteration steps capped at 100 (the
    coarse mesh needs ~180 to converge); ``crash_at``: the solver dies there (the case is broken under
    it a step before: its fvSolution read at ``crash_at`` fails)."""
    cfg = FoamEnvConfig(mesh_scale=0.4, interval=25, max_iterations=100, work_dir=tmp_path / name)
    rewards, terminated, truncated = [], [], []
    with FoamCaseEnv(cfg) as env:
        env.reset(options={"inlet_velocity": U_REF})
        while True:
            if crash_at is not None and (len(rewards) + 1) * 25 == crash_at:
                episode_case.relaxation_fifo(env.case_dir, crash_at).unlink()
            _, reward, term, trunc, info = env.step(BEST)
            rewards.append(reward)
            terminated.append(term)
            truncated.append(trunc)
            if term or trunc:
                return rewards, terminated, truncated, info["outcome"]


@pytest.mark.slow  # whole runs
@needs_openfoam
def test_a_capped_runs_learning_target_is_never_below_a_failed_runs(tmp_path: Path) -> None:
    """The cap is the task's budget: a capped episode is terminated (no bootstrap), so whatever the critic
    says, the return target the learner trains on (GAE with lambda 1) is at least a failure's."""
    capped = _flags(tmp_path, "capped", None)
    failed = _flags(tmp_path, "failed", crash_at=50)
    assert (capped[3], failed[3]) == ("truncated", "crashed")
    assert sum(capped[0]) == sum(failed[0]) == -100  # both cost the whole budget
    for gamma in (0.99, 1.0):
        for critic in (-1e4, -100.0, 0.0):  # any critic, however pessimistic
            targets = [_return_targets(rewards, terminated, truncated, critic, gamma)
                       for rewards, terminated, truncated, _ in (capped, failed)]
            steps = len(failed[0])
            assert np.all(targets[0][:steps] >= targets[1]), (gamma, critic, targets)
    assert capped[1][-1] and failed[1][-1] and not any(capped[2] + failed[2])  # the cap: no time limit


def _return_targets(rewards: list[float], terminated: list[bool], truncated: list[bool], critic: float,
                    gamma: float) -> np.ndarray:
    """The learner's value targets (losses.compute_gae, lambda 1) of one episode, V = ``critic``
    everywhere."""
    column = lambda values, dtype=jnp.float32: jnp.asarray(values, dtype)[:, None]  # noqa: E731
    values = column([critic] * len(rewards))
    _, targets = compute_gae(column(rewards), values, column(terminated, bool), column(truncated, bool),
                             values, jnp.full((1,), critic, jnp.float32), gamma, 1.0)
    return np.asarray(targets)[:, 0]
