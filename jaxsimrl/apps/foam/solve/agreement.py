"""Whether the controller's converged result is the same answer as another run's (``solve --compare``).

Two runs of one case that both met its ``residualControl`` are both "converged", yet they stop at
different points near the discrete solution: a normalised initial residual below r bounds the last
change per iteration, not the distance to the solution, and a run that contracts slowly (low factors)
stops farther from it (foam_bridge._fields). So the question is not "are they equal" but "do they differ
by more than two runs converged to this criterion at the case's own pace differ". :func:`compare_results`
answers it for every field the case solves and every function object's final values.

Measures (the other run, the case's own or the constant one, is the reference b; the controller's is a):

- fields: ``||a - b|| / ||b||`` over the internal field, all cells and components (cells unweighted, as
  foam_bridge._fields.relative_l2); a uniform field is broadcast to the other's cells.
- function objects: every value (a number, or a vector as a whole, as for the fields) of the rows of the
  final time of each time series under ``postProcessing/`` (forces, coefficients, probes, fieldMinMax,
  surfaceFieldValue...; read and named by foam_bridge's function-object reader, ``<object>/<file> [row]
  column``): ``|a - b| / max(|b|, 1e-3 x the row's largest |value|)``. The floor keeps a
  value that is noise next to its row (a side-force coefficient of 1e-24 in a 2D case) from turning
  round-off into a huge relative difference; it is small so that a drag coefficient 100x below the lift
  is still measured against itself. Left out: outputs that are not results (residuals,
  timing), discrete columns (where a minimum sits), files that are not time series
  (VTK streamlines, sampled sets).

Tolerance, from r = the loosest threshold of the case's residualControl (the equation that stops last
sets how far the coupled fields are from the solution): fields ``FIELD_FACTOR x r``, function objects
``FUNCTION_OBJECT_FACTOR x r``. Measured on pitzDaily (benchmarks/bench_agreement.py; p 1e-2, U and
k/epsilon 1e-3, and all 10x tighter), each run against a reference 100x tighter (2000 iterations, where
controller and own agree to 4e-5): the controller's and the own run's fields stop 1.0-1.9 r from the
solution at both criteria (the distance scales with r), a slow constant run (0.7/0.5/0.7, 3-4x the
iterations) 3.7-7.5 r, own runs converged to a 3x and a 10x looser criterion 3.6 r and 10.8 r. So two
runs at the case's own pace differ by at most ~4 r (measured: 1.5-1.6 r), and a run stopped at a 10x
looser criterion by ~10 r (measured: 10.0 r): 5 r separates them. Function objects move more than field
norms between the same two runs (a wall's pressure force, a probe near the outlet where p is small):
controller against own 4.8 r at the tutorial's criterion and 8.1 r at 10x tighter, the 10x looser run
26 r, hence 10 r. A value that is a small difference of large contributions (the pressure moment of two
opposite walls: 5.4 r and 30 r) can differ by more than that between any two converged runs: a flag then
says that it is not settled at this criterion, in either run. The rule is calibrated on one case; on T3A
(benchmarks/RESULTS_solve.md) the transition model's ReThetat stays 150-210 r from the solution in both
runs at its criterion, and the two differ by 70 r: flagged, rightly, though the controller's is the closer
one. Only runs that both converged are compared.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from foam_bridge import FunctionObjectTable as Table
from foam_bridge import (
    final_rows,
    latest_time,
    quantity_name,
    read_internal_field,
    relative_difference,
    relative_l2,
    row_scale,
    time_series,
)

#: Tolerances: these factors x the case's loosest residualControl threshold (see the module docstring).
FIELD_FACTOR = 5.0
FUNCTION_OBJECT_FACTOR = 10.0
def tolerances(criterion: Mapping[str, float]) -> tuple[float, float]:
    """(fields', function objects') agreement tolerance of a case with this residualControl ({field:
    threshold})."""
    loosest = max(criterion.values())
    return FIELD_FACTOR * loosest, FUNCTION_OBJECT_FACTOR * loosest


def compare_results(ours: Path, theirs: Path, fields: Sequence[str], criterion: Mapping[str, float],
                    converged: tuple[bool, bool], label: str = "own", same_run: bool = False,
                    spread: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """solve.json's ``compare.<label>.agreement``: the controller's case ``ours`` (its latest time
    directory) against the ``label`` run's case ``theirs``; ``fields``: the case's solved fields;
    ``converged``: (ours, theirs). With a run that did not converge there is no figure, only the reason.
    ``same_run``: ``ours`` holds that run's result (the controller did not apply, or failed): the
    comparison is exact by construction, and says so. ``spread``: :func:`measure_spread`'s result, how far
    two legitimate runs of the case end apart; each quantity then agrees within the larger of its
    tolerance and its spread (``allowed``)."""
    if not all(converged):
        who = [name for name, done in zip(_runs(label), converged, strict=True) if not done]
        who = [f"the {label} run (the controller's result is its)"] if same_run else who
        return {"agree": None, "reason": f"{' and '.join(who)} did not converge",
                "same_run": same_run}
    if not criterion:  # converged by the case's own function objects (runTimeControl): no threshold
        return {"agree": None, "reason": "the case has no residual criterion to derive a tolerance from (its "
                                         "function objects ended the runs)", "same_run": same_run}
    for_fields, for_objects = tolerances(criterion)
    measured = spread if spread is not None and spread.get("measured") else None
    spread_of = {kind: (measured or {}).get(kind, {}) for kind in ("fields", "function_objects")}
    entries = {name: _entry(value, for_fields, note, spread_of["fields"].get(name)) for name, (value, note)
               in ((name, field_difference(ours, theirs, name, label)) for name in fields)}
    objects, notes = function_object_differences(ours, theirs, label)
    quantities = {name: _entry(value, for_objects, spread=spread_of["function_objects"].get(name))
                  for name, value in objects.items()}
    notes += [f"field {name}: {entry['note']}" for name, entry in entries.items() if "note" in entry]
    agree = all(entry["ok"] is True for entry in (*entries.values(), *quantities.values()))
    rule = (f"fields {FIELD_FACTOR:g}, function objects {FUNCTION_OBJECT_FACTOR:g} x the loosest "
            f"residualControl threshold ({max(criterion.values()):g})")
    return {"agree": agree, "tolerance": {"fields": for_fields, "function_objects": for_objects},
            "rule": rule + (", or the spread of two legitimate runs where larger" if measured else ""),
            "fields": entries, "function_objects": quantities, "notes": notes, "same_run": same_run}


def _runs(label: str) -> tuple[str, str]:
    return "the controller's run", f"the {label} run"


def _entry(value: float | None, tol: float, note: str = "", spread: float | None = None) -> dict[str, Any]:
    """One quantity's verdict: within ``tol``, or within ``spread`` (how far two legitimate runs of the case
    end apart in it) where that is larger."""
    allowed = tol if spread is None or not math.isfinite(spread) else max(tol, spread)
    entry: dict[str, Any] = {"value": value, "tolerance": tol,
                             "ok": None if value is None else value <= allowed}
    if spread is not None:
        entry.update(spread=spread, allowed=allowed)
    return {**entry, "note": note} if note else entry


def measure_spread(own: Path, nudged: Path, fields: Sequence[str], criterion: Mapping[str, float],
                   converged: tuple[bool, bool], nudge: str) -> dict[str, Any]:
    """How far two legitimate runs of the case end apart at its criterion: its own run (``own``) and one at
    its own factors with alpha_u a little off (``nudged``; ``nudge`` says how, "alpha_u 0.85"), per field and
    function-object value, measured as :func:`compare_results` measures; ``settled``: every field's spread
    within the larger of its tolerance and SETTLED (the criterion fixes the answer to what an engineer
    calls the same). Neither run
    is better: the spread is what the criterion leaves open. Not measured (``measured`` False, ``reason``)
    when either run did not converge or the case has no residual criterion."""
    base = {"nudge": nudge, "converged": list(converged)}
    if not all(converged) or not criterion:
        why = "a run did not converge" if not all(converged) else "the case has no residual criterion"
        return {**base, "measured": False, "reason": why}
    for_fields, for_objects = tolerances(criterion)
    values = {name: field_difference(nudged, own, name)[0] for name in fields}
    objects, _ = function_object_differences(nudged, own)
    entries = {"fields": {k: v for k, v in values.items() if v is not None}, "function_objects": objects}
    # the fields decide: a function-object value can be noise around zero in any two runs (a 2-D case's
    # side-force bins: simpleCar's CsBin 1,100 % apart), which says nothing of the flow
    settled = all(v <= max(for_fields, SETTLED) for v in entries["fields"].values())
    return {**base, "measured": True, **entries, "settled": settled}


#: What a CFD engineer calls settled: two legitimate runs within this relative difference.
SETTLED = 0.01


def spread_line(spread: Mapping[str, Any], criterion: Mapping[str, float]) -> str:
    """The summary's words on the spread: whether the criterion fixes the answer, and if not, a criterion
    that would (assuming the spread scales with the threshold, as the distance to the solution did on
    pitzDaily: benchmarks/bench_agreement.py)."""
    if not spread.get("measured"):
        return f"spread not measured ({spread.get('nudge')}): {spread.get('reason')}"
    worst = sorted(((v, k) for k, v in spread["fields"].items() if math.isfinite(v) and v > 0), reverse=True)
    if not worst:
        return f"the criterion fixes the answer: the own run and one at {spread['nudge']} end identical"
    named = ", ".join(f"{name} {100 * value:.2g} %" for value, name in worst[:3])
    if spread["settled"]:
        return (f"the criterion fixes the answer: the own run and one at {spread['nudge']} end {named} apart "
                f"at most")
    tighter = tighter_criterion(max(criterion.values()), worst[0][0], SETTLED)
    return (f"the criterion leaves the answer uncertain: runs at your own factors and at {spread['nudge']} "
            f"both meet it but end {named} apart; a criterion of about {tighter:.0e} (--residual) would "
            f"bring that to ~{100 * SETTLED:g} %")


def tighter_criterion(loosest: float, error: float, target: float) -> float:
    """The residual threshold, a power of ten, that would bring an ``error`` reached at the ``loosest``
    threshold down to ``target``, assuming the error scales with the threshold (as the distance to the
    solution did on pitzDaily: benchmarks/bench_agreement.py)."""
    needed = loosest * target / error
    return 10.0 ** math.floor(math.log10(needed)) if needed > 0 else loosest / 100


def read_internal(path: Path) -> tuple[np.ndarray, bool] | None:
    """(internal field, uniform?) of one field file (foam_bridge's reader: ascii or binary, ``path`` or
    ``path.gz``); None if it is missing or unreadable. A uniform field comes back as its one value."""
    return read_internal_field(path)


def field_difference(ours: Path, theirs: Path, name: str, label: str = "own") -> tuple[float | None, str]:
    """(relative L2 difference of field ``name`` between the two cases' final times, note); the value is
    None, with the reason in the note, when either run lacks a readable field."""
    read = [read_internal(time / name) if time is not None else None
            for time in (latest_time(ours), latest_time(theirs))]
    missing = [who for who, field in zip(_runs(label), read, strict=True) if field is None]
    if missing:
        return None, f"missing or unreadable in {' and '.join(missing)}"
    (a, a_uniform), (b, b_uniform) = read  # type: ignore[misc]
    a = np.broadcast_to(a, b.shape) if a_uniform and not b_uniform else a
    b = np.broadcast_to(b, a.shape) if b_uniform and not a_uniform else b
    if a.shape != b.shape:
        return None, f"shapes differ ({a.shape} against {b.shape})"
    value = relative_l2(a, b)
    if value is None:  # a zero reference: equal only if both are zero
        value = 0.0 if not np.any(a) else math.inf
    return value, ""


def function_object_differences(ours: Path, theirs: Path, label: str = "own") -> tuple[dict[str, float],
                                                                                       list[str]]:
    """({quantity: relative difference} over the function objects' final values, notes on the files that
    could not be compared); see the module docstring for the measure."""
    files = (time_series(ours), time_series(theirs))
    values: dict[str, float] = {}
    notes: list[str] = []
    for key in sorted(files[0].keys() | files[1].keys()):
        a, b = (final_rows(found[key]) if key in found else None for found in files)
        if a is None and b is None:
            continue  # not a time series in either run (VTK streamlines, sampled sets)
        if a is None or b is None:
            notes.append(f"{key}: a time series in {_runs(label)[a is None]} only, not compared")
        elif _layout(a) != _layout(b):
            notes.append(f"{key}: different rows or columns in the two runs, not compared")
        else:
            values.update(_table_differences(key, a, b))
    return values, notes


def _layout(table: Table) -> dict[str, list[str]]:
    return {row: sorted(columns) for row, columns in table.items()}


def _table_differences(key: str, ours: Table, theirs: Table) -> dict[str, float]:
    values = {}
    for row, columns in theirs.items():
        scale = row_scale([*columns.values(), *ours[row].values()])
        for column, reference in columns.items():
            values[quantity_name(key, row, column)] = relative_difference(ours[row][column], reference, scale)
    return values


def summary_line(label: str, agreement: Mapping[str, Any]) -> str:
    """The printed line: agreement with the worst field and function-object value, or the worst
    offenders, or why there is no figure."""
    if agreement.get("agree") is None:
        return f"no agreement figure with {label}: {agreement['reason']}"
    tol = agreement["tolerance"]
    fields, objects = agreement["fields"], agreement["function_objects"]
    measured = (f"{_measured('fields max rel. L2', fields, tol['fields'])}; "
                + (_measured("function objects max", objects, tol["function_objects"]) if objects else
                   "no function-object values"))
    if agreement["agree"]:
        same = " (the same run: the controller's result is this run's)" if agreement.get("same_run") else ""
        return f"results agree with {label}{same}: {measured}"
    offenders = [(name, entry) for name, entry in (*fields.items(), *objects.items())
                 if entry["ok"] is not True]
    # worst first; a quantity one run lacks ("not compared") before any measured one
    offenders.sort(key=lambda item: -math.inf if item[1]["value"] is None else -item[1]["value"])
    named = ", ".join(f"{name} {_value(entry['value'])}" for name, entry in offenders[:3])
    more = f" and {len(offenders) - 3} more" if len(offenders) > 3 else ""
    return f"results DIFFER from {label}: {named}{more}; {measured}"


def _measured(what: str, entries: Mapping[str, Mapping[str, Any]], tol: float) -> str:
    """"<what> <the largest value> (<its name>) <= tol <tol>" ("> tol" above it)."""
    measured = [(entry["value"], name) for name, entry in entries.items() if entry["value"] is not None]
    if not measured:
        return f"{what}: none measured"
    value, name = max(measured, key=lambda pair: pair[0])  # the first of equal ones
    return f"{what} {_value(value)} ({name}) {'<=' if value <= tol else '>'} tol {tol:.0e}"


def _value(value: float | None) -> str:
    return "not compared" if value is None else f"{value:.1e}"
