"""Which environment a run was trained on, rebuilt from its config.json (``record["env"]``).

Each kind of run has a builder from the run's record to an :class:`EnvSpec`: the env object, the
params it trained with and readable names for the observation and action components (used by the
introspection plots). A new kind of run (e.g. train-foam's) adds one entry to ``BUILDERS``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

LORENZ_OBS_NAMES = ("x", "y", "z", "dx/dt", "dy/dt", "dz/dt")
LORENZ_ACTION_NAMES = ("d sigma", "d rho", "d beta")


@dataclass(frozen=True)
class EnvSpec:
    """An env as a policy of a run sees it."""

    env: Any
    params: Any
    obs_names: tuple[str, ...]
    action_names: tuple[str, ...]


def lorenz_spec(record: dict[str, Any]) -> EnvSpec:
    """train-lorenz trains on ``Lorenz().default_params()`` (its config.json stores no env params)."""
    from jaxsimrl.envs.lorenz import Lorenz

    env = Lorenz()
    return EnvSpec(env, env.default_params(), LORENZ_OBS_NAMES, LORENZ_ACTION_NAMES)


BUILDERS: dict[str, Callable[[dict[str, Any]], EnvSpec]] = {"lorenz": lorenz_spec}


def env_spec(record: dict[str, Any]) -> EnvSpec:
    """The env of a run's config.json record; a one-line ValueError for an env this version lacks."""
    name = record.get("env")
    if name not in BUILDERS:
        known = ", ".join(sorted(BUILDERS))
        raise ValueError(f"config.json names env {name!r}, which this version cannot rebuild "
                         f"(known: {known})")
    return BUILDERS[name](record)


def names_for(spec_names: tuple[str, ...] | None, size: int, prefix: str) -> tuple[str, ...]:
    """``spec_names`` if it fits ``size`` components, else generic names (obs[0], ...)."""
    if spec_names is not None and len(spec_names) == size:
        return tuple(spec_names)
    return tuple(f"{prefix}[{i}]" for i in range(size))
