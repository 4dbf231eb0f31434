"""A run directory's trained policy: :func:`load_policy` (one agent) and :func:`load_agents` (all).

The env spec is rebuilt from the run's config.json (:mod:`jaxsimrl.policy.spec`), the network from its
PPO config, and only the two parts of the checkpoint that acting needs (network parameters and
observation statistics) are read, as saved, onto one device. A run written by an older version
therefore loads as long as those two still fit the network its config describes; otherwise the error
is one line saying what does not fit. A run with an up-to-date ``acting.npz`` (jaxsimrl.policy.arrays:
the shipped controller) is read from it, without orbax. ``kind`` is the class built (a
:class:`TrainedPolicy` or a subclass, e.g. :class:`jaxsimrl.introspect.LoadedPolicy`, which adds rollouts).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple, TypeVar

import jax
import jax.numpy as jnp
import numpy as np

from jaxsimrl.agents.ppo.config import PPOConfig
from jaxsimrl.agents.ppo.normalizer import NormalizerState
from jaxsimrl.agents.ppo.policy import Policy, PolicyParams
from jaxsimrl.policy.arrays import read_acting_arrays
from jaxsimrl.policy.spec import EnvSpec, env_spec
from jaxsimrl.policy.trained import TrainedPolicy
from jaxsimrl.runs.run_dir import RunDir

if TYPE_CHECKING:
    from jaxsimrl.runs.checkpoint import Checkpoints

P = TypeVar("P", bound=TrainedPolicy)


def load_policy(run_dir: str | Path, checkpoint: int | None = None, seed: int = 0, agent: int | None = None,
                *, kind: type[P] = TrainedPolicy) -> P:  # type: ignore[assignment]
    """The policy of ``run_dir``'s last checkpoint (or checkpoint ``checkpoint``, numbered by updates
    done); of a ``--seeds`` run (a batch of agents), that of agent ``agent`` (0-based, required there; see
    :func:`load_agents` for all). Any problem with the run is a one-line ValueError."""
    return _restore(run_dir, checkpoint).agent_policy(agent, seed, kind)


def load_agents(run_dir: str | Path, checkpoint: int | None = None, seed: int = 0,
                *, kind: type[P] = TrainedPolicy) -> list[P]:  # type: ignore[assignment]
    """Every agent's policy of a run, read from one checkpoint restore: one for a one-agent run, one per
    seed of a ``--seeds`` run (in agent order)."""
    saved = _restore(run_dir, checkpoint)
    seeds = saved.record.get("seeds")
    agents = [None] if seeds is None else range(len(seeds))
    return [saved.agent_policy(agent, seed, kind) for agent in agents]


class _Saved(NamedTuple):
    """A run's config and one checkpoint as saved (a batch run's leaves have a leading agent axis)."""

    run: RunDir
    record: dict[str, Any]
    config: PPOConfig
    spec: EnvSpec
    tree: Any
    meta: dict[str, Any]
    step: int

    def agent_policy(self, agent: int | None, seed: int, kind: type[P]) -> P:
        """The policy of agent ``agent`` of a batch run, or of the one agent (``agent=None``)."""
        self._check_agent(agent)
        tree = self.tree if agent is None else jax.tree.map(lambda leaf: leaf[agent], self.tree)
        where = f"checkpoint {self.step} in {self.run.checkpoints}"
        params = _policy_params(tree, self.config, self.spec, where)
        update = int(np.asarray(tree.get("update_step", self.meta.get("update", self.step))))
        env_steps = int(self.meta.get("env_steps", update * self.config.steps_per_update))
        # an agent of a --sweep trained with its own values of the swept fields
        swept = {name: values[agent] for name, values in self.record.get("sweep", {}).items()}
        config = dataclasses.replace(self.config, **swept) if swept else self.config
        return kind(config, self.spec, params, update, env_steps, self.record, self.run.path, seed,
                    checkpoint=self.step, agent=agent)

    def _check_agent(self, agent: int | None) -> None:
        seeds = self.record.get("seeds")
        if seeds is None and agent is not None:
            raise ValueError(f"{self.run.path} holds one agent (a --seed run): give no agent")
        if seeds is not None and (agent is None or not 0 <= agent < len(seeds)):
            shown = ", ".join(map(str, seeds[:4])) + (", ..." if len(seeds) > 4 else "")
            got = "" if agent is None else f" (got {agent})"
            raise ValueError(f"{self.run.path} holds {len(seeds)} agents (seeds {shown}): pick one with "
                             f"agent K in 0..{len(seeds) - 1}{got}")


def _restore(run_dir: str | Path, checkpoint: int | None) -> _Saved:
    run = RunDir.existing(run_dir)
    record = run.read_config()
    config = _config_of(run.config, record)
    spec = env_spec(record)
    exported = read_acting_arrays(run, checkpoint)  # the checkpoint's acting arrays, if exported
    if exported is None:
        step, tree, meta = _restore_checkpoint(run, checkpoint)
    else:
        step, tree, meta = exported
        tree = jax.tree.map(jnp.asarray, tree)  # on the device, as orbax restores them
    return _Saved(run, record, config, spec, tree, meta, step)


def _restore_checkpoint(run: RunDir, checkpoint: int | None) -> tuple[int, Any, dict[str, Any]]:
    """(step, tree, meta) restored by orbax (imported here: a run with acting.npz never needs it)."""
    from jaxsimrl.runs.checkpoint import Checkpoints

    with Checkpoints(run.checkpoints, writable=False) as checkpoints:
        step = _pick_checkpoint(checkpoints, checkpoint)
        tree, meta = checkpoints.restore_as_saved(step)
    return step, tree, meta


def _config_of(path: Path, record: dict[str, Any]) -> PPOConfig:
    try:
        return PPOConfig.from_dict(record["ppo"])
    except (TypeError, ValueError) as err:  # e.g. a key a newer or older version wrote
        raise ValueError(f"{path}: cannot rebuild the PPO config: {err}") from None


def _pick_checkpoint(checkpoints: Checkpoints, wanted: int | None) -> int:
    steps = checkpoints.steps()
    if wanted is None:
        return checkpoints.latest_step()
    if wanted not in steps:
        have = ", ".join(map(str, steps)) or "none"
        raise ValueError(f"no checkpoint {wanted} in {checkpoints.directory} (there are: {have})")
    return wanted


def _policy_params(tree: Any, config: PPOConfig, spec: EnvSpec, where: str) -> PolicyParams:
    """The parameters and normaliser of a restored state, checked against the network of ``config``."""
    if not isinstance(tree, dict) or not {"params", "normalizer"} <= set(tree):
        raise ValueError(f"{where} holds no network parameters and observation statistics "
                         f"(written by an incompatible version)")
    stats = tree["normalizer"]
    normalizer = NormalizerState(count=stats["count"], mean=stats["mean"], m2=stats["m2"])
    obs_dim = int(normalizer.mean.shape[0])
    if spec.obs_dim is not None and obs_dim != spec.obs_dim:
        raise ValueError(f"{where} holds observations of size {obs_dim}, but its config.json's env gives "
                         f"{spec.obs_dim}")
    policy = Policy(config, spec.box)
    carry = policy.initial_carry(1)
    expected = jax.eval_shape(policy.network.init, jax.random.PRNGKey(0), carry, jnp.zeros((1, 1, obs_dim)),
                              jnp.ones((1, 1), bool))
    _check_shapes(tree["params"], expected, where)
    return PolicyParams(params=tree["params"], normalizer=normalizer)


def _check_shapes(stored: Any, expected: Any, where: str) -> None:
    flat_stored, flat_expected = _shapes(stored), _shapes(expected)
    if set(flat_stored) != set(flat_expected):
        odd = sorted(set(flat_stored) ^ set(flat_expected))[:2]
        raise ValueError(f"{where} does not fit the network its config.json describes (parameters "
                         f"{', '.join(odd)} differ)")
    for name, shape in flat_expected.items():
        if tuple(flat_stored[name]) != tuple(shape):
            raise ValueError(f"{where} does not fit the network its config.json describes ({name} has shape "
                             f"{tuple(flat_stored[name])}, the config gives {tuple(shape)})")


def _shapes(tree: Any) -> dict[str, tuple[int, ...]]:
    return {jax.tree_util.keystr(path): tuple(leaf.shape)
            for path, leaf in jax.tree_util.tree_flatten_with_path(tree)[0]}
