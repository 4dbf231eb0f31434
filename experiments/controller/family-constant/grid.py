"""The training family's best constant triple per algorithm (issue 35's baseline "the constant a user would
copy from our docs"): constant (alpha_u, alpha_p, turbulence) for the whole run on every training variant
of family-v6 (runs/family-full: 4 variants each of pitzDaily and T3A, SIMPLEC; pitzDailyExptInlet and
airFoil2D, plain SIMPLE), each on its own criterion and budget (3x its own iterations). Training variants
only: no held-out case is run here.

    .venv/bin/python experiments/controller/family-constant/grid.py experiments/controller/family-constant

Appends a row per run to OUT/grid.jsonl (a resumed call skips the runs it holds), then writes
OUT/family_best.json: per algorithm, the triple with the lowest geometric mean over its cases of
(iterations / that case's best converged run), a run that did not converge counting at its case's budget
(the rule of jaxsimrl.apps.foam.evaluation.family, with each case's own budget).
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from pathlib import Path

from atomicfile import atomic_write_text
from foam_bridge import ConstantFactors, EpisodeJob, FoamEnvConfig, run_episodes, shares_of

RUN = Path("experiments/controller/family-v6")
#: Triples per algorithm, chosen before any run from the training tutorials' grids
#: (benchmarks/results/rules-2026-12-03: plain SIMPLE 0.7875 converged both bases, 0.875 neither;
#: family-v6-setup/simplec_top.json: SIMPLEC 0.95 converged both, 0.98 neither).
TRIPLES = {
    "SIMPLE": ((0.7, 0.3, 0.7), (0.75, 0.3, 0.75), (0.8, 0.3, 0.8), (0.8, 0.35, 0.8), (0.8, 0.2, 0.8),
               (0.85, 0.3, 0.85), (0.85, 0.2, 0.85), (0.8, 0.3, 0.9)),
    "SIMPLEC": ((0.9, 1.0, 0.9), (0.95, 1.0, 0.95), (0.95, 0.95, 0.95), (0.95, 0.9, 0.95), (0.95, 0.8, 0.95),
                (0.9, 0.9, 0.9), (0.95, 1.0, 0.9), (0.9, 1.0, 0.95)),
}


def run_grid(out: Path) -> list[dict]:
    family = json.loads((RUN / "config.json").read_text())["family"]
    path = out / "grid.jsonl"
    rows = [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []
    done = {(row["case"], tuple(row["factors"])) for row in rows}
    for case, data in family.items():
        cfg = dataclasses.replace(FoamEnvConfig.from_json(data), freeze_decades=None, action_pivot=None,
                                  action_low=(0.2, 0.2, 0.2), action_high=(0.99, 1.0, 0.99))
        todo = [t for t in TRIPLES[cfg.simple_variant] if (case, t) not in done]
        jobs = [EpisodeJob(k, ConstantFactors(shares_of(cfg, list(t))), seed=0, tag=t)
                for k, t in enumerate(todo)]
        if not jobs:
            continue

        def keep(run, case=case, cfg=cfg):
            row = {"case": case, "algorithm": cfg.simple_variant, "factors": list(run.job.tag),
                   "iterations": run.iterations, "outcome": run.outcome, "cause": run.cause,
                   "budget": cfg.max_iterations, "wall_s": round(run.host_wall_s, 2)}
            rows.append(row)
            with path.open("a") as stream:
                stream.write(json.dumps(row) + "\n")
            print(row, flush=True)

        run_episodes(cfg, jobs, 1, work_dir=f"/tmp/family-constant-{case}", on_result=keep)
    return rows


def family_best(rows: list[dict]) -> dict:
    """Per algorithm: the chosen triple, its ratio to each case's best, and every triple's mean ratio."""
    out = {}
    for algorithm, triples in TRIPLES.items():
        mine = [r for r in rows if r["algorithm"] == algorithm]
        cases = sorted({r["case"] for r in mine})
        best = {c: min((r["iterations"] for r in mine if r["case"] == c and r["outcome"] == "converged"),
                       default=None) for c in cases}
        ranked = [c for c in cases if best[c]]

        def ratios(triple, ranked=ranked, best=best, mine=mine):
            runs = {r["case"]: r for r in mine if tuple(r["factors"]) == triple}
            return {c: (runs[c]["iterations"] if runs[c]["outcome"] == "converged" else runs[c]["budget"])
                    / best[c] for c in ranked}

        means = {t: math.exp(sum(math.log(v) for v in ratios(t).values()) / len(ranked)) for t in triples}
        chosen = min(triples, key=means.__getitem__)
        out[algorithm] = {"factors": list(chosen), "mean_ratio": round(means[chosen], 4),
                          "ratios": {c: round(v, 4) for c, v in ratios(chosen).items()},
                          "left_out": [c for c in cases if c not in ranked],
                          "every_triple": [{"factors": list(t), "mean_ratio": round(m, 4)}
                                           for t, m in means.items()]}
    return out


def main() -> None:
    out = Path(sys.argv[1])
    rows = run_grid(out)
    rule = ("per algorithm, the triple with the lowest geometric mean over its training variants of "
            "(iterations / the variant's best converged run); a run that did not converge counts at the "
            "variant's budget (3x its own iterations)")
    result = {"rule": rule, "family": str(RUN), "best": family_best(rows)}
    atomic_write_text(out / "family_best.json", json.dumps(result, indent=1) + "\n")
    print(json.dumps(result["best"], indent=1))


if __name__ == "__main__":
    main()
