"""Validation of a train-foam --family run's checkpoints: ``jaxsimrl solve`` with each on validation
variants of the TRAINING bases (never a held-out case), against each case's own settings. The checkpoint to
ship is chosen on these numbers, so that the held-out cases stay unseen until the final evaluation.

    .venv/bin/python experiments/controller/family-v1-setup/validate.py experiments/controller/family-v1 \\
        runs/family-val --out experiments/controller/family-v1-setup/validation.jsonl

The validation family: ``run.sh``'s bases, one variant each, other seeds (5 and 6). One JSON line per
checkpoint is appended to --out (checkpoints already in it are skipped): per case the controlled
iterations, where the result's fields came from, the own run's iterations, and their ratio; and the median
ratio. A solve whose controller failed (its fields from the own run) counts at its budget / own.
"""

from __future__ import annotations

import argparse
import datetime
import json
import statistics
import tempfile
from pathlib import Path

from jaxsimrl.apps.foam.solve import solve_case
from jaxsimrl.apps.foam.solve.own import run_own
from jaxsimrl.policy import load_policy
from jaxsimrl.runs.checkpoint import Checkpoints


def own_iterations(cases: list[Path], scratch: Path) -> dict[str, int]:
    """Each case's own settings' iterations (to its criterion, or as far as its endTime)."""
    return {case.name: run_own(case, scratch / f"own-{case.name}", "own", 3600.0).iterations
            for case in cases}


def validate(run: Path, update: int, cases: list[Path], own: dict[str, int], scratch: Path) -> dict:
    """One checkpoint on every validation case."""
    policy = load_policy(run, update)
    rows = {}
    for case in cases:
        out = scratch / f"u{update}-{case.name}"
        report = solve_case(case, out, policy=policy, step_timeout_s=300)
        data = json.loads((out / "solve.json").read_text())
        fields_from = data["result"]["fields_from"]
        failed = not fields_from.startswith("the controller")
        counted = data["settings"]["max_iterations"] if failed else report.iterations
        rows[case.name] = {"iterations": report.iterations, "converged": report.converged,
                           "fields_from": fields_from, "own": own[case.name],
                           "ratio": counted / own[case.name]}
    return {"update": update, "time_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            "median_ratio": statistics.median(row["ratio"] for row in rows.values()), "cases": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path)
    parser.add_argument("cases", type=Path, help="the validation family's directory")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    cases = sorted(p for p in args.cases.iterdir() if (p / "system" / "controlDict").is_file())
    lines = args.out.read_text().splitlines() if args.out.exists() else []
    done = {json.loads(line)["update"] for line in lines}
    updates = [u for u in Checkpoints(args.run / "checkpoints", writable=False).steps() if u not in done]
    with tempfile.TemporaryDirectory(prefix="family-validate-") as scratch:
        own = own_iterations(cases, Path(scratch))
        for update in updates:
            line = validate(args.run, update, cases, own, Path(scratch))
            with args.out.open("a") as handle:
                handle.write(json.dumps(line) + "\n")
            print(f"update {update}: median {line['median_ratio']:.2f}x own; " + ", ".join(
                f"{name} {row['ratio']:.2f}" for name, row in line["cases"].items()), flush=True)


if __name__ == "__main__":
    main()
