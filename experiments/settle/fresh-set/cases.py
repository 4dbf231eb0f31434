# SPDX-License-Identifier: GPL-3.0-or-later
"""The candidates of issue 56's fresh set: one builder per case, each a plain steady simpleFoam case,
meshed, with its user's own settings and, on most, the function objects a user adds (forces or force
coefficients on a body, probes, surface and volume averages).

Issue 56's final table is measured on cases whose own settings never meet their criterion and that nobody
has looked at. heldout-v2's and heldout-v3's cases that did not converge are issue 56's development cases;
these are new instances of the same kinds (bluff bodies, tube banks, impinging jets, ventilated rooms,
annuli, porous obstacles, wall cavities): new dimensions, Reynolds numbers, meshes, models and users'
settings. Written down, with every case's settings and function objects, BEFORE any of them ran (README.md
has the rule that picks the set from them); no case is changed after.

Users' settings: plain SIMPLE conservative (U 0.7, p 0.3, turbulence 0.7) or "between" (U 0.8, p 0.2,
turbulence 0.8); SIMPLEC U 0.8-0.9, p unrelaxed or 1 written out, turbulence 0.8-0.9; residualControl 1e-4
on every field, or 1e-5 (a tight user), or p 1e-3 with U and turbulence 1e-4; endTime 3000, deltaT 1,
fields written every 500 or 1000 iterations.

The builders reuse heldout-v2's geometry helpers, field writers and ``finish`` (imported through
heldout-v3's ``v2_module``, not copied); what this file adds is the controlDict's ``functions`` and the
user's writeInterval (``finish`` below: heldout-v2's, then the controlDict edited), and a channel's patch
namer that gives a solid body its own patch (``obstacle``) so that forces can be taken on it alone.
"""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from types import ModuleType

_V3_CASES = Path(__file__).resolve().parents[2] / "controller" / "heldout-v3" / "cases.py"


def _v3_cases() -> ModuleType:
    """heldout-v3's cases.py under a name of its own (for its ``v2_module``); loaded once."""
    name = "heldout_v3_cases"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, _V3_CASES)
        module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
        sys.modules[name] = module
        spec.loader.exec_module(module)  # type: ignore[union-attr]
    return sys.modules[name]


v2_module = _v3_cases().v2_module
V2 = v2_module("cases")
Flow, fresh, grid_2d, channel_mesh, channel_patches = (V2.Flow, V2.fresh, V2.grid_2d, V2.channel_mesh,
                                                       V2.channel_patches)
TUTORIALS = V2.TUTORIALS
CONSERVATIVE = {"U": 0.7, "p": 0.3, "turbulence": 0.7}
BETWEEN = {"U": 0.8, "p": 0.2, "turbulence": 0.8}
ALL_1E4 = {"p": 1e-4, "U": 1e-4, "turbulence": 1e-4}
ALL_1E5 = {"p": 1e-5, "U": 1e-5, "turbulence": 1e-5}
P_1E3 = {"p": 1e-3, "U": 1e-4, "turbulence": 1e-4}
TWO_SIDED = V2.TWO_SIDED
#: The 2-D meshes' thickness (heldout-v1's blockmesh_2d): the mid-plane for probes, the areas of coefficients.
DEPTH = 0.1
MID = DEPTH / 2

CASES: dict[str, Callable[[Path], None]] = {}
DESCRIPTIONS: dict[str, tuple[str, str, str]] = {}


def register(kind: str, geometry: str) -> Callable:
    """Add the decorated builder to CASES and its description to DESCRIPTIONS."""
    def add(builder: Callable[[Path], None]) -> Callable[[Path], None]:
        CASES[builder.__name__] = builder
        DESCRIPTIONS[builder.__name__] = ("built", kind, geometry)
        return builder
    return add


# ---------------------------------------------------------------------------------------------------
# Function objects, as a user writes them in system/controlDict (v1912's syntax: the tutorials' and
# etc/caseDicts/postProcessing's). Each writes a time series under postProcessing/<name>/0/ every iteration.


def _entry(name: str, lines: Sequence[str]) -> str:
    body = "\n".join(f"        {line}" for line in lines)
    return f"    {name}\n    {{\n{body}\n    }}\n"


def forces(patches: Sequence[str], cofr: tuple[float, float], name: str = "forces") -> str:
    """Forces and moments (about ``cofr``, on the mid-plane) on ``patches``; kinematic pressure, rho 1."""
    return _entry(name, ["type            forces;", "libs            (forces);", "writeControl    timeStep;",
                         "writeInterval   1;", "log             false;",
                         f"patches         ({' '.join(patches)});", "rho             rhoInf;",
                         "rhoInf          1;", f"CofR            ({cofr[0]:g} {cofr[1]:g} {MID:g});"])


