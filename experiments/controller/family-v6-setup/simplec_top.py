"""Where should a SIMPLEC case's box top and starting point be? Constant factors for the whole run on the
SIMPLEC training variants T3A-0 and pitzDaily-0 (family-v5's configs, their own criterion and budget):
their own (0.9, 1.0, 0.9), the residual rule's SIMPLEC start (the box top, 0.95 everywhere), 0.95 with p
unrelaxed, and higher still. Training variants only (issue 35: never tune on held-out cases).

    .venv/bin/python experiments/controller/family-v6-setup/simplec_top.py CASE OUT.json
"""

from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

from foam_bridge import ConstantFactors, EpisodeJob, FoamEnvConfig, run_episodes, shares_of

RUN = Path("experiments/controller/family-v5")
TRIPLES = ((0.9, 1.0, 0.9), (0.95, 0.95, 0.95), (0.95, 1.0, 0.95), (0.98, 1.0, 0.98))


def main() -> None:
    case, out = sys.argv[1], Path(sys.argv[2])
    base = FoamEnvConfig.from_json(json.loads((RUN / "config.json").read_text())["family"][case])
    cfg = dataclasses.replace(base, freeze_decades=None, action_low=(0.2, 0.2, 0.2),
                              action_high=(0.99, 1.0, 0.99), action_pivot=None)
    jobs = [EpisodeJob(k, ConstantFactors(shares_of(cfg, list(triple))), seed=0)
            for k, triple in enumerate(TRIPLES)]
    rows = [{"case": case, "factors": list(triple), "iterations": run.iterations, "outcome": run.outcome,
             "cause": run.cause, "budget": cfg.max_iterations}
            for triple, run in zip(TRIPLES, run_episodes(cfg, jobs, 1, work_dir=f"/tmp/simplec-top-{case}"),
                                   strict=True)]
    out.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
