# SPDX-License-Identifier: GPL-3.0-or-later
"""Issue 47's final evaluation: a learned controller (its pinned checkpoints, one per seed of the recipe)
on heldout-v2 and the solve benchmark's tutorials, beside what a user has without it. Run once, after the
checkpoints and the seed were chosen on validation (validate.py); every case is reported.

    WM_PROJECT_DIR=/usr/share/openfoam .venv/bin/python \\
        experiments/controller/generated-v1-setup/evaluate.py \\
        runs/heldout-v2 --set experiments/controller/heldout-v2/heldout.json \\
        --policy runs/generated-v1-s0-pinned/uN [--policy ...] --out DIR
    .venv/bin/python experiments/controller/generated-v1-setup/evaluate.py runs/tutorials --tutorials ...

Streams started on the same set (one per core) share its cases out one by one (DIR/rows.claims; a stream
killed mid-case leaves its claim: delete the file to rerun what is missing); ``--cases`` restricts a
stream to some cases;
``--learned-only`` runs only the policies' pairs, into learned-rows.jsonl (a seed trained later, beside the
baselines already measured); with no ``--policy`` only the baselines run (while the policies are still being
chosen: nothing in them depends on a policy).

Per case, on its own mesh, criterion and budget:

- ``learned``: ``jaxsimrl solve --policy P`` for each policy, each paired with an own run made just before
  it (solver CPU moves with the machine's load: the ratio is within the pair);
- beside it, once each: the ``bandit``, the ``residual-rule`` and ``random`` through solve; the generated
  family's best constant for the case's algorithm (``GENERATED_CONSTANT``, a plain run); the per-case
  ``oracle``: the best of the constant grid of the resolution check (rank.py's GRID) on the case itself,
  with what the grid cost.

One JSON line per case in DIR/rows.jsonl, appended as each finishes; a rerun skips the cases it holds.
"""

from __future__ import annotations

import argparse
import fcntl
import importlib.util
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

from jaxsimrl.apps.foam.solve import solve_case
from jaxsimrl.apps.foam.solve.own import run_own
from jaxsimrl.apps.foam.solve.settings import read_case_settings

HERE = Path(__file__).resolve().parent
TIMEOUT_S = 3600.0
#: The generated family's best constant per algorithm, from the full-size runs of the resolution check
#: (experiments/controller/generated-ranking/: 10 generated cases, lowest median iterations over own):
#: plain SIMPLE (0.7, 0.3, 0.7), 1.00x (alpha_u 0.9 converged none of six); SIMPLEC (0.95, 1, 0.95), 0.80x.
GENERATED_CONSTANT = {"SIMPLE": (0.7, 0.3, 0.7), "SIMPLEC": (0.95, 1.0, 0.95)}
RULES = ("bandit", "residual-rule", "random")


def _module(path: Path, name: str) -> Any:
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


GRID = _module(HERE.parent / "generated-ranking" / "rank.py", "rank").GRID
SAFETY = _module(HERE.parents[1] / "solve-safety" / "evaluate.py", "safety_evaluate")  # the case sets


def solved(case: Path, out: Path, **how: Any) -> dict[str, Any]:
    """One ``solve``: iterations, solver CPU s, converged, where its fields came from."""
    result = solve_case(case, out, step_timeout_s=900, spread=False, **how).data["result"]
    return {"converged": result["converged"], "iterations": result["iterations"],
            "cpu_s": round(result["solver_cpu_time_s"], 2), "fields_from": result["fields_from"]}


def plain(case: Path, out: Path, factors: tuple[float, ...] | None) -> dict[str, Any]:
    """One plain simpleFoam run (the case's own factors where ``factors`` is None)."""
    run = run_own(case, out, "plain", TIMEOUT_S, factors=factors)
    return {"converged": run.converged, "iterations": run.iterations, "cpu_s": round(run.cpu_time_s, 2)}


