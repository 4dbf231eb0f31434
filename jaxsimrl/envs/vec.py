"""The batched-env boundary between the PPO trainer and every environment.

The trainer never calls an env's ``reset``/``step`` itself: it talks to a :class:`VecEnv`, which owns
``num_envs`` envs and auto-resets them.

    obs, state = vec.reset(keys)                 # keys (N, key): one per env
    out = vec.step(keys, state, actions)         # keys (N, 2, key): a step key and a reset key per env
    out.obs          # (N, obs_dim) next observation; for an env whose episode just ended, the first
                     # observation of its next episode
    out.final_obs    # (N, obs_dim) the observation the step itself reached (pre-reset); the truncation
                     # bootstrap evaluates the critic on it
    out.reward, out.terminated, out.truncated, out.state
    out.ended        # (N,) the envs whose step ended an episode: terminated | truncated, except a host
                     # batch's non-transition (the step after a failed auto-reset, truncated to bootstrap
                     # from the old episode's last observation), which ended none; episode statistics
                     # count these

Two kinds implement it:

- :class:`JaxVecEnv`: a pure-JAX env (Lorenz) vmapped, every env reset at every step and the fresh state
  picked with ``where`` where an episode ended (cheap for a JAX env, and shape-static). Its
  ``sample_observations`` gives reset observations to seed the observation normaliser.
- ``jaxsimrl.envs.host.HostVecEnv``: a batch of host envs (OpenFOAM cases on a process pool) behind one
  ``io_callback`` per step that carries the whole action batch; the host batch auto-resets itself.
  It has no cheap samples (``sample_observations`` returns None): each would be a case build.
  ``jaxsimrl.envs.host_async.AsyncHostVecEnv`` is its asynchronous variant: ``num_envs`` rows per call
  out of ``async_envs`` envs, the state the env id of each row (the rollout: agents/ppo/rollout_async.py).

The keys a VecEnv receives are this device's rows of per-global-env keys, so sharding envs over devices
does not change any sample.
"""

from __future__ import annotations

from typing import Any, NamedTuple, Protocol

import jax
import jax.numpy as jnp


class VecStep(NamedTuple):
    """What :meth:`VecEnv.step` returns (arrays with a leading env axis)."""

    obs: jax.Array
    final_obs: jax.Array
    reward: jax.Array
    terminated: jax.Array
    truncated: jax.Array
    state: Any
    ended: jax.Array


class VecEnv(Protocol):
    """A batch of auto-resetting envs (see the module docstring)."""

    num_envs: int

    def reset(self, keys: jax.Array) -> tuple[jax.Array, Any]: ...

    def step(self, keys: jax.Array, state: Any, actions: jax.Array) -> VecStep: ...

    def action_space(self) -> Any: ...

    def observation_space(self) -> Any: ...

    def sample_observations(self, key: jax.Array, count: int) -> jax.Array | None: ...


class JaxVecEnv:
    """``num_envs`` copies of a pure-JAX env with the same params, vmapped and auto-reset."""

    def __init__(self, env: Any, env_params: Any = None, num_envs: int = 1) -> None:
        self.env = env
        self.env_params = env.default_params() if env_params is None else env_params
        self.num_envs = num_envs

    def action_space(self) -> Any:
        return self.env.action_space(self.env_params)

    def observation_space(self) -> Any:
        return self.env.observation_space(self.env_params)

    def reset(self, keys: jax.Array) -> tuple[jax.Array, Any]:
        return jax.vmap(self.env.reset, in_axes=(0, None))(keys, self.env_params)

    def step(self, keys: jax.Array, state: Any, actions: jax.Array) -> VecStep:
        step = jax.vmap(self.env.step, in_axes=(0, 0, 0, None))(keys[:, 0], state, actions, self.env_params)
        done = step.terminated | step.truncated
        reset_obs, reset_state = self.reset(keys[:, 1])

        def pick(fresh: jax.Array, old: jax.Array) -> jax.Array:
            return jnp.where(done.reshape(done.shape + (1,) * (old.ndim - 1)), fresh, old)

        return VecStep(obs=pick(reset_obs, step.obs), final_obs=step.obs, reward=step.reward,
                       terminated=step.terminated, truncated=step.truncated,
                       state=jax.tree.map(pick, reset_state, step.state), ended=done)

    def sample_observations(self, key: jax.Array, count: int) -> jax.Array:
        """``count`` reset observations (for the normaliser's initial statistics)."""
        return self.reset(jax.random.split(key, count))[0]
