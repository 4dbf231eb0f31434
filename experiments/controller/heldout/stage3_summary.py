"""Stage 3's held-out evaluation in one table and one figure: every number from the eval.csv files of
eval-foam beside this script (no solver run here).

Cases: step heights 0.6h, 1.5h, 3h x 25, 50, 75 m/s (stage 3 trained on 0.75h-2.5h x 35-65 m/s).
Per case: stage 3's deterministic policy (update 26), stage 2's (update 23), the stage 3 family's best
constant and the case's own settings (``eval-stage3-update26/``), sampled actions and the per-case
oracle with its grid's cost (``baselines-stage3-update26/``), random factors (``random-stage3/``).
A run that did not converge counts at the cap, as in the training reward and the family grid's rule.
Writes ``stage3_summary.csv`` and ``stage3_ratios.png``; prints the markdown table and the medians.
Run from the repository root: ``python experiments/controller/heldout/stage3_summary.py``.
"""

from __future__ import annotations

import csv
import json
import statistics
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = Path(__file__).parent
CAP = 4000
#: alpha_p of stage 2's family constant (0.95, 0.9, 0.95; h-2h only): a cell of every oracle grid.
H2H_ALPHA_P = 0.9
#: name -> (eval-foam directory, the controllers of its eval.csv rows)
SOURCES: dict[str, tuple[str, tuple[str, ...]]] = {
    "stage3": ("eval-stage3-update26", ("learned_deterministic",)),
    "stage2": ("eval-stage2-update23-newheights", ("learned_deterministic",)),
    "constant": ("eval-stage3-update26", ("best_constant",)),
    "own": ("eval-stage3-update26", ("tutorial_defaults",)),
    "sampled": ("baselines-stage3-update26", ("learned_stochastic",)),
    # the oracle's best cell is its case_oracle row, the grid's other cells are case_oracle_grid rows
    "oracle_grid": ("baselines-stage3-update26", ("case_oracle", "case_oracle_grid")),
    "random": ("random-stage3", ("random",))}

#: (controller, baseline) pairs whose per-case ratios are summarised
PAIRS = (("stage3", "constant"), ("stage3", "oracle"), ("stage3", "own"), ("stage3", "random"),
         ("sampled", "oracle"), ("stage3", "constant_h2h"), ("stage2", "constant_h2h"),
         ("stage2", "constant"), ("stage2", "oracle"), ("stage3", "stage2"))


def _runs() -> dict[str, dict[tuple[str, float], list[dict[str, str]]]]:
    """{name: {(geometry, velocity): [rows]}} for every source."""
    table: dict = defaultdict(lambda: defaultdict(list))
    for name, (folder, controllers) in SOURCES.items():
        with open(HERE / folder / "eval.csv", newline="") as handle:
            for row in csv.DictReader(handle):
                if row["controller"] in controllers:
                    table[name][(row["geometry"], float(row["velocity"]))].append(row)
    return table


def _its(row: dict[str, str]) -> int:
    return int(row["iterations"]) if row["outcome"] == "converged" else CAP


def _alpha_p(row: dict[str, str]) -> float:
    """alpha_p of a constant run (its first action)."""
    return json.loads(row["actions"])[0][1]


def _mean(rows: list[dict[str, str]]) -> float:
    return statistics.fmean(_its(r) for r in rows)


def summarise() -> list[dict[str, float | str]]:
    """One record per held-out case, in the evaluation's order."""
    table = _runs()
    records = []
    for case, grid in table["oracle_grid"].items():
        best = min(grid, key=_its)
        record = {"geometry": case[0], "velocity": case[1],
                  **{name: _mean(table[name][case]) for name in ("stage3", "stage2", "constant", "own",
                                                                  "sampled", "random")},
                  "oracle": _its(best), "oracle_alpha_p": _alpha_p(best),
                  "oracle_grid_cost": sum(int(r["iterations"]) for r in grid),
                  "constant_h2h": _its(next(r for r in grid if _alpha_p(r) == H2H_ALPHA_P))}
        records.append(record)
    return records


def _ratio(records: list[dict], a: str, b: str) -> list[float]:
    return [r[a] / r[b] for r in records]


def main() -> None:
    records = summarise()
    with open(HERE / "stage3_summary.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(records[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(records)
    print("| height | V | stage 3 | stage 2 | family constant | oracle (alpha_p) | oracle grid cost | own "
          "| sampled (mean) | random (mean) | stage 3 / constant | stage 3 / oracle |")
    print("|" + "---|" * 12)
    for r in records:
        own = "cap" if r["own"] >= CAP else f"{r['own']:.0f}"
        print(f"| {r['geometry']} | {r['velocity']:.0f} | {r['stage3']:.0f} | {r['stage2']:.0f} | "
              f"{r['constant']:.0f} | {r['oracle']} ({r['oracle_alpha_p']:g}) | {r['oracle_grid_cost']:,} | "
              f"{own} | {r['sampled']:.0f} | {r['random']:.0f} | {r['stage3'] / r['constant']:.2f} | "
              f"{r['stage3'] / r['oracle']:.2f} |")
    for a, b in PAIRS:
        ratios = _ratio(records, a, b)
        print(f"{a} / {b}: median {statistics.median(ratios):.3f}, "
              f"range {min(ratios):.2f}-{max(ratios):.2f}, "
              f"<= 1 on {sum(x <= 1 for x in ratios)} of {len(ratios)}")
    for name in ("stage3", "stage2", "constant", "oracle"):
        print(f"sum {name}: {sum(r[name] for r in records):,.0f}")
    print(f"oracle grids: {sum(r['oracle_grid_cost'] for r in records):,} iterations")
    _plot(records)


def _plot(records: list[dict]) -> None:
    """Each controller's iterations over the family constant's, per held-out case."""
    names = (("stage3", "stage 3 (update 26)"), ("stage2", "stage 2 (update 23)"),
             ("oracle", "per-case oracle"), ("sampled", "stage 3 sampled (mean of 3)"))
    fig, ax = plt.subplots(figsize=(10, 4))
    width = 0.8 / len(names)
    for i, (name, label) in enumerate(names):
        xs = [k + (i - (len(names) - 1) / 2) * width for k in range(len(records))]
        ax.bar(xs, _ratio(records, name, "constant"), width, label=label)
    ax.axhline(1.0, color="black", lw=1)
    ax.axhline(0.95, color="grey", lw=1, ls="--", label="target median 0.95")
    ax.set_xticks(range(len(records)), [f"{r['geometry']}\n{r['velocity']:.0f} m/s" for r in records])
    ax.set_ylabel("iterations / family's best constant")
    ax.set_title("Held-out cases (full mesh, test criterion + check): below 1 beats the stage 3 family's "
                 "constant (0.95, 0.75, 0.95)", fontsize=9)
    ax.legend(fontsize=8, ncol=3)
    fig.tight_layout()
    fig.savefig(HERE / "stage3_ratios.png", dpi=120)


if __name__ == "__main__":
    main()