def force_coeffs(patches: Sequence[str], cofr: tuple[float, float], length: float, area: float,
                 speed: float = 1.0, name: str = "forceCoeffs") -> str:
    """Drag, lift and moment coefficients on ``patches`` (flow along x, lift along y, pitch about z)."""
    return _entry(name, ["type            forceCoeffs;", "libs            (forces);",
                         "writeControl    timeStep;", "writeInterval   1;", "log             false;",
                         f"patches         ({' '.join(patches)});", "rho             rhoInf;",
                         "rhoInf          1;", f"CofR            ({cofr[0]:g} {cofr[1]:g} {MID:g});",
                         "liftDir         (0 1 0);", "dragDir         (1 0 0);", "pitchAxis       (0 0 1);",
                         f"magUInf         {speed:g};", f"lRef            {length:g};",
                         f"Aref            {area:g};"])


def probes(points: Sequence[tuple[float, float]], name: str = "probes") -> str:
    """p and U at ``points`` (x, y) on the mid-plane."""
    locations = " ".join(f"({x:g} {y:g} {MID:g})" for x, y in points)
    return _entry(name, ["type            probes;", "libs            (sampling);",
                         "writeControl    timeStep;", "writeInterval   1;", "fields          (p U);",
                         f"probeLocations  ({locations});"])


def surface(name: str, patch: str, operation: str, fields: Sequence[str], weight: str | None = None) -> str:
    """surfaceFieldValue of ``fields`` on ``patch``: ``operation`` (areaAverage, weightedAverage (weighted by
    ``weight``), sum...)."""
    lines = ["type            surfaceFieldValue;", "libs            (fieldFunctionObjects);",
             "writeControl    timeStep;", "writeInterval   1;", "log             false;",
             "writeFields     false;", "regionType      patch;", f"name            {patch};",
             f"operation       {operation};", f"fields          ({' '.join(fields)});"]
    if weight:
        lines.append(f"weightField     {weight};")
    return _entry(name, lines)


def volume_average(name: str, fields: Sequence[str]) -> str:
    """volFieldValue: the volume average of ``fields`` over the whole domain."""
    return _entry(name, ["type            volFieldValue;", "libs            (fieldFunctionObjects);",
                         "writeControl    timeStep;", "writeInterval   1;", "log             false;",
                         "writeFields     false;", "regionType      all;", "operation       volAverage;",
                         f"fields          ({' '.join(fields)});"])


def finish(case: Path, roles: dict, flow: Flow, write_interval: int, functions: Sequence[str] = (),
           *after: tuple[str, ...]) -> None:
    """heldout-v2's finish (dictionaries, fields, blockMesh, ``after``), then the controlDict given the user's
    writeInterval and ``functions`` (function-object entries of the functions above)."""
    V2.finish(case, roles, flow, *after)
    control = case / "system" / "controlDict"
    text = control.read_text()
    old = f"writeInterval {flow.end_time};\n"
    assert text.count(old) == 1, control
    text = text.replace(old, f"writeInterval {write_interval};\n")
    if functions:
        text += "\nfunctions\n{\n" + "\n".join(functions) + "}\n"
    control.write_text(text)


def body_patches(last_column: int, last_row: int, solids: Sequence[tuple[int, int]], lower: str = "walls",
                 upper: str = "walls") -> Callable[[int, int, str], str]:
    """Patches of a channel along x (grid_2d's namer): inlet left, outlet right, the sides of the blocks
    ``solids`` one patch (obstacle), the bottom ``lower``, the top ``upper``, anything else walls."""
    steps = {"bottom": (0, -1), "right": (1, 0), "top": (0, 1), "left": (-1, 0)}

    def patch(i: int, j: int, side: str) -> str:
        if side == "left" and i == 0:
            return "inlet"
        if side == "right" and i == last_column:
            return "outlet"
        if (i + steps[side][0], j + steps[side][1]) in solids:
            return "obstacle"
        if side == "bottom" and j == 0:
            return lower
        return upper if side == "top" and j == last_row else "walls"
    return patch


def rotating_annulus(case: Path, outer: float, offset: float, cells: tuple[int, int]) -> dict:
    """A 2-D annulus: inner radius 1 centred at (offset, 0) rotating at 1 rad/s, outer ``outer`` at rest."""
    fresh(case)
    V2.write_dict(case / "system" / "blockMeshDict", V2.annulus_2d(1, outer, offset, *cells))
    return {"innerWall": ("rotating", (offset, 0), 1), "outerWall": "wall"}


