# SPDX-License-Identifier: GPL-3.0-or-later
"""The held-out cases built here (prepare.py's "built" source): geometries none of the training bases
has, each a steady RAS case with a criterion and factors chosen before any run, as a user would set them:

- cavityRAS: the lid-driven cavity (pisoFoam/RAS/cavity, kEpsilon) made steady, plain SIMPLE;
- planarDiffuser: an asymmetric planar diffuser (one wall opening at 10 degrees, area ratio 4.7, as
  Buice & Eaton's), kOmegaSST, SIMPLEC;
- channelRib: a channel with a square rib on one wall (rib 0.2 of the height), kEpsilon, plain SIMPLE;
- tJunctionSteady: pimpleFoam/RAS/TJunction made steady (a velocity inlet), kEpsilon, plain SIMPLE;
- contraction2D: a 2-D planar contraction (nozzle, area ratio 4), kEpsilon, SIMPLEC;
- bend2D: a 2-D 90-degree channel bend, kOmegaSST, plain SIMPLE;
- elbowRAS: icoFoam/elbow (2-D elbow with a side inlet) made turbulent and steady, kEpsilon, plain SIMPLE.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

from foamcase import TUTORIALS, blockmesh_2d, copy_tutorial, replace_patch, run, write_dict, write_field

#: Plain SIMPLE's usual factors (U 0.7, p 0.3, turbulence 0.7) and SIMPLEC's (U 0.9, turbulence 0.7).
SIMPLE_FACTORS = ("relaxationFactors\n{\n    fields { p 0.3; }\n"
                  "    equations { U 0.7; \"(k|epsilon|omega)\" 0.7; }\n}\n")
SIMPLEC_FACTORS = "relaxationFactors\n{\n    equations { U 0.9; \"(k|epsilon|omega)\" 0.7; }\n}\n"
#: One criterion for every built case: 1e-4 on every field's initial residual, a common engineering choice.
CRITERION = "    residualControl { p 1e-4; U 1e-4; \"(k|epsilon|omega)\" 1e-4; }\n"

SCHEMES = """ddtSchemes { default steadyState; }
gradSchemes { default Gauss linear; }
divSchemes
{
    default none;
    div(phi,U) bounded Gauss linearUpwind grad(U);
    div(phi,k) bounded Gauss limitedLinear 1;
    div(phi,epsilon) bounded Gauss limitedLinear 1;
    div(phi,omega) bounded Gauss limitedLinear 1;
    div((nuEff*dev2(T(grad(U))))) Gauss linear;
}
laplacianSchemes { default Gauss linear corrected; }
interpolationSchemes { default linear; }
snGradSchemes { default corrected; }
wallDist { method meshWave; }
"""

SOLVERS = """solvers
{
    p { solver GAMG; smoother GaussSeidel; tolerance 1e-7; relTol 0.1; }
    "(U|k|epsilon|omega)" { solver smoothSolver; smoother symGaussSeidel; tolerance 1e-8; relTol 0.1; }
}
"""


def write_system(case: Path, consistent: bool, end_time: int, p_ref: bool = False) -> None:
    """controlDict, fvSchemes and fvSolution of a steady case: SIMPLEC when ``consistent``, else plain
    SIMPLE; ``p_ref`` for a domain without a fixed-pressure boundary."""
    write_dict(case / "system" / "controlDict",
               f"application simpleFoam;\nstartFrom startTime;\nstartTime 0;\nstopAt endTime;\n"
               f"endTime {end_time};\ndeltaT 1;\nwriteControl timeStep;\nwriteInterval {end_time};\n"
               "purgeWrite 0;\nwriteFormat ascii;\nwritePrecision 8;\nwriteCompression off;\n"
               "timeFormat general;\ntimePrecision 6;\nrunTimeModifiable true;\n")
    write_dict(case / "system" / "fvSchemes", SCHEMES)
    reference = "    pRefCell 0;\n    pRefValue 0;\n" if p_ref else ""
    simple = ("SIMPLE\n{\n    nNonOrthogonalCorrectors 0;\n"
              f"    consistent {'yes' if consistent else 'no'};\n"
              f"{reference}{CRITERION}}}\n")
    write_dict(case / "system" / "fvSolution", SOLVERS + simple + (SIMPLEC_FACTORS if consistent
                                                                   else SIMPLE_FACTORS))


def write_physics(case: Path, model: str, nu: float) -> None:
    """transportProperties (Newtonian, ``nu``) and turbulenceProperties (RAS ``model``)."""
    write_dict(case / "constant" / "transportProperties", f"transportModel Newtonian;\nnu {nu:g};\n")
    write_dict(case / "constant" / "turbulenceProperties",
               f"simulationType RAS;\nRAS\n{{\n    RASModel {model};\n    turbulence on;\n"
               "    printCoeffs on;\n}\n")


def build_cavity(case: Path) -> None:
    """pisoFoam/RAS/cavity (lid 1 m/s, 0.1 m, nu 1e-5: Re 1e4, kEpsilon, wall functions) made steady:
    simpleFoam, steady schemes, plain SIMPLE with a reference pressure (closed box). Edit: the mesh
    20x20 -> 40x40 (the tutorial's coarse transient mesh puts 2 cells in the corner eddies)."""
    copy_tutorial(TUTORIALS / "incompressible" / "pisoFoam" / "RAS" / "cavity", case)
    mesh = case / "system" / "blockMeshDict"
    mesh.write_text(mesh.read_text().replace("(20 20 1)", "(40 40 1)"))
    write_system(case, consistent=False, end_time=3000, p_ref=True)
    run(case, "blockMesh")


def inlet_turbulence(case: Path, model: str, speed: float, length: float, walls: list[str],
                     patches: tuple[list[str], list[str], str] = (["inlet"], ["outlet"], "frontAndBack"),
                     ) -> None:
    """k and epsilon/omega (5 % of ``speed``, mixing length ``length``) at the inlets, wall functions on
    ``walls``, inletOutlet at the outlets; nut from the model. ``patches``: inlets, outlets, the empty one."""
    inlets, outlets, empty = patches
    k = 1.5 * (0.05 * speed) ** 2
    wall_bc = {"k": "type kqRWallFunction; value uniform {v};",
               "nut": "type nutkWallFunction; value uniform 0;",
               "epsilon": "type epsilonWallFunction; value uniform {v};",
               "omega": "type omegaWallFunction; value uniform {v};"}
    second = "epsilon" if model == "kEpsilon" else "omega"
    values = {"k": k, "epsilon": 0.09**0.75 * k**1.5 / length, "omega": math.sqrt(k) / (0.09**0.25 * length)}
    for name in ("k", second):
        value = f"{values[name]:.6g}"
        bcs = {inlet: f"type fixedValue; value uniform {value};" for inlet in inlets}
        outflow = f"type inletOutlet; inletValue uniform {value}; value uniform {value};"
        bcs |= dict.fromkeys(outlets, outflow)
        bcs |= {wall: wall_bc[name].format(v=value) for wall in walls}
        write_field(case, name, value, bcs, empty)
    nut = {patch: "type calculated; value uniform 0;" for patch in inlets + outlets}
    write_field(case, "nut", "0", nut | {wall: wall_bc["nut"] for wall in walls}, empty)


def channel_fields(case: Path, model: str, speed: float, length: float, walls: list[str],
                   start: str | None = None) -> None:
    """U (uniform ``speed`` in x at the inlet, noSlip walls; inside ``start``, else the inlet's) and p (0
    at the outlet), and the turbulence."""
    u = {"inlet": f"type fixedValue; value uniform ({speed:g} 0 0);",
         "outlet": "type inletOutlet; inletValue uniform (0 0 0); value uniform (0 0 0);"}
    write_field(case, "U", start or f"({speed:g} 0 0)", u | {wall: "type noSlip;" for wall in walls})
    p = {"inlet": "type zeroGradient;", "outlet": "type fixedValue; value uniform 0;"}
    write_field(case, "p", "0", p | {wall: "type zeroGradient;" for wall in walls})
    inlet_turbulence(case, model, speed, length, walls)


def build_diffuser(case: Path) -> None:
    """Inlet channel of height 1 (10 long), diffuser 21 long whose lower wall opens at 10 degrees (outlet
    height 4.7), straight outlet 35 long. U 1, nu 5e-5 (Re 2e4 on the inlet height), kOmegaSST with wall
    functions, SIMPLEC. 6 400 cells, clustered towards both walls."""
    drop = 21.0 * math.tan(math.radians(10.0))
    points = [(-10, 0), (0, 0), (21, -drop), (56, -drop), (56, 1), (21, 1), (0, 1), (-10, 1)]
    ygrade = "((0.5 0.5 4) (0.5 0.5 0.25))"
    blocks = [((0, 1, 6, 7), f"(30 40 1) simpleGrading (0.5 {ygrade} 1)"),
              ((1, 2, 5, 6), f"(80 40 1) simpleGrading (1 {ygrade} 1)"),
              ((2, 3, 4, 5), f"(50 40 1) simpleGrading (4 {ygrade} 1)")]
    patches = {"inlet": ("patch", [(7, 0)]), "outlet": ("patch", [(3, 4)]),
               "lowerWall": ("wall", [(0, 1), (1, 2), (2, 3)]),
               "upperWall": ("wall", [(4, 5), (5, 6), (6, 7)])}
    write_case(case, blockmesh_2d(points, blocks, patches), "kOmegaSST", 5e-5, consistent=True)
    channel_fields(case, "kOmegaSST", 1.0, 0.07, ["lowerWall", "upperWall"])
    run(case, "blockMesh")


def build_contraction(case: Path) -> None:
    """A 2-D planar contraction (nozzle): a channel of height 4 narrowing to 1 over 4 with straight walls
    (20.6 degrees each side), 4 upstream, 8 downstream. U 0.25 in (1 out), nu 1e-5 (Re 1e5 at the outlet),
    kEpsilon with wall functions, SIMPLEC. 4 800 cells, clustered towards both walls."""
    points = [(-4, -2), (0, -2), (4, -0.5), (12, -0.5), (12, 0.5), (4, 0.5), (0, 2), (-4, 2)]
    across = "((0.5 0.5 4) (0.5 0.5 0.25))"
    blocks = [((0, 1, 6, 7), f"(20 40 1) simpleGrading (1 {across} 1)"),
              ((1, 2, 5, 6), f"(40 40 1) simpleGrading (1 {across} 1)"),
              ((2, 3, 4, 5), f"(60 40 1) simpleGrading (4 {across} 1)")]
    patches = {"inlet": ("patch", [(7, 0)]), "outlet": ("patch", [(3, 4)]),
               "lowerWall": ("wall", [(0, 1), (1, 2), (2, 3)]),
               "upperWall": ("wall", [(4, 5), (5, 6), (6, 7)])}
    write_case(case, blockmesh_2d(points, blocks, patches), "kEpsilon", 1e-5, consistent=True)
    channel_fields(case, "kEpsilon", 0.25, 0.07 * 4, ["lowerWall", "upperWall"])
    run(case, "blockMesh")


def build_rib(case: Path) -> None:
    """Channel of height 1 with a square rib (0.2 x 0.2) on the lower wall: 3 upstream, 8 downstream.
    U 1, nu 1e-5 (Re 1e5 on the channel height), kEpsilon with wall functions, plain SIMPLE. 5 900 cells."""
    h = 0.2
    points = [(-3, 0), (0, 0), (0, h), (-3, h), (-3, 1), (0, 1),
              (h, h), (h, 1), (h, 0), (8, 0), (8, h), (8, 1)]
    blocks = [((0, 1, 2, 3), "(40 10 1) simpleGrading (0.2 1 1)"),
              ((3, 2, 5, 4), "(40 30 1) simpleGrading (0.2 4 1)"),
              ((2, 6, 7, 5), "(10 30 1) simpleGrading (1 4 1)"),
              ((8, 9, 10, 6), "(100 10 1) simpleGrading (20 1 1)"),
              ((6, 10, 11, 7), "(100 30 1) simpleGrading (20 4 1)")]
    patches = {"inlet": ("patch", [(4, 3), (3, 0)]), "outlet": ("patch", [(9, 10), (10, 11)]),
               "lowerWall": ("wall", [(0, 1), (1, 2), (2, 6), (6, 8), (8, 9)]),
               "upperWall": ("wall", [(11, 7), (7, 5), (5, 4)])}
    write_case(case, blockmesh_2d(points, blocks, patches), "kEpsilon", 1e-5, consistent=False)
    channel_fields(case, "kEpsilon", 1.0, 0.07, ["lowerWall", "upperWall"])
    run(case, "blockMesh")


def build_bend(case: Path) -> None:
    """A 2-D 90-degree bend of a channel of width 1 (inner radius 1, outer 2), 5 straight upstream, 10
    downstream. U 1, nu 1e-5 (Re 1e5 on the width), kOmegaSST with wall functions, plain SIMPLE. 3 750
    cells, clustered towards both walls. Starts from rest: the inlet's velocity everywhere runs into the
    walls of the outlet leg (its first build did, and crashed at iteration 15)."""
    points = [(-5, -2), (0, -2), (0, -1), (-5, -1), (2, 0), (1, 0), (2, 10), (1, 10)]
    across = "((0.5 0.5 4) (0.5 0.5 0.25))"
    blocks = [((0, 1, 2, 3), f"(25 30 1) simpleGrading (0.5 {across} 1)"),
              ((1, 4, 5, 2), f"(40 30 1) simpleGrading (1 {across} 1)"),
              ((5, 4, 6, 7), f"(30 60 1) simpleGrading ({across} 4 1)")]
    arcs = [(1, 4, (2 * math.sqrt(0.5), -2 * math.sqrt(0.5))), (2, 5, (math.sqrt(0.5), -math.sqrt(0.5)))]
    patches = {"inlet": ("patch", [(3, 0)]), "outlet": ("patch", [(6, 7)]),
               "outerWall": ("wall", [(0, 1), (1, 4), (4, 6)]),
               "innerWall": ("wall", [(7, 5), (5, 2), (2, 3)])}
    write_case(case, blockmesh_2d(points, blocks, patches, arcs=arcs), "kOmegaSST", 1e-5, consistent=False)
    channel_fields(case, "kOmegaSST", 1.0, 0.07, ["outerWall", "innerWall"], start="(0 0 0)")
    run(case, "blockMesh")


def write_case(case: Path, mesh: str, model: str, nu: float, consistent: bool) -> None:
    """A fresh case directory: blockMeshDict, the steady system files (endTime 3000), the physics."""
    if case.exists():
        shutil.rmtree(case)
    write_dict(case / "system" / "blockMeshDict", mesh)
    write_system(case, consistent=consistent, end_time=3000)
    write_physics(case, model, nu)


def build_tjunction(case: Path) -> None:
    """pimpleFoam/RAS/TJunction (3-D T-junction of square ducts, kEpsilon) made steady: simpleFoam, steady
    schemes, plain SIMPLE. Edits: the inlet driven by a velocity (5 m/s, Re 1e4 on the 0.02 m duct)
    instead of the total-pressure ramp (held at its final 40 m2/s2, a steady run from rest crashed at
    iteration 10; potentialFoam cannot start a case no boundary gives a velocity); the outlets keep their
    pressures (10 and 0); the passive scalar (0/s and its function object) and the probes dropped."""
    copy_tutorial(TUTORIALS / "incompressible" / "pimpleFoam" / "RAS" / "TJunction", case)
    (case / "0" / "s").unlink()
    write_system(case, consistent=False, end_time=3000)
    replace_patch(case / "0" / "p", "inlet", "type zeroGradient;")
    replace_patch(case / "0" / "U", "inlet", "type fixedValue; value uniform (5 0 0);")
    run(case, "blockMesh")


def build_elbow(case: Path) -> None:
    """icoFoam/elbow (2-D elbow, Fluent mesh, a main and a side inlet) made a steady RAS case: simpleFoam,
    kEpsilon with wall functions, nu 1.6e-4 instead of 0.01 (Re 1e5 on the 16 m main inlet instead of 1600:
    turbulent), plain SIMPLE. Allrun: fluentMeshToFoam elbow.msh. Its inlet speeds (1 and 3 m/s) kept."""
    copy_tutorial(TUTORIALS / "incompressible" / "icoFoam" / "elbow", case)
    write_system(case, consistent=False, end_time=3000)
    write_physics(case, "kEpsilon", 1.6e-4)
    run(case, "fluentMeshToFoam", "elbow.msh")
    # k and epsilon from the main inlet (1 m/s, 16 wide): the side jet (3 m/s, 4 wide) gets the same
    inlet_turbulence(case, "kEpsilon", 1.0, 0.07 * 16, ["wall-4", "wall-8"],
                     (["velocity-inlet-5", "velocity-inlet-6"], ["pressure-outlet-7"], "frontAndBackPlanes"))
