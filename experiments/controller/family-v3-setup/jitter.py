"""Does airFoil2D converge when its factors change every few dozen iterations around its own? One
training variant (airFoil2D-0 of family-v3), the env as training runs it, the factors its own (share 0.5)
plus seeded uniform noise of +-``spread`` in share, a new draw every ``interval`` iterations; with
``--freeze D`` the env holds the factors once the run is within D decades of its criterion
(FoamEnvConfig.freeze_decades).

    .venv/bin/python experiments/controller/family-v3-setup/jitter.py OUT.json [--freeze 1]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

from foam_bridge._config import FoamEnvConfig
from foam_bridge._env import FoamCaseEnv

RUN = Path("experiments/controller/family-v3")


def episode(cfg: FoamEnvConfig, spread: float, seed: int, work: Path) -> dict:
    env = FoamCaseEnv(cfg, work_dir=work)
    rng = np.random.default_rng(seed)
    try:
        env.reset(seed=0)
        done, info = False, {}
        while not done:
            share = 0.5 + rng.uniform(-spread, spread, cfg.action_size)
            _, _, terminated, truncated, info = env.step(share)
            done = terminated or truncated
    finally:
        env.close()
    return {"interval": cfg.interval, "spread": spread, "seed": seed, "iterations": info["iterations"],
            "outcome": info["outcome"], "budget": cfg.max_iterations}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("out", type=Path)
    parser.add_argument("--freeze", type=float, default=None)
    args = parser.parse_args()
    base = FoamEnvConfig.from_json(json.loads((RUN / "config.json").read_text())["family"]["airFoil2D-0"])
    rows = []
    for interval, spread, seed in ((50, 0.0, 0), (50, 0.1, 0), (50, 0.1, 1), (100, 0.1, 0), (50, 0.03, 0)):
        cfg = dataclasses.replace(base, interval=interval, freeze_decades=args.freeze)
        rows.append({**episode(cfg, spread, seed, Path("/tmp/jitter")), "freeze_decades": args.freeze})
        print(rows[-1], flush=True)
    args.out.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
