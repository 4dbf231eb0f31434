"""``jaxsimrl train-lorenz``: PPO on the Lorenz chaos-restoration task (eval-lorenz: cli/eval_lorenz.py).

train-lorenz resolves a PPOConfig (PPOConfig defaults = the paper's setup, then ``--config FILE``,
then flags) into a plan, creates a run directory (see :mod:`jaxsimrl.runs.run_dir`) and calls
:func:`jaxsimrl.training.lorenz.train_lorenz` (chunk by chunk with a checkpoint after each), then prints.
``--resume RUN_DIR`` continues the run with its saved config.
JAX is imported inside the run functions so ``--help`` and flag errors stay instant.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
import time
from pathlib import Path
from typing import Any

from jaxsimrl.agents.ppo.config import SWEEPABLE, PPOConfig
from jaxsimrl.cli.errors import UsageError, positive_float, positive_int, seed_list, seed_type
from jaxsimrl.runs.run_dir import RunDir, read_json
from jaxsimrl.training.common import RunInputError
from jaxsimrl.training.lorenz import Sweep, TrainPlan, plan_trainer, train_lorenz

# PPOConfig fields with a command-line flag: (flag, type, help). Their defaults are PPOConfig's.
KNOBS: tuple[tuple[str, Any, str], ...] = (
    ("num_envs", positive_int, "parallel environments, the paper's workers (paper: 2; must divide "
                               "--steps-per-update)"),
    ("total_steps", positive_int, "env steps to train for, e.g. 2e5 (paper: 2e5); with --resume it may "
                                  "be raised to train further"),
    ("steps_per_update", positive_int, "env steps per PPO update over all envs (paper: 8000)"),
    ("lr", positive_float, "Adam learning rate (paper: 2.5e-4)"),
    ("gamma", float, "discount factor in [0, 1]"),
    ("gae_lambda", float, "GAE lambda in [0, 1]"),
    ("clip_eps", positive_float, "PPO clipping epsilon"),
    ("ent_coef", float, "entropy bonus coefficient (>= 0)"),
    ("update_epochs", positive_int, "SGD epochs over each update's batch"),
    ("num_minibatches", positive_int, "minibatches per epoch (must divide the sequences per env)"),
    ("seq_len", positive_int, "training sequence length, the LSTM's truncated-backprop window (must "
                              "divide the steps per env per update)"),
    ("updates_per_chunk", positive_int, "updates per jitted chunk: progress, metrics-file and "
                                        "checkpoint granularity"),
)
NETWORKS = ("lstm", "mlp")
INTERRUPTED = 130


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add train-lorenz to the ``jaxsimrl`` dispatcher."""
    train = subparsers.add_parser(
        "train-lorenz", help="train PPO to keep the transiently chaotic Lorenz system chaotic",
        description="Train a PPO agent on the Lorenz chaos-restoration task (Pawar & Maulik, sec. 3.1). "
                    "Without flags it runs the paper's config (PPOConfig defaults: 2 envs, 8000 steps per "
                    "update, 2e5 steps, 2x64 tanh + LSTM 256). A PPO flag left out takes its value from "
                    "--config, else from PPOConfig's defaults; --print-config shows the resolved values.")
    train.add_argument("--config", metavar="FILE.json", help="a PPOConfig as a JSON object, e.g. "
                       "experiments/lorenz_paper.json (unknown keys are an error)")
    for name, kind, text in KNOBS:
        metavar = "N" if kind is positive_int else "X"
        train.add_argument("--" + name.replace("_", "-"), dest=name, type=kind, metavar=metavar,
                           help=text)
    train.add_argument("--network", choices=NETWORKS, help="lstm (the paper's: 2x64 tanh then LSTM 256) "
                       "or mlp (2x64 tanh only) (default: lstm)")
    train.add_argument("--seed", type=seed_type(32), help="PRNG seed; the same seed and config give the "
                       "same "
                       "numbers on the same machine (default: 0)")
    train.add_argument("--seeds", type=seed_list(32), metavar="LIST", help="train one independent agent "
                       "per seed in one jitted call, e.g. 0-15 or 0,3,7; agent i gives the numbers of --seed "
                       "SEEDS[i] alone (up to float rounding)")
    train.add_argument("--sweep", type=sweep_item, nargs="+", metavar="NAME=V1,V2", help="one agent per "
                       "combination of these values (the cross product, times each seed of --seeds), in one "
                       "jitted call; NAME is a scalar of the update (lr, ent_coef, clip_eps, gamma, "
                       "gae_lambda, vf_coef), e.g. --sweep lr=1e-4,2.5e-4 ent_coef=0,0.01")
    train.add_argument("--out", metavar="DIR", help="run directory to create; must not hold anything yet "
                       "(default: runs/lorenz-<UTC timestamp>)")
    train.add_argument("--resume", metavar="RUN_DIR", help="continue RUN_DIR from its last checkpoint with "
                       "its saved config; only --total-steps may be given (to raise it)")
    train.add_argument("--tensorboard", action="store_true", help="also write the metrics as TensorBoard "
                       "event files to RUN_DIR/tensorboard/")
    train.add_argument("--print-config", action="store_true", help="print the resolved PPOConfig as JSON "
                       "(every field, defaults included) and exit without training")
    train.set_defaults(func=run_train)



