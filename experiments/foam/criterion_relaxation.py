"""Does lowering alpha_u "converge" a run? The test criterion against the field's distance from a reference.

Three runs of the built-in case (full mesh, SIMPLEC, k/omega 0.8) at one inlet velocity and step height:

- ``reference``: the constant (0.95, 0.875) for REFERENCE_ITERATIONS iterations, no convergence test;
- ``constant``: (0.95, 0.875) until the test criterion is met;
- ``drop``: (0.95, 0.875) for DROP_AT steps (100 iterations each), then alpha_u 0.2, until the criterion.

For every step it records the initial residuals, and for each run the iterations to the criterion and
the relative L2 distance of its final U field from the reference's (foam_bridge._fields). Writes
criterion_relaxation_<geometry>.json next to this script (atomically).

    python experiments/foam/criterion_relaxation.py               # 2h, 50 m/s (~8 min on 2 cores)
    python experiments/foam/criterion_relaxation.py --step-height 0.0127
"""

from __future__ import annotations

import argparse
import dataclasses
import shutil
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from foam_bridge._config import TEST_CONVERGENCE, FoamEnvConfig, without_convergence_test
from foam_bridge._env import FoamCaseEnv
from foam_bridge._fields import final_field, relative_l2
from jaxsimrl.runs.atomic import atomic_write_json

FACTORS = (0.95, 0.875)
LOW_ALPHA_U = 0.2
DROP_AT = 3
REFERENCE_ITERATIONS = 6000


def run(name: str, cfg: FoamEnvConfig, drop_at: int | None, keep: Path) -> dict:
    """One episode; its per-step residuals, outcome, and final U field (saved as keep/<name>.npy)."""
    import numpy as np

    steps = []
    with FoamCaseEnv(dataclasses.replace(cfg, keep_cases=True), work_dir=keep / f"work_{name}") as env:
        env.reset(seed=0)
        done = False
        while not done:
            low = drop_at is not None and len(steps) >= drop_at
            action = (LOW_ALPHA_U, FACTORS[1]) if low else FACTORS
            _, _, terminated, truncated, info = env.step(action)
            steps.append({"action": list(action), "iterations": info["iterations"],
                          "residuals": info["residuals"]})
            done = terminated or truncated
        field = final_field(env.case_dir, "U")
    shutil.rmtree(keep / f"work_{name}", ignore_errors=True)
    np.save(keep / f"{name}.npy", field[1])
    return {"outcome": info["outcome"], "iterations": info["iterations"], "steps": steps}


def main() -> None:
    import numpy as np

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--step-height", type=float, default=0.0254)
    parser.add_argument("--inlet-velocity", type=float, default=50.0)
    args = parser.parse_args()
    test = FoamEnvConfig(step_height=args.step_height, inlet_velocity=args.inlet_velocity,
                         convergence=dict(TEST_CONVERGENCE), max_iterations=4000)
    reference = dataclasses.replace(without_convergence_test(test), max_iterations=REFERENCE_ITERATIONS)
    keep = Path(tempfile.mkdtemp(prefix="criterion_"))
    plan = {"reference": (reference, None), "constant": (test, None), "drop": (test, DROP_AT)}
    with ProcessPoolExecutor(2) as pool:
        futures = {name: pool.submit(run, name, cfg, drop, keep) for name, (cfg, drop) in plan.items()}
        runs = {name: future.result() for name, future in futures.items()}
    ref = np.load(keep / "reference.npy")
    for name in ("constant", "drop"):
        runs[name]["u_error"] = relative_l2(np.load(keep / f"{name}.npy"), ref)
        done = runs[name]
        print(f"{name}: {done['outcome']} at {done['iterations']}, U error {done['u_error']:.3g}")
    shutil.rmtree(keep, ignore_errors=True)
    from jaxsimrl.apps.foam.evaluation.eval_spec import geometry_name

    out = Path(__file__).with_name(f"criterion_relaxation_{geometry_name(args.step_height)}.json")
    atomic_write_json(out, {"step_height": args.step_height, "inlet_velocity": args.inlet_velocity,
                            "factors": list(FACTORS), "low_alpha_u": LOW_ALPHA_U, "drop_at_step": DROP_AT,
                            "reference_iterations": REFERENCE_ITERATIONS,
                            "criterion": dict(TEST_CONVERGENCE), "runs": runs})
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
