"""A train-foam run's policy, loaded for evaluation, and a batched actor for many episodes at once.

:func:`load_foam_run` reads ``RUN_DIR/config.json`` (``{"env": "foam", "seed", "ppo", "foam"}``) and the
last checkpoint (restored without a template: the acting part of the RunnerState, ``params`` and
``normalizer``). :class:`PolicyActor` acts for a batch of episodes that each run at their own pace:
every row gets its own PRNG key ``fold_in(fold_in(PRNGKey(seed), uid), step)``, so an episode's
sampled actions depend only on (seed, its uid, its step), never on which other episodes shared the
batch. The batch is padded to a fixed size so the jitted function compiles once.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from foam_bridge.config import FoamEnvConfig
from foam_bridge.env import action_spec
from jaxsimrl.agents.ppo.config import PPOConfig
from jaxsimrl.agents.ppo.normalizer import NormalizerState
from jaxsimrl.agents.ppo.policy import Policy, PolicyParams
from jaxsimrl.envs.foam_config import foam_config_from_json


@dataclass(frozen=True)
class FoamRun:
    """What evaluation needs of a train-foam run."""

    path: Path
    config: PPOConfig
    foam: FoamEnvConfig
    params: PolicyParams
    seed: int
    checkpoint_step: int
    update: int


class FoamActionBox:
    """The env-like object Policy needs: the action box of (alpha_u, alpha_p) of a FoamEnvConfig (the
    config given to ``action_space``, else the one it was built with). No OpenFOAM needed."""

    def __init__(self, cfg: FoamEnvConfig) -> None:
        self.cfg = cfg

    def default_params(self) -> FoamEnvConfig:
        return self.cfg

    def action_space(self, params: FoamEnvConfig | None = None) -> Any:
        return action_spec(self.cfg if params is None else params)


def load_foam_run(path: str | Path) -> FoamRun:
    """The config and last checkpoint of a train-foam run directory; one-line ValueError if it is not one."""
    from jaxsimrl.runs.checkpoint import Checkpoints
    from jaxsimrl.runs.run_dir import RunDir

    run = RunDir.existing(path)
    record = run.read_config()
    if record.get("env") != "foam" or not isinstance(record.get("foam"), dict):
        raise ValueError(f"{run.path} is not a train-foam run (its config.json has env "
                         f"{record.get('env')!r}; eval-foam needs env 'foam' and a 'foam' section)")
    config = PPOConfig.from_dict(record["ppo"])
    foam = foam_config_from_json(record["foam"])
    with Checkpoints(run.checkpoints, writable=False) as checkpoints:
        step = checkpoints.latest_step()
        state, _ = checkpoints.restore(None, step)
    params = _policy_params(state, foam, f"checkpoint {step} in {run.checkpoints}")
    update = int(np.asarray(state.get("update_step", step)))
    return FoamRun(run.path, config, foam, params, int(record.get("seed", 0)), step, update)


def _policy_params(state: Any, foam: FoamEnvConfig, where: str) -> PolicyParams:
    """params and normalizer of a restored state (nested dicts); checks the observation size."""
    if not isinstance(state, dict) or "params" not in state or "normalizer" not in state:
        raise ValueError(f"{where} has no params/normalizer: not a PPO training state")
    stats = state["normalizer"]
    try:
        normalizer = NormalizerState(jnp.asarray(stats["count"]), jnp.asarray(stats["mean"]),
                                     jnp.asarray(stats["m2"]))
    except (KeyError, TypeError):
        raise ValueError(f"{where}: the normalizer has no count/mean/m2") from None
    if normalizer.mean.shape != (foam.observation_size,):
        raise ValueError(f"{where}: observations of size {normalizer.mean.shape[-1]}, but the run's foam "
                         f"config gives {foam.observation_size}")
    return PolicyParams(jax.tree.map(jnp.asarray, state["params"]), normalizer)


class PolicyActor:
    """Acts for up to ``batch_size`` episodes per call (see the module docstring)."""

    def __init__(self, run: FoamRun, batch_size: int) -> None:
        self.policy = Policy(run.config, FoamActionBox(run.foam))
        self.params = run.params
        self.batch_size = batch_size
        self.obs_size = run.foam.observation_size
        self._act = {flag: jax.jit(self._rows(flag)) for flag in (True, False)}

    def initial_carry(self) -> Any:
        """One episode's zero recurrent state (numpy, no batch axis)."""
        return jax.tree.map(lambda c: np.asarray(c[0]), self.policy.initial_carry(1))

    def act(self, obs: np.ndarray, carries: list[Any], uids: list[int], steps: list[int],
            deterministic: bool, seed: int = 0) -> tuple[np.ndarray, list[Any]]:
        """Actions (n, 2) for n <= batch_size episodes and their next carries; ``steps[i] == 0`` marks an
        episode's first observation (its carry is reset)."""
        n = len(uids)
        if not 0 < n <= self.batch_size:
            raise ValueError(f"act: expected 1..{self.batch_size} episodes, got {n}")
        pad = self.batch_size - n
        obs = np.concatenate([np.asarray(obs, np.float32).reshape(n, self.obs_size),
                              np.zeros((pad, self.obs_size), np.float32)])
        carry = jax.tree.map(lambda *rows: np.stack(rows), *carries, *[self.initial_carry()] * pad)
        index = np.asarray(list(uids) + [0] * pad, np.int32)
        step = np.asarray(list(steps) + [0] * pad, np.int32)
        key = jax.random.PRNGKey(seed)  # an argument, not a constant: one compilation serves every seed
        actions, carry = self._act[deterministic](self.params, key, obs, carry, index, step)
        actions = np.asarray(actions, np.float64)[:n]
        carry = jax.device_get(carry)
        return actions, [jax.tree.map(lambda c, i=i: c[i], carry) for i in range(n)]

    def _rows(self, deterministic: bool) -> Any:
        policy = self.policy

        def one(params: PolicyParams, base: jax.Array, obs: jax.Array, carry: Any, uid: jax.Array,
                step: jax.Array) -> Any:
            key = jax.random.fold_in(jax.random.fold_in(base, uid), step)
            batch_carry = jax.tree.map(lambda c: c[None], carry)
            action, carry = policy.act(params, obs[None], batch_carry, (step == 0)[None], key, deterministic)
            return action[0], jax.tree.map(lambda c: c[0], carry)

        return jax.vmap(one, in_axes=(None, None, 0, 0, 0, 0))
