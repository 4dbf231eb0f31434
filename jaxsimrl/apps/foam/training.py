"""train-foam as a library call: :func:`train_foam` runs a resolved :class:`FoamPlan` into a run directory.

The same PPO as train-lorenz (jaxsimrl.agents.ppo) on a :class:`jaxsimrl.envs.host.HostVecEnv` over a
``foam_bridge._batched.BatchedFoamEnv`` of ``num_envs`` cases on ``pool`` workers. One update = one
jitted chunk; after it the episodes that ended in it come back from the host env as data
(``HostVecEnv.take_episodes``) and join episodes.csv with that update's number; then the metrics rows,
episodes.csv, a checkpoint and summary.json are written (in that order, Ctrl-C held back). With
PPOConfig.async_envs the batch is asynchronous instead (``foam_bridge._async_batch.AsyncFoamEnv`` behind
:class:`jaxsimrl.envs.host_async.AsyncHostVecEnv`): num_envs of its async_envs cases per learner step,
whichever are ready first.

Resuming: every checkpoint also records the episodes in flight (each env's episode seed, actions so far,
K, observation and seed stream; an asynchronous batch also where each env stands: with the learner, a
step or reset in flight, or a result waiting, AsyncFoamEnv.snapshot): the solvers did not survive the
process, so a resume replays them (the solver is deterministic), checks K, return and observation
against the record, and carries on mid-episode exactly as the run would have (an asynchronous batch:
but for the order in which its envs become ready); where that fails (an older checkpoint, a changed
machine) every env starts a new episode instead, and says so. A run killed before its first checkpoint
starts over from its config.json. The run stops after the update in which the episode target is reached
(PPOConfig.total_steps is only a safety bound), or, with a one-line HostEnvError, when every episode so
far has failed the same way.
"""

from __future__ import annotations

import math
import shutil
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from foam_bridge import AsyncFoamEnv, TimedSteps
from jaxsimrl.apps.foam.episodes import EPISODES_FILE, EpisodeLog
from jaxsimrl.runs.progress import EpisodeProgress
from jaxsimrl.runs.run_dir import MetricsLog
from jaxsimrl.runs.tensorboard import TENSORBOARD_DIR, tensorboard_log
from jaxsimrl.training.common import ResumeError, config_record, restore

__all__ = ["IN_FLIGHT", "FoamPlan", "ResumeError", "foam_summary", "train_foam"]

#: Key of the episodes in flight (BatchedFoamEnv.snapshot) in each checkpoint's record.
IN_FLIGHT = "in_flight"


@dataclass
class FoamPlan:
    """A train-foam run, resolved: configs, length, workers, where it lives and what it starts from."""

    ppo: Any  # PPOConfig
    foam: Any  # FoamEnvConfig
    episodes: int
    seed: int
    pool: int
    backend: str
    ray_address: str | None
    run_path: Path
    resume: bool
    record: dict[str, Any] = field(default_factory=dict)
    init_from: Any = None  # jaxsimrl.introspect.LoadedPolicy whose network the run starts from
    #: What each worker of the batch builds instead of a FoamCaseEnv (tests: foam_bridge._standin).
    make_env: Any = None
    #: A family of cases (name -> FoamEnvConfig, jaxsimrl.apps.foam.cli.train_family): each env draws one per
    # episode.
    family: dict[str, Any] = field(default_factory=dict)


def _say(text: str) -> None:
    sys.stderr.write(f"jaxsimrl train-foam: {text}\n")


