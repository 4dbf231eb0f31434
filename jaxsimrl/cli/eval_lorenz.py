"""``jaxsimrl eval-lorenz RUN_DIR``: a train-lorenz run's policy against the uncontrolled system.

Rolls out the run's last checkpoint (:func:`jaxsimrl.evaluation.lorenz_eval.evaluate_run`): one agent, or
every agent of a ``--seeds`` run with the statistics across them; prints the report and names the files
it wrote. JAX is imported inside :func:`run_eval` so ``--help`` and flag errors stay instant.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from jaxsimrl.cli.errors import UsageError, positive_int, seed_type


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add eval-lorenz to the ``jaxsimrl`` dispatcher."""
    evaluate = subparsers.add_parser(
        "eval-lorenz", help="evaluate a trained Lorenz agent against the uncontrolled system",
        description="Load RUN_DIR's last checkpoint; plot the controlled and uncontrolled trajectories "
                    "from (1, 12, 9) with (sigma, rho, beta) = (10, 20, 8/3) into "
                    "RUN_DIR/eval_trajectory.png; "
                    "measure the mean return and the fraction of steps with |velocity| > 40 over random "
                    "initial states (uniform in [-40, 40]^3) and write them to RUN_DIR/eval.json.")
    evaluate.add_argument("run_dir", metavar="RUN_DIR", help="a run directory written by train-lorenz")
    evaluate.add_argument("--episodes", type=positive_int, default=32, metavar="N",
                          help="4000-step episodes from random initial states (default: 32)")
    evaluate.add_argument("--agent", type=seed_type(), metavar="K", help="of a --seeds run, evaluate agent K "
                          "only (default: every agent, with the statistics across agents)")
    evaluate.add_argument("--stochastic", action="store_true",
                          help="sample actions from the policy instead of taking its mean action")
    evaluate.add_argument("--seed", type=seed_type(32), default=0, help="PRNG seed of the initial states "
                          "and of "
                          "sampled actions (default: 0)")
    evaluate.set_defaults(func=run_eval)


# ---- eval-lorenz -------------------------------------------------------------------------------------
def run_eval(args: argparse.Namespace) -> int:
    """Entry point of eval-lorenz."""
    from jaxsimrl.evaluation.lorenz_eval import evaluate_run  # noqa: PLC0415 (heavy: JAX)

    try:
        report = evaluate_run(Path(args.run_dir), episodes=args.episodes, stochastic=args.stochastic,
                              seed=args.seed, agent=args.agent)
    except ValueError as err:
        raise UsageError(str(err)) from None
    _print_eval(report, Path(args.run_dir), "" if args.agent is None else f"-agent-{args.agent}")
    return 0


def _print_eval(report: dict[str, Any], run_dir: Path, suffix: str) -> None:
    base = report["uncontrolled"]
    written = [f"eval{suffix}.json", f"eval_trajectory{suffix}.png"]
    written += [report["profile_plot"]] if "profile_plot" in report else []
    mode = "sampled" if report["stochastic"] else "mean (deterministic)"
    who = f", agent {report['agent']} (seed {report['agent_seed']})" if "agent" in report else ""
    sys.stdout.write(
        f"eval-lorenz {run_dir}{who}: {report['episodes']} episodes of {report['episode_steps']} steps from "
        f"random initial states, {mode} actions, seed {report['seed']}\n"
        f"  controlled:   {_controlled_text(report)}   "
        f"|velocity| > {report['v_threshold']:g}: {report['fraction_above_threshold']:.1%} of steps\n"
        f"  uncontrolled: mean return {base['mean_return']:10.1f} (std {base['std_return']:.1f}, "
        f"min {base['min_return']:.1f}, max {base['max_return']:.1f})   "
        f"|velocity| > {report['v_threshold']:g}: {base['fraction_above_threshold']:.1%} of steps\n"
        f"{_aggregate_text(report)}"
        f"  wrote {' and '.join(str(run_dir / name) for name in written)}\n")


def _aggregate_text(report: dict[str, Any]) -> str:
    """A batch's IQM, median and mean of the agents' mean returns with their intervals ('' otherwise)."""
    if "aggregate" not in report:
        return ""
    stats = report["aggregate"]
    boot = stats["bootstrap"]
    parts = [f"{name} {stats[key]['value']:.1f} [{stats[key]['ci_low']:.1f}, {stats[key]['ci_high']:.1f}]"
             for key, name in (("iqm", "IQM"), ("median", "median"), ("mean", "mean"))]
    return (f"  across {stats['count']} agents (mean returns, {boot['confidence']:.0%} stratified-bootstrap "
            f"CI, {boot['reps']} reps, seed {boot['seed']}): {'; '.join(parts)}\n")


def _controlled_text(report: dict[str, Any]) -> str:
    """One agent's return statistics, or a batch's mean return and its spread across agents."""
    if "agents" in report:
        spread = report["mean_return_agents"]
        return (f"mean return {report['mean_return']:10.1f} (mean of {report['num_agents']} agents; per "
                f"agent: median {spread['median']:.1f}, min {spread['min']:.1f}, max {spread['max']:.1f}; "
                f"trajectory of agent {report['plotted_agent']})")
    return (f"mean return {report['mean_return']:10.1f} (std {report['std_return']:.1f}, "
            f"min {report['min_return']:.1f}, max {report['max_return']:.1f})")
