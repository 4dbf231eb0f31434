"""Transiently chaotic Lorenz system as a pure-JAX environment (Pawar & Maulik, section 3.1).

dx/dt = sigma (y - x),  dy/dt = x (rho - z) - y,  dz/dt = x y - beta z.
With (sigma, rho, beta) = (10, 20, 8/3) the flow is only transiently chaotic and settles on
P- = (-7.12, -7.12, 19). The agent perturbs (sigma, rho, beta) by at most +-10 % of their base values
at every step to keep the trajectory chaotic.

- observation: (x, y, z, dx/dt, dy/dt, dz/dt) times ``params.obs_scale`` (ones by default); the
  derivative is evaluated with the parameters in force after the action (as the paper's code does).
- action: (d sigma, d rho, d beta), clipped to the box +-``action_fraction`` x base values.
- dynamics: one classical RK4 step of ``dt`` per env step with the perturbed parameters.
- reward: +10 if |velocity| > v_threshold else -10; at the last step of the episode an extra -100 if the
  mean step reward over the last ``terminal_window`` steps is <= -2.
- the episode ends after ``episode_steps`` steps: that is the end of the paper's (fixed-horizon) MDP,
  so it is ``terminated``. ``truncated`` is raised when ``max_steps`` < ``episode_steps`` cuts an
  episode short (a time cap outside the task), and the learner then bootstraps.

Every constant lives in :class:`LorenzParams`, a pytree: it can be changed per call and even vmapped.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from jaxsimrl.envs.protocol import BoxSpec, Step

P_MINUS = (-7.12, -7.12, 19.0)


@struct.dataclass
class LorenzParams:
    sigma: float = 10.0
    rho: float = 20.0
    beta: float = 8.0 / 3.0
    action_fraction: float = 0.1
    dt: float = 0.02
    v_threshold: float = 40.0
    reward_above: float = 10.0
    reward_below: float = -10.0
    terminal_penalty: float = -100.0
    terminal_mean_threshold: float = -2.0
    terminal_window: int = 2000
    episode_steps: int = 4000
    max_steps: int = 2**31 - 1  # optional time cap below episode_steps (truncation); none by default
    random_init: bool = True
    init_low: float = -40.0
    init_high: float = 40.0
    init_state: jax.Array = struct.field(default_factory=lambda: jnp.array([1.0, 12.0, 9.0]))
    obs_scale: jax.Array = struct.field(default_factory=lambda: jnp.ones(6))

    @property
    def horizon(self) -> int:
        """Steps in one episode: the task's ``episode_steps``, or the ``max_steps`` cap if shorter."""
        return min(int(self.episode_steps), int(self.max_steps))

    @property
    def base(self) -> jax.Array:
        """The unperturbed (sigma, rho, beta)."""
        return jnp.stack([jnp.asarray(self.sigma), jnp.asarray(self.rho), jnp.asarray(self.beta)])

    @property
    def action_bound(self) -> jax.Array:
        """Half-width of the action box: +-``action_fraction`` x |base|."""
        return self.action_fraction * jnp.abs(self.base)


@struct.dataclass
class LorenzState:
    xyz: jax.Array  # (3,) raw position
    velocity: jax.Array  # (3,) dx/dt evaluated with the parameters in force
    t: jax.Array  # int32 steps taken in this episode
    window_reward: jax.Array  # sum of step rewards inside the terminal window so far


def lorenz_rhs(xyz: jax.Array, coeffs: jax.Array) -> jax.Array:
    """Time derivative of the Lorenz system; ``coeffs`` = (sigma, rho, beta)."""
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    sigma, rho, beta = coeffs[..., 0], coeffs[..., 1], coeffs[..., 2]
    return jnp.stack([sigma * (y - x), x * (rho - z) - y, x * y - beta * z], axis=-1)


def rk4_step(xyz: jax.Array, coeffs: jax.Array, dt: float | jax.Array) -> jax.Array:
    """One classical 4th-order Runge-Kutta step."""
    k1 = lorenz_rhs(xyz, coeffs)
    k2 = lorenz_rhs(xyz + 0.5 * dt * k1, coeffs)
    k3 = lorenz_rhs(xyz + 0.5 * dt * k2, coeffs)
    k4 = lorenz_rhs(xyz + dt * k3, coeffs)
    return xyz + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


class Lorenz:
    """The Lorenz chaos-restoration task; implements :class:`jaxsimrl.envs.protocol.Environment`."""

    obs_dim = 6
    action_dim = 3

    def default_params(self) -> LorenzParams:
        return LorenzParams()

    def reset(self, key: jax.Array, params: LorenzParams) -> tuple[jax.Array, LorenzState]:
        sampled = jax.random.uniform(key, (3,), minval=params.init_low, maxval=params.init_high)
        xyz = jnp.where(params.random_init, sampled, jnp.asarray(params.init_state, jnp.float32))
        velocity = lorenz_rhs(xyz, params.base)
        state = LorenzState(xyz=xyz, velocity=velocity, t=jnp.int32(0), window_reward=jnp.float32(0.0))
        return self._obs(state, params), state

    def step(self, key: jax.Array, state: LorenzState, action: jax.Array, params: LorenzParams) -> Step:
        del key  # the dynamics are deterministic
        bound = params.action_bound
        coeffs = params.base + jnp.clip(action, -bound, bound)
        xyz = rk4_step(state.xyz, coeffs, params.dt)
        velocity = lorenz_rhs(xyz, coeffs)
        speed = jnp.linalg.norm(velocity)
        reward = jnp.where(speed > params.v_threshold, params.reward_above, params.reward_below)

        t = state.t + 1
        in_window = t > params.episode_steps - params.terminal_window
        window_reward = state.window_reward + jnp.where(in_window, reward, 0.0)
        terminated = t >= params.episode_steps
        window_mean = window_reward / jnp.minimum(params.terminal_window, params.episode_steps)
        penalty = jnp.where(terminated & (window_mean <= params.terminal_mean_threshold),
                            params.terminal_penalty, 0.0)
        truncated = (t >= params.max_steps) & ~terminated

        new_state = LorenzState(xyz=xyz, velocity=velocity, t=t, window_reward=window_reward)
        info = {"state": xyz, "speed": speed, "terminal_penalty": penalty}
        return Step(self._obs(new_state, params), new_state, (reward + penalty).astype(jnp.float32),
                    terminated, truncated, info)

    def observation_space(self, params: LorenzParams) -> BoxSpec:
        return BoxSpec(low=-jnp.inf, high=jnp.inf, shape=(self.obs_dim,))

    def action_space(self, params: LorenzParams) -> BoxSpec:
        bound = params.action_bound
        return BoxSpec(low=-bound, high=bound, shape=(self.action_dim,))

    @staticmethod
    def _obs(state: LorenzState, params: LorenzParams) -> jax.Array:
        return jnp.concatenate([state.xyz, state.velocity]) * params.obs_scale
