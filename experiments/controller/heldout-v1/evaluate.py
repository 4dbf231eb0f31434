# SPDX-License-Identifier: GPL-3.0-or-later
"""Issue 35's held-out evaluation: every case of the evaluation set (heldout.json, fixed on 2026-12-04
before any controller ran on it) under every controller the issue names, each on the case's own mesh,
criterion and budget, through ``jaxsimrl solve`` as a user runs it (its confirmation check and watchdog):

- ``learned``: the policy of RUN at its pinned ``--update``, with ``--compare`` (``own``: the case's own
  settings) and ``--compare-constant`` the training family's constant for the case's algorithm
  (``family-constant``: jaxsimrl.apps.foam.solve.settings.FAMILY_CONSTANT): three solvers side by side,
  so their wall times are not comparable (iterations are);
- ``residual-rule``, ``bandit``, ``random``: ``solve --controller NAME`` (constants frozen on 2026-12-03,
  the random draws seeded);
- ``oracle``: the best of the 8 constant triples of the case's algorithm (the family grid's,
  experiments/controller/family-constant/grid.py), each a plain run of the case with those factors, as
  ``--compare-constant`` runs one; its row carries the grid's cost, and every triple has a row too.

    WM_PROJECT_DIR=/usr/share/openfoam .venv/bin/python experiments/controller/heldout-v1/evaluate.py \\
        runs/heldout-v1 --policy experiments/controller/family-v7 --update N --out DIR [--cases NAME ...]

One JSON line per (case, controller) in DIR/rows.jsonl, appended as each finishes; a rerun skips the rows
it holds. ``--wall``: instead, for cases whose own run takes >= 20 s, the learned solve and the own run
alone, alternated, 3 times each (DIR/wall.jsonl): the wall ratio is a median of 3.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import statistics
import tempfile
from pathlib import Path

from jaxsimrl.apps.foam.solve import solve_case
from jaxsimrl.apps.foam.solve.own import run_own
from jaxsimrl.apps.foam.solve.settings import FAMILY_CONSTANT, read_case_settings
from jaxsimrl.policy import load_policy

HERE = Path(__file__).resolve().parent
GRID = HERE.parent / "family-constant" / "grid.py"
RULES = ("residual-rule", "bandit", "random")
WALL_MIN_S = 20.0
TIMEOUT_S = 3600.0


def _triples() -> dict[str, tuple[tuple[float, ...], ...]]:
    spec = importlib.util.spec_from_file_location("family_constant_grid", GRID)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.TRIPLES


def _solved(data: dict, controller: str, case: str) -> dict:
    result = data["result"]
    return {"case": case, "controller": controller, "converged": result["converged"],
            "iterations": result["iterations"], "fields_from": result["fields_from"],
            "fallback": [event["kind"] for event in data["fallback"]],
            "wall_s": round(result["wall_time_s"], 2)}


def _compared(data: dict, name: str, controller: str, case: str) -> dict:
    other = data["compare"][name]
    agreement = other.get("agreement", {})
    return {"case": case, "controller": controller, "converged": other["converged"],
            "iterations": other["iterations"], "wall_s": round(other["wall_time_s"], 2),
            "agrees_with_learned": agreement.get("agree"), "agreement_reason": agreement.get("reason")}


def evaluate_case(case: Path, policy: object, scratch: Path, done: set[str]) -> list[dict]:
    """The rows of every controller not in ``done`` on ``case``."""
    name, variant = case.name, read_case_settings(case).variant
    constant = list(FAMILY_CONSTANT[variant])
    rows = []
    if "learned" not in done:
        data = solve_case(case, scratch / "learned", policy=policy, compare=True, compare_constant=constant,
                          step_timeout_s=600).data
        rows += [_solved(data, "learned", name), _compared(data, "own", "own", name),
                 {**_compared(data, "constant", "family-constant", name), "factors": constant}]
    for rule in RULES:
        if rule not in done:
            data = solve_case(case, scratch / rule, rule=rule, step_timeout_s=600).data
            rows.append(_solved(data, rule, name))
    if "oracle" not in done:
        grid = [run_own(case, scratch / f"grid-{k}", "grid", TIMEOUT_S, factors=list(t))
                for k, t in enumerate(_triples()[variant])]
        cells = [{"case": name, "controller": "grid", "factors": list(t), "converged": run.converged,
                  "iterations": run.iterations, "wall_s": round(run.wall_time_s, 2)}
                 for t, run in zip(_triples()[variant], grid, strict=True)]
        best = min((c for c in cells if c["converged"]), key=lambda c: c["iterations"], default=None)
        cost = {"grid_runs": len(cells), "grid_iterations": sum(c["iterations"] for c in cells),
                "grid_wall_s": round(sum(c["wall_s"] for c in cells), 1)}
        rows += cells + [{"case": name, "controller": "oracle", "converged": best is not None,
                          "iterations": None if best is None else best["iterations"],
                          "factors": None if best is None else best["factors"], **cost}]
    return [{**row, "algorithm": variant} for row in rows]


def wall_case(case: Path, policy: object, scratch: Path) -> dict:
    """The learned solve alone and the own run alone, alternated, 3 times each."""
    pairs = []
    for k in range(3):
        learned = solve_case(case, scratch / f"wall-learned-{k}", policy=policy, step_timeout_s=600).data
        own = run_own(case, scratch / f"wall-own-{k}", "own", TIMEOUT_S)
        seconds = learned["result"]["wall_time_s"]
        pairs.append({"learned_s": round(seconds, 2), "own_s": round(own.wall_time_s, 2),
                      "ratio": round(seconds / own.wall_time_s, 3)})
    return {"case": case.name, "pairs": pairs, "median_ratio": statistics.median(p["ratio"] for p in pairs)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", type=Path, help="prepare.py's directory (runs/heldout-v1)")
    parser.add_argument("--policy", type=Path, required=True)
    parser.add_argument("--update", type=int, required=True, help="the pinned checkpoint")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--cases", dest="only", nargs="+", help="these cases only (default: the set)")
    parser.add_argument("--wall", action="store_true")
    args = parser.parse_args()
    listed = json.loads((HERE / "heldout.json").read_text())["cases"]
    names = args.only or [c["name"] for c in listed if c["in_evaluation"]]
    policy = load_policy(args.policy, args.update)
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / ("wall.jsonl" if args.wall else "rows.jsonl")
    held = [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []
    for name in names:
        own_s = next((c["wall_s"] for c in listed if c["name"] == name), None)
        if args.wall and (own_s is None or own_s < WALL_MIN_S or any(r["case"] == name for r in held)):
            continue
        with tempfile.TemporaryDirectory(prefix=f"heldout-{name}-") as scratch:
            done = {r["controller"] for r in held if r["case"] == name}
            rows = [wall_case(args.cases / name, policy, Path(scratch))] if args.wall else \
                evaluate_case(args.cases / name, policy, Path(scratch), done)
        with path.open("a") as stream:
            stream.writelines(json.dumps(row) + "\n" for row in rows)
        shown = [f"{r.get('controller', 'wall')} {r.get('iterations', r.get('median_ratio'))}"
                 for r in rows if r.get("controller") != "grid"]
        print(f"{name}: " + ", ".join(shown), flush=True)


if __name__ == "__main__":
    main()
