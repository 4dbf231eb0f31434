# SPDX-License-Identifier: GPL-3.0-or-later
"""rows.jsonl (rank.py) -> table.md: per resolution, how a coarse case ranks the constants against its
full-size version (resolution 1.0).

Per case and resolution: Spearman's rank correlation of the constants' costs with the full-size ones
(a constant that did not converge costs its budget twice: ranked last, ties averaged), and the regret: what
the constant best on the coarse mesh costs on the full one, over the full one's best. Costs are iterations
(exact); CPU seconds beside them (noisy on a shared machine). A resolution "agrees" where the median
correlation is >= 0.8 and the median regret <= 1.05. Then the headroom at full size: per case, the best
of the grid (the oracle constant, own settings included) over the case's own settings, in iterations and
in CPU seconds (each run once).

    python experiments/controller/generated-ranking/summary.py
"""

from __future__ import annotations

import json
import statistics
from collections import defaultdict
from pathlib import Path

import numpy as np
from scipy.stats import spearmanr

HERE = Path(__file__).resolve().parent
FULL = 1.0


def main() -> None:
    rows = [json.loads(line) for line in (HERE / "rows.jsonl").read_text().splitlines() if line.strip()]
    table = defaultdict(dict)  # (case, resolution) -> label -> row
    for row in rows:
        table[(row["case"], row["resolution"])][row["label"]] = row
    cases = sorted({case for case, _ in table})
    resolutions = sorted({res for _, res in table})
    lines = ["| resolution | cases | own CPU s (median) | own iterations (median) | Spearman (iterations) "
             "median [min] | regret median [max] | Spearman (CPU) median |", "|---|---|---|---|---|---|---|"]
    per_case = ["", "| case | kind | algorithm | " + " | ".join(f"r{r:g} rho / regret" for r in resolutions)
                + " |", "|---|---|---|" + "---|" * len(resolutions)]
    found = {}
    for res in resolutions:
        rhos, regrets, rhos_cpu, cpu, its = [], [], [], [], []
        for case in cases:
            if (case, res) not in table or (case, FULL) not in table:
                continue
            coarse, full = table[(case, res)], table[(case, FULL)]
            labels = sorted(set(coarse) & set(full))
            if len(labels) < 3:
                continue
            rho = spearmanr([_cost(coarse[lab]) for lab in labels], [_cost(full[lab]) for lab in labels])[0]
            rho_cpu = spearmanr([_cost(coarse[lab], "cpu_s") for lab in labels],
                                [_cost(full[lab], "cpu_s") for lab in labels])[0]
            best = min(labels, key=lambda lab: _cost(coarse[lab]))
            regret = _cost(full[best]) / min(_cost(full[lab]) for lab in labels)
            rhos.append(rho), regrets.append(regret), rhos_cpu.append(rho_cpu)
            cpu.append(coarse["own"]["cpu_s"]), its.append(coarse["own"]["iterations"])
            found.setdefault(case, {})[res] = (rho, regret)
        if rhos:
            lines.append(f"| {res:g} | {len(rhos)} | {statistics.median(cpu):.2f} | "
                         f"{statistics.median(its):g} | {np.nanmedian(rhos):.2f} [{np.nanmin(rhos):.2f}] | "
                         f"{statistics.median(regrets):.3f} [{max(regrets):.2f}] | "
                         f"{np.nanmedian(rhos_cpu):.2f} |")
    for case in cases:
        own = table.get((case, FULL), {}).get("own") or next(iter(table[(case, resolutions[0])].values()))
        cells = [f"{found[case][r][0]:.2f} / {found[case][r][1]:.2f}" if r in found.get(case, {}) else "-"
                 for r in resolutions]
        per_case.append(f"| {case} | {own['kind']} | {own['algorithm']} | " + " | ".join(cells) + " |")
    out = "\n".join(lines + per_case + _headroom(table, cases))
    (HERE / "table.md").write_text(out + "\n")
    print(out)


def _headroom(table: dict, cases: list[str]) -> list[str]:
    """Per full-size case: the oracle constant (best converged setting of the grid) over own settings."""
    lines = ["", "| case (full size) | algorithm | own iterations / CPU s | oracle (iterations) | "
             "its / own | oracle (CPU) | CPU / own |", "|---|---|---|---|---|---|---|"]
    its_ratio, cpu_ratio = [], []
    for case in cases:
        runs = table.get((case, FULL), {})
        done = {lab: row for lab, row in runs.items() if row["converged"]}
        if "own" not in done:
            continue
        own = done["own"]
        by_its = min(done, key=lambda lab: done[lab]["iterations"])
        by_cpu = min(done, key=lambda lab: done[lab]["cpu_s"])
        its_ratio.append(done[by_its]["iterations"] / own["iterations"])
        cpu_ratio.append(done[by_cpu]["cpu_s"] / own["cpu_s"])
        lines.append(f"| {case} | {own['algorithm']} | {own['iterations']} / {own['cpu_s']:.2f} | {by_its} | "
                     f"{its_ratio[-1]:.2f} | {by_cpu} | {cpu_ratio[-1]:.2f} |")
    if its_ratio:
        lines.append(f"| median of {len(its_ratio)} | | | | {statistics.median(its_ratio):.2f} | | "
                     f"{statistics.median(cpu_ratio):.2f} |")
    return lines


def _cost(row: dict, key: str = "iterations") -> float:
    """A run's cost; one that did not converge: twice what it ran (ranked after every converged one)."""
    return float(row[key]) * (1 if row["converged"] else 2)


if __name__ == "__main__":
    main()