# ---- train-lorenz ------------------------------------------------------------------------------------
def run_train(args: argparse.Namespace, on_chunk: Any = None) -> int:
    """Entry point of train-lorenz; ``on_chunk(updates_done)`` is a test hook (see runs.training.train)."""
    plan = _resume_plan(args) if args.resume else _fresh_plan(args)
    if args.print_config:
        sys.stdout.write(json.dumps(plan.config.to_dict(), indent=2) + "\n")
        return 0

    try:
        trainer = plan_trainer(plan)
    except RunInputError as err:
        raise UsageError(str(err)) from None
    try:
        run = RunDir(plan.run_path) if plan.resume else RunDir.create(plan.run_path)
    except ValueError as err:
        raise UsageError(str(err)) from None
    try:
        summary = train_lorenz(plan, run, trainer, tensorboard=args.tensorboard, on_chunk=on_chunk)
    except KeyboardInterrupt:
        return _interrupted(run)
    except RunInputError as err:  # e.g. a batch too large for memory, found before its first chunk
        if not plan.resume:
            shutil.rmtree(run.path, ignore_errors=True)  # empty or absent when this run started
        raise UsageError(str(err)) from None
    _print_summary(summary, run)
    return 0


def _interrupted(run: Any) -> int:
    """Ctrl-C: everything on disk is whole (writes are atomic and Ctrl-C waits for a chunk's writes)."""
    steps = run.checkpoint_steps()
    if steps:
        sys.stderr.write(f"jaxsimrl train-lorenz: interrupted; saved up to update {steps[-1]}. Resume with: "
                         f"jaxsimrl train-lorenz --resume {run.path}\n")
    else:
        # A fresh run stopped before its first checkpoint has nothing to resume; its directory was
        # empty or absent when it started, so everything in it is this run's.
        shutil.rmtree(run.path, ignore_errors=True)
        sys.stderr.write(f"jaxsimrl train-lorenz: interrupted before the first checkpoint; nothing to resume "
                         f"(removed {run.path})\n")
    return INTERRUPTED


def _print_summary(summary: dict[str, Any], run: Any) -> None:
    final = summary["final_mean_return"]
    final_text = "n/a (no episode ended)" if not math.isfinite(final) else _final_text(summary)
    sys.stdout.write(
        f"done: {summary['updates']} updates, {summary['total_steps']:,} env steps in "
        f"{summary['wall_time_s']:.1f} s ({summary['steps_per_s']:,.0f} steps/s)\n"
        f"  final mean episode return: {final_text}\n"
        f"  run directory: {run.path} (config.json, metrics.jsonl/.csv, summary.json, checkpoints/)\n"
        f"  evaluate with: jaxsimrl eval-lorenz {run.path}\n")


def _final_text(summary: dict[str, Any]) -> str:
    """The final mean return line: one agent's episodes, or the mean and range across a batch's agents."""
    if "agents" in summary:
        spread = summary["final_mean_return_agents"]
        return (f"{spread['mean']:,.1f} (mean over {spread['count']} of {summary['num_agents']} agents; "
                f"min {spread['min']:,.1f}, max {spread['max']:,.1f}; per agent in summary.json)")
    updates = summary["final_return_updates"]
    return (f"{summary['final_mean_return']:,.1f} (over the {summary['final_return_episodes']} episodes "
            f"ending in updates {updates[0]}-{updates[-1]})")


def _fresh_plan(args: argparse.Namespace) -> TrainPlan:
    values = _read_config_file(args.config) if args.config else {}
    values.update(_flag_overrides(args))
    try:
        config = PPOConfig.from_dict(values)
    except (TypeError, ValueError) as err:
        raise UsageError(f"invalid config: {err}") from None
    out = Path(args.out) if args.out else Path("runs") / time.strftime("lorenz-%Y%m%d-%H%M%S", time.gmtime())
    try:
        RunDir.check_new(out)  # before any compiling; RunDir.create checks again
    except ValueError as err:
        raise UsageError(str(err)) from None
    if args.seed is not None and args.seeds is not None:
        raise UsageError("give --seed (one agent) or --seeds (a batch), not both")
    seed = args.seeds[0] if args.seeds else (args.seed or 0)
    if not args.sweep:
        return TrainPlan(config, seed, out, resume=False, record={}, seeds=args.seeds)
    seeds, sweep = _sweep_agents(values, set(_flag_overrides(args)), args.sweep, args.seeds or (seed,))
    return TrainPlan(config, seed, out, resume=False, record={}, seeds=seeds, sweep=sweep)


