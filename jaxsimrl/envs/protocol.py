"""The env contracts of the core: what an environment implements to be trained on.

- :class:`Environment`, a pure-JAX env (Lorenz), gymnax-1.0 style: a stateless object; all episode state
  lives in an explicit ``state`` value and all constants in a ``params`` value, so the same code is
  jitted and vmapped (jaxsimrl.envs.vec.JaxVecEnv).
- :class:`HostBatch` (lock-step, gymnasium's VectorEnv) and :class:`AsyncHostBatch` (EnvPool's
  send/recv): a batch of host envs, a simulation's cases on a worker pool, which an application gives the
  trainer (jaxsimrl.envs.host.HostVecEnv and jaxsimrl.envs.host_async.AsyncHostVecEnv drive it from the
  jitted rollout). Each auto-resets its envs itself, gymnasium's SAME_STEP way (``infos["final_obs"]``,
  ``infos["final_info"]``, their ``_`` masks), and ends a failed episode as an outcome, never raising.

    obs, state = env.reset(key, params)
    step = env.step(key, state, action, params)   # -> Step(obs, state, reward, terminated, truncated, info)

``terminated``: the task's MDP ended (no value is bootstrapped past it).
``truncated``: the episode was cut for an outside reason (time cap, ...): the learner bootstraps.
``step`` never auto-resets; the caller (trainer or batched host env) decides when to reset.

This module imports nothing heavy on purpose: a solver's bridge can implement the protocol without JAX.
"""

from __future__ import annotations

from typing import Any, Generic, NamedTuple, Protocol, TypeVar, runtime_checkable

StateT = TypeVar("StateT")
ParamsT = TypeVar("ParamsT")


class Step(NamedTuple):
    """What one environment step returns (fields are arrays, batched or not)."""

    obs: Any
    state: Any
    reward: Any
    terminated: Any
    truncated: Any
    info: dict[str, Any]


class BoxSpec(NamedTuple):
    """A bounded box of shape ``shape`` (``low``/``high`` broadcast to it)."""

    low: Any
    high: Any
    shape: tuple[int, ...]


class Environment(Protocol, Generic[StateT, ParamsT]):
    """A pure-JAX environment (module docstring)."""

    def default_params(self) -> ParamsT: ...

    def reset(self, key: Any, params: ParamsT) -> tuple[Any, StateT]: ...

    def step(self, key: Any, state: StateT, action: Any, params: ParamsT) -> Step: ...

    def observation_space(self, params: ParamsT) -> BoxSpec: ...

    def action_space(self, params: ParamsT) -> BoxSpec: ...


@runtime_checkable
class HostBatch(Protocol):
    """A lock-step batch of ``num_envs`` host envs (module docstring): every ``step`` steps all of them."""

    num_envs: int
    observation_spec: Any  # BoxSpec-like: low, high, shape
    action_spec: Any

    def reset(self, seed: int | None = None) -> tuple[Any, dict[str, Any]]: ...

    def step(self, actions: Any) -> tuple[Any, Any, Any, Any, dict[str, Any]]: ...

    def close(self) -> None: ...


@runtime_checkable
class AsyncHostBatch(Protocol):
    """An asynchronous batch (module docstring): of ``num_envs`` envs, each ``recv`` returns the
    ``batch_size`` ready first, with their ids, and ``send`` steps the envs it names."""

    num_envs: int
    batch_size: int
    observation_spec: Any
    action_spec: Any

    def async_reset(self, seed: int | None = None) -> None: ...

    def recv(self) -> tuple[Any, Any, Any, Any, Any, dict[str, Any]]: ...

    def send(self, actions: Any, env_ids: Any) -> None: ...

    def close(self) -> None: ...
