"""The environment protocol shared by pure-JAX envs (Lorenz) and host envs (OpenFOAM).

gymnax-1.0 style: environments are stateless objects; all episode state lives in an explicit
``state`` value and all constants in a ``params`` value, so the same code can be jitted and vmapped
(JAX envs) or driven from a host process pool (OpenFOAM envs).

    obs, state = env.reset(key, params)
    step = env.step(key, state, action, params)   # -> Step(obs, state, reward, terminated, truncated, info)

``terminated``: the task's MDP ended (no value is bootstrapped past it).
``truncated``: the episode was cut for an outside reason (time cap, ...): the learner bootstraps.
``step`` never auto-resets; the caller (trainer or batched host env) decides when to reset.

This module imports nothing heavy on purpose: a solver's bridge can implement the protocol without JAX.
"""

from __future__ import annotations

from typing import Any, Generic, NamedTuple, Protocol, TypeVar

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
    """The interface every environment implements, pure-JAX or host."""

    def default_params(self) -> ParamsT: ...

    def reset(self, key: Any, params: ParamsT) -> tuple[Any, StateT]: ...

    def step(self, key: Any, state: StateT, action: Any, params: ParamsT) -> Step: ...

    def observation_space(self, params: ParamsT) -> BoxSpec: ...

    def action_space(self, params: ParamsT) -> BoxSpec: ...
