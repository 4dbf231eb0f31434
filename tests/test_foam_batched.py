"""BatchedFoamEnv on the local process pool: auto-reset, per-env accounting, surviving a killed worker.

The OpenFOAM tests run the real simpleFoam on the smallest usable mesh (mesh_scale 0.4 =
MESH_SCALE_USABLE_MIN, 3,276 cells) with a low iteration cap, so episodes end within a few steps.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import signal
import subprocess
import time

import numpy as np
import pytest
from foam_marks import HAVE_OPENFOAM, needs_openfoam

from foam_bridge._backends import WORKER_DIED, env_dir, validate_pool
from foam_bridge._backends.reaper import kill_processes_under, processes_under
from foam_bridge._batched import BatchedFoamEnv, failure_reward
from foam_bridge._config import FoamEnvConfig
from foam_bridge._env import FoamCaseEnv
from foam_bridge._errors import OpenFOAMNotFoundError
from foam_bridge._openfoam import OpenFOAM
from foam_bridge._records import EpisodeRecord

# Smallest usable mesh, 300-iteration cap: an episode is at most 3 steps of 100 iterations.
COARSE = FoamEnvConfig(mesh_scale=0.4, simple_variant="SIMPLEC", relax_k_omega=0.8, max_iterations=300,
                       step_timeout_s=60.0)
SAFE_ACTION = (0.9, 0.5)  # stable on this mesh: converges in ~270-280 iterations at 35-65 m/s


# ----- no solver needed --------------------------------------------------------------------------
def test_validate_pool_rejects_bad_sizes():
    validate_pool(3, 2)
    for num_envs, pool in [(2, 0), (2, 3), (0, 1), (2, 1.5), (2, True)]:
        with pytest.raises(ValueError, match="pool|num_envs"):
            validate_pool(num_envs, pool)


def test_bad_batch_sizes_are_value_errors_before_anything_is_created(tmp_path):
    assert validate_pool(3, None) == min(3, os.cpu_count() or 1)
    work_dir = tmp_path / "work"
    for num_envs in (-1, 1.5, "2"):
        with pytest.raises(ValueError, match="num_envs"):
            BatchedFoamEnv(COARSE, num_envs, work_dir=work_dir)
    assert not work_dir.exists()


def test_failure_reward_is_the_rest_of_the_cap_or_the_penalty():
    assert failure_reward(FoamEnvConfig(max_iterations=4000), 1269) == -2731.0
    assert failure_reward(FoamEnvConfig(max_iterations=4000, failure_penalty=-2000.0), 1269) == -2000.0


def test_reaper_kills_the_bridges_process_group_and_nothing_else_under_a_directory(tmp_path):
    case = tmp_path / "env_0"
    (case / "episode").mkdir(parents=True)
    # A stand-in for an orphaned solver: the bridge's environment, its own session, a child in its group.
    bridge_env = OpenFOAM(os.environ["PATH"], "").environment(case / "episode")
    proc = subprocess.Popen(["sh", "-c", "sleep 60 & sleep 60"], cwd=case, env=bridge_env,
                            start_new_session=True)
    # The user's: a shell cd-ed into the kept case (its own group, with a child), and one elsewhere.
    user = subprocess.Popen(["sh", "-c", "sleep 60 & sleep 60"], cwd=case / "episode", start_new_session=True)
    bystander = subprocess.Popen(["sleep", "60"], cwd=tmp_path, start_new_session=True)
    try:
        time.sleep(0.2)
        assert proc.pid in processes_under(case)
        assert user.pid not in processes_under(case) and bystander.pid not in processes_under(case)
        assert kill_processes_under(case) >= 1
        assert proc.wait(timeout=5) == -signal.SIGKILL
        deadline = time.monotonic() + 5
        while processes_under(case) and time.monotonic() < deadline:  # the backgrounded child too
            time.sleep(0.05)
        assert processes_under(case) == []
        assert user.poll() is None and bystander.poll() is None
        os.killpg(user.pid, 0)  # the user's whole group lives (ProcessLookupError otherwise)
    finally:
        for p in (proc, user, bystander):
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, signal.SIGKILL)
            p.wait()


@needs_openfoam
def test_reaper_kills_a_bridge_started_solver_and_spares_a_user_in_its_case(tmp_path):
    with FoamCaseEnv(dataclasses.replace(COARSE, interval=10, work_dir=tmp_path)) as env:
        env.reset(seed=0)
        env.step(SAFE_ACTION)  # the solver now waits at its pause after iteration 10
        solver = env.solver_pgid
        user = subprocess.Popen(["sleep", "60"], cwd=env.case_dir, start_new_session=True)
        try:
            assert processes_under(env.root) and user.pid not in processes_under(env.root)
            kill_processes_under(env.root)
            deadline = time.monotonic() + 5
            while processes_under(env.root) and time.monotonic() < deadline:
                time.sleep(0.05)
            assert processes_under(env.root) == [] and user.poll() is None
            assert env.step(SAFE_ACTION)[4]["outcome"] == "crashed"  # its solver was killed
            with pytest.raises(ProcessLookupError):
                os.killpg(solver, 0)
        finally:
            user.kill()
            user.wait()


def test_missing_openfoam_or_case_fails_at_construction(tmp_path):
    with pytest.raises(OpenFOAMNotFoundError, match="install"):
        BatchedFoamEnv(dataclasses.replace(COARSE, openfoam_path=str(tmp_path)), 2, work_dir=tmp_path)
    if HAVE_OPENFOAM:
        missing = dataclasses.replace(COARSE, case_dir=tmp_path / "no_such_case")
        with pytest.raises(ValueError, match="no_such_case"):
            BatchedFoamEnv(missing, 2, work_dir=tmp_path)
    assert list(tmp_path.iterdir()) == []


@needs_openfoam
def test_bad_actions_and_backend_are_one_line_value_errors(tmp_path):
    with pytest.raises(ValueError, match="backend"):
        BatchedFoamEnv(COARSE, 2, backend="mpi", work_dir=tmp_path)
    with pytest.raises(ValueError, match="pool"):
        BatchedFoamEnv(COARSE, 2, pool=3, work_dir=tmp_path)
    with BatchedFoamEnv(COARSE, 2, pool=1, work_dir=tmp_path) as env:
        with pytest.raises(ValueError, match=r"shape \(2, 2\)"):
            env.step(np.zeros((3, 2)))
        with pytest.raises(ValueError, match="finite"):
            env.step(np.array([[0.5, 0.5], [np.nan, 0.5]]))
    assert list(tmp_path.iterdir()) == []  # workers create case dirs only when an env is used


# ----- real simpleFoam ---------------------------------------------------------------------------
def pick(infos: dict, i: int) -> dict:
    """Env ``i``'s entries of gymnasium-batched infos (nested dicts are batched key by key)."""
    return {k: pick(v, i) if isinstance(v, dict) else v[i] for k, v in infos.items() if not k.startswith("_")}


