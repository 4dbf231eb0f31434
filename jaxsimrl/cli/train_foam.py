"""``jaxsimrl train-foam``: PPO on real simpleFoam cases, stepped from the jitted trainer via io_callback.

The same PPO as train-lorenz (jaxsimrl.agents.ppo) on a :class:`jaxsimrl.envs.host.HostVecEnv` over a
``foam_bridge.batched.BatchedFoamEnv`` of ``--num-envs`` cases on ``--pool`` workers. Defaults are the
paper's (Pawar & Maulik, "Solver convergence acceleration"): a 2 x 64 tanh MLP, lr 2.5e-4, gamma 1, inlet
velocity uniform in [35, 65] m/s, actions (alpha_u, alpha_p) in [0.2, 0.95]^2 every 100 iterations, the
training criterion, 2000 episodes, the built-in backward-facing step (SIMPLEC, k/omega relaxed at 0.8).

One update = ``steps_per_update`` env steps (see :func:`jaxsimrl.cli.foam_plan.foam_ppo_defaults` for
the sizes and why); after every update: metrics rows, episodes.csv, a checkpoint, summary.json (in that
order, Ctrl-C held back).
``--resume RUN_DIR`` continues from the last checkpoint. Every checkpoint also records the episodes in
flight (each env's episode seed, actions so far, K, observation and seed stream): the solvers did not
survive the process, so resume replays them (the solver is deterministic), checks K, return and
observation against the record, and carries on mid-episode exactly as the run would have; where that
fails (an older checkpoint, a changed machine) every env starts a new episode instead, and says so.
A run killed before its first checkpoint resumes by starting over from its config.json. The run's
length is ``--episodes``: it stops after the update in which the target is reached (PPOConfig.total_steps
is only a safety bound derived from it, see :func:`jaxsimrl.cli.foam_plan.total_steps_for`).
``--init-from RUN_DIR`` starts a new run from another run's trained network and observation
statistics (e.g. a coarse-mesh policy fine-tuned on the full mesh), with a fresh optimiser and new
episodes.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
import time
from collections.abc import Callable
from typing import Any

from jaxsimrl.cli.errors import UsageError, positive_float, positive_int, seed_type
from jaxsimrl.cli.foam_plan import KNOBS, OBSERVE_SWITCHES, FoamPlan, fresh_plan, resume_plan

INTERRUPTED = 130
#: Key of the episodes in flight (BatchedFoamEnv.snapshot) in each checkpoint's record.
IN_FLIGHT = "in_flight"


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add train-foam to the ``jaxsimrl`` dispatcher."""
    from foam_bridge.config import FOLLOW_ALPHA_U, K_OMEGA_ACTION, MESH_SCALE_USABLE_MIN, REWARDS
    from jaxsimrl.cli.foam import add_confirm_argument, k_omega_setting

    p = subparsers.add_parser(
        "train-foam", help="train PPO to set simpleFoam's relaxation factors (real OpenFOAM cases)",
        description="Train a PPO agent that sets (alpha_u, alpha_p) every 100 SIMPLE iterations of real "
                    "simpleFoam runs of the backward-facing step (Pawar & Maulik, sec. 3.2), with the "
                    "paper's defaults. The cases run on a pool of worker processes; the trainer steps them "
                    "through one io_callback per step.")
    p.add_argument("--pool", type=positive_int, default=None, help="worker processes (the paper: 4, 8, 16; "
                   "default: min(num_envs, CPUs)); may change on --resume")
    p.add_argument("--num-envs", type=positive_int, help="parallel cases (default: = --pool)")
    p.add_argument("--episodes", type=positive_int, help="episodes to train for (default 2000, the paper); "
                   "training stops after the update in which the target is reached, so the episodes that "
                   "also end in that update are kept too; with --resume it may be raised")
    p.add_argument("--mesh-scale", type=positive_float, help=f"mesh resolution factor (1.0 = 20,540 cells, "
                   f"default); >= {MESH_SCALE_USABLE_MIN:g} (coarser meshes are a different control problem)")
    p.add_argument("--step-height", type=positive_float, nargs="+", metavar="M",
                   help="step height in m (default 0.0127 = h), or LOW HIGH: a family of geometries, the "
                   "height drawn per episode (e.g. 0.0127 0.0254 = h to 2h); built-in case only")
    p.add_argument("--relax-k-omega", type=k_omega_setting, metavar="F",
                   help=f"relaxation of k and omega: a factor in (0, 1], {FOLLOW_ALPHA_U!r} (follow alpha_u) "
                   f"or {K_OMEGA_ACTION!r}: a third action alpha_t, in [0.2, 0.95] unless "
                   f"--config sets the box "
                   f"(default: 0.8, the paper's code's; a --case keeps its own)")
    p.add_argument("--max-iterations", type=positive_int, help="iteration cap per episode (default 4000)")
    p.add_argument("--residual-features", type=positive_int, metavar="N", help="observe the log10 initial "
                   "residuals of the criterion's fields at the last N step boundaries (default 0)")
    for name, text in OBSERVE_SWITCHES:
        p.add_argument("--" + name.replace("_", "-"), action="store_true", default=None, help=text)
    p.add_argument("--reward", choices=REWARDS, help="the cost an episode minimises: SIMPLE iterations "
                   "(default, the paper's), the linear solvers' inner iterations, or the solver's CPU "
                   "seconds (not bit-reproducible)")
    add_confirm_argument(p)
    p.add_argument("--case", metavar="CASE_DIR", help="a simpleFoam case of your own instead of the "
                   "built-in backward-facing step")
    p.add_argument("--backend", choices=("local", "ray"), help="worker pool: local processes (default) or "
                   "Ray actors")
    p.add_argument("--ray-address", help="address of a running Ray cluster (with --backend ray)")
    for name, kind, text in KNOBS:
        p.add_argument("--" + name.replace("_", "-"), dest=name, type=kind, metavar="X", help=text)
    p.add_argument("--config", metavar="FILE.json", help='a JSON object {"ppo": {PPOConfig fields}, "foam": '
                   '{FoamEnvConfig fields}} applied after the defaults and before the flags')
    p.add_argument("--seed", type=seed_type(31), help="PRNG seed (default 0): network, actions and episode "
                   "seeds")
    p.add_argument("--out", metavar="DIR", help="run directory to create (default runs/foam-<UTC timestamp>)")
    p.add_argument("--init-from", metavar="RUN_DIR", help="start from the network and observation "
                   "statistics of RUN_DIR's last checkpoint (a train-foam run with the same network, "
                   "observation and action box), e.g. to fine-tune a coarse-mesh policy on the full mesh")
    p.add_argument("--resume", metavar="RUN_DIR", help="continue RUN_DIR from its last checkpoint; only "
                   "--episodes (raised), --pool, --backend and --ray-address may be given")
    p.add_argument("--tensorboard", action="store_true", help="also write the metrics as TensorBoard event "
                   "files to RUN_DIR/tensorboard/")
    p.add_argument("--print-config", action="store_true", help="print the resolved config and exit")
    p.set_defaults(func=run_train_foam)



