"""Lean linear solves: the cost lever of ``solve``'s default that leaves the answer where it was.

SIMPLE solves each equation only part of the way in every outer iteration (``relTol``: the linear
solver stops once its residual fell by that factor): the outer iterations converge to the same discrete
solution however far each inner solve goes, because that solution is where every equation's residual
is zero whatever the linear solver's tolerance, and neither the relaxation's fixed point (it depends on
alpha_u alone: the face fluxes use the momentum matrix's relaxed diagonal) nor the criterion changes.
What changes is the work per iteration, and perhaps the number of iterations. So a controlled run's
linear solves are made no tighter than ``LEAN_REL_TOL`` (pressure) and ``LEAN_OTHER_REL_TOL`` (every other
solved field), never tighter than the case's own; the case's own run and the files written to ``--out``
keep the user's settings.

Measured on the development cases (experiments/solve-safety/pressure.jsonl and its README): the
pressure solve at relTol 0.3 instead of the tutorials' 0.1 took 0-2 % more iterations and 5-10 % fewer
linear iterations; the other fields at 0.3 instead of 0.1 took 20 % more iterations on pitzDaily (so
they are only raised from below 0.1, e.g. bump2D's relTol 0 solves of U, k and omega).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from foamlib import FoamFile

from foam_bridge import find_openfoam, foamdict

#: The pressure equation's relTol in a lean run (at least: a looser own one stays).
LEAN_REL_TOL = 0.3
#: Every other solved field's relTol in a lean run (at least).
LEAN_OTHER_REL_TOL = 0.1
#: The pressure fields' names (simpleFoam's and the buoyant solvers').
PRESSURE = ("p", "p_rgh")


def lean_solvers(case: Path, fields: Sequence[str]) -> dict[str, tuple[float, dict[str, Any]]]:
    """{field: (its own relTol, its solver dictionary with relTol raised)} for each of ``fields`` (the
    case's solved fields) whose own relTol is tighter than the lean one; the dictionary's other entries
    are the case's own, as OpenFOAM resolves them (an exact key, else the last matching pattern such as
    ``"(U|k|epsilon)"``)."""
    solvers = foamdict.expand(find_openfoam(), case, "system/fvSolution").get("solvers", {})
    lean: dict[str, tuple[float, dict[str, Any]]] = {}
    for name in fields:
        try:
            entry = foamdict.lookup(solvers, name)
        except KeyError:
            continue
        target = LEAN_REL_TOL if name in PRESSURE else LEAN_OTHER_REL_TOL
        own = _rel_tol(entry)
        if own is not None and own < target:
            lean[name] = (own, {**entry, "relTol": target})
    return lean


def _rel_tol(entry: Any) -> float | None:
    """A solver dictionary's relTol (0 when it sets none: OpenFOAM's default), None if unreadable."""
    if not isinstance(entry, dict):
        return None
    try:
        return float(entry.get("relTol", 0.0))
    except (TypeError, ValueError):
        return None


def make_lean(case: Path, fields: Sequence[str]) -> dict[str, list[float]]:
    """Append the lean solver entries to ``case``'s system/fvSolution (OpenFOAM merges a repeated
    ``solvers`` dictionary into the first, and an exact key wins over a pattern); returns {field: [own
    relTol, lean relTol]} of what changed, for solve.json."""
    lean = lean_solvers(case, fields)
    if not lean:
        return {}
    entries = {name: entry for name, (_, entry) in lean.items()}
    text = FoamFile.dumps({"solvers": entries}, ensure_header=False)
    text = text.decode() if isinstance(text, bytes) else text
    with open(case / "system" / "fvSolution", "a") as out:
        out.write("\n// ----- jaxsimrl solve: lean linear solves (jaxsimrl.apps.foam.solve.solvers) -----\n"
                  + text + "\n")
    return {name: [own, entry["relTol"]] for name, (own, entry) in lean.items()}