def train_foam(plan: FoamPlan, run: Any, *, tensorboard: bool = False,
               on_chunk: Callable[[int], None] | None = None,
               on_interrupt: Callable[[int, int], None] | None = None) -> dict[str, Any]:
    """Train ``plan`` into ``run`` (a RunDir, created or resumed); returns the final summary.

    ``on_chunk(updates_done)`` is told of each update once it is on disk (a test hook);
    ``on_interrupt(count, signum)`` of each Ctrl-C or SIGTERM during an update, at once (the live
    progress bar is stopped first): the solvers run until the update ends unless the hook ends the
    process, as train-foam's does (its workers then kill their solvers: foam_bridge._backends.local).
    Raises foam_bridge's CaseError / ClusterError / OpenFOAMNotFoundError for a case or setup that cannot
    run, ResumeError for a checkpoint that does not fit, HostEnvError for a broken host side,
    KeyboardInterrupt (Terminated for SIGTERM) after a saved update.
    """
    import jax

    from jaxsimrl.agents.ppo import make_train
    from jaxsimrl.runs.checkpoint import Checkpoints
    from jaxsimrl.runs.training import Session, train

    steps = run.checkpoint_steps() if plan.resume else []
    done = steps[-1] if steps else 0
    # config.json first: from here on the directory is a run that --resume accepts (it starts over
    # while there is no checkpoint)
    record = _config_record(plan)
    run.write_config(record)
    episodes = EpisodeLog.load(run.path / EPISODES_FILE, done)  # rows past the checkpoint are dropped
    if plan.resume and not done:
        _start_over(run, episodes)
    vec = _host_env(plan)
    try:
        trainer = make_train(plan.ppo, vec=vec, devices=jax.devices()[:1])
        with Checkpoints(run.checkpoints) as checkpoints, tensorboard_log(run.path, tensorboard) as tb:
            key = jax.random.PRNGKey(plan.seed)
            if done:
                state = _restored(trainer, checkpoints, key, done, vec)
                log = MetricsLog.load(run, done)
                log.write()
            else:
                state, log = _initial_state(trainer, key, plan.init_from), MetricsLog(run)
            vec.raise_if_failed()
            busy_share = _async_busy_share(vec, plan)
            session = Session(run, _HostTrainer(trainer, vec, episodes, done + 1), log, checkpoints,
                              meta={"config": record}, summary_extra={"run_dir": str(run.path)},
                              before_checkpoint=lambda _: episodes.flush(),
                              # workers_lost: workers lost for good (a Ray node died), one line each
                              summary_hook=lambda s: {**foam_summary(s, episodes, plan),
                                                      **({} if busy_share is None
                                                         else {"pool_utilisation": busy_share()}),
                                                      "workers_lost": list(vec.batch.backend.lost)},
                              tensorboard=tb,
                              checkpoint_meta=lambda: _in_flight(vec))
            with EpisodeProgress(plan.episodes, episodes, plan.pool, log, workers=vec.batch.backend.workers,
                              utilisation=busy_share) as progress:
                vec.on_episode = lambda env_id, info: progress.episode_ended()  # the bar counts them live
                resumed_with = len(episodes.rows)
                train(session, state, done, progress, on_chunk,
                      until=lambda: _target_reached(episodes, plan, resumed_with),
                      on_interrupt=_stopping_progress(progress, on_interrupt))
            return session.write_summary()
    finally:
        vec.batch.close()


def _host_env(plan: FoamPlan) -> Any:
    """The plan's env batch as a VecEnv: lock-step (BatchedFoamEnv), or asynchronous (AsyncFoamEnv of
    async_envs cases, num_envs per learner step) with each worker step timed (foam_bridge._timing.TimedSteps)
    for its pool utilisation. The batch is re-seeded from the trainer's key at every reset; this seed only
    names its streams."""
    if plan.ppo.async_envs is None:
        from jaxsimrl.apps.foam.vec_env import foam_vec_env

        return foam_vec_env(plan.foam, plan.ppo.num_envs, plan.pool, seed=plan.seed, backend=plan.backend,
                            ray_address=plan.ray_address, make_env=plan.make_env)
    from jaxsimrl.envs.host_async import AsyncHostVecEnv

    batch = AsyncFoamEnv(plan.foam, plan.ppo.async_envs, plan.ppo.num_envs, backend=plan.backend,
                         pool=plan.pool, ray_address=plan.ray_address, seed=plan.seed,
                         make_env=TimedSteps(plan.make_env))
    return AsyncHostVecEnv(batch)


def _in_flight(vec: Any) -> dict[str, Any]:
    """A checkpoint's record of the episodes in flight (BatchedFoamEnv.snapshot, AsyncFoamEnv.snapshot),
    for their replay on resume."""
    return {IN_FLIGHT: vec.batch.snapshot()}


