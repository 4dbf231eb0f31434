"""Replay a run's recorded episodes under the convergence check of the code it is run with.

Each episode of RUN/episodes.csv is reset with its seed (the same velocity and step height) and stepped
with its recorded actions; when they run out before the episode ends, its last action is repeated. Run
it once with the code that trained the run (it must reproduce the recorded iterations) and once with
the current code: the difference is what the check change costs those action sequences.

    python experiments/controller/check_replay.py experiments/controller/family-mesh05 --last 20 \
        --out experiments/controller/check_replay/new.csv
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import os
import tempfile
from pathlib import Path

from foam_bridge import FoamCaseEnv, FoamEnvConfig
from jaxsimrl.apps.foam.episodes import EpisodeLog


def replay(cfg: FoamEnvConfig, row: dict) -> dict:
    """Run one recorded episode again; its iterations, outcome and the actions it took."""
    actions = [list(a) for a in row["actions"]]
    with FoamCaseEnv(cfg) as env:
        env.reset(seed=int(row["seed"]))
        taken, done, info = [], False, {}
        while not done:
            action = actions[len(taken)] if len(taken) < len(actions) else actions[-1]
            _, _, terminated, truncated, info = env.step(action)
            taken.append(action)
            done = terminated or truncated
    return {"index": row["index"], "seed": row["seed"], "inlet_velocity": row["inlet_velocity"],
            "step_height": row["step_height"], "recorded": row["iterations"],
            "replayed": info["iterations"], "outcome": info["outcome"], "recorded_steps": len(actions),
            "steps": len(taken), "last_action": json.dumps(actions[-1])}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path)
    parser.add_argument("--last", type=int, default=20, help="the run's last N episodes")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    config = json.loads((args.run / "config.json").read_text())
    rows = EpisodeLog.load(args.run / "episodes.csv", 10**9).rows[-args.last:]
    work = Path(tempfile.mkdtemp(prefix="replay-"))
    cfg = dataclasses.replace(FoamEnvConfig.from_json(config["foam"]), work_dir=work)
    out = [replay(cfg, row) for row in rows]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = args.out.with_suffix(".tmp")
    with tmp.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(out[0]))
        writer.writeheader()
        writer.writerows(out)
    os.replace(tmp, args.out)
    for entry in out:
        print(entry["recorded"], entry["replayed"], entry["outcome"], entry["last_action"])


if __name__ == "__main__":
    main()
