"""The VecEnv boundary (JAX and host envs), and the trainer fixes that came with it: squashed-policy
entropy, bootstrapping only where truncated & ~terminated, the std floor, lr annealing across resumes,
Ctrl-C saving the chunk in flight."""

from __future__ import annotations

import math
import os
import signal

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import integrate

from jaxsimrl.agents.ppo import PPOConfig, make_train
from jaxsimrl.agents.ppo import normalizer as norm
from jaxsimrl.agents.ppo.distribution import log_abs_tanh_jacobian, squashed_entropy
from jaxsimrl.agents.ppo.learner import make_optimizer
from jaxsimrl.agents.ppo.losses import compute_gae
from jaxsimrl.envs.host import HostEnvError, HostVecEnv
from jaxsimrl.envs.lorenz import Lorenz
from jaxsimrl.envs.protocol import BoxSpec
from jaxsimrl.envs.vec import JaxVecEnv

REGRESSION = PPOConfig(num_envs=4, steps_per_update=800, total_steps=2400, seq_len=50, num_minibatches=2,
                       updates_per_chunk=3, hidden_sizes=(16, 16), lstm_size=16)
# Measured with the rollout that vmapped env.step and reset itself (commit ec7558c), seed 3: the VecEnv
# boundary must not change what is learned.
PINNED = {
    "lstm": {"mean_episode_return": [math.nan, 335.0, 425.0], "episodes": [0, 4, 4],
             "value_loss": [0.38032597, 0.32194731, 0.25367069], "param_sum": 522.54767},
    "mlp": {"mean_episode_return": [math.nan, 360.0, 500.0], "episodes": [0, 4, 4],
            "value_loss": [0.41101688, 0.34308940, 0.32107741], "param_sum": 106.04769},
}


@pytest.mark.slow  # trains twice
@pytest.mark.parametrize("network", ["lstm", "mlp"])
def test_lorenz_through_the_vec_env_learns_what_it_learned_before(network):
    config = PPOConfig(**{**REGRESSION.to_dict(), "network": network})
    params = Lorenz().default_params().replace(episode_steps=300, max_steps=250, terminal_window=100)
    trainer = make_train(config, Lorenz(), params)
    state, metrics = trainer.run_chunk(trainer.init(jax.random.PRNGKey(3)))
    pinned = PINNED[network]
    np.testing.assert_array_equal(np.asarray(metrics["episodes"]), pinned["episodes"])
    np.testing.assert_allclose(np.asarray(metrics["mean_episode_return"]), pinned["mean_episode_return"])
    np.testing.assert_allclose(np.asarray(metrics["value_loss"]), pinned["value_loss"], rtol=1e-4)
    param_sum = sum(float(jnp.sum(jnp.abs(x))) for x in jax.tree.leaves(state.params))
    assert param_sum == pytest.approx(pinned["param_sum"], rel=1e-5)


def test_jax_vec_env_auto_resets_and_keeps_the_final_observation():
    params = Lorenz().default_params().replace(max_steps=3)
    vec = JaxVecEnv(Lorenz(), params, num_envs=2)
    keys = jax.random.split(jax.random.PRNGKey(0), 2)
    obs, state = vec.reset(keys)
    for t in range(3):
        step_keys = jnp.stack([jax.random.split(jax.random.PRNGKey(10 + t), 2),
                               jax.random.split(jax.random.PRNGKey(20 + t), 2)], axis=1)
        out = vec.step(step_keys, state, jnp.zeros((2, 3)))
        state = out.state
    assert bool(jnp.all(out.truncated)) and not bool(jnp.any(out.terminated))
    fresh, _ = vec.reset(step_keys[:, 1])
    np.testing.assert_array_equal(out.obs, fresh)  # the next obs is a new episode's first ...
    assert not np.allclose(out.final_obs, out.obs)  # ... and final_obs is where the old one ended
    assert int(state.t[0]) == 0


class CountdownBatch:
    """A numpy host batch: env i's episodes last 2 + i steps (reward -1 each), obs = steps left; env
    ``fail_env`` ends every episode on its first step (a 'crashed' solver) with reward -10."""

    observation_spec = BoxSpec(np.zeros(1), np.full(1, 10.0), (1,))
    action_spec = BoxSpec(np.array([0.2, 0.2]), np.array([0.95, 0.95]), (2,))

    def __init__(self, num_envs: int, fail_env: int | None = None, explode_at: int | None = None) -> None:
        self.num_envs, self.fail_env, self.explode_at = num_envs, fail_env, explode_at
        self.steps = 0
        self.actions: list[np.ndarray] = []

    def _length(self, i: int) -> float:
        return 1.0 if i == self.fail_env else 2.0 + i

    def reset(self, seed: int | None = None):
        self.left = np.array([self._length(i) for i in range(self.num_envs)])
        return self.left[:, None].astype(np.float32), {}

    def step(self, actions):
        self.steps += 1
        if self.explode_at is not None and self.steps >= self.explode_at:
            raise OSError("the pool's pipe broke")
        self.actions.append(np.asarray(actions))
        self.left -= 1
        done = self.left <= 0
        final = self.left[:, None].astype(np.float32).copy()
        reward = np.where(np.arange(self.num_envs) == self.fail_env, -10.0, -1.0)
        outcome = np.array(["crashed" if i == self.fail_env else "converged" for i in range(self.num_envs)])
        for i in np.flatnonzero(done):
            self.left[i] = self._length(i)
        infos = {"final_obs": final, "final_info": {"outcome": outcome}}
        return self.left[:, None].astype(np.float32), reward, done, np.zeros(self.num_envs, bool), infos


