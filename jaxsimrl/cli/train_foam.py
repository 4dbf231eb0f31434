"""``jaxsimrl train-foam``: PPO on real simpleFoam cases, stepped from the jitted trainer via io_callback.

The same PPO as train-lorenz (jaxsimrl.agents.ppo) on a :class:`jaxsimrl.envs.host.HostVecEnv` over a
``foam_bridge.batched.BatchedFoamEnv`` of ``--num-envs`` cases on ``--pool`` workers. Defaults are the
paper's (Pawar & Maulik, "Solver convergence acceleration"): a 2 x 64 tanh MLP, lr 2.5e-4, gamma 1, inlet
velocity uniform in [35, 65] m/s, actions (alpha_u, alpha_p) in [0.2, 0.95]^2 every 100 iterations, the
training criterion, 2000 episodes, the built-in backward-facing step (SIMPLEC, k/omega relaxed at 0.8).

One update = ``steps_per_update`` env steps (see :func:`foam_ppo_defaults` for the sizes and why); after
every update: metrics rows, episodes.csv, a checkpoint, summary.json (in that order, Ctrl-C held back).
``--resume RUN_DIR`` continues from the last checkpoint. Every checkpoint also records the episodes in
flight (each env's episode seed, actions so far, K, observation and seed stream): the solvers did not
survive the process, so resume replays them (the solver is deterministic), checks K, return and
observation against the record, and carries on mid-episode exactly as the run would have; where that
fails (an older checkpoint, a changed machine) every env starts a new episode instead, and says so.
``--init-from RUN_DIR`` starts a new run from another run's trained network and observation
statistics (e.g. a coarse-mesh policy fine-tuned on the full mesh), with a fresh optimiser and new
episodes.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from jaxsimrl.cli.errors import UsageError, positive_float, positive_int, seed_type

INTERRUPTED = 130
#: Key of the episodes in flight (BatchedFoamEnv.snapshot) in each checkpoint's record.
IN_FLIGHT = "in_flight"
#: Env steps per update, summed over envs: ~20-30 episodes of the paper's 4-8 steps (see foam_ppo_defaults).
FOAM_BATCH = 128
#: The built-in case as the paper's code ran it (a user's --case keeps its own settings instead).
PAPER_CASE = {"simple_variant": "SIMPLEC", "relax_k_omega": 0.8, "inlet_velocity": [35.0, 65.0]}
#: Default reward scale per --reward: each makes a step of the built-in case ~ -0.1 (a SIMPLE iteration
#: costs ~11 linear-solver iterations and, on this project's 2-core machine, 6-25 ms of solver CPU time
#: from mesh 0.5 to the full mesh; experiments/foam/eval-full/eval.csv).
REWARD_SCALES = {"iterations": 1e-3, "linear-iterations": 1e-4, "solver-time": 0.1}
#: PPOConfig fields with a train-foam flag (the others come from --config).
KNOBS: tuple[tuple[str, Any, str], ...] = (
    ("steps_per_update", positive_int, f"env steps per PPO update over all envs (default {FOAM_BATCH}, "
                                       "rounded up to a multiple of 4 x num_envs)"),
    ("lr", positive_float, "Adam learning rate (paper: 2.5e-4)"),
    ("gamma", float, "discount factor in [0, 1] (paper: 1)"),
    ("gae_lambda", float, "GAE lambda in [0, 1]"),
    ("clip_eps", positive_float, "PPO clipping epsilon"),
    ("ent_coef", float, "entropy bonus coefficient (>= 0), on the squashed policy's entropy"),
    ("update_epochs", positive_int, "SGD epochs over each update's batch"),
    ("num_minibatches", positive_int, "minibatches per epoch"),
    ("reward_scale", positive_float, "rewards (minus the --reward cost) are multiplied by this before GAE "
                                     "(default: 1e-3 for iterations, 1e-4 for linear-iterations, 0.1 for "
                                     "solver-time)"),
    ("action_margin", float, "the tanh squash maps onto the action box widened by this fraction of its "
                             "width on each side, then clips into the box, so the bounds are reachable "
                             "(default 0: plain tanh, bounds only approached)"),
)


def foam_ppo_defaults(num_envs: int, reward: str = "iterations") -> dict[str, Any]:
    """The PPOConfig fields train-foam sets before --config and flags.

    The paper's network and optimiser (2 x 64 tanh MLP, lr 2.5e-4, gamma 1). Batch sizes: the paper's code
    trained on 200-step batches with minibatches of 128 (RLlib); its episodes last 4-8 steps (400-800
    iterations / 100), so a batch of ~128 steps holds 20-30 whole episodes, enough for a return estimate
    with gamma = 1, while an update still comes every few minutes on 2 cores. 4 minibatches x 10 epochs
    gives 40 SGD steps per update, as RLlib's 30 passes over 1.5 minibatches did. The MLP needs no
    sequence: seq_len 1. Rewards are -100 per step and down to -max_iterations on a failure: a reward
    scale of 1e-3 keeps returns (and so the value targets) O(1) (-0.4 to -4); the other rewards' scales
    (REWARD_SCALES) do the same for their units.
    """
    per_env = max(4, math.ceil(FOAM_BATCH / num_envs))
    per_env += -per_env % 4
    return {"num_envs": num_envs, "steps_per_update": per_env * num_envs, "network": "mlp",
            "hidden_sizes": [64, 64], "activation": "tanh", "lr": 2.5e-4, "gamma": 1.0, "gae_lambda": 0.95,
            "update_epochs": 10, "num_minibatches": 4, "seq_len": 1, "reward_scale": REWARD_SCALES[reward],
            "updates_per_chunk": 1, "ent_coef": 0.0}


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add train-foam to the ``jaxsimrl`` dispatcher."""
    from foam_bridge.config import MESH_SCALE_USABLE_MIN, REWARDS
    from jaxsimrl.cli.foam import add_confirm_argument

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
                   "with --resume it may be raised")
    p.add_argument("--mesh-scale", type=positive_float, help=f"mesh resolution factor (1.0 = 20,540 cells, "
                   f"default); >= {MESH_SCALE_USABLE_MIN:g} (coarser meshes are a different control problem)")
    p.add_argument("--step-height", type=positive_float, help="step height in m (default 0.0127 = h)")
    p.add_argument("--max-iterations", type=positive_int, help="iteration cap per episode (default 4000)")
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