def _sweep_agents(values: dict[str, Any], flags: set[str], items: list[tuple[str, tuple[float, ...]]],
                  seeds: tuple[int, ...]) -> tuple[tuple[int, ...], Sweep]:
    """Each agent's seed and swept values: every combination of ``items``' values (the cross product),
    each with every seed. Every combination must make a valid config with the other ``values``; a swept
    field overrides --config's value but may not be a flag too (``flags``)."""
    import itertools

    names = [name for name, _ in items]
    if len(set(names)) < len(names) or set(names) & flags:
        twice = next(name for name in names if names.count(name) > 1 or name in flags)
        raise UsageError(f"--sweep {twice}: give each field once, swept or as a flag")
    grid = list(itertools.product(*(options for _, options in items)))
    for combo in grid:
        try:
            PPOConfig.from_dict({**values, **dict(zip(names, combo, strict=True))})
        except (TypeError, ValueError) as err:
            swept = dict(zip(names, combo, strict=True))
            raise UsageError(f"invalid --sweep combination {swept}: {err}") from None
    agents = [(combo, seed) for combo in grid for seed in seeds]
    sweep = tuple((name, tuple(combo[i] for combo, _ in agents)) for i, name in enumerate(names))
    return tuple(seed for _, seed in agents), sweep


def _resume_plan(args: argparse.Namespace) -> TrainPlan:
    fixed = ("config", "network", "seed", "seeds", "sweep", "out")
    changed = [flag for flag in fixed if getattr(args, flag) is not None]
    changed += [name for name in _flag_overrides(args) if name != "total_steps"]
    if changed:
        flag = "--" + changed[0].replace("_", "-")
        raise UsageError(f"{flag} cannot be used with --resume: a resumed run keeps its saved config "
                         f"(only --total-steps may be raised)")
    try:
        run = RunDir.existing(args.resume)
        record = run.read_config()
        config = PPOConfig.from_dict(record["ppo"])
    except (TypeError, ValueError) as err:
        raise UsageError(f"cannot resume: {err}") from None
    if not run.checkpoint_steps():
        raise UsageError(f"cannot resume: no checkpoint in {run.path} (it stopped before its first chunk)")
    if args.total_steps is not None:
        if args.total_steps < config.total_steps:
            raise UsageError(f"--total-steps {args.total_steps} is below the run's {config.total_steps}: "
                             f"it may only be raised when resuming")
        config = config.with_total_steps(args.total_steps)
        if config.anneal_lr:  # the rate follows the new horizon's decay: say where it now stands
            done = run.checkpoint_steps()[-1]
            sys.stderr.write(f"jaxsimrl train-lorenz: the annealed learning rate is "
                             f"{config.learning_rate(done):.3g} at update {done} and decays to 0 at update "
                             f"{config.num_updates}\n")
    seeds = tuple(record["seeds"]) if "seeds" in record else None
    sweep = tuple((name, tuple(values)) for name, values in record.get("sweep", {}).items())
    return TrainPlan(config, record.get("seed", 0), run.path, resume=True, record=record, seeds=seeds,
                     sweep=sweep)


def sweep_item(text: str) -> tuple[str, tuple[float, ...]]:
    """argparse type of one --sweep item: NAME=V1,V2,... with NAME a sweepable PPOConfig field."""
    name, _, listed = text.partition("=")
    if name not in SWEEPABLE or not listed:
        raise argparse.ArgumentTypeError(f"expected NAME=V1,V2 with NAME one of {', '.join(SWEEPABLE)}, got "
                                         f"{text!r}")
    try:
        options = tuple(float(value) for value in listed.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name}: expected numbers, got {listed!r}") from None
    if len(set(options)) < len(options):
        raise argparse.ArgumentTypeError(f"{name}: values repeat in {listed!r}")
    return name, options


def _read_config_file(path: str) -> dict[str, Any]:
    try:
        values = read_json(path)
    except ValueError as err:
        raise UsageError(f"--config: {err}") from None
    if not isinstance(values, dict):
        raise UsageError(f"--config {path} must hold a JSON object of PPOConfig fields")
    return values


def _flag_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """The PPOConfig fields given as flags (PPOConfig.from_dict validates their values)."""
    overrides = {name: getattr(args, name) for name, _, _ in KNOBS if getattr(args, name) is not None}
    if args.network is not None:
        overrides["network"] = args.network
    return overrides