# ---- running ------------------------------------------------------------------------------------------
def run_train_foam(args: argparse.Namespace, on_chunk: Any = None) -> int:
    """Entry point of train-foam; ``on_chunk(updates_done)`` is a test hook."""
    plan = resume_plan(args) if args.resume else fresh_plan(args)
    if args.print_config:
        from jaxsimrl.envs.foam_config import foam_config_to_json

        sys.stdout.write(json.dumps({"ppo": plan.ppo.to_dict(), "foam": foam_config_to_json(plan.foam),
                                     "episodes": plan.episodes, "pool": plan.pool}, indent=2) + "\n")
        return 0
    from foam_bridge.errors import CaseError, ClusterError, OpenFOAMNotFoundError
    from jaxsimrl.envs.host import HostEnvError
    from jaxsimrl.runs.run_dir import RunDir

    try:
        run = RunDir(plan.run_path) if plan.resume else RunDir.create(plan.run_path)
    except ValueError as err:
        raise UsageError(str(err)) from None
    try:
        summary = _train(plan, run, on_chunk, args.tensorboard)
    except (CaseError, ClusterError, OpenFOAMNotFoundError) as err:
        _drop_if_empty(run, plan)
        raise UsageError(str(err)) from None
    except KeyboardInterrupt:
        return _interrupted(run, plan)
    except HostEnvError as err:  # not bad input, not a solver fault: a broken host side
        _drop_if_empty(run, plan)
        resume = f"; resume with: jaxsimrl train-foam --resume {run.path}" if run.checkpoint_steps() else ""
        sys.stderr.write(f"jaxsimrl train-foam: error: {err}{resume}\n")
        return 1
    _print_summary(summary, run)
    return 0


