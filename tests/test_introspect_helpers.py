"""The introspection helpers: shapes, one known value each (on a hand-built linear policy or a
synthetic hidden-state trajectory), agreement with the real network, and what their plots draw."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_introspect import LSTM, fresh_params

from jaxsimrl.introspect import (
    LoadedPolicy,
    action_sensitivity,
    hidden_pca,
    plot_hidden_pca,
    plot_policy_slice,
    plot_sensitivity,
    policy_slice,
)

W = np.array([[1.0, 0.0, 2.0, 0.0, 0.0, -1.0], [0.5, -3.0, 0.0, 0.0, 4.0, 0.0]], np.float32)
B = np.array([0.25, -0.5], np.float32)


class LinearPolicy:
    """action = W obs + b, value = sum(obs): the interface the helpers use, with known answers."""

    obs_dim, obs_names, action_names = 6, ("x", "y", "z", "u", "v", "w"), ("a0", "a1")

    def act(self, obs, state=None):
        return np.asarray(obs) @ W.T + B, state

    def value(self, obs, state=None):
        return np.asarray(obs).sum(axis=-1)

    def mean_action(self, obs, carry, start):
        return jnp.asarray(W) @ obs + B

    def initial_state(self):
        return jnp.zeros(1), jnp.zeros(1)


@pytest.fixture(scope="module")
def lstm():
    policy = LoadedPolicy.from_params(LSTM, fresh_params(LSTM, jax.random.PRNGKey(5)))
    return policy, policy.rollout(policy.env_params.replace(random_init=False), steps=40)


def test_slice_of_a_linear_policy_is_the_linear_map_on_the_grid():
    base = np.arange(6, dtype=np.float32)
    data = policy_slice(LinearPolicy(), "x", "z", (-2.0, 2.0), (10.0, 20.0), base=base, resolution=5)
    assert data.actions.shape == (5, 5, 2) and data.values.shape == (5, 5)
    assert (data.x_name, data.y_name) == ("x", "z")
    obs = base.copy()
    obs[0], obs[2] = data.x[3], data.y[1]  # column 3, row 1
    np.testing.assert_allclose(data.actions[1, 3], W @ obs + B, rtol=1e-6)
    np.testing.assert_allclose(data.values[1, 3], obs.sum(), rtol=1e-6)
    fig = plot_policy_slice(data)
    assert len(fig.axes) == 2 * 3  # three heat maps (2 actions + value) and their colour bars
    np.testing.assert_allclose(fig.axes[0].images[0].get_array(), data.actions[..., 0])


def test_slice_refuses_bad_components():
    for x, y, text in (("x", "x", "different"), ("q", "z", "unknown"), (0, 9, "out of range")):
        with pytest.raises(ValueError, match=text):
            policy_slice(LinearPolicy(), x, y, (0, 1), (0, 1))


@pytest.mark.slow  # lstm: trains
def test_slice_of_the_network_matches_acting_on_a_grid_point(lstm):
    policy, record = lstm
    base = record["obs"][0, 10]
    data = policy_slice(policy, "x", "dz/dt", (-30.0, 30.0), (-100.0, 100.0), base=base, resolution=7)
    point = base.copy()
    point[0], point[5] = data.x[2], data.y[6]
    np.testing.assert_allclose(data.actions[6, 2], policy.act(point)[0], rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(data.values[6, 2], policy.value(point), rtol=1e-5)


def test_jacobian_of_a_linear_policy_is_its_matrix_at_every_step():
    record = {"obs": np.random.default_rng(0).normal(size=(1, 12, 6)).astype(np.float32)}
    data = action_sensitivity(LinearPolicy(), record)
    assert data.jacobian.shape == (12, 2, 6)
    np.testing.assert_allclose(data.jacobian, np.broadcast_to(W, (12, 2, 6)))
    fig = plot_sensitivity(data, dt=0.02)
    np.testing.assert_allclose(fig.axes[0].images[0].get_array(), data.jacobian[:, 0, :].T)


@pytest.mark.slow  # lstm: trains
def test_jacobian_of_the_network_matches_finite_differences_from_its_memory(lstm):
    policy, record = lstm
    data = action_sensitivity(policy, record)
    assert data.jacobian.shape == (40, 3, 6) and data.obs_names[2] == "z"
    t, o, eps = 7, 2, 0.25  # z is O(10); float32 needs a wide central difference
    state = None
    for step in range(t):  # the carry the policy had before step t
        state = policy.act(record["obs"][0, step], state)[1]
    up, down = record["obs"][0, t].copy(), record["obs"][0, t].copy()
    up[o] += eps
    down[o] -= eps
    finite = (policy.act(up, state)[0] - policy.act(down, state)[0]) / (2 * eps)
    np.testing.assert_allclose(data.jacobian[t, :, o], finite, rtol=0.02, atol=0.02 * np.abs(finite).max())
    assert np.abs(finite).max() > 0


def test_pca_recovers_a_hidden_trajectory_on_a_line():
    s = np.linspace(-1.0, 3.0, 50)
    direction = np.array([3.0, 0.0, 4.0, 0.0]) / 5.0
    hidden = s[:, None] * direction + np.array([1.0, 2.0, 3.0, 4.0])
    record = {"hidden": hidden[None], "reward": np.where(s > 0, 10.0, -10.0)[None]}
    data = hidden_pca(record, components=2, color="reward")
    np.testing.assert_allclose(data.explained_variance_ratio, [1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(np.abs(data.scores[:, 0]), np.abs(s - s.mean()), atol=1e-12)
    np.testing.assert_allclose(np.abs(data.components[0]), np.abs(direction), atol=1e-12)
    np.testing.assert_array_equal(data.color, record["reward"][0])
    with pytest.raises(ValueError, match="cannot colour"):
        hidden_pca(record, color="speed")
    with pytest.raises(ValueError, match="not recurrent"):
        hidden_pca({"reward": record["reward"]})


@pytest.mark.slow  # lstm: trains
def test_pca_of_the_network_is_coloured_by_speed(lstm):
    _, record = lstm
    data = hidden_pca(record, components=3)
    assert data.scores.shape == (40, 3) and data.components.shape == (3, 8)
    assert np.all(np.diff(data.explained_variance_ratio) <= 0) and data.explained_variance_ratio.sum() <= 1
    np.testing.assert_allclose(data.color, np.linalg.norm(record["state.velocity"][0], axis=-1), rtol=1e-6)
    fig = plot_hidden_pca(data)
    np.testing.assert_allclose(fig.axes[0].collections[0].get_offsets(), data.scores[:, :2], rtol=1e-6)
