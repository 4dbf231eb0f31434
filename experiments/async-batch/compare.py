"""Lock-step vs asynchronous batch: learning per episode and solver throughput (issue 20).

Reads the runs ``lockstep-seedS`` and ``async-seedS`` in this folder (train-foam, mesh 0.5, pool 2, the same
budget) and writes ``compare.json`` and ``compare.png``; prints a markdown table. Usage::

    python experiments/async-batch/compare.py [--window 50]

The learning curve is the mean SIMPLE iterations of consecutive windows of episodes, in the order they
ended (the episode index). One measure of solver use serves both batches: the solvers' own seconds
(``solver_time_s``, OpenFOAM's ExecutionTime, summed over the episodes that ended) over the pool's time
(pool x the run's training wall time). Each batch's own ``pool_utilisation`` (summary.json) is shown
beside it; the two batches compute that one differently (jaxsimrl.apps.foam.training).
"""

from __future__ import annotations

import argparse
import csv
import json
import statistics
from pathlib import Path

HERE = Path(__file__).resolve().parent
MODES = {"lockstep": "lock-step", "async": "asynchronous"}


def load(run: Path) -> dict:
    """One run's episodes (iterations, solver seconds, in index order) and summary."""
    with (run / "episodes.csv").open(newline="") as handle:
        rows = sorted(csv.DictReader(handle), key=lambda row: int(row["index"]))
    summary = json.loads((run / "summary.json").read_text())
    return {"iterations": [int(row["iterations"]) for row in rows],
            "solver_s": sum(float(row["solver_time_s"]) for row in rows),
            "outcomes": sorted({row["outcome"] for row in rows}), "summary": summary}


def windows(values: list[int], size: int, count: int) -> list[float]:
    return [statistics.fmean(values[i * size:(i + 1) * size]) for i in range(count)]


def compare(window: int) -> dict:
    runs = {mode: {int(p.name.rsplit("seed", 1)[1]): load(p) for p in sorted(HERE.glob(f"{mode}-seed*"))
                   if (p / "summary.json").is_file()} for mode in MODES}
    budget = min(s["summary"]["episodes_target"] for r in runs.values() for s in r.values())
    count = budget // window
    table = {}
    for mode, seeds in runs.items():
        for seed, run in seeds.items():
            summary = run["summary"]
            table[f"{mode}-seed{seed}"] = {
                "mode": mode, "seed": seed, "episodes": summary["episodes"],
                "wall_time_s": summary["wall_time_s"], "episodes_per_hour": summary["episodes_per_hour"],
                "iterations_per_hour": sum(run["iterations"]) / summary["wall_time_s"] * 3600,
                "own_pool_utilisation": summary["pool_utilisation"],
                "solver_busy": run["solver_s"] / (summary["pool"] * summary["wall_time_s"]),
                "curve": windows(run["iterations"], window, count),
                "last_100": statistics.fmean(run["iterations"][budget - 100:budget]),
                "outcomes": run["outcomes"]}
    spread = {}
    for mode in MODES:
        points = list(zip(*(row["curve"] for row in table.values() if row["mode"] == mode), strict=True))
        spread[mode] = {"low": [min(p) for p in points], "high": [max(p) for p in points],
                        "mean": [statistics.fmean(p) for p in points]}
    lock, fast = spread["lockstep"], spread["async"]
    inside = [lo <= m <= hi for lo, m, hi in zip(lock["low"], fast["mean"], lock["high"], strict=True)]

    def median(key: str) -> dict[str, float]:
        return {m: statistics.median(r[key] for r in table.values() if r["mode"] == m) for m in MODES}

    return {"window": window, "budget": budget, "runs": table, "spread": spread,
            "async_mean_inside_lockstep_spread": inside,
            **{f"median_{key}": median(key) for key in ("episodes_per_hour", "iterations_per_hour",
                                                        "solver_busy", "last_100")}}


def plot(result: dict, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    window = result["window"]
    fig, ax = plt.subplots(figsize=(7, 4))
    for mode, colour in (("lockstep", "tab:blue"), ("async", "tab:orange")):
        centres = [window * (i + 0.5) for i in range(len(result["spread"][mode]["mean"]))]
        ax.fill_between(centres, result["spread"][mode]["low"], result["spread"][mode]["high"], color=colour,
                        alpha=0.2)
        ax.plot(centres, result["spread"][mode]["mean"], color=colour, marker="o",
                label=f"{MODES[mode]} (3 seeds: mean, min-max)")
    ax.set_xlabel("episode (in the order they ended)")
    ax.set_ylabel(f"mean SIMPLE iterations per {window} episodes")
    ax.set_title("train-foam, mesh 0.5, pool 2: lock-step vs asynchronous batch")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out, dpi=120)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--window", type=int, default=50, help="episodes per point of the curve")
    args = parser.parse_args()
    result = compare(args.window)
    (HERE / "compare.json").write_text(json.dumps(result, indent=2) + "\n")
    plot(result, HERE / "compare.png")
    print("| run | episodes | wall (s) | episodes/h | SIMPLE iterations/h | solvers busy (solver s / pool "
          f"time) | own measure | iterations per {args.window} episodes | last 100 |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, row in result["runs"].items():
        curve = " / ".join(f"{v:.0f}" for v in row["curve"])
        print(f"| {name} | {row['episodes']} | {row['wall_time_s']:.0f} | {row['episodes_per_hour']:.0f} | "
              f"{row['iterations_per_hour']:,.0f} | "
              f"{100 * row['solver_busy']:.1f} % | {100 * row['own_pool_utilisation']:.1f} % | {curve} | "
              f"{row['last_100']:.0f} |")
    print("async mean inside lock-step's spread per window:", result["async_mean_inside_lockstep_spread"])
    for key in [key for key in result if key.startswith("median_")]:
        print(key, result[key])


if __name__ == "__main__":
    main()
