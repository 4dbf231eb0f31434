"""The fields and the system/constant dictionaries of a generated case (foam_bridge._generator).

Every generated case is a steady, incompressible RAS channel flow with the same four patches: ``inlet``
(uniform velocity along x, turbulence from an intensity and a mixing length of 0.07 H), ``outlet`` (fixed
pressure 0, inletOutlet for the rest), ``walls`` (no-slip, wall functions) and the empty ``frontAndBack``.
What differs between cases is the user's part: the turbulence model, plain SIMPLE or SIMPLEC, the
relaxation factors, the residualControl criterion and endTime. The numerics are those of OpenFOAM's own
simpleFoam tutorials (bounded linearUpwind for U, bounded upwind-biased turbulence, GAMG for p), so that
a case converges as a user's would.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

__all__ = ["CMU", "MIXING_LENGTH", "TURBULENCE_FIELDS", "inlet_turbulence", "write_physics"]

CMU = 0.09
#: Inlet mixing length over the inlet channel height (fully developed channel flow).
MIXING_LENGTH = 0.07
#: The fields each turbulence model solves besides U and p.
TURBULENCE_FIELDS = {"kEpsilon": ("k", "epsilon"), "realizableKE": ("k", "epsilon"),
                     "kOmegaSST": ("k", "omega")}

_HEADER = "FoamFile\n{{\n    version 2.0;\n    format ascii;\n    class {cls};\n    object {obj};\n}}\n\n"
_DIMENSIONS = {"U": "[0 1 -1 0 0 0 0]", "p": "[0 2 -2 0 0 0 0]", "k": "[0 2 -2 0 0 0 0]",
               "epsilon": "[0 2 -3 0 0 0 0]", "omega": "[0 0 -1 0 0 0 0]", "nut": "[0 2 -1 0 0 0 0]"}
_WALL = {"k": "kqRWallFunction", "epsilon": "epsilonWallFunction", "omega": "omegaWallFunction"}
_TURBULENCE = '"(k|epsilon|omega)"'


def inlet_turbulence(speed: float, intensity: float, height: float) -> dict[str, float]:
    """k = 1.5 (I U)^2, epsilon = Cmu^0.75 k^1.5 / l and omega = sqrt(k) / (Cmu^0.25 l), l = 0.07 H."""
    k = 1.5 * (intensity * speed) ** 2
    length = MIXING_LENGTH * height
    return {"k": k, "epsilon": CMU**0.75 * k**1.5 / length, "omega": math.sqrt(k) / (CMU**0.25 * length)}


def _write(path: Path, body: str, cls: str = "dictionary") -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(_HEADER.format(cls=cls, obj=path.name) + body)


def _field(case: Path, name: str, internal: str, patches: Mapping[str, str]) -> None:
    """0/<name>: a uniform internal value and one boundary condition per patch (its entries)."""
    cls = "volVectorField" if name == "U" else "volScalarField"
    rows = "".join(f"    {patch} {{ {entries} }}\n" for patch, entries in patches.items())
    _write(case / "0" / name, f"dimensions {_DIMENSIONS[name]};\n\ninternalField uniform {internal};\n\n"
           f"boundaryField\n{{\n{rows}    frontAndBack {{ type empty; }}\n}}\n", cls)


def write_fields(case: Path, model: str, speed: float, intensity: float, height: float, start: float) -> None:
    """0/U (``start`` times the inlet's velocity inside), 0/p, the model's turbulence fields and 0/nut."""
    inflow = f"({speed:.6g} 0 0)"
    _field(case, "U", f"({start * speed:.6g} 0 0)", {
        "inlet": f"type fixedValue; value uniform {inflow};",
        "outlet": "type inletOutlet; inletValue uniform (0 0 0); value uniform (0 0 0);",
        "walls": "type noSlip;"})
    _field(case, "p", "0", {"inlet": "type zeroGradient;", "outlet": "type fixedValue; value uniform 0;",
                            "walls": "type zeroGradient;"})
    values = inlet_turbulence(speed, intensity, height)
    for name in TURBULENCE_FIELDS[model]:
        value = f"{values[name]:.6g}"
        _field(case, name, value, {
            "inlet": f"type fixedValue; value uniform {value};",
            "outlet": f"type inletOutlet; inletValue uniform {value}; value uniform {value};",
            "walls": f"type {_WALL[name]}; value uniform {value};"})
    _field(case, "nut", "0", {"inlet": "type calculated; value uniform 0;",
                              "outlet": "type calculated; value uniform 0;",
                              "walls": "type nutkWallFunction; value uniform 0;"})


def write_constant(case: Path, model: str, nu: float) -> None:
    """transportProperties (Newtonian) and turbulenceProperties (RAS ``model``)."""
    _write(case / "constant" / "transportProperties", f"transportModel Newtonian;\n\nnu {nu:.6g};\n")
    _write(case / "constant" / "turbulenceProperties",
           f"simulationType RAS;\n\nRAS\n{{\n    RASModel {model};\n    turbulence on;\n"
           "    printCoeffs on;\n}\n")


def write_control(case: Path, end_time: int) -> None:
    """controlDict: one iteration per time step, fields written only at the end (or at convergence)."""
    entries = {"application": "simpleFoam", "startFrom": "startTime", "startTime": 0, "stopAt": "endTime",
               "endTime": end_time, "deltaT": 1, "writeControl": "timeStep", "writeInterval": end_time,
               "purgeWrite": 0, "writeFormat": "ascii", "writePrecision": 8, "writeCompression": "off",
               "timeFormat": "general", "timePrecision": 6, "runTimeModifiable": "true"}
    _write(case / "system" / "controlDict", "".join(f"{key} {value};\n" for key, value in entries.items()))


_SCHEMES = """ddtSchemes { default steadyState; }

gradSchemes { default Gauss linear; }

divSchemes
{
    default none;
    div(phi,U) bounded Gauss linearUpwind grad(U);
    div(phi,k) bounded Gauss upwind;
    div(phi,epsilon) bounded Gauss upwind;
    div(phi,omega) bounded Gauss upwind;
    div((nuEff*dev2(T(grad(U))))) Gauss linear;
}

laplacianSchemes { default Gauss linear corrected; }

interpolationSchemes { default linear; }

snGradSchemes { default corrected; }

wallDist { method meshWave; }
"""


def write_solution(case: Path, algorithm: str, factors: Mapping[str, float],
                   criterion: Mapping[str, float]) -> None:
    """fvSchemes and fvSolution: the linear solvers of the tutorials, SIMPLE (``consistent`` for SIMPLEC)
    with residualControl on every field (simpleFoam stops when all are met), the case's own factors.
    A SIMPLEC case with p at 1 leaves p unrelaxed (no ``fields`` entry), as its users write it."""
    _write(case / "system" / "fvSchemes", _SCHEMES)
    solvers = ("solvers\n{\n"
               "    p { solver GAMG; smoother GaussSeidel; tolerance 1e-6; relTol 0.1; }\n"
               "    \"(U|k|epsilon|omega)\" { solver smoothSolver; smoother symGaussSeidel; "
               "tolerance 1e-5; relTol 0.1; }\n}\n\n")
    control = (f"p {criterion['p']:g}; U {criterion['U']:g}; {_TURBULENCE} {criterion['turbulence']:g};")
    simple = ("SIMPLE\n{\n    nNonOrthogonalCorrectors 0;\n"
              f"    consistent {'yes' if algorithm == 'SIMPLEC' else 'no'};\n"
              f"    residualControl {{ {control} }}\n}}\n\n")
    pressure = "" if factors["p"] >= 1 else f"    fields {{ p {factors['p']:g}; }}\n"
    relax = (f"relaxationFactors\n{{\n{pressure}    equations {{ U {factors['U']:g}; "
             f"{_TURBULENCE} {factors['turbulence']:g}; }}\n}}\n")
    _write(case / "system" / "fvSolution", solvers + simple + relax)


def write_physics(case: Path, *, model: str, algorithm: str, factors: Mapping[str, float],
                  criterion: Mapping[str, float], end_time: int, nu: float, speed: float, intensity: float,
                  height: float, start: float) -> None:
    """Everything of a case but its mesh: 0/, constant/ and system/ (less blockMeshDict)."""
    write_fields(case, model, speed, intensity, height, start)
    write_constant(case, model, nu)
    write_control(case, end_time)
    write_solution(case, algorithm, factors, criterion)