def porous_block(case: Path, xs: list, ys: list, nx: list, ny: list, gy: list, zone: tuple[int, int],
                 coefficients: tuple[str, str], last_row: int) -> dict:
    """A walled channel on the lines ``xs`` x ``ys`` whose block ``zone`` is a porous cellZone
    (Darcy-Forchheimer ``coefficients``: d, f)."""
    fresh(case)
    grid = grid_2d(xs, ys, nx, ny, channel_patches(len(nx) - 1, last_row), gx=[0.25, 1, 5], gy=gy,
                   zones={zone: "porous"})
    return channel_mesh(case, grid, porosity={"porous": coefficients})


# ---------------------------------------------------------------------------------------------------
# Bluff bodies


@register("bluff-body", "2-D square cylinder near the floor of a channel, gap 1 D, blockage 0.2, Re 1.5e4")
def squareNearWall(case: Path) -> None:
    """bluff-body. A square cylinder (D = 1) in a channel of height 5 D, 1 D above the floor (3 D below the
    ceiling), 4.5 D upstream, 14.5 D downstream. U 1, nu 6.67e-5: Re 1.5e4 on D. kOmegaSST, plain SIMPLE
    conservative (U 0.7, p 0.3, turbulence 0.7), 1e-4 on every field, endTime 3000, fields every 1000.
    Function objects: forceCoeffs on the cylinder (Aref D x depth), probes 3 D behind it. 9,216 cells.
    Why: a bluff body whose wake the floor makes asymmetric; turbulent square cylinders shed."""
    fresh(case)
    solids = [(1, 1)]
    grid = grid_2d([-5, -0.5, 0.5, 15], [-1.5, -0.5, 0.5, 3.5], [30, 24, 90], [14, 24, 30],
                   body_patches(2, 2, solids), gx=[0.25, 1, 6], gy=[TWO_SIDED, 1, 2],
                   cells={solids[0]: "solid"})
    roles = channel_mesh(case, grid, obstacle="wall")
    finish(case, roles, Flow("kOmegaSST", 6.67e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07 * 5,
                             start="(1 0 0)"), 1000,
           [force_coeffs(["obstacle"], (0, 0), 1, DEPTH), probes([(3.5, 0), (3.5, 1)])])


@register("bluff-body", "2-D circular cylinder in a channel, blockage 1/6, Re 5e4, SIMPLEC")
def cylinderKE(case: Path) -> None:
    """bluff-body. A circular cylinder (D = 1, O-grid) in a channel of height 6 D, 5.5 D upstream, 15.5 D
    downstream. U 1, nu 2e-5: Re 5e4 on D. kEpsilon, SIMPLEC, U 0.9, p 1 (written out), turbulence 0.9,
    1e-4 on every field, endTime 3000, fields every 500. Function objects: forceCoeffs on the cylinder,
    probes 2 D and 5 D behind it. 16,288 cells. Why: a curved bluff body at a lower blockage than
    heldout-v2's, with the standard model (its excess production damps shedding) and SIMPLEC; one of
    the long cases."""
    fresh(case)
    grid = grid_2d([-6, -1, 1, 16], [-3, -1, 1, 3], [36, 32, 110], [24, 32, 24], channel_patches(2, 2),
                   gx=[0.25, 1, 5], gy=[0.5, 1, 2], cells={(1, 1): ("cylinder", 0.5, 24, 0.15)})
    roles = channel_mesh(case, grid, cylinder="wall")
    finish(case, roles, Flow("kEpsilon", 2e-5, True, {"U": 0.9, "p": 1, "turbulence": 0.9}, ALL_1E4, 3000,
                             1.0, 0.07 * 6, start="(1 0 0)"), 500,
           [force_coeffs(["cylinder"], (0, 0), 1, DEPTH), probes([(2, 0), (5, 0.5)])])


