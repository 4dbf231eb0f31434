"""``jaxsimrl train-foam``: PPO on real simpleFoam cases, stepped from the jitted trainer via io_callback.

The same PPO as train-lorenz (jaxsimrl.agents.ppo) on a :class:`jaxsimrl.envs.host.HostVecEnv` over a
``foam_bridge._batched.BatchedFoamEnv`` of ``--num-envs`` cases on ``--pool`` workers. Defaults are the
paper's (Pawar & Maulik, "Solver convergence acceleration"): a 2 x 64 tanh MLP, lr 2.5e-4, gamma 1, inlet
velocity uniform in [35, 65] m/s, actions (alpha_u, alpha_p) in [0.2, 0.95]^2 every 100 iterations, the
training criterion, 2000 episodes, the built-in backward-facing step (SIMPLEC, k/omega relaxed at 0.8).

This module parses the flags, resolves them into a plan (:mod:`jaxsimrl.apps.foam.plan`, every bad input a
one-line error before anything starts), calls :func:`jaxsimrl.apps.foam.training.train_foam` (the run itself:
updates, episodes.csv, checkpoints, resume with the episodes in flight replayed) and prints. ``--resume
RUN_DIR`` continues from the last checkpoint; ``--init-from RUN_DIR`` starts a new run from another run's
trained network and observation statistics (e.g. a coarse-mesh policy fine-tuned on the full mesh), with
a fresh optimiser and new episodes.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import sys
from collections.abc import Callable
from typing import Any

from foam_bridge import (
    FOLLOW_ALPHA_U,
    K_OMEGA_ACTION,
    MESH_SCALE_USABLE_MIN,
    REWARDS,
    CaseError,
    ClusterError,
    OpenFOAMNotFoundError,
)
from jaxsimrl.apps.foam.cli.grid_foam import add_confirm_argument, k_omega_setting
from jaxsimrl.apps.foam.plan import KNOBS, OBSERVE_SWITCHES, FoamPlan, fresh_plan, resume_plan
from jaxsimrl.apps.foam.training import ResumeError, train_foam
from jaxsimrl.cli.errors import UsageError, positive_float, positive_int, seed_type
from jaxsimrl.runs.run_dir import RunDir
from jaxsimrl.runs.signals import exit_code, stop_word


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add train-foam to the ``jaxsimrl`` dispatcher."""
    p = subparsers.add_parser(
        "train-foam", help="train PPO to set simpleFoam's relaxation factors (real OpenFOAM cases)",
        description="Train a PPO agent that sets (alpha_u, alpha_p) every 100 SIMPLE iterations of real "
                    "simpleFoam runs of the backward-facing step (Pawar & Maulik, sec. 3.2), with the "
                    "paper's defaults. The cases run on a pool of worker processes; the trainer steps them "
                    "through one io_callback per step.")
    p.add_argument("--pool", type=positive_int, default=None, help="worker processes (the paper: 4, 8, 16; "
                   "default: min(num_envs, CPUs)); may change on --resume")
    p.add_argument("--num-envs", type=positive_int, help="parallel cases (default: = --pool); with "
                   "--async-envs, the cases the learner takes per step")
    p.add_argument("--async-envs", type=positive_int, metavar="E", help="an asynchronous batch "
                   "(EnvPool-style): E > --num-envs cases on the pool, each learner step takes the "
                   "--num-envs that are ready first, so no worker waits for the slowest case (default: "
                   "lock-step, every case every step); a resume replays its episodes and steps in flight, "
                   "as it does in lock-step")
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
    p.add_argument("--family", nargs="+", metavar="CASE_DIR", help="train one controller on many cases: "
                   "case directories, or directories of cases (e.g. a family `jaxsimrl family` built); each "
                   "episode runs one, in its own box, its reward scaled by its own settings' iterations "
                   "(docs/controller.md)")
    p.add_argument("--backend", choices=("local", "ray"), help="worker pool: local processes (default) or "
                   "Ray actors")
    p.add_argument("--ray-address", help="address of a running Ray cluster (with --backend ray)")
    for name, kind, text in KNOBS:
        p.add_argument("--" + name.replace("_", "-"), dest=name, type=kind, metavar="X", help=text)
    p.add_argument("--init-action", type=float, nargs="+", metavar="A", help="the factors the initial "
                   "policy's mean maps to, one per action (default: the box centre), e.g. a constant that "
                   "grid-foam found good for the training family; exploration starts around it")
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
        sys.stdout.write(json.dumps({"ppo": plan.ppo.to_dict(), "foam": plan.foam.to_json(),
                                     "episodes": plan.episodes, "pool": plan.pool}, indent=2) + "\n")
        return 0
    from jaxsimrl.envs.host import HostEnvError

    try:
        run = RunDir(plan.run_path) if plan.resume else RunDir.create(plan.run_path)
    except ValueError as err:
        raise UsageError(str(err)) from None
    try:
        summary = train_foam(plan, run, tensorboard=args.tensorboard, on_chunk=on_chunk,
                             on_interrupt=_interrupt_handler(run, plan))
    except ResumeError as err:
        raise UsageError(str(err)) from None
    except (CaseError, ClusterError, OpenFOAMNotFoundError) as err:
        _drop_if_empty(run, plan)
        raise UsageError(str(err)) from None
    except KeyboardInterrupt as stop:
        return _interrupted(run, plan, stop)
    except HostEnvError as err:  # not bad input, not a solver fault: a broken host side
        _drop_if_empty(run, plan)
        resume = f"; resume with: jaxsimrl train-foam --resume {run.path}" if run.checkpoint_steps() else ""
        sys.stderr.write(f"jaxsimrl train-foam: error: {err}{resume}\n")
        return 1
    _print_summary(summary, run)
    return 0


def _drop_if_empty(run: Any, plan: FoamPlan) -> None:
    if not plan.resume and not run.checkpoint_steps():
        shutil.rmtree(run.path, ignore_errors=True)


def _interrupted(run: Any, plan: FoamPlan, stop: KeyboardInterrupt) -> int:
    sys.stderr.write(f"jaxsimrl train-foam: {stop_word(stop)}; {_stopped_text(run, plan)}\n")
    return exit_code(stop)


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


def _interrupt_handler(run: Any, plan: FoamPlan) -> Callable[[int, int], None]:
    """What a Ctrl-C or SIGTERM during an update does, at once (runs.training.interrupts_deferred): end
    the process now, as a kill would. Waiting for the update in flight would let every solver run on
    for the rest of it, hours on a big mesh; instead the workers see their driver gone and kill their
    solvers within a second (foam_bridge._backends.local), everything on disk is whole, and --resume
    redoes the update from the last checkpoint, replaying the episodes in flight. (train_foam stops the
    live bar first.)"""
    def react(count: int, signum: int) -> None:
        if count > 1:
            return  # the first is already ending the process
        word = "SIGTERM" if signum == signal.SIGTERM else "Ctrl-C"
        sys.stderr.write(f"jaxsimrl train-foam: stopped now ({word}); the update in flight is redone on "
                         f"--resume; {_stopped_text(run, plan)}\n")
        sys.stderr.flush()
        os._exit(128 + signum)

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
