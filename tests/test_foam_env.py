"""FoamCaseEnv against the real simpleFoam on coarse backward-facing-step meshes (a few seconds each).

mesh_scale 0.4 (3,276 cells) with SIMPLEC and factors (0.95, 0.95) converges in ~180 iterations at the
paper's training criterion and ~215 at its test criterion; mesh_scale 0.25 (below the usable scales,
see FoamEnvConfig.mesh_scale) diverges with them within ~100 iterations: the divergence tests use it.
"""

from __future__ import annotations

import os
import shutil
import signal
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from foam_marks import OPENFOAM
from foamlib import FoamFile

from foam_bridge import _episode_case as episode_case
from foam_bridge import _template as template
from foam_bridge._config import TEST_CONVERGENCE, U_REF, FoamEnvConfig
from foam_bridge._env import FoamCaseEnv, action_spec, observation_spec
from foam_bridge._errors import CaseError
from foam_bridge._logparse import LogParser
from foam_bridge._solver import FoamSolver, run_to_end
from jaxsimrl.agents.ppo.distribution import to_box
from jaxsimrl.envs.host import HostVecEnv

pytestmark = OPENFOAM

BEST = (0.95, 0.95)


def _cfg(tmp_path: Path, **overrides) -> FoamEnvConfig:
    base = dict(mesh_scale=0.4, simple_variant="SIMPLEC", interval=25, max_iterations=1000,
                step_timeout_s=60.0, work_dir=tmp_path)
    return FoamEnvConfig(**{**base, **overrides})