def oracle(case: Path, scratch: Path, algorithm: str) -> dict[str, Any]:
    """The best converged constant of the grid on the case itself, and what finding it cost."""
    runs = {",".join(f"{f:g}" for f in factors): plain(case, scratch / f"grid-{k}", factors)
            for k, factors in enumerate(GRID[algorithm])}
    done = {name: run for name, run in runs.items() if run["converged"]}
    best = min(done, key=lambda name: done[name]["iterations"]) if done else None
    return {"best": best, **(done[best] if best else {"converged": False}),
            "grid_iterations": sum(run["iterations"] for run in runs.values()),
            "grid_cpu_s": round(sum(run["cpu_s"] for run in runs.values()), 2), "grid": runs}


def learned(case: Path, scratch: Path, policies: list[Path]) -> dict[str, Any]:
    """Each policy's solve, paired with an own run made just before it."""
    runs = {}
    for k, policy in enumerate(policies):
        own = plain(case, scratch / f"own-{k}", None)
        ours = solved(case, scratch / f"learned-{k}", policy=policy)
        ratios = {"iterations_vs_own": round(ours["iterations"] / own["iterations"], 3),
                  "cpu_vs_own": round(ours["cpu_s"] / own["cpu_s"], 3)}
        runs[str(policy)] = {**ours, "own": own, **ratios}
    return runs


def evaluate(case: Path, policies: list[Path], learned_only: bool) -> dict[str, Any]:
    algorithm = read_case_settings(case).variant
    with tempfile.TemporaryDirectory(prefix=f"learned-{case.name}-") as scratch_dir:
        scratch = Path(scratch_dir)
        row: dict[str, Any] = {"case": case.name, "algorithm": algorithm,
                               "learned": learned(case, scratch, policies)}
        if learned_only:
            return row
        for rule in RULES:
            own = plain(case, scratch / f"own-{rule}", None)
            row[rule] = {**solved(case, scratch / rule, rule=rule), "own": own}
        row["constant"] = {"factors": GENERATED_CONSTANT[algorithm],
                           **plain(case, scratch / "constant", GENERATED_CONSTANT[algorithm])}
        row["oracle"] = oracle(case, scratch, algorithm)
    return row


def claim(path: Path, names: list[str]) -> str | None:
    """The first of ``names`` neither in ``path`` nor claimed by another stream, claimed now (in
    PATH.claims, under a lock): streams started on the same list share it out case by case."""
    claims = path.with_suffix(".claims")
    with claims.open("a+") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        handle.seek(0)
        taken = set(handle.read().split())
        if path.exists():
            taken |= {json.loads(line)["case"] for line in path.read_text().splitlines()}
        name = next((n for n in names if n not in taken), None)
        if name is not None:
            handle.write(name + "\n")
    return name


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    SAFETY.add_case_set(parser)
    parser.add_argument("--policy", type=Path, action="append", default=[],
                        help="a pinned checkpoint's run directory (one per seed; none: the baselines only)")
    parser.add_argument("--cases", dest="only", nargs="+",
                        help="these cases only (streams on one set share its cases without it)")
    parser.add_argument("--learned-only", action="store_true",
                        help="only the policies' paired runs, into learned-rows.jsonl (a later seed beside "
                             "baselines already measured; eval_table.py joins them)")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    if args.learned_only and not args.policy:
        parser.error("--learned-only needs a --policy")
    names = args.only or SAFETY.case_names(args)
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / ("learned-rows.jsonl" if args.learned_only else "rows.jsonl")
    while (name := claim(path, names)) is not None:
        row = evaluate(args.root / name, args.policy, args.learned_only)
        with path.open("a") as stream:  # whole lines: streams that share rows.jsonl take turns
            fcntl.flock(stream, fcntl.LOCK_EX)
            stream.write(json.dumps(row) + "\n")
        print(f"{name}: " + (", ".join(f"learned {r['iterations_vs_own']:.2f}x its {r['cpu_vs_own']:.2f}x CPU"
                                       for r in row["learned"].values()) or "baselines done"), flush=True)
    sys.exit(0)


if __name__ == "__main__":
    main()
