"""A train-foam run's env as its policy sees it, rebuilt from config.json (the App's ``env_spec``).

The run's FoamEnvConfig (config.json's ``"foam"`` section) is the params, its box of (alpha_u,
alpha_p[, alpha_t]) the action box; there is no env object (episodes are real simpleFoam runs, rolled out
by :mod:`jaxsimrl.apps.foam.introspect.rollout`), and building it needs no OpenFOAM.
"""

from __future__ import annotations

from typing import Any

from foam_bridge import ACTION_NAMES, action_spec
from jaxsimrl.agents.ppo.policy import ActionBox
from jaxsimrl.apps.foam.config import foam_config_from_json
from jaxsimrl.policy.spec import EnvSpec

#: The foam observation's first component: (mean inlet |U|^2 + mean cells |U|^2) / state_scale, the
#: paper's state divided by U_ref^2 = 44.2^2 by default (foam_bridge._env).
FOAM_STATE_NAME = "state"


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
    ``residual_features``), then "progress", "SIMPLEC", the factors in force and the last step's gain,
    where observed."""
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
    if getattr(cfg, "observe_gain", False):
        names.append("last gain")
    return tuple(names)
