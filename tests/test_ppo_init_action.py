"""PPOConfig.init_action: the initial policy's mean action is the given point of the box."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxsimrl.agents.ppo.config import PPOConfig
from jaxsimrl.agents.ppo.distribution import to_box
from jaxsimrl.agents.ppo.networks import initial_carry
from jaxsimrl.agents.ppo.policy import ActionBox, Policy

BOX = ActionBox(jnp.float32([0.2, 0.2, 0.2]), jnp.float32([0.95, 0.95, 0.95]))


def _initial_mean_action(config: PPOConfig, obs: np.ndarray) -> np.ndarray:
    policy = Policy(config, BOX)
    params = policy.network.init(jax.random.PRNGKey(3), initial_carry(config, 1), jnp.asarray(obs)[None],
                                 jnp.ones((1, len(obs)), bool))
    _, mean, _, _ = policy.network.apply(params, initial_carry(config, len(obs)), jnp.asarray(obs)[None],
                                         jnp.ones((1, len(obs)), bool))
    return np.asarray(to_box(mean[0], BOX.low, BOX.high, config.action_margin))


@pytest.mark.parametrize("margin", [0.0, 0.01])
def test_the_initial_mean_action_is_init_action_for_any_observation(margin):
    obs = np.random.default_rng(0).normal(size=(5, 13)).astype(np.float32) * 3
    wanted = (0.9, 0.35, 0.6)
    config = PPOConfig(network="mlp", seq_len=1, init_action=wanted, action_margin=margin)
    # the head's kernel starts at orthogonal(0.01): the observation moves the mean by ~1e-2 at most
    np.testing.assert_allclose(_initial_mean_action(config, obs), np.broadcast_to(wanted, (5, 3)), atol=0.02)
    centre = _initial_mean_action(PPOConfig(network="mlp", seq_len=1, action_margin=margin), obs)
    np.testing.assert_allclose(centre, 0.575, atol=0.02)  # default: the box centre, as before


def test_a_corner_init_action_is_reached_with_a_margin_and_approached_without():
    obs = np.zeros((2, 4), np.float32)
    top = (0.95, 0.95, 0.95)
    with_margin = _initial_mean_action(PPOConfig(network="mlp", seq_len=1, init_action=top,
                                                 action_margin=0.01), obs)
    plain = _initial_mean_action(PPOConfig(network="mlp", seq_len=1, init_action=top), obs)
    assert np.all(with_margin >= np.float32(0.949)) and np.all(plain > 0.94)


@pytest.mark.parametrize("bad, why", [((0.9, 0.5), "expected 3 entries"), ((0.9, 0.5, 0.99), "outside")])
def test_a_wrong_init_action_is_refused(bad, why):
    with pytest.raises(ValueError, match=why):
        Policy(PPOConfig(network="mlp", seq_len=1, init_action=bad), BOX)


def test_init_action_round_trips_through_the_config_dict():
    config = PPOConfig(network="mlp", seq_len=1, init_action=(0.9, 0.5, 0.7))
    assert PPOConfig.from_dict(config.to_dict()) == config
    with pytest.raises(ValueError, match="init_action"):
        PPOConfig.from_dict({**config.to_dict(), "init_action": ["a"]})