def _train(plan: FoamPlan, run: Any, on_chunk: Any, tensorboard: bool = False) -> dict[str, Any]:
    """Build the pool and the trainer, restore or start, train; returns the final summary."""
    import jax

    from jaxsimrl.agents.ppo import make_train
    from jaxsimrl.envs.foam import foam_vec_env
    from jaxsimrl.runs.checkpoint import Checkpoints
    from jaxsimrl.runs.episodes import EPISODES_FILE, EpisodeLog
    from jaxsimrl.runs.progress import FoamProgress
    from jaxsimrl.runs.run_dir import MetricsLog
    from jaxsimrl.runs.tensorboard import tensorboard_log
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
    cursor = {"update": done + 1}
    # the batch is re-seeded from the trainer's key at every reset; this seed only names its streams
    vec = foam_vec_env(plan.foam, plan.ppo.num_envs, plan.pool, seed=plan.seed,
                       backend=plan.backend, ray_address=plan.ray_address,
                       on_episode=lambda env_id, info: episodes.add(env_id, cursor["update"], info))
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
            session = Session(run, _HostTrainer(trainer, vec, episodes, cursor), log, checkpoints,
                              meta={"config": record}, summary_extra={"run_dir": str(run.path)},
                              before_checkpoint=lambda _: episodes.flush(),
                              # workers_lost: workers lost for good (a Ray node died), one line each
                              summary_hook=lambda s: {**foam_summary(s, episodes, plan),
                                                      "workers_lost": list(vec.batch.backend.lost)},
                              tensorboard=tb,
                              checkpoint_meta=lambda: {IN_FLIGHT: vec.batch.snapshot()})
            with FoamProgress(plan.episodes, episodes, plan.pool, log,
                              workers=vec.batch.backend.workers) as progress:
                episodes.on_add = progress.episode_ended  # the bar counts episodes as they end
                resumed_with = len(episodes.rows)
                train(session, state, done, progress, on_chunk,
                      until=lambda: _target_reached(episodes, plan, resumed_with),
                      on_interrupt=_interrupt_handler(run, plan, progress))
            return session.write_summary()
    finally:
        vec.batch.close()


def _start_over(run: Any, episodes: Any) -> None:
    """A resumed run without a checkpoint (killed before its first one was saved) starts over from its
    config.json: the rows it wrote for updates that no checkpoint kept are truncated, so none is
    written twice."""
    from jaxsimrl.runs.run_dir import MetricsLog
    from jaxsimrl.runs.tensorboard import TENSORBOARD_DIR

    sys.stderr.write(f"jaxsimrl train-foam: {run.path} has no checkpoint (it stopped before its first "
                     f"update was saved): starting it over from its config.json\n")
    MetricsLog(run).write()
    episodes.flush()
    shutil.rmtree(run.path / TENSORBOARD_DIR, ignore_errors=True)


def _target_reached(episodes: Any, plan: FoamPlan, resumed_with: int) -> bool:
    """True at the episode target. Checked after each update is saved: a run whose episodes all failed
    the same way (EpisodeLog.systematic_failure) stops there with that cause, resumable once it is fixed
    (the rule waits for an update of this session: ``resumed_with`` rows were there at its start)."""
    from jaxsimrl.envs.host import HostEnvError

    cause = episodes.systematic_failure(plan.ppo.num_envs) if len(episodes.rows) > resumed_with else None
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
    """The state of checkpoint ``done`` with its episodes in flight replayed, else with new episodes."""
    import jax

    try:
        state, meta = checkpoints.restore(jax.eval_shape(trainer.init, key), done)
    except ValueError as err:
        raise UsageError(f"cannot resume: {err}") from None
    why = _replay_in_flight(vec, meta.get(IN_FLIGHT), state)
    if not why:
        sys.stderr.write(f"jaxsimrl train-foam: resumed at update {done} with its {vec.num_envs} episodes in "
                         f"flight replayed\n")
        return state
    sys.stderr.write(f"jaxsimrl train-foam: resumed at update {done}; its episodes in flight were not "
                     f"replayed ({why}): every env starts a new episode\n")
    return trainer.restart_episodes(state, jax.random.fold_in(key, done))


def _replay_in_flight(vec: Any, snapshot: Any, state: Any) -> str:
    """Replay a checkpoint's episodes in flight into the new batch; "" if it matches, else why not."""
    import numpy as np

    if not snapshot:
        return "the checkpoint has no record of them"
    saved = np.asarray(state.obs, np.float32).tolist()
    if [np.float32(entry.get("obs", [])).tolist() for entry in snapshot] != saved:
        return "the record does not match the checkpoint's observations"
    return vec.batch.replay(snapshot)


