# SPDX-License-Identifier: GPL-3.0-or-later
"""Does a coarse generated case rank the factors as its full-size version does? (issue 47)

For each of N generated specs (foam_bridge's generator, a seed no training family uses) and each
resolution, every constant of the grid below runs once to its end with the case's own criterion and
budget (jaxsimrl.apps.foam.solve.own.run_own: plain simpleFoam, constant factors), two at a time. A row
per run goes to ``rows.jsonl`` as it finishes (a rerun skips the rows there: resumable); summary.py
turns them into the rankings' agreement.

    python experiments/controller/generated-ranking/rank.py --cases 8 --seed 4700 \\
        --resolutions 0.4 0.5 0.7 1.0 --work runs/generated-ranking
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

from foam_bridge import sample_specs, write_case
from jaxsimrl.apps.foam.solve.own import run_own

HERE = Path(__file__).resolve().parent
#: The grid of constants (alpha_u, alpha_p, turbulence) per algorithm, besides the case's own factors:
#: the training family's constant, the corners a controller's box reaches and points between (a SIMPLEC
#: case's alpha_u never below 0.8: below its own it is unstable, jaxsimrl.apps.foam.solve.settings).
GRID = {
    "SIMPLE": ((0.8, 0.3, 0.9), (0.7, 0.3, 0.7), (0.9, 0.2, 0.9), (0.9, 0.1, 0.95), (0.6, 0.4, 0.8),
               (0.5, 0.5, 0.5), (0.9, 0.3, 0.6)),
    "SIMPLEC": ((0.95, 1.0, 0.95), (0.9, 1.0, 0.9), (0.85, 1.0, 0.7), (0.95, 0.7, 0.95), (0.9, 0.8, 0.8),
                (0.95, 1.0, 0.6), (0.8, 1.0, 0.95)),
}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=8)
    parser.add_argument("--seed", type=int, default=4700)
    parser.add_argument("--resolutions", type=float, nargs="+", default=[0.4, 0.5, 0.7, 1.0])
    parser.add_argument("--work", type=Path, default=Path("runs/generated-ranking"))
    parser.add_argument("--out", type=Path, default=HERE / "rows.jsonl")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    args.work = args.work.resolve()  # simpleFoam runs with -case from inside the case
    done = _done(args.out)
    jobs = []
    for spec in sample_specs(args.cases, args.seed):
        for resolution in args.resolutions:
            case = args.work / f"{spec.name}-r{resolution:g}"
            if not case.is_dir():
                write_case(spec, case, resolution=resolution)
            for label, factors in [("own", None), *((_label(f), f) for f in GRID[spec.algorithm])]:
                if (spec.name, resolution, label) not in done:
                    jobs.append((spec, resolution, case, label, factors))
    print(f"{len(jobs)} runs to go ({len(done)} done)", flush=True)
    with ThreadPoolExecutor(args.workers) as pool:  # each run_own is its own simpleFoam process
        futures = [pool.submit(_run, args.work, *job) for job in jobs]
        for count, future in enumerate(as_completed(futures), 1):
            row = future.result()
            with args.out.open("a") as out:  # one line per run, appended whole
                out.write(json.dumps(row) + "\n")
            print(f"[{count}/{len(jobs)}] {row['case']} r{row['resolution']:g} {row['label']}: "
                  f"{'converged' if row['converged'] else 'NOT converged'} {row['iterations']} its "
                  f"{row['cpu_s']:.1f} s", flush=True)
    return 0


def _run(work: Path, spec, resolution: float, case: Path, label: str, factors) -> dict:
    dest = work / "runs" / f"{spec.name}-r{resolution:g}-{label}"
    shutil.rmtree(dest, ignore_errors=True)  # a run cut off by an earlier sitting
    own = run_own(case, dest, label, 3600.0, factors=factors)
    shutil.rmtree(dest, ignore_errors=True)  # its fields are not needed: the row holds what is
    return {"case": spec.name, "kind": spec.kind, "algorithm": spec.algorithm, "resolution": resolution,
            "label": label, "factors": None if factors is None else list(factors),
            "own_factors": dict(spec.factors), "converged": own.converged, "iterations": own.iterations,
            "cpu_s": own.cpu_time_s, "wall_s": own.wall_time_s, "error": own.error}


def _label(factors) -> str:
    return "c" + "-".join(f"{f:g}" for f in factors)


def _done(path: Path) -> set[tuple[str, float, str]]:
    if not path.is_file():
        return set()
    rows = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return {(row["case"], row["resolution"], row["label"]) for row in rows}


if __name__ == "__main__":
    sys.exit(main())
