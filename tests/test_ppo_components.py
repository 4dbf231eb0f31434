"""Unit tests of the PPO building blocks: GAE, action mapping, log-probs, LSTM resets, normaliser."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxsimrl.agents.ppo import PolicyParams, PPOConfig, make_policy, make_train
from jaxsimrl.agents.ppo import normalizer as norm
from jaxsimrl.agents.ppo.distribution import gaussian, squashed_entropy, to_box, widened
from jaxsimrl.agents.ppo.learner import _minibatch
from jaxsimrl.agents.ppo.losses import Batch, compute_gae, ppo_loss
from jaxsimrl.agents.ppo.networks import initial_carry, make_network
from jaxsimrl.agents.ppo.rollout import collect
from jaxsimrl.envs.lorenz import Lorenz

TINY = PPOConfig(num_envs=2, steps_per_update=120, total_steps=240, seq_len=10, num_minibatches=2,
                 lstm_size=16, hidden_sizes=(8, 8), updates_per_chunk=1)
TRUNCATING = Lorenz().default_params().replace(max_steps=30)  # 60 steps per env: 2 truncations each


def test_gae_matches_hand_computation_with_termination_and_truncation():
    gamma, lam = 0.9, 0.8
    rewards = jnp.array([1.0, 2.0, 3.0, 4.0])
    values = jnp.array([10.0, 20.0, 30.0, 40.0])
    terminated = jnp.array([False, True, False, False])
    truncated = jnp.array([False, False, True, False])
    final_values = jnp.array([0.0, 0.0, 100.0, 0.0])
    adv, targets = compute_gae(rewards, values, terminated, truncated, final_values, jnp.float32(50.0),
                               gamma, lam)
    # t=3: 4 + .9*50 - 40 = 9;  t=2 (truncated, bootstrap 100): 3 + 90 - 30 = 63;
    # t=1 (terminated, no bootstrap): 2 - 20 = -18;  t=0: 1 + .9*20 - 10 + .9*.8*(-18) = -3.96
    np.testing.assert_allclose(adv, [-3.96, -18.0, 63.0, 9.0], rtol=1e-6)
    np.testing.assert_allclose(targets, np.asarray(adv) + np.asarray(values), rtol=1e-6)


def test_action_mapping_stays_inside_the_box_and_maps_zero_to_the_centre():
    low, high = jnp.array([-1.0, -2.0, -0.25]), jnp.array([1.0, 2.0, 0.25])
    u = jax.random.normal(jax.random.PRNGKey(0), (1000, 3)) * 20.0
    actions = to_box(u, low, high)
    assert bool(jnp.all(actions >= low)) and bool(jnp.all(actions <= high))
    assert float(jnp.max(jnp.abs(actions))) > 0.24  # it does reach towards the edges
    np.testing.assert_allclose(to_box(jnp.zeros(3), low, high), (low + high) / 2, atol=1e-7)


def test_action_margin_makes_the_bounds_reachable_and_zero_keeps_plain_tanh():
    low, high = jnp.array([0.2, -1.0]), jnp.array([0.95, 1.0])
    u = jnp.linspace(-8.0, 8.0, 4001)[:, None] * jnp.ones(2)
    plain = to_box(u, low, high)
    np.testing.assert_array_equal(to_box(u, low, high, 0.0), plain)  # margin 0 is the plain squash
    near = jnp.abs(u[:, 0]) < 4  # the plain tanh only approaches the bounds (float32 rounds beyond ~9)
    assert bool(jnp.all(plain[near] < high)) and bool(jnp.all(plain[near] > low))
    clipped = to_box(u, low, high, 0.05)
    assert bool(jnp.all(clipped >= low)) and bool(jnp.all(clipped <= high))
    assert bool(jnp.all(clipped[u[:, 0] > 2.5] == high)) and bool(jnp.all(clipped[u[:, 0] < -2.5] == low))
    assert bool(jnp.all(jnp.diff(clipped, axis=0) >= 0))  # still monotone in u
    # inside the box the map is the tanh onto the widened box (centre unchanged)
    lo, hi = widened(low, high, 0.05)
    np.testing.assert_allclose(lo, low - 0.05 * (high - low))
    np.testing.assert_allclose(to_box(jnp.zeros(2), low, high, 0.05), (low + high) / 2, atol=1e-7)
    # entropy: a wider squash box spreads the same Gaussian over more width (+log(1.1) per dimension)
    mean, log_std = jnp.zeros((1, 2)), jnp.full(2, -1.0)
    gain = squashed_entropy(mean, log_std, lo, hi) - squashed_entropy(mean, log_std, low, high)
    np.testing.assert_allclose(gain, 2 * np.log(1.1), rtol=1e-5)


def test_policy_with_an_action_margin_acts_on_the_bound_and_its_distribution_has_mass_there():
    from jaxsimrl.policy import ActionDistribution

    config = PPOConfig(**{**TINY.to_dict(), "network": "mlp", "seq_len": 1, "num_minibatches": 2,
                          "action_margin": 0.1})
    policy = make_policy(config, Lorenz(), Lorenz().default_params())
    params = policy.network.init(jax.random.PRNGKey(0), policy.initial_carry(1), jnp.zeros((1, 1, 6)),
                                 jnp.zeros((1, 1), bool))
    head = params["params"][f"Dense_{len(config.hidden_sizes)}"]  # the actor's mean
    head["bias"], head["kernel"] = jnp.full_like(head["bias"], 4.0), jnp.zeros_like(head["kernel"])
    state = PolicyParams(params, norm.init_normalizer(6))
    action, _ = policy.act(state, jnp.zeros((3, 6)), policy.initial_carry(3), jnp.ones(3, bool), None)
    np.testing.assert_array_equal(action, jnp.broadcast_to(policy.high, action.shape))
    plain = PPOConfig(**{**config.to_dict(), "action_margin": 0.0})
    below, _ = make_policy(plain, Lorenz()).act(state, jnp.zeros((3, 6)), policy.initial_carry(3),
                                                jnp.ones(3, bool), None)
    assert bool(jnp.all(below < policy.high))
    # the distribution: a point mass on each bound, the density inside integrates to the rest
    low, high = jnp.array([0.0]), jnp.array([1.0])
    dist = ActionDistribution(jnp.array([0.5]), jnp.array([1.0]), low, high, 0.2)
    draws = dist.sample(jax.random.PRNGKey(5), (20000,))
    lo, hi = widened(low, high, 0.2)
    y = 2 * (high - lo) / (hi - lo) - 1  # tanh(u) at the upper bound
    p_high = 1 - jax.scipy.stats.norm.cdf(jnp.arctanh(y), 0.5, 1.0)
    np.testing.assert_allclose(jnp.mean(draws == high), p_high, atol=0.01)
    grid = jnp.linspace(1e-4, 1 - 1e-4, 20001)[:, None]
    inside = jnp.sum(jnp.exp(dist.log_prob(grid))) * (grid[1, 0] - grid[0, 0])
    np.testing.assert_allclose(inside, 1 - jnp.mean((draws == high) | (draws == low)), atol=0.01)


def _rollout(config: PPOConfig, env_params):
    trainer = make_train(config, Lorenz(), env_params)
    state = trainer.init(jax.random.PRNGKey(3))
    ctx = trainer.ctx._replace(axis_name=None)  # one device, no shard_map around it
    new_state, transitions, carries, _ = jax.jit(lambda s: collect(ctx, s, jax.random.PRNGKey(4)))(state)
    return trainer, state, new_state, transitions, carries


@pytest.fixture(scope="module", params=["lstm", "mlp"])
def rollout(request):
    """One truncating rollout per network type, shared by the tests below."""
    return _rollout(PPOConfig(**{**TINY.to_dict(), "hidden_sizes": (8, 8), "network": request.param}),
                    TRUNCATING)


def test_rollout_log_probs_equal_the_update_recomputation(rollout):
    trainer, state, _, tr, carries = rollout
    config = trainer.config
    box = trainer.env.action_space(trainer.env_params)
    actions = to_box(tr.u, box.low, box.high)
    assert bool(jnp.all(actions >= box.low)) and bool(jnp.all(actions <= box.high))
    zeros = jnp.zeros_like(tr.value)
    data = Batch(tr.obs, tr.starts, tr.u, tr.log_prob, tr.value, zeros, zeros, carries)
    batch = _minibatch(data, jnp.arange(config.chunks_per_env))

    @jax.jit
    def recompute(params, batch):
        _, mean, log_std, value = trainer.network.apply(params, batch.carry, batch.obs, batch.starts)
        log_prob = jax.vmap(jax.vmap(lambda m, u: _log_prob(m, log_std, u)))(mean, batch.u)
        return log_prob, value, ppo_loss(params, trainer.network.apply, batch, config, box.low, box.high)[1]

    recomputed, value, metrics = recompute(state.params, batch)
    np.testing.assert_allclose(recomputed, batch.log_prob, atol=1e-5)
    np.testing.assert_allclose(value, batch.value, atol=1e-5)
    # and the loss sees ratio 1 everywhere: zero KL, nothing clipped
    assert abs(float(metrics["approx_kl"])) < 1e-6 and float(metrics["clip_fraction"]) == 0.0


def _log_prob(mean, log_std, u):
    return gaussian(mean, log_std).log_prob(u)


def test_truncated_steps_store_a_bootstrap_value_and_restart_the_episode(rollout):
    tr = rollout[3]
    flat = lambda x: np.asarray(x).reshape((-1,) + x.shape[2:])  # noqa: E731
    truncated, final_value, starts = flat(tr.truncated), flat(tr.final_value), flat(tr.starts)
    t_idx = np.nonzero(truncated[:, 0])[0]
    assert list(t_idx) == [29, 59]  # every 30 steps (60 per env per update), never terminated
    assert not flat(tr.terminated).any()
    assert np.all(final_value[~truncated] == 0.0) and np.all(final_value[truncated] != 0.0)
    # the reset observation after each truncation starts a new episode (step 0 starts the first)
    assert list(np.nonzero(starts[:, 0])[0]) == [0, 30] and starts.sum() == 4


def test_lstm_output_after_reset_equals_output_from_a_fresh_carry():
    config = TINY
    net = make_network(config, 3)
    obs = jax.random.normal(jax.random.PRNGKey(0), (6, 2, 6))
    starts = jnp.array([[False, False], [False, False], [False, False], [True, True],
                        [False, False], [False, False]])
    apply = jax.jit(net.apply)
    params = jax.jit(net.init)(jax.random.PRNGKey(1), initial_carry(config, 2), obs, starts)
    warm = jax.tree.map(lambda c: c + 0.7, initial_carry(config, 2))
    _, mean, _, value = apply(params, warm, obs, starts)
    _, fresh_mean, _, fresh_value = apply(params, initial_carry(config, 2), obs[3:], starts[3:])
    np.testing.assert_allclose(mean[3:], fresh_mean, atol=1e-6)
    np.testing.assert_allclose(value[3:], fresh_value, atol=1e-6)
    _, no_reset_mean, _, _ = apply(params, warm, obs, jnp.zeros_like(starts))
    assert not np.allclose(no_reset_mean[3:], fresh_mean, atol=1e-4)  # the reset did something


@pytest.mark.slow  # many compilations
def test_policy_act_jits_and_vmaps_and_done_resets_the_carry():
    env = Lorenz()
    policy = make_policy(TINY, env, env.default_params())
    obs = jax.random.normal(jax.random.PRNGKey(1), (4, 3, 6)) * 20
    carry = jax.tree.map(lambda c: c + 0.5, policy.initial_carry(3))
    params = jax.jit(policy.network.init)(jax.random.PRNGKey(0), carry, obs[:1], jnp.zeros((1, 3), bool))
    state = PolicyParams(params, norm.update(norm.init_normalizer(6), obs))
    done = jnp.array([True, False, True])
    act = jax.jit(policy.act, static_argnames="deterministic")
    batched = jax.vmap(lambda o, k: act(state, o, carry, done, k, deterministic=False))
    actions, carries = batched(obs, jax.random.split(jax.random.PRNGKey(2), 4))
    single, _ = act(state, obs[1], carry, done, jax.random.split(jax.random.PRNGKey(2), 4)[1],
                    deterministic=False)
    np.testing.assert_allclose(actions[1], single, atol=1e-6)
    box = env.action_space(env.default_params())
    assert bool(jnp.all(actions >= box.low)) and bool(jnp.all(actions <= box.high))
    fresh, _ = act(state, obs[0], policy.initial_carry(3), done, None)
    warm, _ = act(state, obs[0], carry, done, None)
    np.testing.assert_allclose(warm[done], fresh[done], atol=1e-6)  # done rows ignore the old carry
    assert not np.allclose(warm[~done], fresh[~done], atol=1e-6)


def test_normalizer_merge_equals_statistics_of_the_union():
    x = jax.random.normal(jax.random.PRNGKey(0), (300, 4)) * 3 + 5
    merged = norm.update(norm.update(norm.init_normalizer(4), x[:100]), x[100:])
    np.testing.assert_allclose(merged.mean, x.mean(0), rtol=1e-5)
    np.testing.assert_allclose(merged.m2 / merged.count, x.var(0), rtol=1e-4)
    z = norm.normalize(merged, x, clip=10.0)
    np.testing.assert_allclose(z.mean(0), 0.0, atol=1e-4)
    np.testing.assert_allclose(z.std(0), 1.0, atol=1e-3)
    assert float(norm.normalize(norm.init_normalizer(4), x, 100.0)[0, 0]) == float(x[0, 0])
