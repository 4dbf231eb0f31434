"""A trained policy acting for a batch of episodes that each run at their own pace (eval-foam, foam rollouts).

Every row gets its own PRNG key ``fold_in(fold_in(PRNGKey(seed), uid), step)``, so an episode's sampled
actions depend only on (seed, its uid, its step), never on which other episodes shared the batch. The
batch is padded to a fixed size so the jitted function compiles once. Each row acts through the policy's
one inference function (:meth:`jaxsimrl.agents.ppo.policy.Policy.act`).
"""

from __future__ import annotations

from typing import Any

import jax
import numpy as np

from jaxsimrl.agents.ppo.policy import PolicyParams
from jaxsimrl.policy.trained import TrainedPolicy


class BatchActor:
    """Acts for up to ``batch_size`` episodes per call (see the module docstring)."""

    def __init__(self, policy: TrainedPolicy, batch_size: int) -> None:
        self.policy = policy.policy  # the network and action box the run trained with
        self.params = policy.params
        self.batch_size = batch_size
        self.obs_size = policy.obs_dim
        self._act = {flag: jax.jit(self._rows(flag)) for flag in (True, False)}

    def initial_carry(self) -> Any:
        """One episode's zero recurrent state (numpy, no batch axis)."""
        return jax.tree.map(lambda c: np.asarray(c[0]), self.policy.initial_carry(1))

    def act(self, obs: np.ndarray, carries: list[Any], uids: list[int], steps: list[int],
            deterministic: bool, seed: int = 0) -> tuple[np.ndarray, list[Any]]:
        """Actions (n, A) for n <= batch_size episodes and their next carries; ``steps[i] == 0`` marks an
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
