"""PPOConfig: defaults are the paper's, validation names the bad field, dict round trip."""

from __future__ import annotations

import json

import pytest

from jaxsimrl.agents.ppo import PPOConfig


def test_defaults_are_the_paper_setup():
    cfg = PPOConfig().validate()
    assert (cfg.num_envs, cfg.steps_per_update, cfg.total_steps) == (2, 8000, 200_000)
    assert (cfg.network, cfg.hidden_sizes, cfg.lstm_size, cfg.activation) == ("lstm", (64, 64), 256, "tanh")
    assert cfg.lr == 2.5e-4 and cfg.steps_per_env == 4000 and cfg.num_updates == 25


def test_dict_round_trip_through_json():
    cfg = PPOConfig(num_envs=8, network="mlp", hidden_sizes=(32, 16), anneal_lr=True)
    again = PPOConfig.from_dict(json.loads(json.dumps(cfg.to_dict())))
    assert again == cfg


def test_unknown_keys_are_named():
    with pytest.raises(ValueError, match="unknown PPO config key.*bogus.*lrr"):
        PPOConfig.from_dict({"lrr": 1e-3, "bogus": 1})


@pytest.mark.parametrize("changes, field", [
    ({"num_envs": 0}, "num_envs"),
    ({"num_envs": 3}, "steps_per_update"),  # 8000 steps cannot be split over 3 envs
    ({"steps_per_update": 2.5}, "steps_per_update"),
    ({"network": "gru"}, "network"),
    ({"activation": "sigmoid"}, "activation"),
    ({"hidden_sizes": []}, "hidden_sizes"),
    ({"hidden_sizes": [64, -1]}, "hidden_sizes"),
    ({"lr": -1.0}, "lr"),
    ({"gamma": 1.5}, "gamma"),
    ({"gae_lambda": "0.9"}, "gae_lambda"),
    ({"ent_coef": -0.1}, "ent_coef"),
    ({"seq_len": 300}, "seq_len"),  # does not divide 4000
    ({"num_minibatches": 3}, "num_minibatches"),  # does not divide 80 chunks
    ({"total_steps": 100}, "total_steps"),
    ({"anneal_lr": "yes"}, "anneal_lr"),
    ({"updates_per_chunk": 0}, "updates_per_chunk"),
])
def test_validation_names_the_bad_field(changes, field):
    with pytest.raises(ValueError, match=field) as info:
        PPOConfig.from_dict(changes)
    assert "\n" not in str(info.value)
