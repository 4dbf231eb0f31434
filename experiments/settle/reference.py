# SPDX-License-Identifier: GPL-3.0-or-later
"""A reference run for issue 56: the case at its own settings with no criterion, to FACTOR x its budget.

    WM_PROJECT_DIR=/usr/share/openfoam .venv/bin/python experiments/settle/reference.py CASE \
        --out runs/settle-ref/NAME [--factor 2.5] [--json experiments/settle/references/NAME.json]

The case is copied; its SIMPLE.residualControl is emptied and its runTimeControl function objects disabled
(the run must not stop on them), its endTime moved to start + FACTOR x budget (budget: its own endTime minus
its start). The answer monitor (foam_bridge._answer_monitor) samples the solved fields every 5 iterations,
exactly as a settle run does, so the two runs' trajectories are the same iterations of the same solver: a
settle run that stops at iteration n has the error this run's fields have at n.

Kept on disk (``--out``, not committed): every sample as float32 (``samples/<field>.npy``, up to the
budget every 5 iterations, after it every 25) and the reference answer in float64 (``reference.npz``).
Written (``--json``, committed): per field and function-object value, the relative error of each sample
up to the budget from the reference answer; the reference's kind: "settled" where every field changes by
at most 1e-6 per 100 iterations at the end, else "oscillating", with the reference being the mean over
the run's last third and its half-range (the largest distance from that mean over the last third);
the iteration at which the case's own criterion was first met (None: never within the run); the solver
CPU to the budget and to the end.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from foam_bridge import (
    LogParser,
    copy_case,
    field_residual,
    find_openfoam,
    foamdict,
    run_application,
    solved_field_names,
)
from foam_bridge._answer_monitor import SAMPLE_INTERVAL, install_monitor
from foam_bridge._fields import read_internal_field, relative_l2, time_directories
from foam_bridge._function_objects import (
    TableReader,
    quantity_name,
    relative_difference,
    row_scale,
    time_series,
)

#: A field that moves more than this per 100 iterations at the end of the run is still moving.
STILL = 1e-6
#: After the budget, samples are kept every this many iterations.
LATE_STRIDE = 25


def case_facts(case: Path) -> dict:
    openfoam = find_openfoam()
    control = foamdict.expand(openfoam, case, "system/controlDict")
    solution = foamdict.expand(openfoam, case, "system/fvSolution")
    start = int(float(control.get("startTime", 0) or 0))
    budget = int(round((float(control["endTime"]) - start) / float(control.get("deltaT", 1))))
    simple = solution.get("SIMPLE", {}) or {}
    criterion = {k: float(v) for k, v in (simple.get("residualControl", {}) or {}).items()}
    functions = control.get("functions", {}) or {}
    stops = [name for name, body in functions.items()
             if isinstance(body, dict) and str(body.get("type", "")) == "runTimeControl"]
    return {"start": start, "budget": budget, "criterion": criterion, "run_time_controls": stops,
            "consistent": str(simple.get("consistent", "no")).lower() in ("yes", "true", "on")}


def copy_meshed(case: Path, dest: Path) -> None:
    copy_case(case, dest)
    if not (dest / "constant" / "polyMesh" / "boundary").is_file():
        run_application(find_openfoam(), "blockMesh", dest)


def solved_fields(case: Path, work: Path) -> list[str]:
    """The fields the case solves: one iteration of a scratch copy, its log read."""
    scratch = work / "probe"
    copy_meshed(case, scratch)
    with open(scratch / "system" / "controlDict", "a") as out:
        out.write("\nendTime 1;\nwriteControl timeStep;\nwriteInterval 100;\nfunctions {}\n")
    openfoam = find_openfoam()
    log = subprocess.run([openfoam.executable("simpleFoam"), "-case", str(scratch)], capture_output=True,
                         env=openfoam.environment(scratch), check=False).stdout
    parser = LogParser("", "")
    parser.feed(log)
    parser.finish()
    if not parser.history:
        raise SystemExit(f"{case}: simpleFoam ran no iteration: {log[-500:]!r}")
    return solved_field_names(tuple(parser.history[0]))


def prepare(case: Path, work: Path, factor: float) -> tuple[Path, dict, list[str]]:
    facts = case_facts(case)
    fields = solved_fields(case, work)
    run = work / "case"
    copy_meshed(case, run)
    end = facts["start"] + int(math.ceil(factor * facts["budget"]))
    extra = "".join(f"    {name} {{ enabled false; }}\n" for name in facts["run_time_controls"])
    with open(run / "system" / "controlDict", "a") as out:
        out.write(f"\n// ----- issue 56 reference run -----\nendTime {end};\n"
                  + (f"functions\n{{\n{extra}}}\n" if extra else ""))
    with open(run / "system" / "fvSolution", "a") as out:  # no criterion; the rest of SIMPLE the case's
        out.write("\nrefSIMPLE { $SIMPLE; }\n#overwrite SIMPLE\n{\n    $refSIMPLE;\n"
                  "    #remove residualControl\n}\n#remove refSIMPLE\n")
    install_monitor(run, fields)
    return run, {**facts, "end": end, "fields": fields}, fields


def run(run_dir: Path, facts: dict, samples: Path) -> dict:
    """simpleFoam to its end, every sample moved into ``samples`` as it comes (float32 stacks)."""
    openfoam = find_openfoam()
    start, budget, fields = facts["start"], facts["budget"], facts["fields"]
    parser = LogParser("", "", start=start)
    stacks: dict[str, list[np.ndarray]] = {name: [] for name in fields}
    iterations: list[int] = []
    log_path = run_dir / "log.simpleFoam"
    began = time.monotonic()
    with open(log_path, "wb") as log:
        process = subprocess.Popen([openfoam.executable("simpleFoam"), "-case", str(run_dir)], cwd=run_dir,
                                   env=openfoam.environment(run_dir), stdout=log, stderr=subprocess.STDOUT)
        offset, done = 0, False
        while not done:
            done = process.poll() is not None
            with open(log_path, "rb") as reader:
                reader.seek(offset)
                chunk = reader.read()
            offset += len(chunk)
            parser.feed(chunk)
            for value, directory in time_directories(run_dir):
                at = int(round(value)) - start
                if at <= 0 or (not done and at >= parser.iteration):
                    continue
                read = {name: read_internal_field(directory / name) for name in fields}
                full = (directory / "phi").exists()
                if not full:
                    shutil.rmtree(directory, ignore_errors=True)
                if any(v is None or v[1] for v in read.values()) or at in iterations:
                    continue
                arrays = {name: v[0] for name, v in read.items()}  # type: ignore[index]
                if at <= budget or at % LATE_STRIDE == 0:
                    iterations.append(at)
                    for name in fields:
                        stacks[name].append(arrays[name].astype(np.float32))
            if not done:
                time.sleep(0.2)
        parser.finish()
    wall = time.monotonic() - began
    samples.mkdir(parents=True, exist_ok=True)
    order = np.argsort(iterations)
    np.save(samples / "iterations.npy", np.asarray(iterations)[order])
    for name in fields:
        np.save(samples / f"{name}.npy", np.stack(stacks[name])[order])
    times = [float(t) for t in re.findall(rb"^ExecutionTime = ([0-9.eE+-]+) s", log_path.read_bytes(),
                                          re.MULTILINE)]
    return {"exit_code": process.returncode, "iterations": parser.completed, "wall_s": wall,
            "cpu_to_budget_s": times[budget - 1] if len(times) >= budget else None,
            "cpu_s": parser.execution_time, "history": parser.history,
            "error": parser.error}


def criterion_met(history: list[dict[str, float]], criterion: dict[str, float]) -> int | None:
    """The first iteration (1-based) at which every criterion field's initial residual is below its
    threshold (simpleFoam's residualControl), None if never."""
    if not criterion or not history:
        return None
    solved = solved_field_names(tuple(history[0]))
    thresholds = {}
    for key, value in criterion.items():  # a key may be a regular expression, "(k|epsilon|omega)"
        pattern = re.compile(key.strip('"'))
        thresholds.update({name: value for name in solved if pattern.fullmatch(name)})
    for index, row in enumerate(history):
        values = {name: field_residual(row, name) for name in thresholds}
        if all(v is not None and v < thresholds[name] for name, v in values.items()):
            return index + 1
    return None


def fields_reference(samples: Path, fields: list[str], budget: int, end: int) -> dict:
    its = np.load(samples / "iterations.npy")
    result: dict = {"iterations": [int(i) for i in its if i <= budget], "fields": {}}
    third = its >= end - (end - its[0]) / 3.0
    moving = False
    out = {}
    for name in fields:
        stack = np.load(samples / f"{name}.npy", mmap_mode="r")
        final = stack[-1].astype(np.float64)
        # the largest change within the last 100 iterations, against every sample there: samples every 25
        # (odd) iterations alternate the phase of a two-iteration cycle, which one lag of 100 would not see
        back = int(np.searchsorted(its, its[-1] - 100))
        per100 = max((relative_l2(final, stack[j].astype(np.float64)) or 0.0)
                     for j in range(back, len(its) - 1))
        moving = moving or per100 > STILL
        mean = stack[third].astype(np.float64).mean(axis=0)
        half = max(relative_l2(s.astype(np.float64), mean) or 0.0 for s in stack[third])
        out[name] = {"final": final, "mean": mean, "change_per_100": per100, "half_range": half}
    kind = "oscillating" if moving else "settled"
    arrays = {}
    for name, found in out.items():
        ref = found["mean"] if moving else found["final"]
        stack = np.load(samples / f"{name}.npy", mmap_mode="r")
        errors = [relative_l2(stack[i].astype(np.float64), ref) for i in range(len(its)) if its[i] <= budget]
        result["fields"][name] = {"change_per_100_at_end": found["change_per_100"],
                                  "half_range_last_third": found["half_range"], "errors": errors}
        arrays[name] = ref
    result["kind"] = kind
    np.savez_compressed(samples.parent / "reference.npz", **arrays)
    return result


def values_reference(case: Path, start: int, budget: int, end: int, kind: str) -> dict:
    """Every function-object value: its error at each iteration up to the budget (every 5th kept) from the
    reference (its final value, or its mean over the last third when the run oscillates)."""
    out = {}
    for key, path in time_series(case).items():
        if key.startswith("jaxsimrlSettle"):
            continue
        rows = TableReader(path).read()
        if not rows:
            continue
        series: dict[str, list[tuple[int, np.ndarray, float]]] = {}
        for time_value, row, columns in rows:
            floor = row_scale(list(columns.values()))
            for column, value in columns.items():
                series.setdefault(quantity_name(key, row, column), []).append(
                    (int(round(time_value)) - start, np.asarray(value, dtype=np.float64), floor))
        for name, points in series.items():
            its = np.asarray([p[0] for p in points])
            values = np.stack([p[1] for p in points])
            third = its >= end - (end - start) / 3.0
            mean = values[third].mean(axis=0)
            ref = values[-1] if kind == "settled" else mean
            floor = points[-1][2]
            half = max(relative_difference(v, mean, floor) for v in values[third])
            errors = [relative_difference(v, ref, floor) for it, v in zip(its, values, strict=True)
                      if it <= budget and it % SAMPLE_INTERVAL == 0]
            out[name] = {"half_range_last_third": half, "errors": errors,
                         "reference": ref.tolist(), "floor": floor}
    return out


def recompute(out: Path) -> tuple[Path, dict, dict, list[str]]:
    """What ``run`` returned, from the run's files (its reference.json, log and samples)."""
    old = json.loads((out / "reference.json").read_text())
    facts = {k: old[k] for k in ("start", "budget", "end", "criterion", "consistent", "run_time_controls")}
    facts["fields"] = list(old["fields"])  # the per-field entries name them
    parser = LogParser("", "", start=facts["start"])
    parser.feed((out / "case" / "log.simpleFoam").read_bytes())
    parser.finish()
    ran = {k: old[k if k != "iterations" else "iterations_run"] for k in (
        "exit_code", "error", "iterations", "cpu_to_budget_s", "cpu_s", "wall_s")}
    return out / "case", {**ran, "history": parser.history}, facts, facts["fields"]


def _write(record: dict, args: argparse.Namespace) -> None:
    text = json.dumps(record, indent=1, default=float)
    (args.out / "reference.json").write_text(text)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(text)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("case", type=Path)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--json", type=Path)
    parser.add_argument("--factor", type=float, default=2.5)
    parser.add_argument("--recompute", action="store_true",
                        help="no run: the reference again from the samples and the log of --out's run")
    args = parser.parse_args()
    args.out = args.out.resolve()
    args.out.mkdir(parents=True, exist_ok=True)
    if args.recompute:
        run_dir, ran, facts, fields = recompute(args.out)
    else:
        run_dir, facts, fields = prepare(args.case.resolve(), args.out, args.factor)
        ran = run(run_dir, facts, args.out / "samples")
    met = criterion_met(ran["history"], facts["criterion"])
    if ran["exit_code"] != 0:  # no reference answer: the record says why (the fresh set's rule reads it)
        print(f"{args.case}: simpleFoam exited {ran['exit_code']}: {ran['error']}", file=sys.stderr)
        record = {"case": args.out.name if args.recompute else args.case.name, "kind": "crashed",
                  **{k: facts[k] for k in ("start", "budget", "end", "criterion", "consistent")},
                  "criterion_met_at": met, "met_within_budget": met is not None and met <= facts["budget"],
                  "exit_code": ran["exit_code"], "error": ran["error"], "iterations_run": ran["iterations"],
                  "cpu_to_budget_s": ran["cpu_to_budget_s"], "cpu_s": ran["cpu_s"]}
        _write(record, args)
        return
    reference = fields_reference(args.out / "samples", fields, facts["budget"], facts["end"] - facts["start"])
    values = values_reference(run_dir, facts["start"], facts["budget"], facts["end"], reference["kind"])
    name = args.out.name if args.recompute else args.case.name
    record = {"case": name, "source": str(args.case), **{k: facts[k] for k in (
        "start", "budget", "end", "criterion", "consistent", "fields", "run_time_controls")},
        "criterion_met_at": met, "met_within_budget": met is not None and met <= facts["budget"],
        "exit_code": ran["exit_code"], "error": ran["error"], "iterations_run": ran["iterations"],
        "cpu_to_budget_s": ran["cpu_to_budget_s"], "cpu_s": ran["cpu_s"], "wall_s": ran["wall_s"],
        "cells": int(np.load(args.out / "samples" / f"{fields[0]}.npy", mmap_mode="r").shape[1]),
        "sample_interval": SAMPLE_INTERVAL, "date": time.strftime("%Y-%m-%d"),
        **reference, "values": values}
    _write(record, args)
    print(f"{args.case.name}: {reference['kind']}, criterion met at {met}, cpu to budget "
          f"{ran['cpu_to_budget_s']}, {ran['iterations']} iterations")


if __name__ == "__main__":
    main()
