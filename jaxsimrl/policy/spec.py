"""Which environment a run was trained on, rebuilt from its config.json (``record["env"]``).

Each kind of run has a builder from the run's record to an :class:`EnvSpec`: the action box the policy
acts in, the env params it trained with, readable names for the observation and action components (used
by the introspection plots), the observation size the run's config implies (checked against the
checkpoint) and, for a pure-JAX env, the env object itself (what a jitted rollout steps). The core's own kind
is ``"lorenz"`` (train-lorenz: the pure-JAX Lorenz env and its default params, ``BUILDERS``); an
application's runs are rebuilt by its App's ``env_spec`` (jaxsimrl.apps).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from jaxsimrl.agents.ppo.policy import ActionBox
from jaxsimrl.envs.lorenz import Lorenz
from jaxsimrl.plugin import application, applications, load

LORENZ_OBS_NAMES = ("x", "y", "z", "dx/dt", "dy/dt", "dz/dt")
LORENZ_ACTION_NAMES = ("d sigma", "d rho", "d beta")


@dataclass(frozen=True)
class EnvSpec:
    """An env as a policy of a run sees it."""

    box: ActionBox
    params: Any
    obs_names: tuple[str, ...] | None
    action_names: tuple[str, ...] | None
    obs_dim: int | None = None  # the observation size the run's config implies; None: not checked
    env: Any = None  # the pure-JAX env a jitted rollout steps; None: no such env (train-foam)

    @classmethod
    def of_env(cls, env: Any, env_params: Any = None, obs_names: tuple[str, ...] | None = None,
               action_names: tuple[str, ...] | None = None) -> EnvSpec:
        """The spec of a pure-JAX env object under ``env_params`` (default: its default params)."""
        params = env.default_params() if env_params is None else env_params
        return cls(ActionBox.of_env(env, params), params, obs_names, action_names, env=env)


def lorenz_spec(record: dict[str, Any]) -> EnvSpec:
    """train-lorenz trains on ``Lorenz().default_params()`` (its config.json stores no env params)."""
    return EnvSpec.of_env(Lorenz(), None, LORENZ_OBS_NAMES, LORENZ_ACTION_NAMES)


BUILDERS: dict[str, Callable[[dict[str, Any]], EnvSpec]] = {"lorenz": lorenz_spec}


def env_spec(record: dict[str, Any]) -> EnvSpec:
    """The env of a run's config.json record (the core's, or an application's); a one-line ValueError
    for an env this version lacks."""
    name = record.get("env")
    if name in BUILDERS:
        return BUILDERS[name](record)
    app = application(name)
    if app is None or app.env_spec is None:
        known = ", ".join(sorted({*BUILDERS, *(a.env for a in applications() if a.env_spec)}))
        raise ValueError(f"config.json names env {name!r}, which this version cannot rebuild "
                         f"(known: {known})")
    return load(app.env_spec)(record)


def names_for(spec_names: tuple[str, ...] | None, size: int, prefix: str) -> tuple[str, ...]:
    """``spec_names`` if it fits ``size`` components, else generic names (obs[0], ...)."""
    if spec_names is not None and len(spec_names) == size:
        return tuple(spec_names)
    return tuple(f"{prefix}[{i}]" for i in range(size))