HOST = PPOConfig(num_envs=3, steps_per_update=12, total_steps=36, network="mlp", seq_len=1, num_minibatches=2,
                 updates_per_chunk=1, gamma=1.0, hidden_sizes=(8, 8))


def test_host_vec_env_inside_the_jitted_rollout_one_call_per_step():
    ended: list[tuple[int, str]] = []
    batch = CountdownBatch(3, fail_env=2)
    vec = HostVecEnv(batch, on_episode=lambda i, info: ended.append((i, info["outcome"])))
    trainer = make_train(HOST, vec=vec, devices=jax.devices()[:1])
    state = trainer.init(jax.random.PRNGKey(0))
    state, metrics = trainer.run_chunk(state)
    vec.raise_if_failed()
    assert batch.steps == 4  # 12 steps over 3 envs: one host call per step, all envs at once
    assert all(a.shape == (3, 2) and np.all((a >= 0.2) & (a <= 0.95)) for a in batch.actions)
    # episodes of different lengths auto-reset independently: env 0 (2 steps) twice, env 1 (3 steps)
    # once, the failing env 2 at every step; returns -2, -3 and -10
    assert sorted(ended) == [(0, "converged")] * 2 + [(1, "converged")] + [(2, "crashed")] * 4
    assert int(metrics["episodes"][0]) == 7
    assert float(metrics["mean_episode_return"][0]) == pytest.approx((2 * -2 - 3 - 4 * 10) / 7)
    assert state.obs.shape == (3, 1) and state.obs.dtype == jnp.float32


class NonTransitionBatch(CountdownBatch):
    """A CountdownBatch with gymnasium's masks whose env 0, at its first step, returns what
    BatchedFoamEnv returns once a failed auto-reset's retry succeeds: a non-transition (reward 0,
    truncated, a final observation but no final info) and a new episode."""

    def step(self, actions):
        obs, reward, terminated, truncated, infos = super().step(actions)
        done = terminated | truncated
        infos = {**infos, "_final_obs": done.copy(), "_final_info": done.copy()}
        if self.steps == 1:
            self.left[0] = self._length(0)
            obs[0], reward[0], truncated[0], infos["_final_obs"][0] = self.left[0], 0.0, True, True
        return obs, reward, terminated, truncated, infos


@pytest.mark.slow  # compiles a trainer
def test_a_non_transition_is_no_episode_in_the_update_s_statistics():
    ended: list[tuple[int, str]] = []
    vec = HostVecEnv(NonTransitionBatch(3), on_episode=lambda i, info: ended.append((i, info["outcome"])))
    trainer = make_train(HOST, vec=vec, devices=jax.devices()[:1])
    _, metrics = trainer.run_chunk(trainer.init(jax.random.PRNGKey(0)))
    vec.raise_if_failed()
    # 4 steps: env 0 restarts at step 1 (no episode) and ends a 2-step one at step 3; env 1 (3 steps)
    # and env 2 (4 steps) end one each: returns -2, -3, -4
    assert sorted(ended) == [(0, "converged"), (1, "converged"), (2, "converged")]
    assert int(metrics["episodes"][0]) == 3
    assert float(metrics["mean_episode_return"][0]) == pytest.approx(-3.0)


@pytest.mark.slow  # compiles a trainer
def test_a_host_failure_is_raised_after_the_call_not_inside_it():
    batch = CountdownBatch(3, explode_at=2)
    vec = HostVecEnv(batch)
    trainer = make_train(HOST, vec=vec, devices=jax.devices()[:1])
    state, _ = trainer.run_chunk(trainer.init(jax.random.PRNGKey(0)))  # the callback itself never raises
    assert batch.steps == 2  # after the failure the batch is not touched again
    with pytest.raises(HostEnvError, match="OSError: the pool's pipe broke") as caught:
        vec.raise_if_failed()
    assert "\n" not in str(caught.value)


