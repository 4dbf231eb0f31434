"""A train-foam run's policy, loaded for evaluation, and a batched actor for many episodes at once.

:func:`load_foam_run` reads ``RUN_DIR/config.json`` (``{"env": "foam", "seed", "ppo", "foam"}``) and the
last checkpoint through :func:`jaxsimrl.load_policy` (the acting part of the RunnerState: ``params`` and
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
import numpy as np

from foam_bridge.config import FoamEnvConfig
from foam_bridge.env import action_spec
from jaxsimrl.agents.ppo.config import PPOConfig
from jaxsimrl.agents.ppo.policy import Policy, PolicyParams


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
    """The config and last checkpoint of a train-foam run directory (read by jaxsimrl.load_policy); one-line
    ValueError if it is not one."""
    from jaxsimrl.introspect import load_policy
    from jaxsimrl.runs.run_dir import RunDir

    run = RunDir.existing(path)
    record = run.read_config()
    if record.get("env") != "foam" or not isinstance(record.get("foam"), dict):
        raise ValueError(f"{run.path} is not a train-foam run (its config.json has env "
                         f"{record.get('env')!r}; eval-foam needs env 'foam' and a 'foam' section)")
    policy = load_policy(run.path)
    return FoamRun(run.path, policy.config, policy.env_params, policy.params, int(record.get("seed", 0)),
                   policy.checkpoint, policy.update)


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