def _run_episode(env: FoamCaseEnv, actions) -> tuple[list[float], dict]:
    """Step until the episode ends; ``actions`` is one action or a list (the last one repeats)."""
    schedule = list(actions) if isinstance(actions, list) else [actions]
    rewards, t = [], 0
    while True:
        _, reward, terminated, truncated, info = env.step(schedule[min(t, len(schedule) - 1)])
        rewards.append(reward)
        t += 1
        if terminated or truncated:
            return rewards, info


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def _wait_group_gone(pgid: int, timeout_s: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while _group_alive(pgid):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


def test_chunked_equals_uninterrupted_and_rewards_sum_to_minus_iterations(tmp_path: Path) -> None:
    cfg = _cfg(tmp_path)
    env = FoamCaseEnv(cfg)
    try:
        obs, info = env.reset(options={"inlet_velocity": U_REF})
        assert obs.shape == (1,) and obs[0] == pytest.approx(1.0)  # inlet U_REF^2, cells ~0
        rewards, info = _run_episode(env, BEST)
        chunked = env.parser.history
        reference_case = tmp_path / "reference"
        episode_case.write_episode_case(env.base, reference_case, env.cfg, U_REF, env.case_info)
        episode_case.make_uninterrupted(reference_case, env.cfg, *BEST)
        reference = LogParser(episode_case.CELLS_FUNCTION, episode_case.INLET_FUNCTION)
        code, _ = run_to_end(reference_case, env.openfoam, reference, timeout_s=120)
    finally:
        env.close()
    assert code == 0 and info["outcome"] == "converged"
    total = info["iterations"]
    assert total == reference.converged_at == len(chunked) > 2 * cfg.interval
    # the residual histories agree to the last printed digit (17 significant digits)
    assert chunked == reference.history
    assert sum(rewards) == -total == info["episode"]["return"]
    assert rewards[:-1] == [-cfg.interval] * (len(rewards) - 1)
    assert 0 < -rewards[-1] <= cfg.interval
    assert info["episode"]["steps"] == len(rewards) and info["episode"]["actions"][0] == list(BEST)


def test_new_factors_govern_the_iteration_after_the_pause(tmp_path: Path) -> None:
    cfg = _cfg(tmp_path, interval=20, max_iterations=200)
    env = FoamCaseEnv(cfg)
    try:
        histories = []
        for second in (BEST, (0.6, 0.4)):
            env.reset(seed=1)
            env.step(BEST)
            env.step(second)
            histories.append(env.parser.history)
    finally:
        env.close()
    constant, switched = histories
    assert len(constant) == len(switched) == 40
    assert constant[:20] == switched[:20]  # iterations 1..20: same factors, same numbers
    # iteration 21 is the first one relaxed with the new factors: its U matrix already differs
    assert constant[20]["Ux"] != switched[20]["Ux"]


@pytest.mark.slow  # whole runs
def test_test_criterion_converges_later_than_training_criterion(tmp_path: Path) -> None:
    iterations = {}
    for name, convergence in (("train", None), ("test", dict(TEST_CONVERGENCE))):
        extra = {} if convergence is None else {"convergence": convergence}
        env = FoamCaseEnv(_cfg(tmp_path / name, interval=100, **extra))
        try:
            env.reset(options={"inlet_velocity": U_REF})
            _, info = _run_episode(env, BEST)
        finally:
            env.close()
        assert info["outcome"] == "converged"
        limits = convergence or env.cfg.convergence
        assert all(info["residuals"][field] < limit for field, limit in limits.items())
        iterations[name] = info["iterations"]
    assert iterations["train"] < iterations["test"] < 1000


@pytest.mark.slow  # diverging runs, twice
def test_divergence_is_deterministic_with_the_penalty_and_a_bounded_observation(tmp_path: Path) -> None:
    """The same diverging episode 3x: same K, outcome, cause and record; the state never blows up."""
    cfg = _cfg(tmp_path, mesh_scale=0.25, interval=10, max_iterations=1000)
    runs = []
    with FoamCaseEnv(cfg) as env:
        for _ in range(3):
            obs, _ = env.reset(options={"inlet_velocity": U_REF})
            observations, rewards = [obs], []
            while True:
                obs, reward, terminated, truncated, info = env.step(BEST)
                observations.append(obs)
                rewards.append(reward)
                if terminated or truncated:
                    break
            record = {key: value for key, value in info["episode"].items()
                      if key not in ("wall_time_s", "solver_idle_s", "solver_time_s")}
            runs.append((info["iterations"], info["outcome"], info["cause"], rewards, record))
            # the learner only ever sees finite float32 states well below the blow-up (<= 2 x the limit)
            states = np.array([o[0] for o in observations])
            assert all(o.dtype == np.float32 for o in observations) and np.all(np.isfinite(states))
            assert states.max() <= 2 * cfg.state_divergence_ratio * U_REF**2 / cfg.state_scale
    assert runs[0] == runs[1] == runs[2]
    iterations, outcome, cause, rewards, record = runs[0]
    assert outcome == "diverged" and cause.startswith("diverged: ")
    assert cause.endswith(f"at iteration {iterations}")  # K is the first bad iteration
    assert record["outcome"] == "diverged" and record["cause"] == cause and record["iterations"] == iterations
    steps_before = len(rewards) - 1
    assert steps_before * 10 < iterations <= (steps_before + 1) * 10
    assert rewards[-1] == -(1000 - 10 * steps_before)  # as if it had run to max_iterations
    assert sum(rewards) == -1000


def test_the_state_every_five_iterations_leaves_the_run_and_still_catches_a_blow_up(tmp_path: Path) -> None:
    """state_interval 5 (solve's, for a controller that does not observe the state): the same residual
    history and the state printed at every fifth iteration only; a blow-up still ends the episode as
    diverged, at most 4 iterations later than the state read every iteration would have."""
    histories, printed = [], []
    for every in (1, 5):
        with FoamCaseEnv(_cfg(tmp_path / f"every-{every}", state_interval=every)) as env:
            env.reset(options={"inlet_velocity": U_REF})
            _, info = _run_episode(env, BEST)
            histories.append(list(env.parser.history))
            log = (env.case_dir / "log.simpleFoam").read_text()
        printed.append(log.count(f"volFieldValue {episode_case.CELLS_FUNCTION} write:"))
        assert info["outcome"] == "converged"
    assert histories[0] == histories[1]
    assert printed[0] == len(histories[0]) and printed[1] == len(histories[0]) // 5
    ends = []
    for every in (1, 5):
        cfg = _cfg(tmp_path / f"blow-up-{every}", mesh_scale=0.25, interval=10, state_interval=every)
        with FoamCaseEnv(cfg) as env:
            env.reset(options={"inlet_velocity": U_REF})
            _, info = _run_episode(env, BEST)
        assert info["outcome"] == "diverged"
        ends.append(info["iterations"])
    assert 0 <= ends[1] - ends[0] <= 4


def test_solver_crash_mid_run_is_recorded_and_the_next_episode_works(tmp_path: Path) -> None:
    env = FoamCaseEnv(_cfg(tmp_path, failure_penalty=-2000.0))
    try:
        env.reset(seed=0)
        env.step(BEST)
        pgid = env.solver_pgid
        assert pgid is not None and _group_alive(pgid)
        # break the case under the running solver: it resumes, then its next fvSolution read fails
        episode_case.relaxation_fifo(env.case_dir, 50).unlink()
        _, reward, terminated, truncated, info = env.step(BEST)
        assert (terminated, truncated, reward) == (True, False, -2000.0)
        assert info["outcome"] == "crashed" and "FOAM FATAL" in info["cause"]
        assert "Cannot open include file" in info["cause"]
        assert "iteration 50" in info["cause"] and info["iterations"] == 50
        assert info["episode"]["outcome"] == "crashed" and info["episode"]["return"] == -25 - 2000
        assert _wait_group_gone(pgid)
        with pytest.raises(RuntimeError):
            env.step(BEST)
        env.reset(seed=0)  # the case is rebuilt
        _, reward, _, _, info = env.step(BEST)
        assert (reward, info["outcome"]) == (-25.0, "running")
    finally:
        env.close()


def test_floating_point_exception_is_a_crash(tmp_path: Path) -> None:
    env = FoamCaseEnv(_cfg(tmp_path))
    try:
        env.reset(seed=0)
        with FoamFile(env.case_dir / "0" / "omega") as omega:  # corrupted field: nu_t = k / 0
            omega["internalField"] = 0.0
        _, reward, terminated, _, info = env.step(BEST)
    finally:
        env.close()
    assert terminated and info["outcome"] == "crashed"
    assert "SIGFPE" in info["cause"] and reward == -1000


def test_hung_solver_is_killed_by_the_watchdog(tmp_path: Path) -> None:
    env = FoamCaseEnv(_cfg(tmp_path, interval=10, step_timeout_s=3.0))
    try:
        env.reset(seed=0)
        env.step(BEST)
        pgid = env.solver_pgid
        assert pgid is not None
        os.killpg(pgid, signal.SIGSTOP)
        start = time.monotonic()
        _, reward, terminated, _, info = env.step(BEST)
        waited = time.monotonic() - start
    finally:
        env.close()
    assert terminated and info["outcome"] == "hung" and "watchdog" in info["cause"]
    assert 3.0 <= waited < 15 and reward == -(1000 - 10)
    # stopped at the pause after iteration 10: K and the cause name that iteration, whatever the timing
    assert info["iterations"] == 10 and info["cause"].endswith("(last iteration started: 10)")
    assert _wait_group_gone(pgid)


def test_two_envs_cannot_share_an_env_directory(tmp_path: Path) -> None:
    first = FoamCaseEnv(_cfg(tmp_path))
    try:
        with pytest.raises(ValueError, match="in use by another FoamCaseEnv") as error:
            FoamCaseEnv(_cfg(tmp_path))
        assert "\n" not in str(error.value)
        with FoamCaseEnv(_cfg(tmp_path), env_id=1) as other:  # another env_id is another directory
            other.reset(seed=0)
        # the refused env touched nothing: the first one's case still runs
        first.reset(seed=0)
        _, reward, _, _, info = first.step(BEST)
        assert (reward, info["outcome"]) == (-25.0, "running")
    finally:
        first.close()
    with FoamCaseEnv(_cfg(tmp_path)) as again:  # released by close()
        assert again.root == first.root


def test_close_leaves_no_process_behind(tmp_path: Path) -> None:
    with FoamCaseEnv(_cfg(tmp_path)) as env:
        env.reset(seed=0)
        env.step(BEST)
        pgid = env.solver_pgid
        assert pgid is not None and _group_alive(pgid)
    assert _wait_group_gone(pgid)
    assert not (tmp_path / "env_0").exists()


def test_user_case_with_a_renamed_inlet_patch(tmp_path: Path) -> None:
    user_case = tmp_path / "my_case"
    shutil.copytree(template.TEMPLATE_DIR, user_case)
    with FoamFile(user_case / "system" / "meshParameters") as params:
        params.update(template.mesh_parameters(0.4, 0.0127))
    blocks = user_case / "system" / "blockMeshDict"
    blocks.write_text(blocks.read_text().replace("    inlet\n    {", "    entry\n    {"))
    for name in ("U", "p", "k", "omega", "nut"):
        field = user_case / "0" / name
        field.write_text(field.read_text().replace("    inlet\n    {", "    entry\n    {"))
    message = f"^{user_case}/0/U: no boundaryField entry for the inlet patch 'inlet'"
    with pytest.raises(CaseError, match=message):
        FoamCaseEnv(_cfg(tmp_path / "wrong", case_dir=user_case))
    assert not (tmp_path / "wrong" / "env_0").exists()
    # the template has no relaxationFactors of its own: a user's copy of it must name the k/omega factor
    env = FoamCaseEnv(_cfg(tmp_path / "right", case_dir=user_case, inlet_patch="entry", relax_k_omega=0.8))
    try:
        obs, _ = env.reset(options={"inlet_velocity": 50.0})
        assert obs[0] == pytest.approx(50.0**2 / U_REF**2)
        _, reward, _, _, info = env.step(BEST)
        assert reward == -25.0 and info["outcome"] == "running"
        # the inlet term printed by the solver's function object is the inlet speed squared
        assert env.parser.inlet_state == pytest.approx(2500.0)
    finally:
        env.close()
    # the user's case itself is untouched
    original = FoamFile(user_case / "0" / "U")["boundaryField"]["entry"]["value"]
    np.testing.assert_allclose(original, [44.2, 0, 0])


def test_broken_user_case_is_a_one_line_value_error(tmp_path: Path) -> None:
    user_case = tmp_path / "broken"
    shutil.copytree(template.TEMPLATE_DIR, user_case)
    (user_case / "0" / "U").unlink()
    with pytest.raises(ValueError, match=r"missing 0/U") as error:
        FoamCaseEnv(_cfg(tmp_path, case_dir=user_case))
    assert "\n" not in str(error.value)
    assert not (tmp_path / "env_0").exists()  # a failed construction leaves nothing behind


def test_seeded_inlet_velocity_and_residual_features(tmp_path: Path) -> None:
    env = FoamCaseEnv(_cfg(tmp_path, residual_features=2))
    try:
        speeds = [env.reset(seed=s)[1]["inlet_velocity"] for s in (7, 7, 8)]
        assert speeds[0] == speeds[1] != speeds[2] and all(35 <= v <= 65 for v in speeds)
        obs, _ = env.reset(seed=7)
        for bad in ([np.nan, 0.5], [0.5, 0.5, 0.5], "fast"):
            with pytest.raises(ValueError, match="action"):
                env.step(bad)
        assert obs.shape == (9,) and env.observation_space_spec.shape == (9,)
        assert np.all(obs[1:] == 0.0)  # no residual yet: log10(1)
        obs, _, _, _, info = env.step(BEST)
        expected = [np.log10(info["residuals"][name]) for name in env.cfg.convergence]
        np.testing.assert_allclose(obs[5:], expected, rtol=1e-5)
        assert obs[0] == pytest.approx((env.parser.inlet_state + env.parser.cells_state) / U_REF**2)
    finally:
        env.close()


def test_one_step_of_a_fixed_inlet_costs_one_interval_in_its_boxes(tmp_path: Path) -> None:
    with FoamCaseEnv(_cfg(tmp_path, inlet_velocity=40.0)) as env:
        obs, _ = env.reset(seed=3)
        next_obs, reward, terminated, _, info = env.step(np.array(BEST))
        assert env.action_space_spec.shape == (2,) and env.observation_space_spec.shape == (1,)
    assert obs[0] == pytest.approx(40.0**2 / U_REF**2)
    assert next_obs.shape == (1,) and next_obs.dtype == np.float32
    assert reward == -25.0 and not terminated and info["iterations"] == 25


def test_an_action_on_the_float32_boxs_edge_reaches_fvsolution_as_the_exact_bound(tmp_path: Path,
                                                                                   monkeypatch) -> None:
    """The trainer's box is float32 (float32(0.95) = 0.949999988); with an action margin the policy's
    clipped action is that value exactly. What the bridge feeds fvSolution must be 0.95 itself."""
    cfg = _cfg(tmp_path, interval=10)
    edge = np.array([cfg.action_high[0], cfg.action_low[1]], np.float32).astype(np.float64)
    assert edge.tolist() != [0.95, 0.2]
    fed: list[bytes] = []
    real_release = FoamSolver.release

    def recording_release(solver: FoamSolver, text: bytes) -> None:
        fed.append(text)
        real_release(solver, text)

    monkeypatch.setattr(FoamSolver, "release", recording_release)
    with FoamCaseEnv(cfg) as env:
        env.reset(seed=0)
        _, _, _, _, info = env.step(edge)
        assert info["outcome"] == "running"
        env.step(edge)
    factors = FoamFile.loads(fed[-1])["relaxationFactors"]  # the FIFO fvSolution #includes
    assert (factors["equations"]["U"], factors["fields"]["p"]) == (0.95, 0.2)
    assert all(text == fed[0] for text in fed)
    # that edge is exactly what the trainer's policy sends (after the solver ran: JAX threads, then no fork)
    batch = SimpleNamespace(num_envs=1, observation_spec=observation_spec(cfg), action_spec=action_spec(cfg))
    box = HostVecEnv(batch).action_space()  # the box the trainer acts in
    sent = to_box(np.array([50.0, -50.0], np.float32), box.low, box.high, 0.1)
    assert np.asarray(sent, np.float64).tolist() == edge.tolist()
