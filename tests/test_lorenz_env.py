"""Tests of the pure-JAX Lorenz environment (jaxsimrl.envs.lorenz).

The dynamics are checked against an independent float64 Taylor-series integrator; the reward, the
terminal penalty and the episode flags on hand-built states whose outcome is known exactly.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxsimrl.envs.lorenz import P_MINUS, Lorenz, LorenzParams, LorenzState, lorenz_rhs

ENV = Lorenz()
BASE = np.array([10.0, 20.0, 8.0 / 3.0])
STEP = jax.jit(ENV.step)
RESET = jax.jit(ENV.reset)
KEY = jax.random.key(0)


@partial(jax.jit, static_argnames="n")
def rollout(params: LorenzParams, state: LorenzState, actions: jax.Array, n: int):
    """``n`` env steps with ``actions`` (broadcast to (n, 3)); returns the final state and per-step data."""
    actions = jnp.broadcast_to(actions, (n, 3))

    def body(s, a):
        out = ENV.step(KEY, s, a, params)
        return out.state, (out.reward, out.terminated, out.truncated, out.info["terminal_penalty"],
                           out.info["state"])

    return jax.lax.scan(body, state, actions)


def fixed_start(params: LorenzParams) -> LorenzState:
    return RESET(KEY, params.replace(random_init=False))[1]


def make_state(xyz, params: LorenzParams, t: int = 0, window_reward: float = 0.0) -> LorenzState:
    xyz = jnp.asarray(xyz, jnp.float32)
    return LorenzState(xyz=xyz, velocity=lorenz_rhs(xyz, params.base), t=jnp.int32(t),
                       window_reward=jnp.float32(window_reward))


# ----------------------------------------------------------------------------- dynamics


def taylor_reference(xyz, coeffs, t_end: float, h: float = 0.01, order: int = 20) -> np.ndarray:
    """High-order Taylor-series integration in float64, independent of RK4.

    The Lorenz right-hand side is quadratic, so the Taylor coefficients follow from Cauchy products:
    (k+1) x_{k+1} = sigma (y_k - x_k), (k+1) y_{k+1} = rho x_k - (xz)_k - y_k, (k+1) z_{k+1} = (xy)_k -
    beta z_k. With h = 0.01 and order 20 the truncation error is far below 1e-10 on this horizon.
    """
    sigma, rho, beta = coeffs
    x = np.asarray(xyz, np.float64)
    for _ in range(int(round(t_end / h))):
        c = np.zeros((3, order + 1))
        c[:, 0] = x
        for k in range(order):
            xz = c[0, : k + 1] @ c[2, k::-1]
            xy = c[0, : k + 1] @ c[1, k::-1]
            c[:, k + 1] = np.array([sigma * (c[1, k] - c[0, k]), rho * c[0, k] - xz - c[1, k],
                                    xy - beta * c[2, k]]) / (k + 1)
        x = c @ h ** np.arange(order + 1)
    return x


def rk4_float64(xyz, coeffs, dt: float, n: int) -> np.ndarray:
    sigma, rho, beta = coeffs

    def f(v):
        return np.array([sigma * (v[1] - v[0]), v[0] * (rho - v[2]) - v[1], v[0] * v[1] - beta * v[2]])

    v = np.asarray(xyz, np.float64)
    for _ in range(n):
        k1 = f(v)
        k2 = f(v + dt / 2 * k1)
        k3 = f(v + dt / 2 * k2)
        k4 = f(v + dt * k3)
        v = v + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return v


@pytest.mark.parametrize("action", [(0.0, 0.0, 0.0), (0.5, -1.0, 0.1)])
def test_rk4_trajectory_matches_independent_reference_at_t1(action):
    params = LorenzParams(random_init=False)
    final, _ = rollout(params, fixed_start(params), jnp.asarray(action, jnp.float32), 50)  # t = 50 dt = 1
    coeffs = BASE + np.asarray(action)
    xyz = np.asarray(final.xyz, np.float64)
    # Same scheme in float64: only float32 round-off separates them (measured 4e-6 / 4e-5).
    np.testing.assert_allclose(xyz, rk4_float64([1, 12, 9], coeffs, 0.02, 50), rtol=0, atol=5e-4)
    # Against the exact solution the gap is RK4's global truncation error, O(dt^4): a float64 RK4 at
    # dt = 0.02 is off by 1.0e-3 (no action) and 3.1e-3 (constant action) here, whereas a 3rd-order
    # Runge-Kutta is off by 0.35 and Heun by ~0.8. 1e-2 admits the former and rejects any lower order.
    np.testing.assert_allclose(xyz, taylor_reference([1, 12, 9], coeffs, 1.0), rtol=0, atol=1e-2)


def test_uncontrolled_rho20_settles_on_p_minus_with_penalty_only_at_the_end():
    params = LorenzParams(random_init=False)
    final, (reward, terminated, truncated, penalty, _) = rollout(params, fixed_start(params), jnp.zeros(3),
                                                                 4000)
    np.testing.assert_allclose(np.asarray(final.xyz), P_MINUS, atol=0.05)
    assert np.linalg.norm(np.asarray(final.velocity)) < 1e-2
    # The flow decays onto the fixed point: every step of the last 2000 is below V_th ...
    assert np.all(np.asarray(reward[2000:-1]) == -10.0)
    # ... so the terminal -100 is paid, once, on the last step.
    assert np.asarray(penalty)[-1] == -100.0 and np.all(np.asarray(penalty)[:-1] == 0.0)
    assert np.asarray(reward)[-1] == -110.0
    assert np.asarray(terminated)[-1] and not np.any(np.asarray(terminated)[:-1])
    assert not np.any(np.asarray(truncated))


# ----------------------------------------------------------------------------- rewards


@pytest.mark.parametrize(("z", "expected"), [(20.5, 10.0), (20.0, -10.0), (19.5, -10.0)])
def test_step_reward_compares_speed_with_threshold(z, expected):
    # dt = 0 freezes the state and beta = 2 makes the velocity exactly (0, 0, -2 z): speed 41, 40, 39.
    params = LorenzParams(dt=0.0, beta=2.0, v_threshold=40.0)
    out = STEP(KEY, make_state([0.0, 0.0, z], params), jnp.zeros(3), params)
    assert float(out.info["speed"]) == 2 * z
    assert float(out.reward) == expected


def test_velocity_and_reward_use_the_perturbed_parameters():
    # Frozen state (0, 0, 20) with beta = 2: speed 2 z = 40 at the base beta (reward -10), 42 with
    # d beta = +0.1, so the reward flips only if the action enters the velocity.
    params = LorenzParams(dt=0.0, beta=2.0)
    state = make_state([0.0, 0.0, 20.0], params)
    base = STEP(KEY, state, jnp.zeros(3), params)
    perturbed = STEP(KEY, state, jnp.array([0.0, 0.0, 0.1]), params)
    assert float(base.reward) == -10.0 and float(perturbed.reward) == 10.0
    np.testing.assert_allclose(np.asarray(perturbed.obs[3:]), [0.0, 0.0, -42.0], rtol=1e-6)
    np.testing.assert_allclose(float(perturbed.info["speed"]), 42.0, rtol=1e-6)


def test_step_reward_on_real_dynamics():
    params = LorenzParams()
    near_fixed_point = make_state(P_MINUS, params)
    fast = make_state([10.0, -10.0, 0.0], params)  # dx/dt = -200
    assert float(STEP(KEY, near_fixed_point, jnp.zeros(3), params).reward) == -10.0
    out = STEP(KEY, fast, jnp.zeros(3), params)
    assert float(out.info["speed"]) > 40.0 and float(out.reward) == 10.0


def _last_step(window_reward: float, speed_z: float, t: int = 3999):
    """One step from step ``t`` with a chosen window sum and a step reward of +10 (z=25) or -10 (z=15)."""
    params = LorenzParams(dt=0.0, beta=2.0)
    return STEP(KEY, make_state([0.0, 0.0, speed_z], params, t=t, window_reward=window_reward), jnp.zeros(3),
                params)


def test_terminal_penalty_when_window_mean_is_exactly_minus_two():
    out = _last_step(-3990.0, 15.0)  # -3990 - 10 = -4000 over 2000 steps: mean exactly -2
    assert bool(out.terminated)
    assert float(out.info["terminal_penalty"]) == -100.0
    assert float(out.reward) == -110.0


def test_no_terminal_penalty_just_above_minus_two():
    out = _last_step(-3990.0, 25.0)  # -3990 + 10 = -3980: mean -1.99
    assert bool(out.terminated)
    assert float(out.info["terminal_penalty"]) == 0.0
    assert float(out.reward) == 10.0


def test_terminal_penalty_only_on_the_last_step():
    out = _last_step(-3990.0, 15.0, t=3998)  # same window sum, one step before the end
    assert not bool(out.terminated)
    assert float(out.info["terminal_penalty"]) == 0.0
    assert float(out.reward) == -10.0


@pytest.mark.parametrize(("rewards", "penalised"), [
    ([-10] * 4 + [10] + [-10, -10, -10, 10, 10], True),  # window mean exactly -2; the +10 before it
    ([-10] * 5 + [-10, -10, 10, 10, 10], False),  # window mean +2
    ([10] * 5 + [-10] * 5, True),  # only the window counts ...
    ([-10] * 5 + [10] * 5, False),  # ... not the steps before it
])
def test_terminal_window_covers_only_the_last_steps(rewards, penalised):
    # Each step's reward is set through v_threshold: -1 (always above) or +inf (always below).
    params = LorenzParams(episode_steps=10, max_steps=10, terminal_window=5, random_init=False)
    state = fixed_start(params)
    for i, r in enumerate(rewards):
        out = STEP(KEY, state, jnp.zeros(3), params.replace(v_threshold=-1.0 if r > 0 else jnp.inf))
        state = out.state
        assert float(out.reward) == r + (-100.0 if penalised and i == 9 else 0.0)
    assert bool(out.terminated)


# ----------------------------------------------------------------------------- episode flags


@pytest.mark.parametrize(("episode_steps", "max_steps"), [(6, 6), (6, 9), (6, 4)])
def test_terminated_at_episode_end_truncated_only_by_a_shorter_cap(episode_steps, max_steps):
    params = LorenzParams(episode_steps=episode_steps, max_steps=max_steps, terminal_window=3)
    _, (_, terminated, truncated, _, _) = rollout(params, fixed_start(params), jnp.zeros(3), 6)
    t = np.arange(1, 7)
    np.testing.assert_array_equal(np.asarray(terminated), t >= episode_steps)
    np.testing.assert_array_equal(np.asarray(truncated), (t >= max_steps) & (t < episode_steps))
    assert not np.any(np.asarray(terminated) & np.asarray(truncated))



def test_no_time_cap_by_default_so_a_longer_episode_is_never_truncated():
    params = LorenzParams(episode_steps=4005, terminal_window=3)
    _, (_, terminated, truncated, _, _) = rollout(params, fixed_start(params), jnp.zeros(3), 4005)
    assert not np.any(np.asarray(truncated))
    assert np.flatnonzero(np.asarray(terminated)).tolist() == [4004]
    assert params.horizon == 4005 and params.replace(max_steps=7).horizon == 7


# ----------------------------------------------------------------------------- action box


@pytest.mark.parametrize("rho", [20.0, 28.0])
def test_actions_are_clipped_to_ten_percent_of_the_base_parameters(rho):
    params = LorenzParams(rho=rho, random_init=False)
    base = np.array([10.0, rho, 8.0 / 3.0])
    space = ENV.action_space(params)
    np.testing.assert_allclose(np.asarray(space.high), 0.1 * base, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(space.low), -0.1 * base, rtol=1e-6)

    huge = jnp.array([1e3, -1e3, 1e3])
    corner = jnp.asarray(0.1 * base * np.array([1, -1, 1]), jnp.float32)
    start = fixed_start(params)
    # Ten steps at the corner: the bound is recomputed from the base values, so it never drifts.
    clipped, _ = rollout(params, start, huge, 10)
    at_corner, _ = rollout(params, start, corner, 10)
    np.testing.assert_array_equal(np.asarray(clipped.xyz), np.asarray(at_corner.xyz))
    expected = rk4_float64([1, 12, 9], base + 0.1 * base * np.array([1, -1, 1]), 0.02, 10)
    np.testing.assert_allclose(np.asarray(clipped.xyz), expected, atol=1e-4)
    # Inside the box, actions are used as given.
    inside, _ = rollout(params, start, 0.5 * corner, 10)
    assert np.abs(np.asarray(inside.xyz) - np.asarray(at_corner.xyz)).max() > 1e-3


# ----------------------------------------------------------------------------- jit / vmap


def test_vmap_over_keys_matches_unbatched_steps():
    params = LorenzParams()
    keys = jax.random.split(jax.random.key(1), 4)
    obs, states = jax.jit(jax.vmap(ENV.reset, in_axes=(0, None)))(keys, params)
    actions = jnp.array([[0.5, -1.0, 0.1]] * 4)
    batched = jax.jit(jax.vmap(ENV.step, in_axes=(0, 0, 0, None)))(keys, states, actions, params)
    assert len(np.unique(np.asarray(obs)[:, 0])) == 4
    for i in range(4):
        o, s = RESET(keys[i], params)
        np.testing.assert_array_equal(np.asarray(obs[i]), np.asarray(o))
        single = STEP(keys[i], s, actions[i], params)
        np.testing.assert_allclose(np.asarray(batched.obs[i]), np.asarray(single.obs), rtol=1e-6, atol=1e-5)
        assert float(batched.reward[i]) == float(single.reward)


def test_vmap_over_params_gives_one_trajectory_per_rho():
    rhos = jnp.array([18.0, 20.0, 24.0, 28.0])
    params = LorenzParams(random_init=False)
    batch = params.replace(rho=rhos)
    axes = jax.tree.map(lambda _: None, params).replace(rho=0)

    def run(p):
        return rollout(p, fixed_start(p), jnp.zeros(3), 200)[0].xyz

    finals = np.asarray(jax.jit(jax.vmap(run, in_axes=(axes,)))(batch))
    for i, rho in enumerate(rhos):
        np.testing.assert_allclose(finals[i], np.asarray(run(params.replace(rho=float(rho)))), atol=1e-3)
    distances = np.linalg.norm(finals[:, None] - finals[None], axis=-1)
    assert distances[~np.eye(4, dtype=bool)].min() > 0.1


# ----------------------------------------------------------------------------- reset


def test_random_initial_states_are_uniform_in_the_box_and_depend_on_the_key():
    params = LorenzParams()
    keys = jax.random.split(jax.random.key(7), 4096)
    _, states = jax.vmap(ENV.reset, in_axes=(0, None))(keys, params)
    xyz = np.asarray(states.xyz)
    assert xyz.min() >= -40.0 and xyz.max() <= 40.0
    # Uniform on [-40, 40]: mean 0 and std 80 / sqrt(12) = 23.09; 4096 samples give a mean's s.e. of 0.36.
    np.testing.assert_allclose(xyz.mean(axis=0), 0.0, atol=1.5)
    np.testing.assert_allclose(xyz.std(axis=0), 80 / np.sqrt(12), rtol=0.05)
    counts, _ = np.histogram(xyz[:, 0], bins=8, range=(-40, 40))
    assert counts.min() > 0.8 * 512 and counts.max() < 1.2 * 512
    assert len(np.unique(xyz, axis=0)) == 4096  # distinct keys, distinct points
    again = np.asarray(RESET(keys[3], params)[1].xyz)
    np.testing.assert_array_equal(again, xyz[3])
    narrow = np.asarray(RESET(keys[3], params.replace(init_low=1.0, init_high=2.0))[1].xyz)
    assert np.all((narrow >= 1.0) & (narrow <= 2.0))


def test_fixed_initial_state_is_honoured_whatever_the_key():
    params = LorenzParams(random_init=False, init_state=jnp.array([3.0, -4.0, 5.0]))
    for seed in (0, 1):
        obs, state = RESET(jax.random.key(seed), params)
        np.testing.assert_array_equal(np.asarray(state.xyz), [3.0, -4.0, 5.0])
        # velocity at reset: base parameters, sigma (y - x), x (rho - z) - y, x y - beta z
        np.testing.assert_allclose(np.asarray(obs[3:]), [-70.0, 49.0, -12.0 - 40.0 / 3.0], rtol=1e-6)
    default = RESET(KEY, LorenzParams(random_init=False))[1]
    np.testing.assert_array_equal(np.asarray(default.xyz), [1.0, 12.0, 9.0])


def test_obs_scale_scales_the_observation_not_info_state():
    scale = jnp.array([0.1, 0.2, 0.3, 0.01, 0.02, 0.03])
    plain, scaled = LorenzParams(random_init=False), LorenzParams(random_init=False, obs_scale=scale)
    obs_p, state_p = RESET(KEY, plain)
    obs_s, state_s = RESET(KEY, scaled)
    np.testing.assert_allclose(np.asarray(obs_s), np.asarray(obs_p) * np.asarray(scale), rtol=1e-6)
    out_p = STEP(KEY, state_p, jnp.zeros(3), plain)
    out_s = STEP(KEY, state_s, jnp.zeros(3), scaled)
    np.testing.assert_allclose(np.asarray(out_s.obs), np.asarray(out_p.obs) * np.asarray(scale), rtol=1e-6)
    np.testing.assert_array_equal(np.asarray(out_s.info["state"]), np.asarray(out_p.info["state"]))
    np.testing.assert_array_equal(np.asarray(out_s.info["state"]), np.asarray(out_p.obs[:3]))
    assert float(out_s.reward) == float(out_p.reward)


def test_spaces_have_the_documented_shapes():
    params = LorenzParams()
    assert ENV.observation_space(params).shape == (6,)
    assert ENV.action_space(params).shape == (3,)
    obs, _ = RESET(KEY, params)
    assert obs.shape == (6,) and obs.dtype == jnp.float32
