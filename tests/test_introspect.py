"""jaxsimrl.load_policy on a small saved run: acting like the trainer's policy, batching, the action
distribution, values, checkpoint choice, one-line errors for runs it cannot load, and rollouts."""

from __future__ import annotations

import functools
import json
import shutil

import distrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_cli_plot import tiny_run

import jaxsimrl
from jaxsimrl.agents.ppo import PolicyParams, PPOConfig, make_train
from jaxsimrl.agents.ppo.networks import initial_carry, make_network
from jaxsimrl.agents.ppo.normalizer import batch_stats
from jaxsimrl.envs.lorenz import Lorenz
from jaxsimrl.introspect import LoadedPolicy, load_policy
from jaxsimrl.runs.checkpoint import Checkpoints

OBS = np.array([[1.0, 12.0, 9.0, 110.0, -1.0, -12.0], [-7.0, -7.0, 19.0, 0.5, 0.2, -0.1],
                [20.0, -5.0, 30.0, -250.0, 100.0, -200.0]], np.float32)
# A small recurrent policy (untrained: fresh parameters are enough to test the API's plumbing).
LSTM = PPOConfig(network="lstm", lstm_size=8, num_envs=2, steps_per_update=64, seq_len=16, num_minibatches=2,
                 total_steps=64)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return tiny_run(tmp_path_factory)  # 5 updates in chunks of 2: checkpoints 4 and 5 are kept


@pytest.fixture(scope="module")
def policy(run):
    return load_policy(run)


@pytest.fixture(scope="module")
def lstm_policy():
    return LoadedPolicy.from_params(LSTM, fresh_params(LSTM, jax.random.PRNGKey(3)))


def fresh_params(config: PPOConfig, key: jax.Array) -> PolicyParams:
    """Initial network parameters, and observation statistics of a few reset observations."""
    return _fresh_params(config)(key)


@functools.cache
def _fresh_params(config: PPOConfig):
    env, network = Lorenz(), make_network(config, 3)

    @jax.jit  # one compilation instead of many small eager ones
    def init(key: jax.Array) -> PolicyParams:
        obs = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(key, 64), env.default_params())[0]
        params = network.init(key, initial_carry(config, 1), obs[:1][None], jnp.ones((1, 1), bool))
        return PolicyParams(params, batch_stats(obs))

    return init


def one_line_error(call) -> str:
    with pytest.raises(ValueError) as caught:
        call()
    message = str(caught.value)
    assert "\n" not in message
    return message


def test_load_policy_is_exported_from_the_package():
    # lazily: `import jaxsimrl` staying JAX-free is tested in test_gym_lorenz
    assert jaxsimrl.load_policy is load_policy
    with pytest.raises(AttributeError):
        jaxsimrl.no_such_name  # noqa: B018


def test_record_of_the_checkpoint(policy, run):
    assert policy.update == 5 and policy.env_steps == 320
    assert policy.config.network == "mlp" and policy.config.gamma == 0.95
    assert policy.record["env"] == "lorenz" and policy.run_dir == run
    assert float(policy.env_params.rho) == 20.0
    assert policy.obs_names[3] == "dx/dt" and policy.action_names == ("d sigma", "d rho", "d beta")


def test_acts_exactly_like_the_trainers_policy_on_the_restored_state(policy, run):
    trainer = make_train(policy.config)
    with Checkpoints(run / "checkpoints", writable=False) as checkpoints:
        state, _ = checkpoints.restore(jax.eval_shape(trainer.init, jax.random.PRNGKey(0)))
    carry, starts = trainer.policy.initial_carry(3), jnp.ones(3, bool)
    expected, _ = trainer.policy.act(state, jnp.asarray(OBS), carry, starts, jax.random.PRNGKey(0))
    actions, _ = policy.act(OBS)
    np.testing.assert_allclose(actions, expected, rtol=1e-6)
    assert np.all(actions >= policy.action_low) and np.all(actions <= policy.action_high)
    assert not np.allclose(actions[0], actions[1])  # the observations matter


def test_one_observation_answers_like_its_row_of_a_batch(policy):
    actions, _ = policy.act(OBS)
    single, _ = policy.act(OBS[1])
    assert single.shape == (3,)
    # a batch of one and a batch of three take different matmul kernels: equal up to float32 rounding
    np.testing.assert_allclose(single, actions[1], rtol=1e-6, atol=1e-6)
    values = policy.value(OBS)
    assert values.shape == (3,) and np.ndim(policy.value(OBS[2])) == 0
    np.testing.assert_allclose(policy.value(OBS[2]), values[2], rtol=1e-6)
    message = one_line_error(lambda: policy.act(np.zeros(5)))
    assert "(6,)" in message


def test_stochastic_actions_follow_their_key(policy):
    first, _ = policy.act(OBS, deterministic=False, key=7)
    again, _ = policy.act(OBS, deterministic=False, key=7)
    other, _ = policy.act(OBS, deterministic=False, key=8)
    np.testing.assert_array_equal(first, again)
    assert not np.allclose(first, other)
    # without a key, each policy draws from its own stream, seeded when it is made
    twins = [LoadedPolicy.from_params(policy.config, policy.params, seed=4) for _ in range(2)]
    draws = [twin.act(OBS, deterministic=False)[0] for twin in twins]
    np.testing.assert_array_equal(draws[0], draws[1])
    assert not np.allclose(draws[0], twins[0].act(OBS, deterministic=False)[0])


