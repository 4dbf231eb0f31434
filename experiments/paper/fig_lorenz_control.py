"""Paper figure "results_lorenz": controlled (blue) vs uncontrolled (black) trajectories from (1, 12, 9),
(sigma, rho, beta) = (10, 20, 8/3), for the agents trained with N = 2, 4 and 8 workers.

    python experiments/paper/fig_lorenz_control.py [--runs-dir runs/paper] [--workers 2 4 8]

Evaluates the runs that fig_lorenz_workers.py trained (run it first). Per agent: the return and the
share of steps with |velocity| > 40 of the plotted episode, and eval-lorenz's statistics over 32 random
initial states (its eval.json is written into each run directory). Writes fig_lorenz_control.png and
fig_lorenz_control.json beside this script.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from fig_lorenz_trajectories import uncontrolled_run  # noqa: E402
from fig_lorenz_workers import run_dir  # noqa: E402

from jaxsimrl import load_policy  # noqa: E402
from jaxsimrl.envs.lorenz import P_MINUS, LorenzParams  # noqa: E402
from jaxsimrl.evaluation.lorenz_eval import evaluate_run  # noqa: E402
from jaxsimrl.evaluation.plots import CONTROLLED, UNCONTROLLED, save_figure  # noqa: E402
from jaxsimrl.runs.atomic import atomic_write_json  # noqa: E402

HERE = Path(__file__).resolve().parent
EPISODES = 32


def controlled_run(run: Path, params: LorenzParams) -> dict:
    """The agent's episode from ``params.init_state`` (start state first) and its numbers."""
    policy = load_policy(run)
    record = policy.rollout(params.replace(random_init=False))
    xyz = np.concatenate([np.asarray(params.init_state)[None], record["info.state"][0]])
    speed = record["info.speed"][0]
    return {"xyz": xyz, "return": float(record["reward"][0].sum()), "update": policy.update,
            "fraction_above_v_threshold": float(np.mean(speed > float(params.v_threshold)))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs-dir", type=Path, default=Path("runs/paper"))
    parser.add_argument("--workers", type=int, nargs="+", default=[2, 4, 8])
    args = parser.parse_args()
    missing = [str(run_dir(args.runs_dir, n)) for n in args.workers if not run_dir(args.runs_dir, n).is_dir()]
    if missing:
        sys.exit(f"fig_lorenz_control.py: no run {missing[0]}; train it with fig_lorenz_workers.py first")

    params = LorenzParams()
    base = uncontrolled_run(params)
    fig = plt.figure(figsize=(5 * len(args.workers), 5))
    numbers = {"uncontrolled": {"return": float(base.reward[0].sum()),
                                "fraction_above_v_threshold": float(np.mean(base.speed[0] > 40.0))}}
    for panel, workers in enumerate(args.workers, start=1):
        run = run_dir(args.runs_dir, workers)
        agent = controlled_run(run, params)
        report = evaluate_run(run, episodes=EPISODES)
        ax = fig.add_subplot(1, len(args.workers), panel, projection="3d")
        ax.plot(*agent["xyz"].T, color=CONTROLLED, lw=0.4, label="controlled")
        ax.plot(*base.xyz[0].T, color=UNCONTROLLED, lw=0.9, label="uncontrolled")
        ax.scatter(*np.asarray(P_MINUS)[:, None], color="red", marker="*", s=120, label="P-")
        ax.set(xlabel="x", ylabel="y", zlabel="z", title=f"N = {workers}")
        ax.legend(loc="upper left", fontsize=8)
        numbers[f"N={workers}"] = {
            "run_dir": str(run), "checkpoint_update": agent["update"], "return": agent["return"],
            "fraction_above_v_threshold": agent["fraction_above_v_threshold"],
            f"mean_return_{EPISODES}_random_states": report["mean_return"],
            f"fraction_above_v_threshold_{EPISODES}_random_states": report["fraction_above_threshold"],
            f"uncontrolled_mean_return_{EPISODES}_random_states": report["uncontrolled"]["mean_return"]}
    fig.suptitle("Lorenz system from (1, 12, 9), (sigma, rho, beta) = (10, 20, 8/3)\ncontrolled by the agent "
                 "trained with N workers (blue) vs uncontrolled (black)")
    fig.tight_layout()
    save_figure(fig, HERE / "fig_lorenz_control.png")
    atomic_write_json(HERE / "fig_lorenz_control.json", numbers)
    for name, values in numbers.items():
        print(name, {k: v for k, v in values.items() if k != "run_dir"})


if __name__ == "__main__":
    main()