@pytest.mark.slow  # a quadrature over many samples
def test_squashed_entropy_matches_quadrature_and_stays_bounded():
    low, high = jnp.array([0.2, -3.0]), jnp.array([0.95, 1.0])
    mean, log_std = jnp.array([0.3, -1.0]), jnp.array([-0.5, 0.0])
    gauss = 0.5 * np.log(2 * np.pi * np.e) * 2 + float(jnp.sum(log_std))

    def expected_log_jacobian(mu: float, sigma: float) -> float:
        density = lambda u: np.exp(-(u - mu) ** 2 / (2 * sigma**2)) / np.sqrt(2 * np.pi) / sigma  # noqa: E731
        return integrate.quad(lambda u: float(log_abs_tanh_jacobian(u)) * density(u), -40, 40, limit=200)[0]

    exact = gauss + sum(expected_log_jacobian(m, float(np.exp(s))) + np.log((h - lo) / 2)
                        for m, s, lo, h in zip(mean, log_std, low, high, strict=True))
    assert float(squashed_entropy(mean, log_std, low, high)) == pytest.approx(exact, abs=1e-5)
    # The Gaussian's entropy grows for ever with sigma; the squashed one turns down: a bonus on it
    # cannot push sigma up without bound.
    grad = jax.grad(lambda s: squashed_entropy(jnp.zeros(2), jnp.full(2, s), low, high))
    assert float(grad(-2.0)) > 0 > float(grad(1.0))


def test_no_bootstrap_where_the_same_step_terminated_and_truncated():
    adv, _ = compute_gae(jnp.array([-1.0]), jnp.array([0.0]), jnp.array([True]), jnp.array([True]),
                         jnp.array([100.0]), jnp.float32(7.0), 1.0, 1.0)
    assert float(adv[0]) == -1.0


def test_std_floor_keeps_a_feature_constant_at_reset_finite():
    stats = norm.batch_stats(jnp.array([[1.0, 0.0]] * 8 + [[2.0, 0.0]] * 8))
    moved = norm.normalize(stats, jnp.array([1.5, 0.05]), clip=10.0, std_floor=0.01)
    assert float(moved[1]) == pytest.approx(5.0)  # 0.05 / 0.01, not 0.05 / 1e-4 clipped to 10
    assert float(norm.normalize(stats, jnp.array([1.5, 0.05]), clip=10.0)[1]) == 10.0


def test_raising_total_steps_follows_the_new_horizon_and_revives_a_finished_anneal():
    config = PPOConfig(steps_per_update=8000, total_steps=80_000, anneal_lr=True, lr=1e-3)  # 10 updates
    assert config.learning_rate(6) == pytest.approx(4e-4) and config.learning_rate(10) == 0.0
    longer = config.with_total_steps(160_000)  # now 20 updates: the decay of a run planned for 20
    assert longer.learning_rate(6) == pytest.approx(7e-4)
    # a finished run (its rate reached 0) trains on at a rate > 0, down to 0 at the new end
    assert longer.learning_rate(10) == pytest.approx(5e-4) and longer.learning_rate(20) == 0.0
    _, schedule = make_optimizer(longer, longer.num_updates)
    per_update = longer.update_epochs * longer.num_minibatches
    for update in (6, 10, 13, 19):
        assert float(schedule(update * per_update)) == pytest.approx(longer.learning_rate(update), rel=1e-5)
    assert config.with_total_steps(80_000) == config  # unchanged total: unchanged config
    # a run re-anchored by an older version keeps its anchor
    old = PPOConfig.from_dict({**config.to_dict(), "total_steps": 160_000, "anneal_start_update": 10,
                               "anneal_start_lr": 1e-4})
    assert old.with_total_steps(240_000).learning_rate(15) == pytest.approx(1e-4 * (1 - 5 / 20))


def test_ctrl_c_during_a_chunk_saves_that_chunk(tmp_path):
    from jaxsimrl.runs.checkpoint import Checkpoints
    from jaxsimrl.runs.run_dir import MetricsLog, RunDir
    from jaxsimrl.runs.training import Session, train

    class SignalledTrainer:
        num_updates = 5

        def run_chunk(self, state):
            os.kill(os.getpid(), signal.SIGINT)  # arrives while the chunk "computes"
            step = state["update"] + 1
            return {"update": step}, {"env_steps": np.array([10 * step]), "episodes": np.array([0])}

    class Quiet:
        def update(self, *args):
            pass

    run = RunDir.create(tmp_path / "run")
    with Checkpoints(run.checkpoints) as checkpoints:
        session = Session(run, SignalledTrainer(), MetricsLog(run), checkpoints, meta={})
        with pytest.raises(KeyboardInterrupt):
            train(session, {"update": np.int32(0)}, 0, Quiet())
    assert run.checkpoint_steps() == [1]
    assert [row["update"] for row in MetricsLog.load(run, 10).rows] == [1]