@register("bluff-body", "2-D 3:1 rectangular cylinder in a channel, blockage 0.125, Re 4e4")
def rectangle3to1(case: Path) -> None:
    """bluff-body. A 3:1 rectangular cylinder (chord 3 D, D = 1) centred in a channel of height 8 D, 8 D
    upstream, 20 D downstream. U 1, nu 2.5e-5: Re 4e4 on D. realizableKE, plain SIMPLE "between" (U 0.8,
    p 0.2, turbulence 0.8), 1e-4 on every field, endTime 3000, fields every 1000. Function objects: forces
    on the body (moments about its centre), probes 2 D behind it. 12,264 cells. Why: an elongated body
    whose leading-edge shear layers may reattach (heldout-v2's 5:1 section did not converge)."""
    fresh(case)
    solids = [(1, 1)]
    grid = grid_2d([-8, 0, 3, 23], [-4, -0.5, 0.5, 4], [36, 48, 90], [28, 20, 28], body_patches(2, 2, solids),
                   gx=[0.2, 1, 6], gy=[0.2, 1, 5], cells={solids[0]: "solid"})
    roles = channel_mesh(case, grid, obstacle="wall")
    finish(case, roles, Flow("realizableKE", 2.5e-5, False, BETWEEN, ALL_1E4, 3000, 1.0, 0.07 * 8,
                             start="(1 0 0)"), 1000,
           [forces(["obstacle"], (1.5, 0)), probes([(5, 0.25)])])


@register("bluff-body", "2-D 2:1 rectangular cylinder in a channel, blockage 1/6, half domain (symmetry "
                        "plane on the wake's centre line), Re 3e4, SIMPLEC")
def halfRectangle(case: Path) -> None:
    """bluff-body. A 2:1 rectangular cylinder (chord 2 D, D = 1) in a channel of height 6 D, modelled as a
    user does for a steady drag estimate: the half domain above the wake's centre plane (a symmetry
    plane), 5 D upstream, 15 D downstream. U 1, nu 3.33e-5: Re 3e4. kOmegaSST, SIMPLEC, U 0.9, p
    unrelaxed, turbulence 0.9; p 1e-3, U and turbulence 1e-4; endTime 3000, fields every 500. Function
    objects: forceCoeffs on the half body (Aref D/2 x depth). 5,520 cells. Why: the symmetric steady model
    of another bluff section (heldout-v2's half square cylinder cycled between two iterations)."""
    fresh(case)
    solids = [(1, 0)]
    grid = grid_2d([-5, 0, 2, 17], [0, 0.5, 3], [30, 30, 80], [12, 30],
                   body_patches(2, 1, solids, lower="symmetryLower"), gx=[0.25, 1, 6], gy=[1, 2],
                   cells={solids[0]: "solid"})
    roles = channel_mesh(case, grid, obstacle="wall", symmetryLower="symmetry")
    finish(case, roles, Flow("kOmegaSST", 3.33e-5, True, {"U": 0.9, "turbulence": 0.9}, P_1E3, 3000, 1.0,
                             0.07 * 6, start="(1 0 0)"), 500,
           [force_coeffs(["obstacle"], (1, 0), 1, 0.5 * DEPTH)])


@register("bluff-body", "2-D square cylinder in a narrow channel, blockage 1/3, Re 1e4, SIMPLEC")
def squareNarrowKE(case: Path) -> None:
    """bluff-body. A square cylinder (D = 1) centred in a channel of height 3 D, 4.5 D upstream, 14.5 D
    downstream. U 1, nu 1e-4: Re 1e4 on D. kEpsilon, SIMPLEC, U 0.8, p unrelaxed, turbulence 0.8, 1e-4 on
    every field, endTime 3000, fields every 1000. Function objects: forceCoeffs on the cylinder. 7,488
    cells. Why: a confined square cylinder (heldout-v2's at blockage 0.5 never held still) at another
    blockage, model and algorithm."""
    fresh(case)
    solids = [(1, 1)]
    grid = grid_2d([-5, -0.5, 0.5, 15], [-1.5, -0.5, 0.5, 1.5], [30, 24, 90], [16, 24, 16],
                   body_patches(2, 2, solids), gx=[0.25, 1, 6], gy=[0.5, 1, 2], cells={solids[0]: "solid"})
    roles = channel_mesh(case, grid, obstacle="wall")
    finish(case, roles, Flow("kEpsilon", 1e-4, True, {"U": 0.8, "turbulence": 0.8}, ALL_1E4, 3000, 1.0,
                             0.07 * 3, start="(1 0 0)"), 1000,
           [force_coeffs(["obstacle"], (0, 0), 1, DEPTH)])


# ---------------------------------------------------------------------------------------------------
# Tube banks