def _async_busy_share(vec: Any, plan: FoamPlan) -> Callable[[], float] | None:
    """An asynchronous batch's pool utilisation (summary.json and the progress line): the workers' step
    seconds over this session's pool time; None for lock-step, whose episodes give it. (Episodes'
    ``wall_time_s - solver_idle_s`` would also count the time a step waits in a worker's queue behind
    another env's: at 2 workers x 2 envs it read 120 %.)"""
    if not getattr(vec, "async_envs", None):
        return None
    started = time.monotonic()
    return lambda: vec.busy_s / (plan.pool * max(time.monotonic() - started, 1e-9))


def _stopping_progress(progress: Any, on_interrupt: Callable[[int, int], None] | None
                       ) -> Callable[[int, int], None] | None:
    """``on_interrupt`` with the live bar stopped first (the hook may end the process: the terminal is
    given back before)."""
    if on_interrupt is None:
        return None

    def react(count: int, signum: int) -> None:
        progress.stop()
        on_interrupt(count, signum)

    return react


def _start_over(run: Any, episodes: Any) -> None:
    """A resumed run without a checkpoint (killed before its first one was saved) starts over from its
    config.json: the rows it wrote for updates that no checkpoint kept are truncated, so none is
    written twice."""
    _say(f"{run.path} has no checkpoint (it stopped before its first update was saved): starting it over "
         f"from its config.json")
    MetricsLog(run).write()
    episodes.flush()
    shutil.rmtree(run.path / TENSORBOARD_DIR, ignore_errors=True)


def _target_reached(episodes: Any, plan: FoamPlan, resumed_with: int) -> bool:
    """True at the episode target. Checked after each update is saved: a run whose episodes all failed
    the same way (EpisodeLog.systematic_failure) stops there with that cause, resumable once it is fixed
    (the rule waits for an update of this session: ``resumed_with`` rows were there at its start)."""
    from jaxsimrl.envs.host import HostEnvError

    envs = plan.ppo.async_envs or plan.ppo.num_envs
    cause = episodes.systematic_failure(envs) if len(episodes.rows) > resumed_with else None
    if cause is not None:
        raise HostEnvError(f"all {len(episodes.rows)} episodes so far failed the same way, {cause}; fix the "
                           f"case or settings, then resume")
    return len(episodes.rows) >= plan.episodes


def _initial_state(trainer: Any, key: Any, start: Any) -> Any:
    """A fresh state; with ``--init-from``, its network and normaliser are the starting policy's."""
    import jax

    state = trainer.init(key)
    if start is None:
        return state
    placed = jax.tree.map(lambda new, old: jax.device_put(jax.numpy.asarray(old, new.dtype), new.sharding),
                          (state.params, state.normalizer), (start.params.params, start.params.normalizer))
    return state.replace(params=placed[0], normalizer=placed[1])


def _restored(trainer: Any, checkpoints: Any, key: Any, done: int, vec: Any) -> Any:
    """The state of checkpoint ``done`` with its episodes in flight replayed, else with new episodes.
    A checkpoint that does not fit is a ResumeError "cannot resume: ..."."""
    import jax

    state, meta = restore(checkpoints, trainer, key, done)
    why = _replay_in_flight(vec, meta.get(IN_FLIGHT), state)
    if not why:
        _say(f"resumed at update {done} with its {getattr(vec, 'async_envs', None) or vec.num_envs} "
             f"episodes in flight replayed")
        return state
    _say(f"resumed at update {done}; its episodes in flight were not replayed ({why}): every env starts a "
         f"new episode")
    return trainer.restart_episodes(state, jax.random.fold_in(key, done))


def _replay_in_flight(vec: Any, snapshot: Any, state: Any) -> str:
    """Replay a checkpoint's episodes in flight into the new batch; "" if it matches, else why not."""
    if not snapshot:
        return "the checkpoint has no record of them"
    return _learner_mismatch(vec, snapshot, state) or vec.batch.replay(snapshot)


