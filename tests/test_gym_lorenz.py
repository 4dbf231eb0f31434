"""Tests of the gymnasium wrapper (jaxsimrl.envs.gym_lorenz) and of its registration."""

from __future__ import annotations

import subprocess
import sys
import warnings

import gymnasium
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import jaxsimrl
from jaxsimrl.envs.gym_lorenz import LorenzGymEnv
from jaxsimrl.envs.lorenz import Lorenz, LorenzParams

# Warnings check_env gives by design: the brief fixes the action space to the physical perturbation box
# and the observation space to an unbounded Box; check_env on a gymnasium.make env notes the wrappers,
# and a directly built env has no spec to re-make other render modes from.
EXPECTED_WARNINGS = (
    "recommend using a symmetric and normalized space",
    "observation space minimum value is -infinity",
    "observation space maximum value is infinity",
    "is different from the unwrapped version",
    "Not able to test alternative render modes",
)


def unexpected_warnings(run) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run()
    messages = [str(w.message) for w in caught]
    return [m for m in messages if not any(e in m for e in EXPECTED_WARNINGS)]


@pytest.mark.parametrize("render_mode", [None, "rgb_array"])
def test_check_env_passes_on_the_raw_and_the_made_env(render_mode):
    made = gymnasium.make(jaxsimrl.LORENZ_ENV_ID, render_mode=render_mode)
    assert isinstance(made.unwrapped, LorenzGymEnv)
    assert unexpected_warnings(lambda: check_env(made.unwrapped)) == []
    assert unexpected_warnings(lambda: check_env(made)) == []


def test_spaces_are_float32_and_follow_the_params():
    env = LorenzGymEnv(rho=28.0)
    assert env.action_space.dtype == np.float32 and env.observation_space.dtype == np.float32
    np.testing.assert_allclose(env.action_space.high, [1.0, 2.8, 0.8 / 3], rtol=1e-6)
    np.testing.assert_allclose(env.action_space.low, -env.action_space.high)
    assert env.observation_space.shape == (6,) and np.all(np.isinf(env.observation_space.high))


def test_registered_with_a_string_entry_point_and_no_time_limit():
    spec = gymnasium.spec(jaxsimrl.LORENZ_ENV_ID)
    assert spec.entry_point == "jaxsimrl.envs.gym_lorenz:LorenzGymEnv"
    assert spec.max_episode_steps is None