@register("tube-bank", "2-D inline bank of square tubes, 4 deep, pitches 1.75 D x 2.5 D, Re 2e4, SIMPLEC")
def squareBankInline(case: Path) -> None:
    """tube-bank. An inline bank of square tubes (D = 1), 4 deep, longitudinal pitch 1.75 D, transverse
    2.5 D, infinitely wide (one row between symmetry planes through the tube centres), 6 D upstream, 15 D
    downstream. U 1, nu 5e-5: Re 2e4. kOmegaSST, SIMPLEC, U 0.9, p unrelaxed, turbulence 0.9, 1e-4 on
    every field, endTime 3000, fields every 500. Function objects: forces on the tubes, the inlet's
    area-averaged pressure (the bank's pressure drop). 13,944 cells. Why: tube banks under SST did not
    converge in heldout-v2 and -v3 (staggered); an inline one; one of the long cases."""
    roles = V2.square_tube_bank(case, 4, 0.75, 2.5, (36, 20, 14, 80), [14, 40, 14], staggered=False)
    finish(case, roles, Flow("kOmegaSST", 5e-5, True, {"U": 0.9, "turbulence": 0.9}, ALL_1E4, 3000, 1.0,
                             0.07 * 2.5, start="(1 0 0)"), 500,
           [forces(["walls"], (0, 0)), surface("inletPressure", "inlet", "areaAverage", ["p"])])


@register("tube-bank", "2-D staggered bank of 10 circular tubes, 5 x 4, pitch 1.4 D, Re 1.5e4")
def tubeBankRKE(case: Path) -> None:
    """tube-bank. A staggered bank (checkerboard) of 10 circular tubes (D = 1, O-grids) on a 1.4 D grid, 5
    columns x 4 rows, between channel walls, 6 D upstream, 15 D downstream. U 1, nu 6.67e-5: Re 1.5e4.
    realizableKE, plain SIMPLE conservative, p 1e-3, U and turbulence 1e-4 (a bank's user settles for p
    1e-3), endTime 3000, fields every 1000. Function objects: forces on the tubes. 13,440 cells. Why: a
    compact staggered bank of round tubes (heldout-v2's were inline or sparser), plain SIMPLE."""
    roles = V2.tube_bank(case, 5, 4, 1.4, 16, 8, staggered=True, ends=(30, 60))
    finish(case, roles, Flow("realizableKE", 6.67e-5, False, CONSERVATIVE, P_1E3, 3000, 1.0, 0.07 * 5.6,
                             start="(1 0 0)"), 1000, [forces(["cylinder"], (3.5, 2.8))])


@register("tube-bank", "2-D staggered bank of square tubes, 8 deep, pitches 1.6 D x 3 D, Re 8e3")
def squareBankDeep(case: Path) -> None:
    """tube-bank. A staggered bank of square tubes (D = 1), 8 deep, longitudinal pitch 1.6 D, transverse
    3 D, infinitely wide (the strip between symmetry planes through neighbouring tubes' centres, 1.5 D
    apart), 6 D upstream, 15 D downstream. U 1, nu 1.25e-4: Re 8e3. kEpsilon, plain SIMPLE "between",
    1e-4 on every field, endTime 3000, fields every 500. Function objects: forces on the tubes, probes
    behind the last tube. 6,492 cells. Why: a deep sparse bank with the standard model (heldout-v2's
    inline kEpsilon row wandered)."""
    roles = V2.square_tube_bank(case, 8, 0.6, 1.5, (30, 12, 8, 60), [8, 14, 8], staggered=True)
    finish(case, roles, Flow("kEpsilon", 1.25e-4, False, BETWEEN, ALL_1E4, 3000, 1.0, 0.07 * 1.5,
                             start="(1 0 0)"), 500,
           [forces(["walls"], (0, 0)), probes([(14.2, 0.75)])])


# ---------------------------------------------------------------------------------------------------
# Impinging jets (heldout-v2's confined slot jet: half domain, slot width B = 1, U 1 downwards)


@register("impinging-jet", "2-D confined slot jet on a plate, H/B 7, half domain, Re 1.5e4")
def jetSST(case: Path) -> None:
    """impinging-jet. The plate 7 B below the slot, 20 B to the outlet. U 1, nu 6.67e-5: Re 1.5e4 on B.
    kOmegaSST, plain SIMPLE conservative, 1e-4 on every field, endTime 3000, fields every 1000. Function
    objects: probes on the jet's axis near the plate and in the wall jet, the plate's area-averaged
    pressure. 9,000 cells. Why: a jet between the near and far ones, SST on plain SIMPLE."""
    roles = V2.slot_jet(case, 7, 20, [10, 30, 60], 90)
    finish(case, roles, Flow("kOmegaSST", 6.67e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07), 1000,
           [probes([(0.05, 0.3), (4, 0.1)]), surface("platePressure", "plate", "areaAverage", ["p"])])