def run_until_each_env_ended(env: BatchedFoamEnv, episodes: int, action=SAFE_ACTION, max_steps: int = 30):
    """Step with a constant action until every env ended ``episodes`` episodes; returns per-env records."""
    obs, infos = env.reset()
    returns = np.zeros(env.num_envs)
    ended: list[list[dict]] = [[] for _ in range(env.num_envs)]
    actions = np.tile(action, (env.num_envs, 1))
    for _ in range(max_steps):
        obs, reward, terminated, truncated, infos = env.step(actions)
        returns += reward
        assert obs.shape == (env.num_envs, COARSE.observation_size) and obs.dtype == np.float32
        for i in np.flatnonzero(terminated | truncated):
            final = pick(infos["final_info"], i)
            final["sum_of_rewards"] = returns[i]
            final["next_obs"] = obs[i].copy()
            final["next_inlet_velocity"] = infos["inlet_velocity"][i]
            final["final_obs"] = infos["final_obs"][i]
            ended[i].append(final)
            returns[i] = 0.0
        if all(len(e) >= episodes for e in ended):
            return ended
    raise AssertionError(f"episodes did not end within {max_steps} steps: {[len(e) for e in ended]}")


@pytest.mark.slow  # real episodes to their end
@needs_openfoam
def test_pool_of_two_runs_two_cases_with_autoreset_and_accounting(tmp_path):
    with BatchedFoamEnv(COARSE, 2, pool=2, work_dir=tmp_path, seed=1) as env:
        assert len(set(env.worker_pids())) == 2
        ended = run_until_each_env_ended(env, episodes=2)
        assert sorted(p.name for p in tmp_path.iterdir()) == ["env_0", "env_1"]
    for records in ended:
        velocities = [r["inlet_velocity"] for r in records]
        assert len(set(velocities)) == len(velocities)  # each episode drew its own inlet velocity
        for record in records:
            assert 0 < record["iterations"] <= COARSE.max_iterations
            # gamma = 1: the return is minus the iterations (a failure: as if run to the cap), and the
            # host's per-env sum of the rewards agrees with the env's own episode record.
            failed = record["outcome"] in ("crashed", "diverged", "hung")
            expected = -COARSE.max_iterations if failed else -record["iterations"]
            assert record["sum_of_rewards"] == expected == record["episode"]["return"]
            # one record (foam_bridge._records), with where it ran and which env ran it
            assert set(record["episode"]) == set(EpisodeRecord(env_id=0, node="").to_json())
            # Auto-reset: obs is the next episode's first observation (internal field at rest, so the
            # state is the inlet's |U|^2 only), not the final one.
            assert record["next_obs"][0] == pytest.approx(
                record["next_inlet_velocity"] ** 2 / COARSE.state_scale, rel=1e-3)
            assert record["final_obs"][0] != pytest.approx(record["next_obs"][0], rel=1e-3)


