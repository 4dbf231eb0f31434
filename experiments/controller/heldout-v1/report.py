# SPDX-License-Identifier: GPL-3.0-or-later
"""Issue 35's held-out table and figure from an evaluation directory (evaluate.py's rows.jsonl, and
wall.jsonl when ``--wall`` ran): every case, every controller, losses included, and the issue's targets.

    .venv/bin/python experiments/controller/heldout-v1/report.py experiments/controller/heldout-v1/eval-v7-u51

Writes DIR/table.md (the table, the medians against each target) and DIR/ratios.png (each controller's
iterations / the case's own, per case). A run that did not converge counts at the iterations it ran (its
budget): a ratio against it flatters the other side, and the table marks it.
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

SHOWN = ("learned", "family-constant", "residual-rule", "bandit", "random", "oracle")


def _rows(directory: Path) -> dict[str, dict[str, dict]]:
    """case -> controller -> row (the grid's cells dropped: the oracle row carries them)."""
    cases: dict[str, dict[str, dict]] = {}
    for line in (directory / "rows.jsonl").read_text().splitlines():
        row = json.loads(line)
        if row["controller"] != "grid":
            cases.setdefault(row["case"], {})[row["controller"]] = row
    return cases


def _cell(row: dict | None) -> str:
    if row is None or row.get("iterations") is None:
        return "none converged" if row is not None else "-"
    return f"{row['iterations']}" + ("" if row["converged"] else " (not converged)")


def _ratio(a: dict, b: dict | None) -> float | None:
    if b is None or b.get("iterations") is None or a.get("iterations") is None:
        return None
    return a["iterations"] / b["iterations"]


def _better_rule(rows: dict[str, dict]) -> dict:
    return min((rows["residual-rule"], rows["bandit"]), key=lambda r: (not r["converged"], r["iterations"]))


def _median(values: list[float | None]) -> str:
    known = [v for v in values if v is not None]
    return f"{statistics.median(known):.3f} (of {len(known)})" if known else "-"


def table(cases: dict[str, dict[str, dict]], walls: dict[str, dict]) -> str:
    """The markdown table and the medians against the issue's targets."""
    lines = ["| case | algorithm | own | learned (ratio to own) | family constant | residual rule | bandit | "
             "random | oracle (its grid's cost) | learned / better rule | learned / oracle | agrees | "
             "learned's fallback | wall ratio (median of 3) |", "|" + "---|" * 14]
    ratios: dict[str, list[float | None]] = {"own": [], "constant": [], "rule": [], "oracle": []}
    for name, rows in sorted(cases.items(), key=lambda item: item[0].lower()):
        learned, own, oracle = rows["learned"], rows["own"], rows.get("oracle")
        to_own, to_rule, to_oracle = (_ratio(learned, other) for other in (own, _better_rule(rows), oracle))
        ratios["own"].append(to_own)
        ratios["constant"].append(_ratio(learned, rows["family-constant"]))
        ratios["rule"].append(to_rule)
        ratios["oracle"].append(to_oracle)
        cost = f" ({oracle['grid_iterations']} its, {oracle['grid_runs']} runs)" if oracle else ""
        wall = walls.get(name)
        cells = [name, learned["algorithm"], _cell(own),
                 f"{_cell(learned)} ({to_own:.3f})", _cell(rows["family-constant"]),
                 _cell(rows["residual-rule"]), _cell(rows["bandit"]), _cell(rows["random"]),
                 _cell(oracle) + cost, f"{to_rule:.3f}", "-" if to_oracle is None else f"{to_oracle:.3f}",
                 str(own.get("agrees_with_learned")), ", ".join(learned["fallback"]) or "none",
                 "-" if wall is None else f"{wall['median_ratio']:.3f}"]
        lines.append("| " + " | ".join(cells) + " |")
    simple = [_ratio(rows["learned"], rows["own"]) for rows in cases.values()
              if rows["own"]["algorithm"] == "SIMPLE"]
    lines += ["", "| target (issue 35) | wanted | measured (median) |", "|---|---|---|",
              f"| learned / own | <= 0.75 (moonshot 0.60) | {_median(ratios['own'])} |",
              f"| worst learned / own | <= 1.05 | {max(v for v in ratios['own'] if v is not None):.3f} |",
              f"| learned / family constant | <= 0.90 | {_median(ratios['constant'])} |",
              f"| learned / better no-training rule | <= 0.90 | {_median(ratios['rule'])} |",
              f"| learned / per-case oracle | <= 1.05 | {_median(ratios['oracle'])} |",
              f"| learned / own, plain SIMPLE cases | (part of the above) | {_median(simple)} |"]
    if walls:
        lines.append(f"| wall: learned solve / own run, cases >= 20 s | <= 0.80 | "
                     f"{_median([w['median_ratio'] for w in walls.values()])} |")
    return "\n".join(lines) + "\n"


def figure(cases: dict[str, dict[str, dict]], path: Path) -> None:
    """Each controller's iterations / own, per case (log scale; hollow: did not converge)."""
    names = sorted(cases, key=str.lower)
    fig, ax = plt.subplots(figsize=(10, 4.5))
    for k, controller in enumerate(SHOWN):
        for j, name in enumerate(names):
            row, own = cases[name].get(controller), cases[name]["own"]
            ratio = None if row is None else _ratio(row, own)
            if ratio is None:
                continue
            x = j + (k - (len(SHOWN) - 1) / 2) * 0.12
            face, label = f"C{k}" if row["converged"] else "none", controller if j == 0 else None
            ax.scatter(x, ratio, color=f"C{k}", facecolors=face, label=label, zorder=3)
    ax.axhline(1.0, color="k", lw=0.8)
    ax.axhline(0.75, color="k", lw=0.8, ls="--")
    ax.set_yscale("log")
    ax.set_xticks(range(len(names)), names, rotation=20)
    ax.set_ylabel("iterations / the case's own")
    ax.set_title("held-out cases (heldout-v1): hollow = did not converge in the budget")
    ax.legend(ncol=3, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("directory", type=Path, help="evaluate.py's --out")
    args = parser.parse_args()
    walls_path = args.directory / "wall.jsonl"
    walls = {} if not walls_path.exists() else {
        row["case"]: row for row in map(json.loads, walls_path.read_text().splitlines())}
    cases = _rows(args.directory)
    text = table(cases, walls)
    (args.directory / "table.md").write_text(text)
    figure(cases, args.directory / "ratios.png")
    print(text)


if __name__ == "__main__":
    main()