@register("impinging-jet", "2-D confined slot jet on a plate, H/B 14, half domain, Re 3e4, SIMPLEC")
def jetLongKE(case: Path) -> None:
    """impinging-jet. The plate 14 B below the slot, 28 B to the outlet, fine. U 1, nu 3.33e-5: Re 3e4.
    kEpsilon, SIMPLEC, U 0.9, p 1 (written out), turbulence 0.9; 1e-5 on every field (heat-transfer users
    converge impingement further); endTime 3000, fields every 500. Function objects: the plate's
    area-averaged pressure, probes on the axis. 15,600 cells. Why: the longest jet, the standard model,
    a tight criterion; one of the long cases."""
    roles = V2.slot_jet(case, 14, 28, [12, 36, 72], 130)
    finish(case, roles, Flow("kEpsilon", 3.33e-5, True, {"U": 0.9, "p": 1, "turbulence": 0.9}, ALL_1E5, 3000,
                             1.0, 0.07), 500,
           [surface("platePressure", "plate", "areaAverage", ["p"]), probes([(0.05, 0.5), (0.05, 7)])])


@register("impinging-jet", "2-D confined slot jet on a plate, H/B 2.5, half domain, Re 4e4")
def jetNearRKE(case: Path) -> None:
    """impinging-jet. The plate 2.5 B below the slot, 12 B to the outlet. U 1, nu 2.5e-5: Re 4e4.
    realizableKE, plain SIMPLE "between", 1e-4 on every field, endTime 3000, fields every 1000. No function
    objects (a user who looks at the fields). 4,500 cells. Why: a near jet (its potential core reaches
    the plate) at a higher Reynolds number than heldout-v2's, with the realizable model."""
    roles = V2.slot_jet(case, 2.5, 12, [10, 30, 50], 50)
    finish(case, roles, Flow("realizableKE", 2.5e-5, False, BETWEEN, ALL_1E4, 3000, 1.0, 0.07), 1000)


# ---------------------------------------------------------------------------------------------------
# Ventilated rooms (heldout-v2's room: a ceiling slot on the left wall, a low outlet; starts from rest)


@register("ventilated-room", "2-D room 7.5 x 3 m, 0.1 m ceiling slot at 3 m/s, low outlet opposite, Re 2e4")
def roomSlotKE(case: Path) -> None:
    """ventilated-room. A 7.5 x 3 m room, a slot 0.1 m high at the top of the left wall blowing 3 m/s along
    the ceiling, an outlet 0.3 m high at the bottom of the right wall. nu 1.5e-5: Re 2e4 on the slot.
    kEpsilon, plain SIMPLE conservative, 1e-4 on every field, endTime 3000, fields every 500. Function
    objects: probes at a seated occupant's head (mid-room, 1.1 m) and near the floor by the outlet wall,
    the room's volume-averaged k. 14,280 cells. Why: turbulent rooms did not converge under their own
    settings; a narrow, fast slot; one of the long cases."""
    roles = V2.room(case, 7.5, [0, 0.3, 2.9, 3], (140, (12, 80, 10)), 3.0)
    finish(case, roles, Flow("kEpsilon", 1.5e-5, False, CONSERVATIVE, ALL_1E4, 3000, 3.0, 0.07 * 0.1), 500,
           [probes([(3.75, 1.1), (6.5, 0.3)]), volume_average("roomK", ["k"])])


@register("ventilated-room", "2-D room 5 x 3.6 m, ceiling slot and low extract on the same wall, Re 1.5e4, "
                             "SIMPLEC")
def roomSameWallSST(case: Path) -> None:
    """ventilated-room. A 5 x 3.6 m room supplied through a slot 0.15 m high at the top of the left wall
    (1.5 m/s along the ceiling) and extracted through a grille 0.3 m high at the bottom of the same wall.
    nu 1.5e-5: Re 1.5e4 on the slot. kOmegaSST, SIMPLEC, U 0.9, p unrelaxed, turbulence 0.8, 1e-4 on every
    field, endTime 3000, fields every 1000. Function objects: probes mid-room at 1.2 m and by the far
    wall, the supply's area-averaged pressure. 12,320 cells. Why: a room-filling eddy (supply and
    extract on one wall) under SST; one of the long cases."""
    roles = V2.room(case, 5, [0, 0.3, 3.45, 3.6], (110, (12, 90, 10)), 1.5, outlet_wall="left")
    finish(case, roles, Flow("kOmegaSST", 1.5e-5, True, {"U": 0.9, "turbulence": 0.8}, ALL_1E4, 3000, 1.5,
                             0.07 * 0.15), 1000,
           [probes([(2.5, 1.2), (4.7, 1.8)]), surface("supplyPressure", "inlet", "areaAverage", ["p"])])


