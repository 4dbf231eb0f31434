"""How low may T3A's alpha_u go under SIMPLEC? T3A-0 of the training family (family-v5's config), constant
factors (alpha_u, its own p 1.0, its own turbulence 0.9) for the whole run, alpha_u from its own 0.9 down;
family-v5's episodes diverged after a first action with alpha_u <= 0.8.

    .venv/bin/python experiments/controller/family-v5-setup/t3a_floor.py OUT.json
"""

from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

from foam_bridge import FoamCaseEnv, FoamEnvConfig, shares_of

RUN = Path("experiments/controller/family-v5")


def main() -> None:
    base = FoamEnvConfig.from_json(json.loads((RUN / "config.json").read_text())["family"]["T3A-0"])
    cfg = dataclasses.replace(base, freeze_decades=None)
    rows = []
    for alpha_u in (0.9, 0.85, 0.8, 0.7):
        env = FoamCaseEnv(cfg, work_dir=Path("/tmp/t3a-floor"))
        try:
            env.reset(seed=0)
            share = shares_of(cfg, [alpha_u, 1.0, 0.9])
            done, info = False, {}
            while not done:
                _, _, terminated, truncated, info = env.step(share)
                done = terminated or truncated
        finally:
            env.close()
        rows.append({"alpha_u": alpha_u, "alpha_p": 1.0, "alpha_t": 0.9, "iterations": info["iterations"],
                     "outcome": info["outcome"], "cause": info["cause"], "budget": cfg.max_iterations})
        print(rows[-1], flush=True)
    Path(sys.argv[1]).write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