# ---- the plan: everything resolved before anything heavy starts ---------------------------------------
@dataclass
class FoamPlan:
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


def _fresh_plan(args: argparse.Namespace) -> FoamPlan:
    from foam_bridge.backends import validate_pool
    from jaxsimrl.agents.ppo.config import PPOConfig
    from jaxsimrl.runs.run_dir import RunDir

    extra = _read_config(args.config) if args.config else {}
    num_envs = args.num_envs or args.pool or 2
    try:
        foam = _foam_config(args, extra.get("foam", {}))
        ppo_values = {**foam_ppo_defaults(num_envs, foam.reward), **extra.get("ppo", {})}
        ppo_values.update({name: getattr(args, name) for name, _, _ in KNOBS
                           if getattr(args, name) is not None})
        ppo_values["steps_per_update"] += -ppo_values["steps_per_update"] % (ppo_values["num_minibatches"]
                                                                             * num_envs)
        ppo = PPOConfig.from_dict(ppo_values)
        pool = validate_pool(num_envs, args.pool)
    except (TypeError, ValueError) as err:
        raise UsageError(f"invalid config: {err}") from None
    if ppo.updates_per_chunk != 1:
        raise UsageError("invalid config: updates_per_chunk must be 1 for train-foam (a checkpoint after "
                         "every update)")
    if args.backend != "ray" and args.ray_address:
        raise UsageError("--ray-address needs --backend ray")
    out = Path(args.out) if args.out else Path("runs") / time.strftime("foam-%Y%m%d-%H%M%S", time.gmtime())
    try:
        RunDir.check_new(out)
    except ValueError as err:
        raise UsageError(str(err)) from None
    init_from = _starting_policy(args.init_from, ppo, foam) if args.init_from else None
    return FoamPlan(ppo, foam, args.episodes or 2000, 0 if args.seed is None else args.seed, pool,
                    args.backend or "local", args.ray_address, out, resume=False, init_from=init_from)


def _starting_policy(run_dir: str, ppo: Any, foam: Any) -> Any:
    """The policy of ``--init-from``, checked to fit this run's network, observation and action box."""
    import numpy as np

    from jaxsimrl.introspect import load_policy

    try:
        policy = load_policy(run_dir)
    except ValueError as err:
        raise UsageError(f"--init-from: {err}") from None
    if policy.record.get("env") != "foam":
        raise UsageError(f"--init-from: {run_dir} is not a train-foam run")
    mine = (ppo.network, tuple(ppo.hidden_sizes), ppo.activation, foam.observation_size)
    trained = policy.config
    theirs = (trained.network, tuple(trained.hidden_sizes), trained.activation, policy.obs_dim)
    if mine != theirs:
        raise UsageError(f"--init-from: {run_dir} has (network, hidden sizes, activation, observation size) "
                         f"{theirs}, this run {mine}")
    box = (list(foam.action_low), list(foam.action_high))
    if not (np.allclose(policy.action_low, box[0]) and np.allclose(policy.action_high, box[1])):
        raise UsageError(f"--init-from: {run_dir} acts in the box {policy.action_low.tolist()}-"
                         f"{policy.action_high.tolist()}, this run in {box[0]}-{box[1]}")
    return policy