@pytest.mark.slow  # a worker killed, episodes to their end
@needs_openfoam
def test_killed_worker_ends_only_its_episode_and_is_replaced(tmp_path):
    with BatchedFoamEnv(COARSE, 2, pool=2, work_dir=tmp_path, seed=2) as env:
        env.reset()
        actions = np.tile(SAFE_ACTION, (2, 1))
        env.step(actions)
        victim = env.worker_pids()[0]
        orphans = processes_under(env_dir(tmp_path, 0))
        assert orphans, "env 0 should have a paused solver"
        # a user's shell in the running case, which the bridge did not start: the replacement spares it
        user = subprocess.Popen(["sleep", "60"], cwd=env_dir(tmp_path, 0) / "episode", start_new_session=True)
        os.kill(victim, signal.SIGKILL)
        try:
            obs, reward, terminated, truncated, infos = env.step(actions)
            assert user.poll() is None
        finally:
            user.kill()
            user.wait()

        assert terminated.tolist() == [True, False] and truncated.tolist() == [False, False]
        assert infos["final_info"]["outcome"][0] == "crashed"
        assert infos["final_info"]["cause"][0] == WORKER_DIED
        assert infos["final_info"]["episode"]["iterations"][0] == 100
        # the batch's record of it is the env's record (its costs unknown), env_id aside
        keys = {key for key in infos["final_info"]["episode"] if not key.startswith("_")}  # not the masks
        assert keys == set(EpisodeRecord(node="").to_json())
        assert infos["final_info"]["episode"]["steps"][0] == 2
        assert reward[0] == failure_reward(COARSE, 100)
        assert reward[1] == -100 and infos["iterations"][1] == 200  # the other env went on
        new_pid = env.worker_pids()[0]
        assert new_pid != victim and env.worker_pids()[1] != victim
        for pid in orphans:  # the dead worker's solver was reaped, not left running
            assert not os.path.exists(f"/proc/{pid}") or _is_zombie(pid)

        obs, reward, terminated, truncated, infos = env.step(actions)  # env 0's new episode runs
        assert infos["iterations"][0] == 100 and infos["outcome"][0] == "running"
        assert reward[0] == -100


def _is_zombie(pid: int) -> bool:
    with open(f"/proc/{pid}/stat") as handle:
        return handle.read().split(")")[-1].split()[0] == "Z"


@pytest.mark.slow  # two batches of real episodes
@needs_openfoam
def test_a_snapshot_replays_the_running_episodes_into_a_new_batch_exactly(tmp_path):
    """Three steps, snapshot (through JSON, as a checkpoint holds it), then the original batch and a new
    one with other seeds replayed from the snapshot go on identically: same observations, rewards and
    episode ends, and the same seeds for the episodes after the auto-reset (the streams travel too)."""
    import json

    cfg = dataclasses.replace(COARSE, interval=50, max_iterations=400)
    rng = np.random.default_rng(0)
    schedule = [np.column_stack([rng.uniform(0.85, 0.95, 2), rng.uniform(0.5, 0.9, 2)]) for _ in range(12)]

    def go_on(envs):
        out = []
        for actions in schedule[3:]:
            obs, reward, terminated, truncated, infos = envs.step(actions)
            out.append((obs.tolist(), reward.tolist(), terminated.tolist(), truncated.tolist(),
                        envs.snapshot()[0]["seed"], envs.snapshot()[1]["seed"]))
        return out

    with BatchedFoamEnv(cfg, 2, pool=2, seed=5, work_dir=tmp_path / "a") as first:
        first.reset()
        for actions in schedule[:3]:
            first.step(actions)
        snapshot = json.loads(json.dumps(first.snapshot()))
        assert [len(entry["actions"]) for entry in snapshot] == [3, 3]
        expected = go_on(first)
    assert any(step[2][0] or step[3][0] for step in expected)  # an episode ended and was auto-reset
    with BatchedFoamEnv(cfg, 2, pool=2, seed=99, work_dir=tmp_path / "b") as second:
        second.reset()
        assert second.replay(snapshot) == ""
        np.testing.assert_array_equal(second.iterations(), [e["iterations"] for e in snapshot])
        assert go_on(second) == expected
        tampered = [dict(snapshot[0], iterations=snapshot[0]["iterations"] + 1), snapshot[1]]
        assert "differs" in second.replay(tampered)