def _learner_mismatch(vec: Any, snapshot: Any, state: Any) -> str:
    """Why the record does not fit the learner's side of the checkpoint ("" if it does): the observations
    of its rows (lock-step: every env's; asynchronous: those of the envs the last recv returned, in the
    order of env_state.ids) and, asynchronous, which envs have a step in flight (its pending transitions)."""
    import numpy as np

    def differs(entries: list) -> str:
        saved = np.asarray(state.obs, np.float32).tolist()
        same = [np.float32(entry.get("obs", [])).tolist() for entry in entries] == saved
        return "" if same else "the record does not match the checkpoint's observations"

    if not getattr(vec, "async_envs", None):
        return differs(snapshot)
    envs = snapshot.get("envs") if isinstance(snapshot, dict) else None
    ids = np.asarray(state.env_state.ids).tolist()
    if not isinstance(envs, list) or len(envs) != vec.async_envs \
            or sorted(ids) != sorted(snapshot.get("with_learner", [])):
        return "the record does not hold the envs the learner holds"
    if mismatch := differs([envs[i] for i in ids]):
        return mismatch
    pending = np.asarray(state.env_state.pending.valid).tolist()
    sent = ["step" in entry or "reset" in entry for entry in envs]  # results the learner still awaits
    if any(pending[i] for i in ids) or any(s and not p for s, p in zip(sent, pending, strict=True)):
        return "the record does not match the checkpoint's steps in flight"
    return ""


class _HostTrainer:
    """The trainer as the training loop sees it: after each chunk (one update) the episodes that ended
    in it join the log with the update's number; a chunk whose host side failed raises, unsaved, and
    its episodes are dropped with it."""

    def __init__(self, trainer: Any, vec: Any, episodes: Any, update: int) -> None:
        self.trainer, self.vec, self.episodes, self.update = trainer, vec, episodes, update
        self.num_updates = trainer.num_updates

    def run_chunk(self, state: Any) -> tuple[Any, dict[str, Any]]:
        import jax

        state, metrics = self.trainer.run_chunk(state)
        metrics = jax.device_get(metrics)
        ended = self.vec.take_episodes()
        self.vec.raise_if_failed()
        for env_id, info in ended:
            self.episodes.add(env_id, self.update, info)
        self.update += 1
        return state, metrics


def foam_summary(summary: dict[str, Any], episodes: Any, plan: FoamPlan) -> dict[str, Any]:
    """summary.json entries of a foam run (from episodes.csv and the metrics rows' training time)."""
    wall = float(summary.get("wall_time_s", 0.0))
    count = len(episodes.rows)
    # num_updates: none is planned, the episode target sets the length (trainer.num_updates is only a
    # safety bound, see total_steps_for)
    return {"episodes": count, "episodes_target": plan.episodes, "complete": count >= plan.episodes,
            "num_updates": None,
            "episodes_per_hour": count / wall * 3600 if wall > 0 else math.nan,
            "final_mean_iterations": episodes.moving_iterations(),
            # None where a row lacks the cost (episodes of a run written before it was recorded)
            "final_mean_linear_iterations": _finite_or_none(episodes.moving_mean("linear_iterations")),
            "final_mean_solver_time_s": _finite_or_none(episodes.moving_mean("solver_time_s")),
            "failures": episodes.failures(),
            "outcomes": episodes.outcomes(), "pool": plan.pool,
            "pool_utilisation": episodes.busy_s() / (plan.pool * wall) if wall > 0 else math.nan}


def _finite_or_none(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _config_record(plan: FoamPlan) -> dict[str, Any]:
    """The run's config.json: the plan's configs and setup (a resumed run's record, with this resume)."""
    start = {} if plan.init_from is None else {
        "init_from": {"run_dir": str(plan.init_from.run_dir), "update": plan.init_from.update}}
    return config_record({"env": "foam", "seed": plan.seed}, plan.record if plan.resume else None,
                         {**start, "ppo": plan.ppo.to_dict(), "foam": plan.foam.to_json(),
                          "episodes_target": plan.episodes, "pool": plan.pool, "backend": plan.backend,
                          **({"family": {n: c.to_json() for n, c in plan.family.items()}} if plan.family
                             else {})})