def test_importing_jaxsimrl_does_not_import_jax():
    code = ("import sys, gymnasium, jaxsimrl; "
            "assert 'jaxsimrl/Lorenz-v0' in gymnasium.registry; print('jax' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_reset_options_state_is_honoured():
    env = LorenzGymEnv()
    obs, info = env.reset(seed=0, options={"state": [1.0, 12.0, 9.0]})
    np.testing.assert_array_equal(info["state"], [1.0, 12.0, 9.0])
    np.testing.assert_array_equal(obs[:3], [1.0, 12.0, 9.0])
    np.testing.assert_allclose(obs[3:], [110.0, -1.0, 12.0 - 24.0], rtol=1e-6)  # rhs, base params
    _, info = env.reset(seed=0)  # without options: back to the random start
    assert np.abs(info["state"] - [1.0, 12.0, 9.0]).max() > 1e-3
    assert np.all(np.abs(info["state"]) <= 40.0)


def test_info_state_is_raw_whatever_the_observation_scaling():
    scale = np.array([0.1, 0.1, 0.1, 0.01, 0.01, 0.01], np.float32)
    plain, scaled = LorenzGymEnv(), LorenzGymEnv(obs_scale=scale)
    obs_p, info_p = plain.reset(seed=5)
    obs_s, info_s = scaled.reset(seed=5)
    np.testing.assert_array_equal(info_s["state"], info_p["state"])
    np.testing.assert_allclose(obs_s, obs_p * scale, rtol=1e-6)
    for _ in range(20):
        action = plain.action_space.sample()
        obs_p, _, _, _, info_p = plain.step(action)
        obs_s, _, _, _, info_s = scaled.step(action)
        np.testing.assert_array_equal(info_s["state"], info_p["state"])
        np.testing.assert_array_equal(info_s["state"], obs_p[:3])
        np.testing.assert_allclose(obs_s, obs_p * scale, rtol=1e-6)


def _trajectory(env: gymnasium.Env, seed: int, actions: np.ndarray, again: bool = False) -> np.ndarray:
    obs, _ = env.reset(seed=seed)
    if again:
        obs, _ = env.reset()  # second episode: continues gymnasium's seeded stream
    return np.stack([obs] + [env.step(a)[0] for a in actions])


def test_same_seed_same_trajectory_different_seed_different_start():
    actions = np.random.default_rng(0).uniform(-0.1, 0.1, (50, 3)).astype(np.float32)
    first = _trajectory(LorenzGymEnv(), 11, actions)
    np.testing.assert_array_equal(_trajectory(LorenzGymEnv(), 11, actions), first)
    assert np.abs(_trajectory(LorenzGymEnv(), 12, actions)[0] - first[0]).max() > 1e-3
    second = _trajectory(LorenzGymEnv(), 11, actions, again=True)
    np.testing.assert_array_equal(_trajectory(LorenzGymEnv(), 11, actions, again=True), second)
    assert np.abs(second[0] - first[0]).max() > 1e-3


def test_episode_lasts_4000_steps_and_terminates_at_the_end():
    env = gymnasium.make(jaxsimrl.LORENZ_ENV_ID)
    env.reset(seed=0, options={"state": [1.0, 12.0, 9.0]})
    zero = np.zeros(3, np.float32)
    length, terminated = 0, False
    while not terminated and length < 5000:
        _, reward, terminated, truncated, info = env.step(zero)
        length += 1
        assert not truncated
    assert length == 4000
    # Uncontrolled at rho = 20 the flow has settled: the terminal -100 is paid on the last step.
    assert reward == -110.0 and info["terminal_penalty"] == -100.0
    np.testing.assert_allclose(info["state"], [-7.12, -7.12, 19.0], atol=0.05)


def test_gymnasium_rollout_matches_the_pure_jax_env_step_for_step():
    env = LorenzGymEnv()
    obs, info = env.reset(seed=3)
    jax_env = Lorenz()
    params = LorenzParams(random_init=False, init_state=jnp.asarray(info["state"]))
    jax_obs, state = jax_env.reset(jax.random.key(0), params)
    step = jax.jit(jax_env.step)
    np.testing.assert_allclose(obs, np.asarray(jax_obs), rtol=1e-6)
    rng = np.random.default_rng(1)
    for _ in range(300):
        action = rng.uniform(env.action_space.low * 1.5, env.action_space.high * 1.5).astype(np.float32)
        obs, reward, terminated, truncated, info = env.step(action)
        out = step(jax.random.key(0), state, jnp.asarray(action), params)
        state = out.state
        np.testing.assert_allclose(obs, np.asarray(out.obs), rtol=1e-5, atol=1e-4)
        assert reward == float(out.reward)
        assert (terminated, truncated) == (bool(out.terminated), bool(out.truncated))
        assert info["speed"] == pytest.approx(float(out.info["speed"]), rel=1e-5)


def test_constructor_kwargs_map_onto_params():
    env = LorenzGymEnv(rho=24.0, random_init=False, init_state=[2.0, 3.0, 4.0], episode_steps=10,
                       max_steps=10)
    assert env.params.rho == 24.0 and env.params.episode_steps == 10
    _, info = env.reset(seed=0)
    np.testing.assert_array_equal(info["state"], [2.0, 3.0, 4.0])
    flags = [env.step(np.zeros(3, np.float32))[2] for _ in range(10)]
    assert flags == [False] * 9 + [True]


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"rhoo": 20.0}, "rhoo"),
    ({"obs_scale": [1.0, 2.0]}, "obs_scale"),
    ({"init_state": ["a", "b", "c"]}, "init_state"),
    ({"max_steps": float("nan")}, "max_steps"),
    ({"episode_steps": 0}, "episode_steps"),
    ({"max_steps": 2**40}, "max_steps"),  # beyond the int32 step counter
    ({"action_fraction": -0.1}, "action_fraction"),
    ({"dt": "fast"}, "dt"),
    ({"random_init": "yes"}, "random_init"),
    ({"init_low": 5.0, "init_high": -5.0}, "init_low"),
    ({"render_mode": "human"}, "render_mode"),
])
def test_bad_constructor_arguments_raise_value_error_naming_them(kwargs, message):
    with pytest.raises(ValueError, match=message):
        LorenzGymEnv(**kwargs)


def test_bad_calls_raise_clear_errors():
    env = LorenzGymEnv()
    with pytest.raises(RuntimeError, match="before reset"):
        env.step(np.zeros(3, np.float32))
    with pytest.raises(ValueError, match="state"):
        env.reset(options={"state": [1.0, 2.0]})
    with pytest.raises(ValueError, match="speed"):
        env.reset(options={"speed": 1.0})
    env.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(2, np.float32))


def test_render_draws_the_trail_and_marks_the_current_point():
    env = LorenzGymEnv(render_mode="rgb_array")
    env.reset(seed=0, options={"state": [0.0, 1.0, 15.0]})
    first = env.render()
    for _ in range(200):
        env.step(np.zeros(3, np.float32))
    image = env.render()
    assert image.shape == (256, 256, 3) and image.dtype == np.uint8
    assert (image.any(axis=-1)).sum() > (first.any(axis=-1)).sum() + 50  # the trail grew
    red = (image[..., 0] == 255) & (image[..., 1] == 40)
    assert 0 < red.sum() <= 25
    assert LorenzGymEnv().render() is None
