"""Many independent agents in one jitted call: a :class:`PPOTrainer` vmapped over seeds.

PureJaxRL's pattern (``jax.vmap(make_train(config))(keys)``), kept chunked for progress and checkpoints:
the batch's :class:`RunnerState` is the one-agent state with a leading agent axis on every leaf. Inside
the same ``shard_map`` over the env mesh as one agent, each update is ``vmap(trainer._update)``, so an
agent's envs stay its own, still sharded over the devices (axis 1 of the env fields), and the
collectives (gradient ``pmean``, normaliser ``psum``) act per agent. The agents are initialised one by
one and stacked, so agent i starts exactly as ``make_train(config).init(PRNGKey(seeds[i]))``; its
updates agree with that agent's alone up to float rounding (XLA may order a batched reduction
differently; see tests/test_seed_batch.py).

Before the first chunk runs, :meth:`SeedBatch.compile` compiles it and checks its memory (argument,
output and temporary buffers, from XLA's memory analysis) against the device's: a batch that would not
fit is refused with the largest number of agents that would.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
from jax.sharding import NamedSharding
from jax.sharding import PartitionSpec as P

from jaxsimrl.agents.ppo.config import SWEEPABLE
from jaxsimrl.agents.ppo.rollout import RunnerState
from jaxsimrl.agents.ppo.train import PPOTrainer, run_chunk_with


class BatchTooLarge(ValueError):
    """The batch's chunk needs more memory than the device has; the message names the largest that fits."""


def _agent_specs(specs: RunnerState) -> RunnerState:
    """The one-agent PartitionSpecs with an unsharded agent axis in front."""
    return jax.tree.map(lambda spec: P(None, *spec), specs, is_leaf=lambda x: isinstance(x, P))


def seed_keys(seeds: Sequence[int]) -> jax.Array:
    """(N, 2) raw keys: row i is exactly the key a single-seed run of ``seeds[i]`` starts from."""
    return jnp.stack([jax.random.PRNGKey(seed) for seed in seeds])