def _foam_config(args: argparse.Namespace, extra: dict[str, Any]) -> Any:
    """The FoamEnvConfig: the paper's built-in case, then --config's "foam" section, then flags."""
    from foam_bridge.config import FoamEnvConfig
    from jaxsimrl.envs.foam_config import foam_config_from_json, foam_config_to_json

    values = {**foam_config_to_json(FoamEnvConfig()), **extra}
    flags = {"mesh_scale": args.mesh_scale, "step_height": args.step_height,
             "max_iterations": args.max_iterations, "case_dir": args.case, "reward": args.reward,
             "confirm_alpha_u": args.confirm_alpha_u}
    values.update({name: value for name, value in flags.items() if value is not None})
    if values.get("case_dir") is None:  # the built-in case: its paper defaults, written out in config.json
        for name, value in PAPER_CASE.items():
            values[name] = value if values.get(name) is None else values[name]
    if values.get("case_dir") is not None:
        values["case_dir"] = str(Path(values["case_dir"]).resolve())
    values["work_dir"] = None  # cases live in a temporary directory per process, never in the run dir
    return foam_config_from_json(values)


def _resume_plan(args: argparse.Namespace) -> FoamPlan:
    from foam_bridge.backends import validate_pool
    from jaxsimrl.agents.ppo.config import PPOConfig
    from jaxsimrl.envs.foam_config import foam_config_from_json
    from jaxsimrl.runs.run_dir import RunDir

    fixed = ["config", "num_envs", "mesh_scale", "step_height", "max_iterations", "case", "reward", "seed",
             "out", "init_from", "confirm_alpha_u"]
    changed = [name for name in fixed + [k for k, _, _ in KNOBS] if getattr(args, name) is not None]
    if changed:
        flag = "--" + changed[0].replace("_", "-")
        raise UsageError(f"{flag} cannot be used with --resume: a resumed run keeps "
                         f"its saved config (only --episodes, --pool, --backend, --ray-address)")
    try:
        run = RunDir.existing(args.resume)
        record = run.read_config()
        if record.get("env") != "foam":
            raise ValueError(f"{run.path} is not a train-foam run (env {record.get('env')!r})")
        ppo = PPOConfig.from_dict(record["ppo"])
        foam = foam_config_from_json(record["foam"])
        pool = validate_pool(ppo.num_envs, args.pool or record.get("pool"))
    except (KeyError, TypeError, ValueError) as err:
        raise UsageError(f"cannot resume: {err}") from None
    if not run.checkpoint_steps():
        raise UsageError(f"cannot resume: no checkpoint in {run.path} (it stopped before its first update)")
    episodes = int(record.get("episodes_target", 2000))
    if args.episodes is not None:
        if args.episodes < episodes:
            raise UsageError(f"--episodes {args.episodes} is below the run's {episodes}: it may only be "
                             f"raised")
        episodes = args.episodes
    return FoamPlan(ppo, foam, episodes, int(record.get("seed", 0)), pool,
                    args.backend or record.get("backend", "local"), args.ray_address, run.path, resume=True,
                    record=record)


def _read_config(path: str) -> dict[str, Any]:
    from jaxsimrl.runs.run_dir import read_json

    try:
        values = read_json(path)
    except ValueError as err:
        raise UsageError(f"--config: {err}") from None
    if not isinstance(values, dict) or set(values) - {"ppo", "foam"}:
        raise UsageError(f'--config {path} must hold a JSON object with "ppo" and/or "foam" sections')
    for name in ("ppo", "foam"):
        if not isinstance(values.get(name, {}), dict):
            raise UsageError(f'--config {path}: "{name}" must be a JSON object')
    return values