@register("ventilated-room", "2-D long room 12 x 3 m, 0.2 m ceiling slot, low outlet opposite, Re 1.6e4, "
                             "SIMPLEC")
def roomLongRKE(case: Path) -> None:
    """ventilated-room. A 12 x 3 m room (a hall), a slot 0.2 m high at the top of the left wall blowing
    1.2 m/s along the ceiling, an outlet 0.4 m high at the bottom of the right wall. nu 1.5e-5: Re 1.6e4
    on the slot. realizableKE, SIMPLEC, U 0.9, p unrelaxed, turbulence 0.9, 1e-4 on every field, endTime
    3000, fields every 1000. No function objects. 17,280 cells. Why: a room longer than the ceiling jet's
    reach, whose far half is fed by a weak return flow; one of the long cases."""
    roles = V2.room(case, 12, [0, 0.4, 2.8, 3], (160, (12, 84, 12)), 1.2)
    finish(case, roles, Flow("realizableKE", 1.5e-5, True, {"U": 0.9, "turbulence": 0.9}, ALL_1E4, 3000, 1.2,
                             0.07 * 0.2), 1000)


# ---------------------------------------------------------------------------------------------------
# Annuli


@register("annulus", "2-D concentric annulus, radius ratio 0.45, inner wall rotating, Re 6e4, SIMPLEC")
def annulusWideRKE(case: Path) -> None:
    """annulus. Inner radius 1 rotating at 1 rad/s, outer 2.2 at rest; nu 2e-5: Re 6e4 on the inner wall's
    speed and the gap. realizableKE, SIMPLEC, U 0.9, p unrelaxed, turbulence 0.8, 1e-4 on every field,
    endTime 3000, fields every 500. pRefCell 0. Function objects: forces on the inner wall (its moment
    about the axis: the torque). 12,672 cells. Why: wide gaps with the realizable model did not converge
    in heldout-v3 (plain SIMPLE); the widest gap, SIMPLEC; one of the long cases."""
    roles = rotating_annulus(case, 2.2, 0, (44, 72))
    finish(case, roles, Flow("realizableKE", 2e-5, True, {"U": 0.9, "turbulence": 0.8}, ALL_1E4, 3000, 1.0,
                             0.07 * 1.2, closed=True), 500, [forces(["innerWall"], (0, 0))])


@register("annulus", "2-D eccentric annulus (journal bearing), radius ratio 0.56, eccentricity 0.3, Re 3.2e4")
def bearingSST(case: Path) -> None:
    """annulus. A journal bearing: inner radius 1 centred 0.3 off the centre of an outer radius 1.8 (gaps
    0.5 to 1.1), the inner wall rotating at 1 rad/s. nu 2.5e-5: Re 3.2e4 on the inner wall's speed and the
    mean gap. kOmegaSST, plain SIMPLE conservative, 1e-4 on every field, endTime 3000, fields every 1000.
    pRefCell 0. Function objects: forces on the journal (the torque, and the load that pushes it off
    centre). 9,600 cells. Why: heldout-v2's eccentric annulus (kEpsilon) did not converge; another
    eccentricity, Reynolds number and model."""
    roles = rotating_annulus(case, 1.8, 0.3, (40, 60))
    finish(case, roles, Flow("kOmegaSST", 2.5e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07 * 0.8,
                             closed=True), 1000, [forces(["innerWall"], (0.3, 0))])


# ---------------------------------------------------------------------------------------------------
# Porous obstacles (a cellZone of the blockMesh, a Darcy-Forchheimer explicitPorositySource)


@register("porous-obstacle", "2-D walled channel, a dense porous block on the centre line, Re 5e4")
def porousDenseSIMPLE(case: Path) -> None:
    """porous-obstacle. A walled channel of height 1 with a porous block 1.2 long, 0.6 high on its centre
    line (d 3e5 1/m2, f 60 1/m: most of the flow goes round it), 4 upstream, 9 downstream. U 1, nu 2e-5:
    Re 5e4 on the height. kOmegaSST, plain SIMPLE "between", 1e-4 on every field, endTime 3000, fields
    every 500. Function objects: the inlet's area-averaged pressure (the pressure drop), probes in the
    wake. 14,592 cells. Why: dense porous blocks under SST did not converge (heldout-v3's, SIMPLEC); a
    denser, longer one on plain SIMPLE; one of the long cases."""
    roles = porous_block(case, [-4, 0, 1.2, 10.2], [0, 0.2, 0.8, 1], [46, 36, 110], [20, 36, 20],
                         ["((0.5 0.5 4) (0.5 0.5 1))", 1, "((0.5 0.5 1) (0.5 0.5 0.25))"], (1, 1),
                         ("(3e5 3e5 3e5)", "(60 60 60)"), 2)
    finish(case, roles, Flow("kOmegaSST", 2e-5, False, BETWEEN, ALL_1E4, 3000, 1.0, 0.07, start="(1 0 0)"),
           500, [surface("inletPressure", "inlet", "areaAverage", ["p"]), probes([(2.2, 0.5), (4.2, 0.5)])])


