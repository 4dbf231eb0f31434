"""train-lorenz as a library call: :func:`train_lorenz` runs a resolved :class:`TrainPlan` into a run
directory.

PPO on the Lorenz chaos-restoration task: one agent (``plan.seeds`` None) or a batch of agents trained in
one jitted call (a list of seeds, a sweep of update scalars), chunk by chunk with the metrics rows, a
checkpoint and summary.json after each (:mod:`jaxsimrl.runs.training`); resumed from the run's last
checkpoint. Input a run cannot start with is a one-line :class:`jaxsimrl.training.common.RunInputError`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from jaxsimrl.runs.progress import TrainingProgress
from jaxsimrl.runs.run_dir import MetricsLog, summarise, summarise_agents
from jaxsimrl.runs.tensorboard import tensorboard_log
from jaxsimrl.training.common import ResumeError, RunInputError, config_record, restore

Sweep = tuple[tuple[str, tuple[float, ...]], ...]  # (field, each agent's value), hashable for the caches


@dataclass
class TrainPlan:
    """What train-lorenz will do, resolved from the flags before anything heavy happens."""

    config: Any  # PPOConfig
    seed: int
    run_path: Path
    resume: bool
    record: dict[str, Any]  # config.json of a resumed run
    seeds: tuple[int, ...] | None = None  # each agent's seed in a batch (--seeds, --sweep); None: one agent
    sweep: Sweep = ()  # the swept fields of a --sweep


@functools.lru_cache(maxsize=2)
def lorenz_trainer(config: Any) -> Any:
    """The PPO trainer of ``config`` on the Lorenz env. Trainers are stateless, so repeated runs in one
    process (notebooks, tests) share one and compile its chunk once."""
    from jaxsimrl.agents.ppo import make_train
    from jaxsimrl.envs.lorenz import Lorenz

    try:
        return make_train(config, Lorenz())
    except ValueError as err:
        raise RunInputError(f"invalid config: {err}") from None


@functools.lru_cache(maxsize=2)
def lorenz_batch(config: Any, num_agents: int, sweep: Sweep = ()) -> Any:
    """A batch of ``num_agents`` agents of ``config`` on the Lorenz env, with each agent's values of the
    ``sweep``ed fields (cached as :func:`lorenz_trainer`)."""
    from jaxsimrl.agents.ppo.batch import SeedBatch

    return SeedBatch(lorenz_trainer(config), num_agents, dict(sweep))


def plan_trainer(plan: TrainPlan) -> Any:
    """The plan's trainer: one agent's, or its batch's (built before the run directory exists)."""
    if plan.seeds is None:
        return lorenz_trainer(plan.config)
    return lorenz_batch(plan.config, len(plan.seeds), plan.sweep)


def train_lorenz(plan: TrainPlan, run: Any, trainer: Any, *, tensorboard: bool = False,
                 on_chunk: Callable[[int], None] | None = None) -> dict[str, Any]:
    """Train ``plan`` with ``trainer`` (:func:`plan_trainer`) into ``run`` (a RunDir, created or resumed);
    returns the final summary. ``on_chunk(updates_done)`` is told of each chunk on disk (a test hook).
    Raises RunInputError (a batch too large for memory, a checkpoint that does not fit) before anything
    is written, KeyboardInterrupt after a saved chunk."""
    from jaxsimrl.runs.checkpoint import Checkpoints
    from jaxsimrl.runs.training import Session, train

    with Checkpoints(run.checkpoints) as checkpoints, tensorboard_log(run.path, tensorboard) as tb:
        state, done, log = _starting_point(plan, trainer, run, checkpoints)
        record = _config_record(plan)
        run.write_config(record)
        session = Session(run, trainer, log, checkpoints, meta={"config": record},
                          summary_extra=_summary_extra(plan, run), tensorboard=tb,
                          summarise_rows=summarise if plan.seeds is None else summarise_agents)
        total = trainer.num_updates * plan.config.steps_per_update
        with TrainingProgress(total, log.env_steps) as progress:
            train(session, state, done, progress, on_chunk)
        return session.write_summary()


def _summary_extra(plan: TrainPlan, run: Any) -> dict[str, Any]:
    """What summary.json repeats from the plan: where, which seed(s), which network."""
    return {"run_dir": str(run.path), **_agents_record(plan), "network": plan.config.network}


def _agents_record(plan: TrainPlan) -> dict[str, Any]:
    """Who the agents are, for config.json and summary.json: ``seed``; or each agent's ``seeds`` and, for
    a sweep, ``sweep`` (each agent's value of every swept field)."""
    if plan.seeds is None:
        return {"seed": plan.seed}
    sweep = {"sweep": {name: list(values) for name, values in plan.sweep}} if plan.sweep else {}
    return {"seeds": list(plan.seeds), **sweep}


def _starting_point(plan: TrainPlan, trainer: Any, run: Any, checkpoints: Any) -> tuple[Any, int, Any]:
    """(state, updates done, metrics log): fresh, or restored from the run's last checkpoint. A batch's
    chunk is compiled here, so that one too large for memory is refused before anything is written."""
    import jax

    from jaxsimrl.agents.ppo.batch import seed_keys

    key = jax.random.PRNGKey(plan.seed) if plan.seeds is None else seed_keys(plan.seeds)
    if not plan.resume:
        state = trainer.init(key)
        _check_memory(trainer, state)
        return state, 0, MetricsLog(run)
    try:
        done = checkpoints.latest_step()  # a checkpoint is named by the number of updates done
    except ValueError as err:
        raise ResumeError(f"cannot resume: {err}") from None
    state, _ = restore(checkpoints, trainer, key, done)
    _check_memory(trainer, state)
    log = MetricsLog.load(run, done)  # drops rows of a chunk whose checkpoint never landed
    log.write()
    return state, done, log


def _check_memory(trainer: Any, state: Any) -> None:
    """Compile a batch's chunk and refuse it in one line if it would not fit (one agent: no check)."""
    from jaxsimrl.agents.ppo.batch import BatchTooLarge, SeedBatch

    if isinstance(trainer, SeedBatch):
        try:
            trainer.compile(state)
        except BatchTooLarge as err:
            raise RunInputError(str(err)) from None


def _config_record(plan: TrainPlan) -> dict[str, Any]:
    """config.json: the resolved config plus what is needed to reproduce or audit the run."""
    import jax

    return config_record({"env": "lorenz", **_agents_record(plan)}, plan.record if plan.resume else None,
                         {"ppo": plan.config.to_dict()},
                         last={"devices": [str(device) for device in jax.devices()]})