# ---- running ------------------------------------------------------------------------------------------
def run_train_foam(args: argparse.Namespace, on_chunk: Any = None) -> int:
    """Entry point of train-foam; ``on_chunk(updates_done)`` is a test hook."""
    plan = _resume_plan(args) if args.resume else _fresh_plan(args)
    if args.print_config:
        from jaxsimrl.envs.foam_config import foam_config_to_json

        sys.stdout.write(json.dumps({"ppo": plan.ppo.to_dict(), "foam": foam_config_to_json(plan.foam),
                                     "episodes": plan.episodes, "pool": plan.pool}, indent=2) + "\n")
        return 0
    from foam_bridge.errors import CaseError, OpenFOAMNotFoundError
    from jaxsimrl.envs.host import HostEnvError
    from jaxsimrl.runs.run_dir import RunDir

    try:
        run = RunDir(plan.run_path) if plan.resume else RunDir.create(plan.run_path)
    except ValueError as err:
        raise UsageError(str(err)) from None
    try:
        summary = _train(plan, run, on_chunk, args.tensorboard)
    except (CaseError, OpenFOAMNotFoundError) as err:
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
    from jaxsimrl.runs.episodes import EpisodeLog
    from jaxsimrl.runs.progress import FoamProgress
    from jaxsimrl.runs.run_dir import MetricsLog
    from jaxsimrl.runs.tensorboard import tensorboard_log
    from jaxsimrl.runs.training import Session, train

    done = run.checkpoint_steps()[-1] if plan.resume else 0
    episodes = EpisodeLog.load(run.path / "episodes.csv", done) if plan.resume else EpisodeLog(
        run.path / "episodes.csv")
    cursor = {"update": done + 1}
    # the batch is re-seeded from the trainer's key at every reset; this seed only names its streams
    vec = foam_vec_env(plan.foam, plan.ppo.num_envs, plan.pool, seed=plan.seed,
                       backend=plan.backend, ray_address=plan.ray_address,
                       on_episode=lambda env_id, info: episodes.add(env_id, cursor["update"], info))
    try:
        trainer = make_train(plan.ppo, vec=vec, devices=jax.devices()[:1])
        with Checkpoints(run.checkpoints) as checkpoints, tensorboard_log(run.path, tensorboard) as tb:
            key = jax.random.PRNGKey(plan.seed)
            if plan.resume:
                state = _restored(trainer, checkpoints, key, done, vec)
                log = MetricsLog.load(run, done)
                log.write()
            else:
                state, log = _initial_state(trainer, key, plan.init_from), MetricsLog(run)
            vec.raise_if_failed()
            record = _config_record(plan)
            run.write_config(record)
            session = Session(run, _HostTrainer(trainer, vec, episodes, cursor), log, checkpoints,
                              meta={"config": record}, summary_extra={"run_dir": str(run.path)},
                              before_checkpoint=lambda _: episodes.flush(),
                              summary_hook=lambda s: foam_summary(s, episodes, plan), tensorboard=tb,
                              checkpoint_meta=lambda: {IN_FLIGHT: vec.batch.snapshot()})
            with FoamProgress(plan.episodes, episodes, plan.pool, log) as progress:
                train(session, state, done, progress, on_chunk,
                      until=lambda: len(episodes.rows) >= plan.episodes)
            return session.write_summary()
    finally:
        vec.batch.close()


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
    return {"episodes": count, "episodes_target": plan.episodes, "complete": count >= plan.episodes,
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
    steps = run.checkpoint_steps()
    if steps:
        sys.stderr.write(f"jaxsimrl train-foam: interrupted; saved up to update {steps[-1]}. Resume with: "
                         f"jaxsimrl train-foam --resume {run.path}\n")
    else:
        _drop_if_empty(run, plan)
        sys.stderr.write("jaxsimrl train-foam: interrupted before the first update; nothing to resume\n")
    return INTERRUPTED


def _print_summary(summary: dict[str, Any], run: Any) -> None:
    failures = ", ".join(f"{k} {v}" for k, v in summary["failures"].items()) or "none"
    sys.stdout.write(
        f"done: {summary['episodes']} episodes in {summary['updates']} updates, "
        f"{summary['wall_time_s']:.0f} s "
        f"({summary['episodes_per_hour']:.0f} episodes/hour, pool utilisation "
        f"{summary['pool_utilisation']:.0%})\n"
        f"  mean iterations over the last 100 episodes: {summary['final_mean_iterations']:.1f}; "
        f"failures: {failures}\n"
        f"  run directory: {run.path} (config.json, episodes.csv, metrics.jsonl/.csv, summary.json, "
        f"checkpoints/)\n"
        f"  evaluate with: jaxsimrl eval-foam {run.path}\n")