@register("porous-obstacle", "2-D walled channel, a porous hedge on the floor, 0.4 of the height, Re 1e5, "
                             "SIMPLEC")
def porousHedge(case: Path) -> None:
    """porous-obstacle. A walled channel of height 1 with a porous block standing on its floor (a hedge or
    a filter bank), 0.5 long, 0.4 high (d 5e4 1/m2, f 15 1/m), 4 upstream, 10 downstream. U 1, nu 1e-5:
    Re 1e5 on the height. realizableKE, SIMPLEC, U 0.9, p unrelaxed, turbulence 0.9; 1e-5 on every field (a
    tight user); endTime 3000, fields every 1000. Function objects: the inlet's area-averaged pressure, the
    outlet's volume flux (sum of phi), probes above and behind the hedge. 12,600 cells. Why: a
    wall-mounted porous obstacle (the flow over it separates from its top edge); one of the long cases."""
    roles = porous_block(case, [-4, 0, 0.5, 10.5], [0, 0.4, 1], [50, 20, 110], [30, 40],
                         ["((0.5 0.5 4) (0.5 0.5 1))", "((0.5 0.5 1) (0.5 0.5 0.25))"], (1, 0),
                         ("(5e4 5e4 5e4)", "(15 15 15)"), 1)
    finish(case, roles, Flow("realizableKE", 1e-5, True, {"U": 0.9, "turbulence": 0.9}, ALL_1E5, 3000, 1.0,
                             0.07, start="(1 0 0)"), 1000,
           [surface("inletPressure", "inlet", "areaAverage", ["p"]),
            surface("outletFlux", "outlet", "sum", ["phi"]), probes([(0.25, 0.6), (2, 0.2)])])


# ---------------------------------------------------------------------------------------------------
# Wall cavities (heldout-v2's: a channel of height 2 over a floor cavity, 5 upstream, 10 downstream)


@register("wall-cavity", "2-D channel over a deep floor cavity, L/D 0.75, Re 7.5e4")
def cavityDeepRKE(case: Path) -> None:
    """wall-cavity. A channel of height 2 over a cavity 1.5 long and 2 deep (L/D 0.75). U 1, nu 2e-5: Re
    7.5e4 on the length. realizableKE, plain SIMPLE conservative, 1e-4 on every field, endTime 3000,
    fields every 1000. No function objects. 8,040 cells. Why: turbulent cavities stalled in heldout-v2;
    a deep one between its square and deep ones, with the realizable model on plain SIMPLE."""
    roles = V2.cavity(case, 1.5, 2, [40, 36, 80], [50, 40])
    finish(case, roles, Flow("realizableKE", 2e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07 * 2,
                             start="(1 0 0)"), 1000)


@register("wall-cavity", "2-D channel over a shallow floor cavity, L/D 5, Re 3e4, SIMPLEC")
def cavityShallowSST(case: Path) -> None:
    """wall-cavity. A channel of height 2 over a cavity 5 long and 1 deep (L/D 5: the shear layer may
    touch the floor). U 1, nu 3.33e-5: Re 3e4 on the depth. kOmegaSST, SIMPLEC, U 0.9, p unrelaxed,
    turbulence 0.9, 1e-4 on every field, endTime 3000, fields every 500. Function objects: probes in the
    cavity (a quarter and three quarters along, half depth), the inlet's area-averaged pressure. 9,350
    cells. Why: a shallow cavity under SST (heldout-v2's L/D 4 was realizableKE)."""
    roles = V2.cavity(case, 5, 1, [40, 70, 80], [25, 40])
    finish(case, roles, Flow("kOmegaSST", 3.33e-5, True, {"U": 0.9, "turbulence": 0.9}, ALL_1E4, 3000, 1.0,
                             0.07 * 2, start="(1 0 0)"), 500,
           [probes([(1.25, -0.5), (3.75, -0.5)]), surface("inletPressure", "inlet", "areaAverage", ["p"])])
