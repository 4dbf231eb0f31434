"""What ``solve`` says of the answer: settled, oscillating, converged or not, and how precise it is.

The answer monitor (foam_bridge's AnswerMonitor, in the case's own run: jaxsimrl.apps.foam.solve.own)
reports each monitored quantity's estimated iterative error and model; this module turns that into
solve.json's ``result`` keys and the summary's words:

- ``result.outcome``: "converged" (the criterion), "settled" (every quantity within the tolerance of where
  the run settles; the criterion not met), "oscillating" (an answer cycling or wandering about a steady
  mean: its error is half its range), or "not converged" (the budget, or a failure). Exit code 0 for
  converged or settled, 1 otherwise (``succeeded``).
- ``result.iterative_error``: {quantity: estimated relative error at the stop}: fields by their OpenFOAM
  names ("U", "p"), function-object values as solve's agreement names them (``<object>/<file> [row]
  column``); a field's at least the rounding of its written digits (foam_bridge's monitor report).
- ``result.residuals_not_met``: each criterion field whose initial residual never met its threshold, and
  the level where it held (the median over the run's last tenth).
"""

from __future__ import annotations

import statistics
from collections.abc import Mapping, Sequence
from typing import Any

from foam_bridge import field_residual
from jaxsimrl.apps.foam.solve.agreement import tighter_criterion

SETTLED, OSCILLATING = "settled", "oscillating"
#: Outcomes whose answer a user can take: exit code 0 (a campaign's rows too).
SUCCESS = ("converged", SETTLED)


def succeeded(result: Mapping[str, Any]) -> bool:
    """Converged by the criterion, or settled: the exit code is 0."""
    return bool(result.get("converged")) or result.get("outcome") == SETTLED


def answer_result(answer: Mapping[str, Any] | None, converged: bool, history: Sequence[Mapping[str, float]],
                  criterion: Mapping[str, float]) -> dict[str, Any]:
    """The ``result`` keys the answer monitor adds (none without a monitor): the outcome where it stopped
    the run, the iterative errors and the residuals that never met the criterion."""
    if answer is None:
        return {}
    keys: dict[str, Any] = {"iterative_error": dict(answer.get("iterative_error") or {}),
                            "residuals_not_met": residuals_not_met(history, criterion)}
    if answer.get("outcome") in (SETTLED, OSCILLATING) and not converged:
        keys["outcome"] = answer["outcome"]
    return keys


def residuals_not_met(history: Sequence[Mapping[str, float]], criterion: Mapping[str, float]
                      ) -> dict[str, dict[str, float]]:
    """{field: {"criterion": threshold, "held_at": median residual over the last tenth}} of each criterion
    field whose initial residual never fell below its threshold."""
    found = {}
    tail = max(1, len(history) // 10)
    for name, threshold in criterion.items():
        values = [field_residual(dict(row), name) for row in history]
        values = [v for v in values if v is not None]
        if values and min(values) >= threshold:
            found[name] = {"criterion": threshold, "held_at": statistics.median(values[-tail:])}
    return found


def answer_lines(data: Mapping[str, Any]) -> list[str]:
    """The summary's lines on the answer: its error, the models, what never met the criterion, and where the
    criterion stopped a run short of the tolerance, a --residual that would reach it."""
    answer, result = data.get("answer"), data["result"]
    if not answer:
        return []
    tol = float(answer["tolerance"])
    errors = {k: v for k, v in (result.get("iterative_error") or {}).items() if v is not None}
    lines = []
    if errors:
        worst = sorted(errors.items(), key=lambda item: -item[1])
        named = ", ".join(f"{name} {value:.1e}" for name, value in worst[:4])
        more = f" (+{len(worst) - 4} more)" if len(worst) > 4 else ""
        models = _models(answer.get("quantities") or {})
        lines.append(f"  iterative error (estimated, relative): {named}{more}; tolerance {tol:g}; {models}")
    else:
        lines.append(f"  iterative error: not estimated (the run's first {answer.get('min_history', 300)} "
                     f"iterations are its start-up, too early to extrapolate); tolerance {tol:g}")
    lines += [f"  note: {note}" for note in answer.get("notes", [])]
    unmet = result.get("residuals_not_met") or {}
    if unmet:
        lines.append("  residuals that never met the criterion: " + ", ".join(
            f"{name} held at {v['held_at']:.1e} (criterion {v['criterion']:g})" for name, v in unmet.items()))
    if result.get("converged") and errors and max(errors.values()) > tol:
        lines.append(f"  the criterion stopped the run {max(errors.values()):.1e} from where its answer "
                     f"settles ({max(errors, key=errors.get)}); "
                     + _tighter(data["settings"].get("criterion") or {}, max(errors.values()), tol))
    return lines


def _models(quantities: Mapping[str, Mapping[str, Any]]) -> str:
    counts: dict[str, int] = {}
    for entry in quantities.values():
        counts[entry["model"]] = counts.get(entry["model"], 0) + 1
    return ", ".join(f"{count} {model}" for model, count in sorted(counts.items(), key=lambda kv: -kv[1]))


def _tighter(criterion: Mapping[str, float], error: float, tol: float) -> str:
    """A --residual that would bring the answer within ``tol`` (agreement.tighter_criterion)."""
    if not criterion:
        return "the case has no residual criterion to tighten"
    tighter = tighter_criterion(max(criterion.values()), error, tol)
    return f"--residual {tighter:.0e} would bring it within {tol:g}"