class _HostTrainer:
    """The trainer as the training loop sees it: a chunk whose host side failed raises, unsaved."""

    def __init__(self, trainer: Any, vec: Any, episodes: Any, cursor: dict[str, int]) -> None:
        self.trainer, self.vec, self.episodes, self.cursor = trainer, vec, episodes, cursor
        self.num_updates = trainer.num_updates

    def run_chunk(self, state: Any) -> tuple[Any, dict[str, Any]]:
        import jax

        state, metrics = self.trainer.run_chunk(state)
        metrics = jax.device_get(metrics)
        if self.vec.error is not None:
            self.episodes.discard_pending()
        self.vec.raise_if_failed()
        self.cursor["update"] += 1
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
    from importlib.metadata import version

    import jax

    from jaxsimrl.envs.foam_config import foam_config_to_json

    now = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    base = plan.record if plan.resume else {"env": "foam", "seed": plan.seed, "created_utc": now}
    if plan.init_from is not None:
        base["init_from"] = {"run_dir": str(plan.init_from.run_dir), "update": plan.init_from.update}
    record = {**base, "ppo": plan.ppo.to_dict(), "foam": foam_config_to_json(plan.foam),
              "episodes_target": plan.episodes, "pool": plan.pool, "backend": plan.backend,
              "jax_version": jax.__version__, "jaxsimrl_version": version("jaxsimrl")}
    if plan.resume:
        record["resumed_utc"] = [*base.get("resumed_utc", []), now]
    return record


def _drop_if_empty(run: Any, plan: FoamPlan) -> None:
    if not plan.resume and not run.checkpoint_steps():
        shutil.rmtree(run.path, ignore_errors=True)


def _interrupted(run: Any, plan: FoamPlan) -> int:
    sys.stderr.write(f"jaxsimrl train-foam: interrupted; {_stopped_text(run, plan)}\n")
    return INTERRUPTED


def _stopped_text(run: Any, plan: FoamPlan) -> str:
    """What an interrupted run left: the last checkpoint and how to resume, or nothing (a fresh run
    stopped before its first checkpoint, whose directory is removed)."""
    steps = run.checkpoint_steps()
    if steps:
        return f"saved up to update {steps[-1]}. Resume with: jaxsimrl train-foam --resume {run.path}"
    if plan.resume:
        return f"no checkpoint yet; --resume {run.path} starts it over"
    _drop_if_empty(run, plan)
    return "stopped before the first update was saved; nothing to resume"


def _interrupt_handler(run: Any, plan: FoamPlan, progress: Any) -> Callable[[int], None]:
    """What a Ctrl-C during an update does, at once (runs.training.interrupts_deferred): the first is
    acknowledged and stops the run after the update in flight is saved; the second ends the process
    now, as a kill would (the solvers die with their workers, everything on disk is whole), and the run
    resumes from its last checkpoint."""
    def react(count: int) -> None:
        if count == 1:
            sys.stderr.write(f"jaxsimrl train-foam: stopping after this update (waiting for {plan.pool} "
                             f"solver worker(s))... press Ctrl-C again to stop now, losing the update in "
                             f"flight\n")
            sys.stderr.flush()
            return
        progress.stop()  # gives the terminal back
        sys.stderr.write(f"jaxsimrl train-foam: stopped now, without the update in flight; "
                         f"{_stopped_text(run, plan)}\n")
        sys.stderr.flush()
        os._exit(INTERRUPTED)

    return react


def _print_summary(summary: dict[str, Any], run: Any) -> None:
    failures = ", ".join(f"{k} {v}" for k, v in summary["failures"].items()) or "none"
    target = summary["episodes_target"]
    extra = summary["episodes"] - target
    more = (f" (target {target}; the {extra} more ended in the update that reached it)" if extra > 0 else "")
    sys.stdout.write(
        f"done: {summary['episodes']} episodes{more} in {summary['updates']} updates, "
        f"{summary['wall_time_s']:.0f} s "
        f"({summary['episodes_per_hour']:.0f} episodes/hour, pool utilisation "
        f"{summary['pool_utilisation']:.0%})\n"
        f"  mean iterations over the last 100 episodes: {summary['final_mean_iterations']:.1f}; "
        f"failures: {failures}\n"
        + "".join(f"  {line}\n" for line in summary.get("workers_lost", []))
        + f"  run directory: {run.path} (config.json, episodes.csv, metrics.jsonl/.csv, summary.json, "
        f"checkpoints/)\n"
        f"  evaluate with: jaxsimrl eval-foam {run.path}\n")
