# SPDX-License-Identifier: GPL-3.0-or-later
"""Validation of a controller trained on generated cases (issue 47): ``jaxsimrl solve`` with a checkpoint
on full-size generated cases of another seed (never a held-out case), beside the case's own run and the
online bandit. The checkpoint (and the seed of the recipe) to evaluate on heldout-v2 is chosen on these
numbers only.

    .venv/bin/python experiments/controller/generated-v1-setup/validate.py RUN runs/generated-val \\
        --out experiments/controller/generated-v1-setup/validation-s0.jsonl [--updates 20 40]

The baselines (each case's own settings, plain simpleFoam; the bandit through solve) run once per case and
are kept in ``--baselines`` (a JSON line per case and controller); a checkpoint is one JSON line of --out
(checkpoints already there are skipped): per case iterations, solver CPU seconds, where the fields came
from, and the ratios to own (iterations; CPU within a pair with an own run made just before it) and to
the bandit (CPU, each over its own pair's own run); their medians. A solve whose
controller gave way to the case's own run counts as it ran (its iterations and seconds in all).
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


def solved(case: Path, out: Path, **how) -> dict:
    """One solve of ``case``: iterations, solver CPU s, converged, where its fields came from."""
    report = solve_case(case, out, step_timeout_s=300, spread=False, **how)
    result = json.loads((out / "solve.json").read_text())["result"]
    return {"iterations": report.iterations, "cpu_s": result["solver_cpu_time_s"],
            "converged": result["converged"], "fields_from": result["fields_from"]}


def baselines(cases: list[Path], path: Path, scratch: Path) -> dict[str, dict[str, dict]]:
    """{case: {"own": ..., "bandit": ...}}, run where ``path`` does not hold them yet."""
    known: dict[str, dict[str, dict]] = {}
    for line in path.read_text().splitlines() if path.exists() else []:
        row = json.loads(line)
        known.setdefault(row["case"], {})[row["controller"]] = row
    for case in cases:
        for name in ("own", "bandit"):
            if name in known.get(case.name, {}):
                continue
            if name == "own":
                own = run_own(case, scratch / f"own-{case.name}", "own", 3600.0)
                row = {"iterations": own.iterations, "cpu_s": own.cpu_time_s, "converged": own.converged}
            else:
                row = solved(case, scratch / f"bandit-{case.name}", rule="bandit")
            row = {"case": case.name, "controller": name, **row}
            with path.open("a") as handle:
                handle.write(json.dumps(row) + "\n")
            known.setdefault(case.name, {})[name] = row
    return known


def validate(run: Path, update: int, cases: list[Path], base: dict, scratch: Path,
             kept: dict | None = None) -> dict:
    """One checkpoint on every validation case. CPU seconds move with the machine's load, so each learned
    solve is paired with an own run made just before it: its CPU ratio to own is within the pair, and its
    ratio to the bandit is that over the bandit's own ratio within its pair (the baselines'). ``kept``:
    rows of an earlier validation of this checkpoint to keep for the cases not in ``cases``."""
    policy = load_policy(run, update)
    rows = dict(kept or {})
    for case in cases:
        paired = run_own(case, scratch / f"u{update}-own-{case.name}", "own", 3600.0)
        row = solved(case, scratch / f"u{update}-{case.name}", policy=policy)
        own, bandit = base[case.name]["own"], base[case.name]["bandit"]
        cpu_vs_own = row["cpu_s"] / paired.cpu_time_s
        rows[case.name] = {**row, "own_cpu_s": paired.cpu_time_s, "cpu_vs_own": cpu_vs_own,
                           "iterations_vs_own": row["iterations"] / own["iterations"],
                           "cpu_vs_bandit": cpu_vs_own / (bandit["cpu_s"] / own["cpu_s"])}
    medians = {key: statistics.median(r[key] for r in rows.values())
               for key in ("iterations_vs_own", "cpu_vs_own", "cpu_vs_bandit")}
    return {"update": update, "time_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            "median": medians, "worst_iterations_vs_own": max(r["iterations_vs_own"] for r in rows.values()),
            "cases": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="a train-foam run directory (or a pinned copy); '-': the "
                        "baselines only")
    parser.add_argument("cases", type=Path, help="the validation cases' directory (jaxsimrl generate-cases)")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--baselines", type=Path,
                        default=Path(__file__).with_name("validation-baselines.jsonl"))
    parser.add_argument("--updates", type=int, nargs="*", help="checkpoints to validate (default: every one)")
    parser.add_argument("--rerun", nargs="+", metavar="CASE",
                        help="run only these cases again; the other cases' rows come from --earlier (solve's "
                             "watchdog stall window grew from 3 to 12 steps at interval 25: a run it never "
                             "handed back is the same run, so only the handed-back cases need running)")
    parser.add_argument("--earlier", type=Path, help="the validation file --rerun takes the other rows from")
    args = parser.parse_args()
    cases = sorted(p for p in args.cases.iterdir()
                   if not p.name.startswith(".") and (p / "system" / "controlDict").is_file())
    earlier = {json.loads(line)["update"]: json.loads(line)["cases"]
               for line in (args.earlier.read_text().splitlines() if args.earlier else [])}
    done = {json.loads(line)["update"] for line in (args.out.read_text().splitlines() if args.out.exists()
                                                     else [])}
    steps = [] if str(args.run) == "-" else args.updates or Checkpoints(args.run / "checkpoints",
                                                                          writable=False).steps()
    with tempfile.TemporaryDirectory(prefix="generated-validate-") as scratch:
        base = baselines(cases, args.baselines, Path(scratch))
        rerun = set(args.rerun or ())
        for update in (u for u in steps if u not in done):
            kept = {name: row for name, row in earlier.get(update, {}).items() if name not in rerun}
            line = validate(args.run, update, [c for c in cases if not kept or c.name in rerun], base,
                            Path(scratch), kept)
            if kept:
                line["rerun"] = sorted(rerun)
            with args.out.open("a") as handle:
                handle.write(json.dumps(line) + "\n")
            median = line["median"]
            print(f"update {update}: median {median['cpu_vs_own']:.2f}x own CPU, "
                  f"{median['cpu_vs_bandit']:.2f}x bandit CPU, {median['iterations_vs_own']:.2f}x own "
                  f"iterations (worst "
                  f"{line['worst_iterations_vs_own']:.2f})", flush=True)


if __name__ == "__main__":
    main()
