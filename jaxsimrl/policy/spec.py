"""Which environment a run was trained on, rebuilt from its config.json (``record["env"]``).

Each kind of run has a builder from the run's record to an :class:`EnvSpec`: the action box the policy
acts in, the env params it trained with, readable names for the observation and action components (used
by the introspection plots), the observation size the run's config implies (checked against the
checkpoint) and, for a pure-JAX env, the env object itself (what a jitted rollout steps). A new kind of
run adds one entry to ``BUILDERS``:

- ``"lorenz"`` (train-lorenz): the pure-JAX Lorenz env and its default params;
- ``"foam"`` (train-foam): the run's FoamEnvConfig (config.json's ``"foam"`` section) as the params and
  its box of (alpha_u, alpha_p[, alpha_t]); no env object (episodes are real simpleFoam runs, rolled out
  by :mod:`jaxsimrl.introspect.foam_rollout`), and building it needs no OpenFOAM.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from foam_bridge.config import ACTION_NAMES
from foam_bridge.env import action_spec
from jaxsimrl.agents.ppo.policy import ActionBox
from jaxsimrl.envs.foam_config import foam_config_from_json
from jaxsimrl.envs.lorenz import Lorenz

LORENZ_OBS_NAMES = ("x", "y", "z", "dx/dt", "dy/dt", "dz/dt")
LORENZ_ACTION_NAMES = ("d sigma", "d rho", "d beta")
FOAM_ACTION_NAMES = ("alpha_u", "alpha_p")  # a 3-entry action adds "alpha_t" (foam_spec)
#: The foam observation's first component: (mean inlet |U|^2 + mean cells |U|^2) / state_scale, the
#: paper's state divided by U_ref^2 = 44.2^2 by default (foam_bridge.env).
FOAM_STATE_NAME = "state"


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


def foam_spec(record: dict[str, Any]) -> EnvSpec:
    """train-foam's env: the FoamEnvConfig of config.json's "foam" section (a one-line ValueError if it
    is missing or bad) and its action box."""
    if "foam" not in record:
        raise ValueError("config.json names env 'foam' but has no 'foam' section (the FoamEnvConfig)")
    cfg = foam_config_from_json(record["foam"])
    names = ACTION_NAMES[:cfg.action_size]
    return EnvSpec(ActionBox.of(action_spec(cfg)), cfg, foam_obs_names(cfg), names, cfg.observation_size)


def foam_obs_names(cfg: Any) -> tuple[str, ...]:
    """"state" (unless left out), then per residual feature block (oldest first) "log10 r_<field>", with
    "(t-k)" for the block k step boundaries before the latest (foam_bridge keeps the last
    ``residual_features``), then "progress", "SIMPLEC" and the factors in force, where observed."""
    names = [FOAM_STATE_NAME] if getattr(cfg, "observe_state", True) else []
    blocks = cfg.residual_features
    for block in range(blocks):
        lag = blocks - 1 - block
        names += [f"log10 r_{field}" + (f" (t-{lag})" if lag else "") for field in cfg.observed]
    if cfg.observe_progress:
        names.append("progress")
    if getattr(cfg, "observe_algorithm", False):
        names.append("SIMPLEC")
    if cfg.observe_action:
        names += [f"last {name}" for name in ACTION_NAMES[:cfg.action_size]]
    return tuple(names)


BUILDERS: dict[str, Callable[[dict[str, Any]], EnvSpec]] = {"lorenz": lorenz_spec, "foam": foam_spec}


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
