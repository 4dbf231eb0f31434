"""The cost-aware rewards (FoamEnvConfig.reward): linear-solver iterations and solver CPU time.

The env's incremental parser counts the costs as the solver prints them; the tests check them against
an independent reading of the whole log (jaxsimrl.evaluation.foam_cost) after real simpleFoam runs on the
coarse mesh (mesh_scale 0.4, a few seconds each).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from foam_marks import needs_openfoam

from foam_bridge.config import U_REF, FoamEnvConfig, cost_per_iteration, failure_reward
from foam_bridge.env import FoamCaseEnv
from foam_bridge.logparse import LogParser
from jaxsimrl.evaluation.foam_cost import read_solver_cost

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
