"""The trainer on an asynchronous env batch (PPOConfig.async_envs: jaxsimrl.envs.host_async and
jaxsimrl.agents.ppo.rollout_async), on foam_bridge's stand-in solver: per-env GAE, one io_callback per
learner step, each env's transitions paired with its own results, faults, and train-foam's use of it,
killed with SIGKILL and resumed.

One trainer is compiled for the module; each test gives its host env a batch of its own (the callback
reads ``vec.batch`` when it runs), so the tests cost the stand-in's sleeps, not a compile each.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_async_batch import FAST, FailingResets

from foam_bridge._async_batch import AsyncFoamEnv
from foam_bridge._batched import BatchedFoamEnv
from foam_bridge._config import FoamEnvConfig
from foam_bridge._standin import Profile, StandIn
from jaxsimrl.agents.ppo import make_train
from jaxsimrl.agents.ppo.config import PPOConfig
from jaxsimrl.agents.ppo.losses import Batch, compute_gae_per_env, ppo_loss
from jaxsimrl.agents.ppo.networks import make_network
from jaxsimrl.agents.ppo.rollout import collect
from jaxsimrl.agents.ppo.rollout_async import async_env_step
from jaxsimrl.cli.main import main
from jaxsimrl.envs.host_async import AsyncHostVecEnv

CFG = FoamEnvConfig(mesh_scale=0.5)
B, E, T = 2, 4, 8  # learner rows, envs, learner steps per update
PPO = PPOConfig(num_envs=B, async_envs=E, steps_per_update=B * T, total_steps=B * T * 100, network="mlp",
                hidden_sizes=(8,), seq_len=1, num_minibatches=2, update_epochs=1, updates_per_chunk=1,
                normalize_obs=False, reward_scale=0.01)


class Recorded(AsyncFoamEnv):
    """An AsyncFoamEnv that counts its recv calls, keeps its reset seed, and can kill worker 1 at the
    first send from number ``kill_after_send`` on that steps one of its envs (the step is in flight)."""

    def __init__(self, *args, kill_after_send: int | None = None, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.recvs, self.sends, self.seed, self.kill_after_send = 0, 0, None, kill_after_send
        self.killed: int | None = None

    def async_reset(self, seed=None, options=None) -> None:
        self.seed = seed
        super().async_reset(seed, options)

    def recv(self):
        self.recvs += 1
        return super().recv()

    def send(self, actions, env_ids) -> None:
        super().send(actions, env_ids)
        self.sends += 1
        on_victim = {1, 3} & {int(i) for i in env_ids}  # worker 1 hosts envs 1 and 3
        if self.killed is None and self.kill_after_send and self.sends >= self.kill_after_send and on_victim:
            self.killed = self.worker_pids()[1]  # with a step of one of its envs in flight
            os.kill(self.killed, signal.SIGKILL)


@pytest.fixture(scope="module")
def trainer():
    """(trainer, host env) compiled once; :func:`_train` swaps the batch behind the host env."""
    batch = Recorded(CFG, num_envs=E, batch_size=B, pool=2, seed=0, make_env=StandIn(FAST))
    vec = AsyncHostVecEnv(batch)
    try:
        yield make_train(PPO, vec=vec, devices=jax.devices()[:1]), vec
    finally:
        vec.batch.close()


def _train(trainer, batch: AsyncFoamEnv, updates: int, until=None) -> tuple[list[dict], list, object]:
    """Run ``updates`` updates on ``batch`` (closed when the next test swaps it), and then more (up to
    50) until ``until(episodes)``: (metrics rows, ended episodes, state)."""
    ppo, vec = trainer
    vec.batch.close()
    vec.batch, vec.error, vec.busy_s = batch, None, 0.0
    vec.take_episodes()
    state, rows, episodes = ppo.init(jax.random.PRNGKey(1)), [], []
    vec.raise_if_failed()
    while len(rows) < updates or (until is not None and not until(episodes) and len(rows) < updates + 50):
        state, metrics = ppo.run_chunk(state)
        vec.raise_if_failed()
        rows.append({name: float(value[0]) for name, value in jax.device_get(metrics).items()})
        episodes += vec.take_episodes()
    return rows, episodes, state


def _per_env(episodes: list[tuple[int, dict]]) -> dict[int, list[int]]:
    return {i: [int(info["iterations"]) for j, info in episodes if j == i] for i in range(E)}


def test_gae_per_env_matches_a_numpy_loop_over_each_env_s_own_steps():
    rng = np.random.default_rng(0)
    ids = np.array([[0, 1], [2, 0], [1, 2], [0, 1], [2, 3], [1, 0], [3, 2]], np.int32)
    steps = ids.shape[0]
    weights = np.ones(ids.shape, np.float32)
    weights[0, :] = weights[1, 0] = weights[4, 1] = 0  # first appearances: no transition completed
    rewards, values, finals = (rng.normal(size=ids.shape).astype(np.float32) for _ in range(3))
    terminated, truncated = np.zeros(ids.shape, bool), np.zeros(ids.shape, bool)
    terminated[2, 0] = truncated[3, 1] = truncated[5, 1] = terminated[5, 1] = True
    seeds = rng.normal(size=4).astype(np.float32)
    gamma, lam = 0.97, 0.9
    adv, targets = compute_gae_per_env(*map(jnp.asarray, (rewards, values, terminated, truncated, finals,
                                                          weights, ids, seeds)), gamma, lam)
    expected = np.zeros(ids.shape, np.float32)
    for env in range(4):
        rows = [(t, r) for t in range(steps) for r in range(2) if ids[t, r] == env and weights[t, r]]
        next_value, next_adv = seeds[env], 0.0
        for t, r in reversed(rows):
            following = 0.0 if terminated[t, r] else finals[t, r] if truncated[t, r] else next_value
            cut = terminated[t, r] or truncated[t, r]
            carried = 0.0 if cut else gamma * lam * next_adv
            next_adv = rewards[t, r] + gamma * following - values[t, r] + carried
            expected[t, r], next_value = next_adv, values[t, r]
    np.testing.assert_allclose(np.asarray(adv), expected, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(np.asarray(targets), expected + values, rtol=1e-5, atol=1e-6)


@pytest.mark.slow  # compiles the loss for a batch
def test_rows_of_weight_zero_count_in_no_loss():
    rng = np.random.default_rng(1)
    config = PPO
    network = make_network(PPO, 2)
    params = network.init(jax.random.PRNGKey(0), (jnp.zeros((1, 1)),) * 2, jnp.zeros((1, 1, 1)),
                          jnp.zeros((1, 1), bool))
    shape = (1, 6)
    batch = Batch(jnp.asarray(rng.normal(size=shape + (1,)), jnp.float32), jnp.zeros(shape, bool),
                  jnp.asarray(rng.normal(size=shape + (2,)), jnp.float32), jnp.full(shape, -1.0),
                  jnp.zeros(shape), jnp.asarray(rng.normal(size=shape), jnp.float32),
                  jnp.asarray(rng.normal(size=shape), jnp.float32), (jnp.zeros((6, 1)),) * 2,
                  jnp.array([[1, 1, 0, 1, 0, 1]], jnp.float32))
    keep = np.flatnonzero(np.asarray(batch.weight[0]))
    kept = jax.tree.map(lambda x: x[:, keep] if x.ndim >= 2 and x.shape[:2] == shape else x,
                        batch._replace(carry=(jnp.zeros((4, 1)),) * 2, weight=None))
    garbage = batch._replace(advantage=batch.advantage.at[0, 2].set(1e6).at[0, 4].set(-1e6))
    low, high = jnp.array([0.2, 0.2]), jnp.array([0.95, 0.95])
    loss = jax.jit(lambda batch: ppo_loss(params, network.apply, batch, config, low, high))
    (total, metrics), (expected, expected_metrics) = loss(garbage), loss(kept)
    np.testing.assert_allclose(float(total), float(expected), rtol=1e-5)
    for name in metrics:
        np.testing.assert_allclose(float(metrics[name]), float(expected_metrics[name]), rtol=1e-5, atol=1e-7)


@pytest.mark.slow  # trainer: compiles and trains
def test_one_callback_per_learner_step_and_each_env_s_episodes_are_the_standin_s(trainer):
    batch = Recorded(CFG, num_envs=E, batch_size=B, pool=2, seed=0, make_env=StandIn(FAST))
    rows, episodes, _ = _train(trainer, batch, updates=3)
    assert batch.recvs == 1 + 3 * T  # the reset's, then one per learner step
    per_env = _per_env(episodes)
    assert all(per_env.values()), per_env  # every env ran episodes
    # the episode seeds come from each env's stream: the lock-step batch of the same seed runs the same
    with BatchedFoamEnv(CFG, num_envs=E, pool=2, seed=0, make_env=StandIn(FAST)) as lock:
        lock.reset(seed=batch.seed)
        ran = {i: [] for i in range(E)}
        while any(len(ran[i]) < len(ks) for i, ks in per_env.items()):
            *_, infos = lock.step(np.full((E, 2), 0.5))
            for i in np.flatnonzero(infos.get("_final_info", [])):
                ran[int(i)].append(int(infos["final_info"]["iterations"][i]))
    assert all(ran[i][:len(ks)] == ks for i, ks in per_env.items())
    # each update's episode statistics come from its envs' own rewards: the return of a stand-in
    # episode is minus its iterations
    assert sum(row["episodes"] for row in rows) == len(episodes)
    first = [info["iterations"] for _, info in episodes[:int(rows[0]["episodes"])]]
    assert rows[0]["mean_episode_return"] == pytest.approx(-np.mean(first))


@pytest.mark.slow  # trainer: compiles and trains
def test_each_env_s_transitions_pair_its_actions_with_its_own_results(trainer):
    ppo, vec = trainer
    batch = Recorded(CFG, num_envs=E, batch_size=B, pool=2, seed=0, make_env=StandIn(FAST))
    _, _, state = _train(trainer, batch, updates=1)  # pending transitions now carry over
    ctx = ppo.ctx._replace(axis_name=None)
    state, tr, _, _ = jax.jit(lambda s: collect(ctx, s, jax.random.PRNGKey(2), async_env_step))(state)
    episodes = _per_env(vec.take_episodes())
    vec.raise_if_failed()
    flat = jax.tree.map(lambda x: np.asarray(x).reshape((T,) + x.shape[2:]), tr)  # (T, B, ...)
    assert flat.weight.all()  # after the first update every returned env had a step in flight
    checked = 0
    for env in range(E):
        rows = [(t, r) for t in range(T) for r in range(B) if flat.env_id[t, r] == env]
        obs = [float(flat.obs[t, r, 0]) for t, r in rows]  # the fraction of its episode left
        done = [bool(flat.terminated[t, r]) for t, r in rows]
        rewards = [float(flat.reward[t, r]) / PPO.reward_scale for t, r in rows]
        for k in range(1, len(rows)):  # an episode's steps go down from 1; a new one starts at 1
            assert obs[k] == 1.0 if done[k - 1] else obs[k] < obs[k - 1], (env, obs, done)
        starts = [k for k in range(len(rows)) if obs[k] == 1.0]
        whole = [-sum(rewards[a:b + 1]) for a in starts for b in range(a, len(rows)) if done[b]
                 and not any(done[a:b])]
        assert whole == pytest.approx(episodes[env][len(episodes[env]) - len(whole):])
        checked += len(whole)
    assert checked  # some episodes ran whole within the rollout


@pytest.mark.slow  # trainer: compiles and trains
def test_a_killed_worker_ends_its_envs_episodes_and_training_goes_on(trainer):
    slow = Profile(iterations=(400,), seconds_per_iteration=(5e-4,), reset_s=0.002)  # 50 ms steps
    batch = Recorded(CFG, num_envs=E, batch_size=B, pool=2, seed=0, make_env=StandIn(slow),
                     kill_after_send=3)
    # the crash comes back once the env's reset on the replacement worker is done
    rows, episodes, _ = _train(trainer, batch, updates=2,
                               until=lambda ended: any(info["outcome"] == "crashed" for _, info in ended))
    crashed = [(i, info) for i, info in episodes if info["outcome"] == "crashed"]
    assert crashed and {i for i, _ in crashed} <= {1, 3}
    assert all(info["cause"] == "worker died" for _, info in crashed)
    assert batch.worker_pids()[1] != batch.killed  # replaced
    assert len(episodes) > len(crashed) and all(np.isfinite(row["value_loss"]) for row in rows)


@pytest.mark.slow  # trainer: compiles and trains
def test_a_failed_reset_is_a_non_transition_and_training_goes_on(trainer):
    make = FailingResets(FAST, env_id=0, failing=(2,))  # env 0's first auto-reset fails, its retry works
    batch = Recorded(CFG, num_envs=E, batch_size=B, pool=2, seed=0, make_env=make)
    rows, episodes, _ = _train(trainer, batch, updates=3)
    per_env = _per_env(episodes)
    assert len(per_env[0]) >= 2 and {info["outcome"] for _, info in episodes} == {"converged"}
    assert sum(row["episodes"] for row in rows) == len(episodes)  # the retry's non-transition is none
    assert all(np.isfinite(row["value_loss"]) for row in rows)


def _plan(args: dict) -> Any:
    """The FoamPlan of ``args`` ({"episodes", "run", "resume"}) on the
    stand-in: the plan :func:`main_of_a_killed_run` runs in a process of its own."""
    from jaxsimrl.apps.foam.training import FoamPlan
    from jaxsimrl.runs.run_dir import RunDir

    run_path = Path(args["run"])
    record = RunDir.existing(run_path).read_config() if args["resume"] else {}
    return FoamPlan(PPO, CFG, args["episodes"], seed=0, pool=2,
                    backend="local", ray_address=None, run_path=run_path, resume=args["resume"],
                    record=record, make_env=StandIn(FAST))


def _train_foam(args: dict) -> dict:
    from jaxsimrl.apps.foam.training import train_foam
    from jaxsimrl.runs.run_dir import RunDir

    plan = _plan(args)
    return train_foam(plan, RunDir.existing(plan.run_path) if plan.resume else RunDir.create(plan.run_path))


def main_of_a_killed_run() -> None:
    """``python -c`` entry of the run that the test below kills: sys.argv[1] is its :func:`_plan` JSON."""
    _train_foam(json.loads(sys.argv[1]))


def _per_env_episodes(run_path: Path, num_envs: int, up_to_update: int = 10**9) -> dict[int, list[tuple]]:
    """Each env's episodes in episodes.csv (those of updates up to ``up_to_update``), in order: (seed,
    iterations, outcome); the file is whole, in order, and holds no episode twice."""
    from jaxsimrl.apps.foam.episodes import EPISODES_FILE, EpisodeLog

    rows = EpisodeLog.load(run_path / EPISODES_FILE, up_to_update).rows
    assert [r["index"] for r in rows] == list(range(len(rows)))
    assert [r["update"] for r in rows] == sorted(r["update"] for r in rows)
    assert len({(r["env"], r["seed"]) for r in rows}) == len(rows)
    return {i: [(r["seed"], r["iterations"], r["outcome"]) for r in rows if r["env"] == i]
            for i in range(num_envs)}


def test_train_foam_runs_asynchronously_with_its_async_envs_fixed_on_resume(tmp_path, capsys):
    from jaxsimrl.runs.run_dir import RunDir

    run_path = tmp_path / "run"
    summary = _train_foam({"episodes": 8, "run": str(run_path), "resume": False})
    assert summary["episodes"] >= 8 and 0 < summary["pool_utilisation"] <= 1
    # the progress line's share is the workers' step seconds too (episodes' wall - idle read > 100 %)
    busy = [int(share) for share in re.findall(r"pool (\d+)% busy", capsys.readouterr().out)]
    assert busy and all(0 <= share <= 100 for share in busy), busy
    assert RunDir.existing(run_path).read_config()["ppo"]["async_envs"] == E
    code = _cli_code(["train-foam", "--resume", str(run_path), "--async-envs", "3"])
    assert code == 2 and "differs from" in capsys.readouterr().err


@pytest.mark.slow  # train-foam runs (stand-in solver) killed and resumed
def test_train_foam_killed_and_resumed_loses_no_episode_and_doubles_none(tmp_path, capsys):
    """SIGKILL after the second checkpoint, then --resume: the episodes in flight are replayed, so each
    env's episodes are those of the same run never interrupted (its seed stream's, once each). The
    lock-step batch's kill and resume is tests/test_train_foam.py's, with the real solver."""
    from jaxsimrl.runs.run_dir import RunDir

    num_envs, run = E, tmp_path / "killed"
    tests = Path(__file__).parent
    args = {"episodes": 10**6, "run": str(run), "resume": False}
    process = subprocess.Popen(
        [sys.executable, "-c", f"import sys; sys.path.insert(0, {str(tests)!r}); "
         f"from test_async_trainer import main_of_a_killed_run; main_of_a_killed_run()", json.dumps(args)],
        env={**os.environ, "TMPDIR": str(tmp_path)}, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
        text=True)
    deadline = time.monotonic() + 300
    while not (run / "checkpoints" / "2").is_dir():
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()[1][-2000:]
        time.sleep(0.05)
    process.kill()  # SIGKILL, mid-update
    process.communicate()
    checkpoint = RunDir.existing(run).checkpoint_steps()[-1]
    before = _per_env_episodes(run, num_envs, checkpoint)  # a resume drops the rows of later updates
    target = sum(map(len, before.values())) + 8
    _train_foam({**args, "episodes": target, "resume": True})
    assert f"resumed at update {checkpoint} with its {num_envs} episodes in flight replayed" \
        in capsys.readouterr().err
    after = _per_env_episodes(run, num_envs)
    _train_foam({**args, "run": str(tmp_path / "uninterrupted"), "episodes": target + 8})
    never_stopped = _per_env_episodes(tmp_path / "uninterrupted", num_envs)
    for i in range(num_envs):
        common = min(len(after[i]), len(never_stopped[i]))
        assert after[i][:len(before[i])] == before[i]
        assert common > len(before[i]), (i, before[i], after[i], never_stopped[i])  # ran on after the kill
        assert after[i][:common] == never_stopped[i][:common], (i, len(before[i]))


def test_a_record_that_does_not_fit_the_learner_s_side_of_the_checkpoint_is_not_replayed():
    """The learner's rows must be the recorded envs with the learner, with their observations, and every
    env the record has a step or reset in flight for must be one whose result the learner awaits."""
    from types import SimpleNamespace as Fake

    from jaxsimrl.apps.foam.training import _learner_mismatch

    vec = Fake(async_envs=3)
    record = {"envs": [{"obs": [0.5]}, {"obs": [1.0], "step": [0.5, 0.5]}, {"obs": [0.2], "ready": {}}],
              "with_learner": [0], "ready": [2]}

    def state(ids=(0,), obs=((0.5,),), valid=(False, True, False)):
        return Fake(obs=obs, env_state=Fake(ids=ids, pending=Fake(valid=valid)))

    assert _learner_mismatch(vec, record, state()) == ""
    assert _learner_mismatch(vec, record, state(valid=(False, True, True))) == ""  # ready: sent or not
    assert "holds" in _learner_mismatch(vec, record, state(ids=(1,)))
    assert "observations" in _learner_mismatch(vec, record, state(obs=((0.25,),)))
    assert "in flight" in _learner_mismatch(vec, record, state(valid=(False, False, False)))
    assert "in flight" in _learner_mismatch(vec, record, state(valid=(True, True, False)))
    assert "holds" in _learner_mismatch(vec, [{"obs": [0.5]}], state())  # a lock-step record


def _cli_code(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as exit_:
        return exit_.code


def test_async_envs_must_exceed_num_envs_and_needs_the_mlp(capsys):
    assert _cli_code(["train-foam", "--print-config", "--pool", "2", "--async-envs", "2"]) == 2
    err = capsys.readouterr().err
    assert "async_envs must be null or an integer > num_envs (2)" in err
    assert len(err.strip().splitlines()) == 1
    assert _cli_code(["train-foam", "--print-config", "--pool", "2", "--async-envs", "4"]) == 0
    assert '"async_envs": 4' in capsys.readouterr().out
    with pytest.raises(ValueError, match="mlp"):
        PPOConfig(num_envs=2, async_envs=4, steps_per_update=100, seq_len=50, num_minibatches=1).validate()
    legacy = {k: v for k, v in PPO.to_dict().items() if k != "async_envs"}
    assert PPOConfig.from_dict(legacy).async_envs is None  # config.json of older runs
