"""The convergence criterion of a solve: the case's own ``SIMPLE.residualControl``, or ``--residual``.

``--residual 1e-4`` sets one threshold for every field the case solves (as its dry run names them: U,
p, k, epsilon...), ``--residual p=1e-3,U=1e-4`` thresholds for the named fields only. The criterion is
the one every run of the solve uses: the controlled run (the bridge writes it into the episode's SIMPLE),
the case's own run of ``--compare`` and of a fallback (:func:`write_criterion` on their copies: runs
with different criteria are not comparable) and the output case, whose fvSolution carries it, so that a
plain ``simpleFoam`` restart of it stops where solve's did.

A case without residualControl whose controlDict has a ``runTimeControl`` function object that ends the
run (``satisfiedAction end``, its default) has a criterion of its own: that function object. Its runs
then have no residual criterion (every field's threshold is NEVER_CONVERGED, so the bridge never
reports a residual convergence) and end when it says so (foam_bridge._env.CASE_STOP).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from foam_bridge import CASE_STOP, NEVER_CONVERGED
from jaxsimrl.runs.atomic import atomic_write_text

#: Where the criterion came from, as the report says it.
FROM_CASE = "the case's residualControl"
FROM_FLAG = "--residual"
FROM_STOP = "the case's runTimeControl function objects: it has no residualControl"
#: The scratch entry that carries the case's SIMPLE across its #overwrite (removed after).
_SCRATCH = "jaxsimrlCaseSIMPLE"

Residual = float | Mapping[str, float]


def parse_residual(text: str) -> Residual:
    """``--residual``'s value: a threshold (``1e-4``) or ``FIELD=THRESHOLD`` pairs (``p=1e-3,U=1e-4``);
    a one-line ValueError otherwise."""
    if "=" not in text:
        return _threshold(text, "--residual")
    pairs: dict[str, float] = {}
    for item in text.split(","):
        name, _, value = item.partition("=")
        name = name.strip()
        if not name or not name.replace("_", "").isalnum() or name in pairs:
            raise ValueError(f"--residual {text}: expected a threshold (1e-4) or FIELD=THRESHOLD pairs "
                             f"separated by commas (p=1e-3,U=1e-4), each field once")
        pairs[name] = _threshold(value, f"--residual {name}")
    return pairs


def _threshold(text: str | float, what: str) -> float:
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: expected a threshold > 0 such as 1e-4, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{what}: expected a threshold > 0 such as 1e-4, got {text!r}")
    return value


def resolve(residual: Residual | str, solved: Sequence[str], case: Path) -> dict[str, float]:
    """{field: threshold} of ``residual`` (see :func:`parse_residual`; a string is parsed) for a case
    whose solved fields are ``solved`` (field names: U, p, k...); a one-line ValueError naming a field it
    does not solve."""
    if isinstance(residual, str):
        residual = parse_residual(residual)
    if not isinstance(residual, Mapping):
        threshold = _threshold(residual, "--residual")
        return {name: threshold for name in solved}
    unknown = [name for name in residual if name not in solved]
    if unknown:
        raise ValueError(f"--residual names {', '.join(unknown)}, which case {case} does not solve (it "
                         f"solves {', '.join(solved)})")
    if not residual:
        raise ValueError("--residual: no field given")
    return {name: _threshold(value, f"--residual {name}") for name, value in residual.items()}


def stopping_function_objects(controls: Mapping[str, Any]) -> list[str]:
    """The names of the runTimeControl function objects that end the run in an expanded controlDict."""
    functions = controls.get("functions")
    if not isinstance(functions, Mapping):
        return []
    return [name for name, entry in functions.items() if isinstance(entry, Mapping)
            and entry.get("type") == "runTimeControl" and entry.get("satisfiedAction", "end") == "end"]


def reported(convergence: Mapping[str, float]) -> dict[str, float]:
    """The criterion as the report gives it: none for a case that only its runTimeControl ends."""
    return {} if source_of(convergence, None) == FROM_STOP else dict(convergence)


def describe(criterion: Mapping[str, float], source: str) -> str:
    """The criterion as printed: its thresholds and where they came from (or only where, when none)."""
    return f"{dict(criterion)} ({source})" if criterion else source


def stop_only(solved: Sequence[str]) -> dict[str, float]:
    """The criterion of a case that only its runTimeControl ends: no field ever meets it."""
    return {name: NEVER_CONVERGED for name in solved}


def source_of(convergence: Mapping[str, float], residual: Residual | str | None) -> str:
    """Where a solve's criterion came from: FROM_FLAG, FROM_STOP or FROM_CASE."""
    if residual is not None:
        return FROM_FLAG
    return FROM_STOP if all(value == NEVER_CONVERGED for value in convergence.values()) else FROM_CASE


def criterion_text(criterion: Mapping[str, float]) -> str:
    """Entries for the end of an fvSolution that make ``criterion`` its SIMPLE.residualControl, whatever
    the case had there (``#overwrite``: merging would keep the case's other entries, its
    regular-expression keys included); the rest of SIMPLE stays the case's."""
    entries = "".join(f"        {name} {float(value)!r};\n" for name, value in criterion.items())
    return (f"\n// ----- jaxsimrl solve --residual: the convergence criterion (replaces the case's "
            f"SIMPLE.residualControl) -----\n"
            f"{_SCRATCH} {{ $SIMPLE; }}\n#overwrite SIMPLE\n{{\n    ${_SCRATCH};\n"
            f"    #remove residualControl\n    residualControl\n    {{\n{entries}    }}\n}}\n"
            f"#remove {_SCRATCH}\n")


def write_criterion(case: Path, criterion: Mapping[str, float]) -> None:
    """Make ``criterion`` the SIMPLE.residualControl of ``case``'s system/fvSolution (appended; the
    user's own text above it is kept as it was; written atomically)."""
    path = case / "system" / "fvSolution"
    atomic_write_text(path, path.read_text() + criterion_text(criterion))


def converged_by(run: Any, rescue: Any, criterion_from: str) -> str | None:
    """What ended the run whose fields ``out`` holds as converged (None if it did not converge): the
    controlled ``run`` (the criterion, ``criterion_from``; or the case's own function object,
    foam_bridge._env.CASE_STOP), or the case's own run ``rescue`` that replaced it."""
    if rescue is not None:
        return own_converged_by(rescue, criterion_from)
    if run.outcome != "converged":
        return None
    if run.cause.startswith(CASE_STOP):
        return run.cause.replace(CASE_STOP, "the case's function object", 1)
    confirmed = run.record is not None and run.record.confirmations
    return f"{criterion_from}, confirmed" if confirmed else criterion_from


def own_converged_by(own: Any, criterion_from: str) -> str | None:
    """What ended a run of the case with its own settings (jaxsimrl.apps.foam.solve.own.OwnRun) as
    converged."""
    if not own.converged:
        return None
    if own.stopped_by:
        return f"the case's function object {own.stopped_by} (runTimeControl)"
    return criterion_from
