"""AsyncFoamEnv (foam_bridge._async_batch) and the stand-in solver (foam_bridge._standin), on the local pool;
AsyncFoamEnv's snapshot and replay (a resume) from every state an env can be in.

The stand-in sleeps milliseconds per step, so these run in seconds without OpenFOAM; the real solver
goes through the same pool code (tests/test_foam_batched.py and friends cover it in lock-step).
"""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest
from foam_marks import needs_openfoam

from foam_bridge._async_batch import AsyncFoamEnv
from foam_bridge._batched import SEED_BOUND, BatchedFoamEnv
from foam_bridge._config import FoamEnvConfig
from foam_bridge._standin import Profile, StandIn, StandInEnv

CFG = FoamEnvConfig(mesh_scale=0.5)
#: Episodes of 2, 3 and 4 steps (the last one partial: 50, 20 iterations), 5-10 ms per step.
FAST = Profile(iterations=(150, 220, 400), seconds_per_iteration=(1e-4, 5e-5, 1e-4), reset_s=0.002)


class FailingResets(StandIn):
    """A stand-in whose env ``env_id`` fails its resets number ``failing`` (1 = the first) in a worker."""

    def __init__(self, profile: Profile, env_id: int, failing: tuple[int, ...]) -> None:
        super().__init__(profile)
        self.env_id, self.failing = env_id, failing

    def __call__(self, cfg: FoamEnvConfig, work_dir: Path, env_id: int) -> StandInEnv:
        env = super().__call__(cfg, work_dir, env_id)
        if env_id == self.env_id:
            resets, reset = [0], env.reset

            def failing_reset(*args, **kwargs):
                resets[0] += 1
                if resets[0] in self.failing:
                    raise RuntimeError(f"reset {resets[0]} refused")
                return reset(*args, **kwargs)

            env.reset = failing_reset
        return env


def _episodes(infos: dict, ids: np.ndarray) -> list[tuple[int, dict]]:
    """(env id, final info) of each row whose episode ended."""
    mask = infos.get("_final_info", np.zeros(len(ids), bool))
    ended = []
    for row in np.flatnonzero(mask):
        info = infos["final_info"]
        ended.append((int(ids[row]), {key: info[key][row] for key in ("outcome", "cause", "iterations")}))
    return ended


def _run_async(env: AsyncFoamEnv, rounds: int) -> list[tuple[int, dict]]:
    env.async_reset(seed=3)
    ended = []
    for _ in range(rounds):
        ids, obs, reward, terminated, truncated, infos = env.recv()
        assert len(set(ids.tolist())) == env.batch_size and obs.shape == (env.batch_size, 1)
        ended += _episodes(infos, ids)
        env.send(np.full((len(ids), 2), 0.5), ids)
    return ended