class SeedBatch:
    """``num_agents`` independent PPO agents of one ``trainer``'s config, trained in one jitted chunk.

    Has the trainer interface of :mod:`jaxsimrl.runs.training` (``run_chunk``, ``num_updates``); its
    metrics have one column per agent: shape (updates, num_agents). ``hparams`` maps fields of
    ``config.SWEEPABLE`` to one value per agent (a sweep); the others are the trainer's config's."""

    def __init__(self, trainer: PPOTrainer, num_agents: int,
                 hparams: dict[str, Sequence[float]] | None = None) -> None:
        if num_agents < 1:
            raise ValueError(f"a seed batch needs at least one agent, got {num_agents}")
        if getattr(trainer.vec, "single_device", False):  # its envs are stepped on the host, one batch
            raise ValueError("a host env batch (a solver's cases on a pool) cannot be vmapped over agents")
        self.hparams = _check_hparams(hparams or {}, num_agents)
        self.trainer, self.num_agents = trainer, num_agents
        self.config, self.num_updates = trainer.config, trainer.num_updates
        specs = _agent_specs(trainer._specs)
        shardings = jax.tree.map(lambda spec: NamedSharding(trainer.mesh, spec), specs,
                                 is_leaf=lambda x: isinstance(x, P))
        self._shardings = shardings
        per_chunk = trainer.config.updates_per_chunk
        swept = {name: jnp.asarray(values, jnp.float32) for name, values in self.hparams.items()}

        def updates(state: RunnerState) -> tuple[RunnerState, dict[str, jax.Array]]:
            return jax.vmap(trainer._update)(state, swept or None)

        def chunk(state: RunnerState) -> tuple[RunnerState, dict[str, jax.Array]]:
            return trainer._run_updates(state, per_chunk, updates)

        self._chunk_jit = jax.jit(jax.shard_map(chunk, mesh=trainer.mesh, in_specs=(specs,),
                                                out_specs=(specs, P()), check_vma=False))
        self._compiled: tuple[str, Any, int | None] | None = None  # (state signature, executable, bytes)

    def init(self, keys: jax.Array) -> RunnerState:
        """Fresh states of every agent from (num_agents, 2) raw keys (see :func:`seed_keys`)."""
        if keys.shape[0] != self.num_agents:
            raise ValueError(f"{keys.shape[0]} keys for a batch of {self.num_agents} agents")
        # One agent at a time (one compiled init), stacked: each agent starts bit-identical to its seed
        # alone, and it sidesteps a deadlock of XLA:CPU (jax 0.10.2) running the vmapped init of an LSTM
        # network of 64 units or more.
        agents = [self.trainer.init(keys[i]) for i in range(self.num_agents)]
        stacked = jax.tree.map(lambda *leaves: jnp.stack(leaves), *agents)
        return jax.device_put(stacked, self._shardings)

    def compile(self, state: RunnerState, limit_bytes: int | None = None) -> int:
        """Compile the chunk for ``state`` and check that it fits in ``limit_bytes`` (default: the
        device's memory, see :func:`device_memory_bytes`); returns the bytes it needs. Raises
        :class:`BatchTooLarge` if it does not fit. The compiled chunk is the one :meth:`run_chunk` runs
        (compiled once per state layout)."""
        signature = str(jax.tree.map(lambda leaf: (leaf.shape, leaf.dtype, leaf.sharding), state))
        if self._compiled is None or self._compiled[0] != signature:  # runs in one process share it
            compiled = self._chunk_jit.lower(state).compile()
            self._compiled = (signature, compiled, compiled_bytes(compiled))
        needed = self._compiled[2]
        limit = device_memory_bytes(self.trainer.devices[0]) if limit_bytes is None else limit_bytes
        if needed is not None and limit is not None and needed > limit:
            # Nearly all of the memory is per agent (states, rollouts, activations): scale linearly.
            largest = self.num_agents * limit // needed
            raise BatchTooLarge(f"{self.num_agents} agents need {needed / 2**30:.2f} GiB but "
                                f"{limit / 2**30:.2f} GiB are available; the largest batch that would fit "
                                f"is about {largest} agents")
        return needed or 0

    def run_chunk(self, state: RunnerState) -> tuple[RunnerState, dict[str, jax.Array]]:
        """Up to ``updates_per_chunk`` updates of every agent (see :meth:`PPOTrainer.run_chunk`)."""
        chunk = self._chunk_jit if self._compiled is None else self._compiled[1]
        return run_chunk_with(chunk, state, self.config.updates_per_chunk, self.num_updates)


def _check_hparams(hparams: dict[str, Sequence[float]], num_agents: int) -> dict[str, tuple[float, ...]]:
    """``hparams`` as tuples, each field sweepable and with one value per agent (else a ValueError)."""
    for name, values in hparams.items():
        if name not in SWEEPABLE:
            raise ValueError(f"{name} cannot differ between the agents of a batch (only "
                             f"{', '.join(SWEEPABLE)})")
        if len(values) != num_agents:
            raise ValueError(f"{name} has {len(values)} values for {num_agents} agents")
    return {name: tuple(float(v) for v in values) for name, values in hparams.items()}


def compiled_bytes(compiled: Any) -> int | None:
    """Peak bytes of a compiled call per XLA: arguments + outputs + temporaries, less donated aliases
    (None where the backend gives no analysis)."""
    stats = compiled.memory_analysis()
    if stats is None:
        return None
    return int(stats.argument_size_in_bytes + stats.output_size_in_bytes + stats.temp_size_in_bytes
               - stats.alias_size_in_bytes)


def device_memory_bytes(device: jax.Device, meminfo: Path = Path("/proc/meminfo")) -> int | None:
    """The memory a batch may use on ``device``: its allocator's limit on an accelerator, the available
    RAM on CPU (None where neither is known)."""
    if device.platform != "cpu":
        stats = device.memory_stats() or {}
        return stats.get("bytes_limit")
    try:
        match = re.search(r"^MemAvailable:\s+(\d+) kB", meminfo.read_text(), re.MULTILINE)
    except OSError:
        return None
    return int(match.group(1)) * 1024 if match else None