def test_distribution_is_the_squashed_gaussian_in_env_units(policy):
    dist = policy.distribution(OBS)
    np.testing.assert_allclose(dist.median, policy.act(OBS)[0], rtol=1e-6)
    reference = distrax.Transformed(  # distrax's own squashed Gaussian: tanh, then onto [low, high]
        distrax.MultivariateNormalDiag(dist.loc, dist.scale),
        distrax.Block(distrax.Chain([distrax.ScalarAffine(policy.action_low, (policy.action_high
                                                                               - policy.action_low) / 2),
                                     distrax.ScalarAffine(1.0, 1.0), distrax.Tanh()]), 1))
    actions = dist.sample(jax.random.PRNGKey(1))
    np.testing.assert_allclose(dist.log_prob(actions), reference.log_prob(actions), rtol=1e-4)
    mean, std = dist.mean_and_std(jax.random.PRNGKey(2), samples=4000)
    assert mean.shape == std.shape == (3, 3) and np.all(std > 0)
    assert np.all(np.abs(mean - dist.median) < 0.05 * (policy.action_high - policy.action_low))


def test_value_is_in_reward_units(policy):
    from jaxsimrl.agents.ppo.acting import forward

    raw = forward(policy.policy.network.apply, policy.config, policy.params.params, policy.params.normalizer,
                  policy.policy.initial_carry(3), jnp.asarray(OBS), jnp.ones(3, bool))[3]
    np.testing.assert_allclose(policy.value(OBS), raw / policy.config.reward_scale, rtol=1e-6)


def test_an_earlier_checkpoint_loads_and_a_missing_one_says_which_exist(policy, run):
    earlier = load_policy(run, checkpoint=4)
    assert earlier.update == 4 and earlier.env_steps == 256
    assert not np.allclose(earlier.act(OBS)[0], policy.act(OBS)[0])
    assert "there are: 4, 5" in one_line_error(lambda: load_policy(run, checkpoint=1))


@pytest.mark.parametrize(("edit", "expected"), [
    (lambda record: record["ppo"].update(lstm_layers=2), "lstm_layers"),
    (lambda record: record["ppo"].update(hidden_sizes=[32, 32]), "does not fit the network"),
    (lambda record: record.update(env="foam-v9"), "foam-v9"),
])
def test_a_run_it_cannot_load_is_a_one_line_error(run, tmp_path, edit, expected):
    copy = tmp_path / "copy"
    shutil.copytree(run, copy)
    record = json.loads((copy / "config.json").read_text())
    edit(record)
    (copy / "config.json").write_text(json.dumps(record))
    assert expected in one_line_error(lambda: load_policy(copy))
    assert "does not exist" in one_line_error(lambda: load_policy(tmp_path / "nothing"))


def test_recurrent_state_carries_over_and_none_starts_an_episode(lstm_policy):
    first, state = lstm_policy.act(OBS[0])
    assert state[0].shape == (8,)
    second, _ = lstm_policy.act(OBS[0], state)
    restart, _ = lstm_policy.act(OBS[0])
    assert not np.allclose(first, second)  # the memory of the first step changes the second
    np.testing.assert_array_equal(first, restart)


def test_rollout_records_what_the_policy_did(lstm_policy):
    params = lstm_policy.env_params.replace(random_init=False)
    record = lstm_policy.rollout(params, steps=30, episodes=2, seed=1)
    assert record["obs"].shape == (2, 30, 6) and record["hidden"].shape == (2, 30, 8)
    assert record["action"].shape == (2, 30, 3) and record["value"].shape == (2, 30)
    np.testing.assert_allclose(record["state.xyz"][0, 0], [1.0, 12.0, 9.0])
    np.testing.assert_allclose(record["state.xyz"][:, 1:], record["info.state"][:, :-1], rtol=1e-6)
    np.testing.assert_array_equal(record["reward"], np.where(record["info.speed"] > 40.0, 10.0, -10.0))
    # the same steps taken one call at a time
    state = None
    for t in range(3):
        action, state = lstm_policy.act(record["obs"][0, t], state)
        np.testing.assert_allclose(action, record["action"][0, t], rtol=1e-5, atol=1e-7)
        np.testing.assert_allclose(state[1], record["hidden"][0, t], rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(lstm_policy.value(record["obs"][1, 0]), record["value"][1, 0], rtol=1e-5)
    again = lstm_policy.rollout(params, steps=30, episodes=2, seed=1)
    np.testing.assert_array_equal(again["action"], record["action"])
    random_starts = lstm_policy.rollout(steps=30, episodes=2, seed=1)["state.xyz"][:, 0]  # compiled above
    assert not np.allclose(random_starts[0], random_starts[1])
    assert "steps" in one_line_error(lambda: lstm_policy.rollout(steps=0))


def test_feed_forward_rollout_has_no_hidden_state(policy):
    record = policy.rollout(steps=4)
    assert "hidden" not in record and record["obs"].shape == (1, 4, 6)