def test_the_standin_profile_fits_a_runs_episodes_and_its_env_sleeps_that_long():
    csv = Path(__file__).parents[1] / "experiments/foam/train-mesh05/episodes.csv"
    profile, raw = Profile.from_csv(csv, 757), Profile.from_csv(csv, 757, detrend=0)
    assert len(profile.iterations) == 757 and profile.iterations == raw.iterations
    assert 40 < profile.describe()["mean_last_step_iterations"] < 55  # RESULTS_train_foam: 47 of 100
    spread = [np.std(p.seconds_per_iteration) / np.mean(p.seconds_per_iteration) for p in (profile, raw)]
    assert spread[0] < 0.5 * spread[1]  # the machine's load over time taken out
    env = StandInEnv(CFG, FAST, env_id=0)
    env.reset(seed=1)
    started, done, steps = time.monotonic(), False, 0
    while not done:
        _, reward, done, _, info = env.step([0.5, 0.5])
        steps += 1
    record = info["episode"]
    assert record["iterations"] in FAST.iterations and steps == -(-record["iterations"] // 100)
    assert record["return"] == -record["iterations"]
    assert 0 < record["solver_time_s"] <= record["wall_time_s"] <= time.monotonic() - started


def test_async_steps_every_env_and_its_episodes_are_the_lock_step_ones():
    with AsyncFoamEnv(CFG, num_envs=4, batch_size=2, pool=2, seed=0, make_env=StandIn(FAST)) as env:
        ended = _run_async(env, 40)
    per_env = {i: [e["iterations"] for j, e in ended if j == i] for i in range(4)}
    assert all(len(ks) >= 2 for ks in per_env.values()), per_env  # every env got its turns
    assert {e["outcome"] for _, e in ended} == {"converged"}
    # the same seed streams: each env's episodes are the ones the lock-step batch runs
    with BatchedFoamEnv(CFG, num_envs=4, pool=2, seed=0, make_env=StandIn(FAST)) as batch:
        batch.reset(seed=3)
        lock = {i: [] for i in range(4)}
        while min(len(ks) for ks in lock.values()) < max(len(ks) for ks in per_env.values()):
            *_, infos = batch.step(np.full((4, 2), 0.5))
            for i, e in _episodes(infos, np.arange(4)):
                lock[i].append(e["iterations"])
    assert all(lock[i][:len(ks)] == ks for i, ks in per_env.items())


def test_an_ended_episode_comes_back_with_the_next_episodes_first_observation():
    with AsyncFoamEnv(CFG, num_envs=3, batch_size=1, pool=1, seed=0, make_env=StandIn(FAST)) as env:
        env.async_reset()
        for _ in range(30):
            ids, obs, reward, terminated, truncated, infos = env.recv()
            if terminated[0]:
                assert infos["_final_info"][0] and infos["final_obs"][0][0] == 0.0  # nothing left of it
                assert obs[0, 0] == 1.0  # the new episode's start
                assert reward[0] < 0
            env.send([[0.5, 0.5]], ids)


def test_a_killed_worker_ends_its_envs_episodes_and_the_batch_goes_on():
    slow = Profile(iterations=(400,), seconds_per_iteration=(2e-3,), reset_s=0.002)  # 0.2 s steps
    with AsyncFoamEnv(CFG, num_envs=4, batch_size=2, pool=2, seed=0, make_env=StandIn(slow)) as env:
        env.async_reset()
        victim = env.worker_pids()[1]  # hosts envs 1 and 3
        ids, *_ = env.recv()
        env.send(np.full((2, 2), 0.5), ids)
        os.kill(victim, signal.SIGKILL)
        crashed = []
        for _ in range(6):
            ids, _, _, terminated, _, infos = env.recv()
            crashed += [(i, e) for i, e in _episodes(infos, ids) if e["outcome"] == "crashed"]
            env.send(np.full((2, 2), 0.5), ids)
        assert crashed and {i for i, _ in crashed} <= {1, 3}
        assert all(e["cause"] == "worker died" for _, e in crashed)
        assert env.worker_pids()[1] != victim  # replaced


def test_a_failed_reset_is_retried_when_the_env_is_sent_as_the_lock_step_batch_does():
    make = FailingResets(FAST, env_id=0, failing=(2,))  # env 0's first auto-reset fails, its retry works
    with AsyncFoamEnv(CFG, num_envs=1, batch_size=1, pool=1, seed=0, make_env=make) as env:
        env.async_reset()
        seen = []
        for _ in range(8):
            ids, obs, reward, terminated, truncated, infos = env.recv()
            seen.append((bool(terminated[0]), bool(truncated[0]), bool(infos.get("_final_info", [0])[0]),
                         float(reward[0]), float(obs[0, 0])))
            env.send([[0.5, 0.5]], ids)
    ends = [i for i, (term, *_) in enumerate(seen) if term]
    first = ends[0]
    assert seen[first][2] and seen[first][4] == 0.0  # ended, with final info; obs stays the final one
    assert seen[first + 1] == (False, True, False, 0.0, 1.0)  # the retry: a non-transition, new episode


@needs_openfoam
def test_the_real_solver_runs_asynchronously_and_reports_its_episodes():
    # mesh 0.4, a 200-iteration cap: every episode is 2 steps of 100 iterations, converged or truncated
    cfg = FoamEnvConfig(mesh_scale=0.4, max_iterations=200, step_timeout_s=60.0)
    with AsyncFoamEnv(cfg, num_envs=1, batch_size=1, pool=1, seed=0) as env:  # one case build
        env.async_reset()
        ended = []
        for _ in range(3):
            ids, obs, reward, terminated, truncated, infos = env.recv()
            assert obs.shape == (1, 1) and np.isfinite(obs).all()
            ended += _episodes(infos, ids)
            env.send([[0.9, 0.5]], ids)
    assert ended and all(e["outcome"] in ("converged", "truncated") and 0 < e["iterations"] <= 200
                         for _, e in ended)


def test_the_caller_s_errors_are_one_line_value_errors():
    with pytest.raises(ValueError, match="batch_size"):
        AsyncFoamEnv(CFG, num_envs=2, batch_size=3, pool=1, make_env=StandIn(FAST))
    with AsyncFoamEnv(CFG, num_envs=2, batch_size=1, pool=1, make_env=StandIn(FAST)) as env:
        with pytest.raises(ValueError, match="async_reset"):
            env.recv()
        env.async_reset()
        ids, *_ = env.recv()
        with pytest.raises(ValueError, match="send"):
            env.recv()
        with pytest.raises(ValueError, match="env ids"):
            env.send([[0.5, 0.5]], [1 - ids[0]])
        with pytest.raises(ValueError, match="finite"):
            env.send([[np.nan, 0.5]], ids)
        env.send([[0.5, 0.5]], ids)
        assert len(env.recv()[0]) == 1


# ---- an episode that went with its worker while its result waited ----------------------------------
class DiesOnReset(StandIn):
    """Env ``env_id`` ends in one step and kills its worker at its second reset there (an auto-reset
    that only it does in lock-step), once per work directory; the other envs run 4 steps."""

    def __init__(self, env_id: int) -> None:
        super().__init__(Profile(iterations=(400,), seconds_per_iteration=(1e-4,), reset_s=0.002))
        self.env_id = env_id

    def __call__(self, cfg: FoamEnvConfig, work_dir: Path, env_id: int) -> StandInEnv:
        if env_id != self.env_id:
            return super().__call__(cfg, work_dir, env_id)
        short = Profile(iterations=(100,), seconds_per_iteration=(1e-4,), reset_s=0.002)
        env = StandInEnv(cfg, short, env_id)
        resets, reset = [0], env.reset

        def dying_reset(*args, **kwargs):
            resets[0] += 1
            if resets[0] == 2 and not (work_dir / "died").exists():
                (work_dir / "died").touch()
                os._exit(1)
            return reset(*args, **kwargs)

        env.reset = dying_reset
        return env


def _ends(ids: np.ndarray, infos: dict) -> list[tuple[int, str, str]]:
    return [(i, e["outcome"], e["cause"]) for i, e in _episodes(infos, ids)]


def test_async_an_episode_lost_with_its_worker_while_its_result_waited_ends_with_the_worker_s_cause():
    # 5 envs on 2 workers, 2 per call: env 4 (worker 0) is still waiting when worker 0 dies under envs
    # 0 and 2; its next step must not go to the fresh worker, which has no episode of it
    slow = Profile(iterations=(400,), seconds_per_iteration=(2e-3,), reset_s=0.002)
    with AsyncFoamEnv(CFG, num_envs=5, batch_size=2, pool=2, seed=0, make_env=StandIn(slow)) as env:
        env.async_reset()
        victim = env.worker_pids()[0]
        for _ in range(2):
            ids, *_ = env.recv()
            env.send(np.full((2, 2), 0.5), ids)
        os.kill(victim, signal.SIGKILL)
        ends = []
        while not any(i == 4 and outcome == "converged" for i, outcome, _ in ends):
            ids, _, _, _, _, infos = env.recv()
            ends += _ends(ids, infos)
            env.send(np.full((2, 2), 0.5), ids)
    crashed = sorted((i, cause) for i, outcome, cause in ends if outcome == "crashed")
    assert crashed == [(0, "worker died"), (2, "worker died"), (4, "worker died")], ends


def test_lock_step_an_episode_lost_with_its_worker_during_another_env_s_reset_ends_with_its_cause():
    # env 1's auto-reset kills worker 1 and is retried on its replacement; env 3, on the same worker and
    # in mid-episode, had no request in that reset: its episode died with the worker all the same
    with BatchedFoamEnv(CFG, num_envs=4, pool=2, seed=0, make_env=DiesOnReset(env_id=1)) as env:
        env.reset()
        ends = []
        for _ in range(5):
            *_, infos = env.step(np.full((4, 2), 0.5))
            ends += _ends(np.arange(4), infos)
    assert [(i, cause) for i, outcome, cause in ends if outcome == "crashed"] == [(3, "worker died")], ends
    assert [i for i, outcome, _ in ends if outcome == "converged"].count(1) >= 3  # env 1 goes on


# ---- snapshot and replay (a resume) -------------------------------------------------------------------
#: 5-10 ms steps, 30 ms resets: at most moments some env has a background reset in flight.
SLOW_RESETS = Profile(iterations=(150, 220, 400), seconds_per_iteration=(1e-4, 5e-5, 1e-4), reset_s=0.03)


class FailingSeeds(StandIn):
    """A stand-in that refuses the resets with a seed in ``failing``: the same resets fail in any batch
    with the same seed streams, a replayed one included (FailingResets counts per worker)."""

    def __init__(self, profile: Profile, failing: set[int]) -> None:
        super().__init__(profile)
        self.failing = failing

    def __call__(self, cfg: FoamEnvConfig, work_dir: Path, env_id: int) -> StandInEnv:
        env = super().__call__(cfg, work_dir, env_id)
        reset = env.reset

        def failing_reset(seed=None, options=None):
            if seed in self.failing:
                raise RuntimeError(f"seed {seed} refused")
            return reset(seed, options)

        env.reset = failing_reset
        return env


def _stream_seeds(seed: int, num_envs: int, env_id: int, count: int) -> list[int]:
    """The first ``count`` episode seeds of env ``env_id`` in a batch seeded with ``seed``."""
    stream = np.random.default_rng(np.random.SeedSequence(seed).spawn(num_envs)[env_id])
    return [int(stream.integers(SEED_BOUND)) for _ in range(count)]


def _rows(ids, obs, reward, terminated, truncated, infos) -> list[tuple[int, tuple]]:
    """(env, what its row says) of each row of a recv: observation, reward, ends, the ended episode."""
    ended = dict(_episodes(infos, ids))
    return [(int(i), (obs[r].tolist(), float(reward[r]), bool(terminated[r]), bool(truncated[r]),
                      ended.get(int(i)))) for r, i in enumerate(ids)]


def _places(snapshot: dict) -> set[str]:
    """Where the snapshot's envs stand."""
    places = set()
    for i, entry in enumerate(snapshot["envs"]):
        ready = entry.get("ready")
        places |= {"with learner"} if i in snapshot["with_learner"] else set()
        places |= {"step in flight"} if "step" in entry else set()
        places |= {f"reset in flight ({entry['reset']['kind']})"} if "reset" in entry else set()
        places |= {"ready" if not ready or not (ready["terminated"] or ready["truncated"])
                   else "ended, ready"} if ready else set()
        places |= {"reset failed"} if entry["reset_failure"] else set()
    return places


ALL_PLACES = {"with learner", "step in flight", "reset in flight (ended)", "reset in flight (retry)", "ready",
              "ended, ready", "reset failed"}


@pytest.mark.slow  # many batches
def test_a_snapshot_in_every_state_replays_into_a_new_batch_that_goes_on_as_the_first():
    """Snapshots after recv (a checkpoint's moment), through JSON, replayed into a batch of other seeds:
    its snapshot is the same, and from there each env returns the rows the first batch's env returned."""
    seeds = _stream_seeds(3, 4, env_id=0, count=3)  # env 0's first auto-reset fails, and its retry
    make = FailingSeeds(SLOW_RESETS, failing={seeds[1], seeds[2]})
    with AsyncFoamEnv(CFG, num_envs=4, batch_size=1, pool=2, seed=0, make_env=make) as env:
        env.async_reset(seed=3)
        trace, snapshots = {i: [] for i in range(4)}, []
        for round_ in range(60):
            if round_ % 3 == 2:  # a slow learner: results pile up, ended episodes among them
                time.sleep(0.04)
            received = env.recv()
            for i, row in _rows(*received):
                trace[i].append(row)
            counts = {i: len(rows) for i, rows in trace.items()}
            snapshots.append((counts, json.loads(json.dumps(env.snapshot()))))
            env.send(np.full((1, 2), 0.5), received[0])
    covered, chosen = set(), []
    for counts, snapshot in snapshots[:40]:  # each replayed one is followed for 10 rows of 20 recorded
        if _places(snapshot) - covered:
            covered |= _places(snapshot)
            chosen.append((counts, snapshot))
    assert covered == ALL_PLACES
    with AsyncFoamEnv(CFG, num_envs=4, batch_size=1, pool=2, seed=99, make_env=make) as other:
        for counts, snapshot in chosen:
            assert other.replay(snapshot) == ""
            assert other.snapshot() == snapshot
            ids = snapshot["with_learner"]
            went_on = {i: [] for i in range(4)}
            for _ in range(10):
                other.send(np.full((1, 2), 0.5), ids)
                received = other.recv()
                ids = received[0]
                for i, row in _rows(*received):
                    went_on[i].append(row)
            for i, rows in went_on.items():
                assert rows == trace[i][counts[i]:counts[i] + len(rows)], (i, snapshot)
        # a snapshot that does not fit is refused, with why
        snapshot, running = next((s, i) for _, s in chosen for i, e in enumerate(s["envs"])
                                 if e["running"] and e["actions"])
        snapshot["envs"][running]["iterations"] += 1
        assert "differs" in other.replay(snapshot)
        snapshot["with_learner"] = []
        assert "does not place each env once" in other.replay(snapshot)
