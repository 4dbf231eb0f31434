"""What the convergence check reads: earlier evaluations' runs replayed, then checked at two factors.

For every run of ``eval-h-error/`` and ``eval-2h-error/`` at one inlet velocity (the policy's mean
action, the best constant, three random runs; full mesh, test criterion, no check), and for the
alpha_u-0.2 run of ``criterion_relaxation.py``: replay its actions in a FoamCaseEnv, then run the
check of foam_bridge._confirm on its final fields at alpha_u 0.95 and 0.9. Writes
check_relaxation.json next to this script (atomically): per run, its iterations, its U error from
the evaluation, the solver's residuals at K and each check's residuals.

    python experiments/foam/check_relaxation.py              # 50 m/s, ~6 min on 2 cores
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from foam_bridge._config import TEST_CONVERGENCE, FoamEnvConfig
from foam_bridge._confirm import confirm
from foam_bridge._env import FoamCaseEnv
from jaxsimrl.runs.atomic import atomic_write_json

HERE = Path(__file__).parent
EVALUATIONS = {"h": HERE / "eval-h-error" / "eval.json", "2h": HERE / "eval-2h-error" / "eval.json"}
FACTORS = (0.95, 0.9)
#: criterion_relaxation.py's run: (0.95, 0.875) for three steps, then alpha_u 0.2, on 2h.
DROP = [[0.95, 0.875]] * 3 + [[0.2, 0.875]] * 40


def replay(job: dict) -> dict:
    """Run the job's actions (the last one repeats) to the end, then check its final fields."""
    cfg = FoamEnvConfig(step_height=job["step_height"], inlet_velocity=job["velocity"],
                        convergence=dict(TEST_CONVERGENCE), max_iterations=4000)
    with FoamCaseEnv(cfg) as env:
        env.reset(seed=0)
        for action in job["actions"]:
            _, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        checks = {f"{a:g}": confirm(env.case_dir, env.base, dataclasses.replace(env.cfg, confirm_alpha_u=a),
                                    env.openfoam, info["iterations"], action[1], info["residuals"]).record()
                  for a in FACTORS}
    return {**{k: job[k] for k in ("name", "u_error")}, "outcome": info["outcome"],
            "iterations": info["iterations"], "solver_residuals": info["residuals"],
            "checks": {a: {"passed": c["passed"], "residuals": c["residuals"]} for a, c in checks.items()}}


def jobs(velocity: float) -> list[dict]:
    found = []
    for geometry, path in EVALUATIONS.items():
        report = json.loads(path.read_text())
        for controller, cells in report["results"].items():
            for run in cells[geometry][f"{velocity:g}"]["runs"]:
                found.append({"name": f"{geometry} {controller} #{run['sample']}", "u_error": run["u_error"],
                              "step_height": run["step_height"], "velocity": velocity,
                              "actions": run["actions"]})
    drop = json.loads((HERE / "criterion_relaxation_2h.json").read_text())
    found.append({"name": "2h alpha_u 0.2 from iteration 300", "u_error": drop["runs"]["drop"]["u_error"],
                  "step_height": drop["step_height"], "velocity": drop["inlet_velocity"], "actions": DROP})
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--velocity", type=float, default=50.0)
    args = parser.parse_args()
    with ProcessPoolExecutor(2) as pool:
        runs = list(pool.map(replay, jobs(args.velocity)))
    for run in runs:
        checks = "  ".join(f"check {a}: U {c['residuals'].get('U', float('nan')):.2e}"
                           for a, c in run["checks"].items())
        print(f"{run['name']:40s} K={run['iterations']:5d} U error {100 * run['u_error']:5.1f} %  "
              f"solver U {run['solver_residuals']['U']:.2e}  {checks}")
    out = HERE / "check_relaxation.json"
    atomic_write_json(out, {"velocity": args.velocity, "criterion": dict(TEST_CONVERGENCE),
                            "factors": list(FACTORS), "runs": runs})
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
