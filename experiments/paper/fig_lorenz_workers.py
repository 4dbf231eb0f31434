"""Paper figure "mean_reward_lorenz": mean episode reward during training (moving average over 5
episodes) for 2, 4 and 8 workers, and the wall time each training took.

    python experiments/paper/fig_lorenz_workers.py [--runs-dir runs/paper] [--workers 2 4 8] [--seed 0]

Each worker count is one `jaxsimrl train-lorenz --config experiments/lorenz_paper.json --num-envs N`
run (the paper's 8000 steps per update split over N workers, 2e5 steps), started as its own process
and timed whole. Runs already complete in --runs-dir are reused (--retrain trains them again); their
directories are what fig_lorenz_control.py evaluates. Writes fig_lorenz_workers.png and
fig_lorenz_workers.json (the numbers, with the machine's load) beside this script.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402

from jaxsimrl.evaluation.curves import episode_curve, read_rows  # noqa: E402
from jaxsimrl.evaluation.plots import save_figure  # noqa: E402
from jaxsimrl.runs.atomic import atomic_write_json  # noqa: E402

HERE = Path(__file__).resolve().parent
PAPER_CONFIG = HERE.parent / "lorenz_paper.json"
COMMAND_FILE = "paper_command.json"  # the whole command's timing, kept in the run directory
WINDOW = 5


def run_dir(runs_dir: Path, workers: int) -> Path:
    """Where the run with ``workers`` workers lives (fig_lorenz_control.py reads it from here)."""
    return runs_dir / f"lorenz-workers-{workers}"


def train(run: Path, workers: int, seed: int, retrain: bool) -> dict:
    """Train (or reuse) one run; returns its command timing record."""
    record_path = run / COMMAND_FILE
    summary = run / "summary.json"
    complete = summary.is_file() and json.loads(summary.read_text())["complete"]
    if not retrain and complete and record_path.is_file():
        return json.loads(record_path.read_text())
    shutil.rmtree(run, ignore_errors=True)
    argv = [sys.executable, "-m", "jaxsimrl.cli.main", "train-lorenz", "--config", str(PAPER_CONFIG),
            "--num-envs", str(workers), "--seed", str(seed), "--out", str(run)]
    load_before = os.getloadavg()[0]
    started = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL)
    record = {"argv": argv[2:], "command_s": time.perf_counter() - started, "load_1min_before": load_before,
              "load_1min_after": os.getloadavg()[0],
              "utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    atomic_write_json(record_path, record)
    return record


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs-dir", type=Path, default=Path("runs/paper"))
    parser.add_argument("--workers", type=int, nargs="+", default=[2, 4, 8])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--retrain", action="store_true", help="train again even if a run is complete")
    args = parser.parse_args()

    results = {}
    for workers in args.workers:
        run = run_dir(args.runs_dir, workers)
        command = train(run, workers, args.seed, args.retrain)
        summary = json.loads((run / "summary.json").read_text())
        curve = episode_curve(read_rows(run), WINDOW)
        results[workers] = {"run_dir": str(run), "training_s": summary["wall_time_s"],
                            "command_s": command["command_s"], "load_1min": command["load_1min_before"],
                            "final_moving_average": float(curve.moving_average[-1]),
                            "episodes": int(curve.episode[-1]), "curve": curve}

    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.5), gridspec_kw={"width_ratios": [2, 1]})
    for workers, result in results.items():
        curve = result["curve"]
        left.plot(curve.episode, curve.moving_average, lw=1.5, label=f"N = {workers}")
    left.set_xlabel("episode")
    left.set_ylabel(f"mean episode reward (moving average, {WINDOW} episodes)")
    left.legend()
    left.grid(alpha=0.3)
    names = [str(w) for w in results]
    right.bar(names, [r["training_s"] for r in results.values()], color="tab:blue", label="training")
    right.bar(names, [r["command_s"] - r["training_s"] for r in results.values()],
              bottom=[r["training_s"] for r in results.values()], color="tab:gray", label="start-up, writing")
    right.set_xlabel("workers N")
    right.set_ylabel("wall time (s)")
    right.legend()
    fig.suptitle("PPO on the Lorenz system (paper config, 2e5 steps); this machine: "
                 f"{os.cpu_count()} cores, JAX on CPU")
    fig.tight_layout()
    save_figure(fig, HERE / "fig_lorenz_workers.png")
    numbers = {str(w): {k: v for k, v in r.items() if k != "curve"} for w, r in results.items()}
    atomic_write_json(HERE / "fig_lorenz_workers.json", numbers)
    for workers, r in results.items():
        print(f"N={workers}: training {r['training_s']:.1f} s, command {r['command_s']:.1f} s, final moving "
              f"average {r['final_moving_average']:.0f} over {r['episodes']} episodes")


if __name__ == "__main__":
    main()
