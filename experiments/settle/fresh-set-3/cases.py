# SPDX-License-Identifier: GPL-3.0-or-later
"""The candidates of issue 56's third fresh set: one builder per case, each a plain steady simpleFoam case,
meshed, with its user's own settings and, on most, the function objects a user adds (forces or force
coefficients on a body, probes, surface and volume averages).

The first and second fresh sets (experiments/settle/fresh-set, fresh-set-2) were evaluated once and are
spent. These are new instances, none a case of them, of heldout-v2 or of heldout-v3, of the kinds whose own
settings tended not to converge there (turbulent bluff bodies alone, in tandem, side by side and near a
wall; tube banks; impinging jets; ventilated rooms; wall cavities; backward-facing steps): new dimensions,
Reynolds numbers, meshes, models and users' settings. No annulus, no porous obstacle and no symmetric
expansion (their kinds met their criterion in the earlier sets). Written down, with every case's settings
and function objects, BEFORE any of them ran (README.md has the rule that picks the set from them); no
case is changed after.

Users' settings as in the earlier sets: plain SIMPLE conservative (U 0.7, p 0.3, turbulence 0.7) or
"between" (U 0.8, p 0.2, turbulence 0.8); SIMPLEC U 0.8-0.9, p unrelaxed or 1 written out, turbulence
0.8-0.9; residualControl 1e-4 on every field, or 1e-5 (a tight user), or p 1e-3 with U and turbulence
1e-4; endTime 3000, deltaT 1, fields written every 500 or 1000 iterations.

The builders reuse the second fresh set's cases.py (its two-body namers and its widening channel; loaded by
path, not copied) and through it the first set's (function objects, ``finish``, body patch namer) and
heldout-v2's geometry helpers and field writers. What this file adds: a namer that gives each circular
cylinder of a grid its own patch by its block (two cylinders side by side, in one column).
"""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Callable
from pathlib import Path
from types import FunctionType, ModuleType

_SECOND_SET = Path(__file__).resolve().parent.parent / "fresh-set-2" / "cases.py"


def _second_set() -> ModuleType:
    """The second fresh set's cases.py under a name of its own (every set calls its file cases.py)."""
    name = "settle_fresh_set_second_cases"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, _SECOND_SET)
        sys.modules[name] = module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
        spec.loader.exec_module(module)  # type: ignore[union-attr]
    return sys.modules[name]


SECOND = _second_set()
V2, v2_module, TUTORIALS = SECOND.V2, SECOND.v2_module, SECOND.TUTORIALS
Flow, fresh, grid_2d, channel_mesh, channel_patches = (SECOND.Flow, SECOND.fresh, SECOND.grid_2d,
                                                       SECOND.channel_mesh, SECOND.channel_patches)
finish, forces, force_coeffs, probes, surface, volume_average = (SECOND.finish, SECOND.forces,
                                                                 SECOND.force_coeffs, SECOND.probes,
                                                                 SECOND.surface, SECOND.volume_average)
body_patches, two_bodies, widening = SECOND.body_patches, SECOND.two_bodies, SECOND.widening
CONSERVATIVE, BETWEEN, ALL_1E4, ALL_1E5, P_1E3 = (SECOND.CONSERVATIVE, SECOND.BETWEEN, SECOND.ALL_1E4,
                                                  SECOND.ALL_1E5, SECOND.P_1E3)
TWO_SIDED, DEPTH = SECOND.TWO_SIDED, SECOND.DEPTH

CASES: dict[str, Callable[[Path], None]] = {}
DESCRIPTIONS: dict[str, tuple[str, str, str]] = {}
#: The first set's register (add the decorated builder to CASES, its description to DESCRIPTIONS), its code
#: bound to this module's globals: it fills this set's CASES and DESCRIPTIONS, not an earlier set's.
register = FunctionType(SECOND.register.__code__, globals(), "register")


def block_cylinders(last_column: int, last_row: int,
                    names: dict[tuple[int, int], str]) -> Callable[[int, int, str], str]:
    """channel_patches, but the cylinder of block (i, j) is its own patch ``names[(i, j)]``."""
    plain = channel_patches(last_column, last_row)
    return lambda i, j, side: names[(i, j)] if side == "cylinder" else plain(i, j, side)


# ---------------------------------------------------------------------------------------------------
# Bluff bodies


@register("bluff-body", "2-D square cylinder in a wide channel, blockage 0.1, Re 1e5")
def squareOpenSST(case: Path) -> None:
    """bluff-body. A square cylinder (D = 1) centred in a channel of height 10 D, 5.5 D upstream, 15.5 D
    downstream. U 1, nu 1e-5: Re 1e5 on D. kOmegaSST, plain SIMPLE "between" (U 0.8, p 0.2, turbulence
    0.8), 1e-4 on every field, endTime 3000, fields every 1000. Function objects: forceCoeffs on the
    cylinder (Aref D x depth, about its centre), probes 2.5 D and 5.5 D behind it. 7,920 cells. Why: a
    nearly unconfined square cylinder at a high Reynolds number (fixed separation, strong shedding)."""
    fresh(case)
    solids = [(1, 1)]
    grid = grid_2d([-6, -0.5, 0.5, 16], [-5, -0.5, 0.5, 5], [30, 20, 80], [22, 20, 22],
                   body_patches(2, 2, solids), gx=[0.25, 1, 6], gy=[0.4, 1, 2.5], cells={solids[0]: "solid"})
    roles = channel_mesh(case, grid, obstacle="wall")
    finish(case, roles, Flow("kOmegaSST", 1e-5, False, BETWEEN, ALL_1E4, 3000, 1.0, 0.07 * 10,
                             start="(1 0 0)"), 1000,
           [force_coeffs(["obstacle"], (0, 0), 1, DEPTH), probes([(3, 0), (6, 0.5)])])


@register("bluff-body", "2-D 1.5:1 rectangular cylinder in a channel, blockage 1/7, Re 3e4, SIMPLEC")
def rectangleShortKE(case: Path) -> None:
    """bluff-body. A 1.5:1 rectangular cylinder (chord 1.5 D, D = 1) centred in a channel of height 7 D, 6 D
    upstream, 16 D downstream. U 1, nu 3.33e-5: Re 3e4 on D. kEpsilon, SIMPLEC, U 0.9, p unrelaxed,
    turbulence 0.9, 1e-4 on every field, endTime 3000, fields every 500. Function objects: forces on the
    body (moments about its centre), probes 2 D behind it and off the wake's axis. 9,128 cells. Why: a
    short section whose leading-edge shear layers pass close to its rear corners (no steady reattachment);
    the standard model on SIMPLEC."""
    fresh(case)
    solids = [(1, 1)]
    grid = grid_2d([-6, 0, 1.5, 17.5], [-3.5, -0.5, 0.5, 3.5], [32, 30, 90], [22, 20, 22],
                   body_patches(2, 2, solids), gx=[0.25, 1, 6], gy=[0.4, 1, 2.5], cells={solids[0]: "solid"})
    roles = channel_mesh(case, grid, obstacle="wall")
    finish(case, roles, Flow("kEpsilon", 3.33e-5, True, {"U": 0.9, "turbulence": 0.9}, ALL_1E4, 3000, 1.0,
                             0.07 * 7, start="(1 0 0)"), 500,
           [forces(["obstacle"], (0.75, 0)), probes([(3.5, 0), (5, 1)])])


@register("bluff-body", "2-D square rib on the floor of a channel (height h, length h), blockage 0.2, "
                        "Re 4e4, SIMPLEC")
def ribFloorSST(case: Path) -> None:
    """bluff-body. A square rib (h = 1 high, 1 long) on the floor of a channel of height 5 h, 6 h upstream,
    20 h downstream. U 1, nu 2.5e-5: Re 4e4 on h. kOmegaSST, SIMPLEC, U 0.85, p 1 (written out),
    turbulence 0.85, 1e-4 on every field, endTime 3000, fields every 1000. Function objects: forces on the
    rib (moments about its centre), probes in the separation behind it and near reattachment. 9,288 cells.
    Why: a wall-mounted block (a roughness rib, a low building): the separation over its top may
    reattach on it or behind it, a long recirculation downstream."""
    fresh(case)
    solids = [(1, 0)]
    grid = grid_2d([-6, 0, 1, 21], [0, 1, 5], [30, 16, 110], [24, 38], body_patches(2, 1, solids),
                   gx=[0.25, 1, 6], gy=[TWO_SIDED, TWO_SIDED], cells={solids[0]: "solid"})
    roles = channel_mesh(case, grid, obstacle="wall")
    finish(case, roles, Flow("kOmegaSST", 2.5e-5, True, {"U": 0.85, "p": 1, "turbulence": 0.85}, ALL_1E4,
                             3000, 1.0, 0.07 * 5, start="(1 0 0)"), 1000,
           [forces(["obstacle"], (0.5, 0.5)), probes([(3, 0.3), (8, 0.3)])])


@register("bluff-body", "2-D two square cylinders in tandem, spacing 2.5 D, in a channel, blockage 1/8, "
                        "Re 2e4")
def squaresCloseKE(case: Path) -> None:
    """bluff-body. Two square cylinders (D = 1) one behind the other, centres 2.5 D apart (a gap of 1.5 D),
    on the centre line of a channel of height 8 D, 4.5 D upstream of the first, 15 D downstream of the
    second. U 1, nu 5e-5: Re 2e4 on D. kEpsilon, plain SIMPLE conservative (U 0.7, p 0.3, turbulence 0.7),
    1e-4 on every field, endTime 3000, fields every 500. Function objects: forceCoeffs on each cylinder
    (Aref D x depth, about its centre), probes in the gap and the wake. 8,336 cells. Why: at 2.5 D the
    gap is near the critical spacing (the front body's shear layers either reattach on the rear body or
    roll up in the gap)."""
    fresh(case)
    grid = grid_2d([-5, -0.5, 0.5, 2, 3, 18], [-4, -0.5, 0.5, 4], [26, 16, 20, 16, 80], [20, 16, 20],
                   two_bodies(4, 2, (1, 1), (3, 1), ("front", "rear")), gx=[0.25, 1, 1, 1, 6],
                   gy=[0.4, 1, 2.5], cells={(1, 1): "solid", (3, 1): "solid"})
    roles = channel_mesh(case, grid, front="wall", rear="wall")
    finish(case, roles, Flow("kEpsilon", 5e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07 * 8,
                             start="(1 0 0)"), 500,
           [force_coeffs(["front"], (0, 0), 1, DEPTH, name="frontCoeffs"),
            force_coeffs(["rear"], (2.5, 0), 1, DEPTH, name="rearCoeffs"), probes([(1.25, 0.25), (6, 0)])])


@register("bluff-body", "2-D circular cylinder in a narrow channel, blockage 0.25, Re 3e4")
def cylinderConfinedRKE(case: Path) -> None:
    """bluff-body. A circular cylinder (D = 1, O-grid) centred in a channel of height 4 D, 4 D upstream,
    14 D downstream. U 1, nu 3.33e-5: Re 3e4 on D. realizableKE, plain SIMPLE conservative, 1e-4 on every
    field, endTime 3000, fields every 1000. Function objects: forceCoeffs on the cylinder (Aref D x depth,
    about its centre), probes 2 D behind it and off its axis. 8,832 cells. Why: a confined round cylinder
    (the walls accelerate the flow past it and squeeze its wake), the realizable model on plain SIMPLE."""
    fresh(case)
    grid = grid_2d([-5, -1, 1, 15], [-2, -1, 1, 2], [30, 24, 90], [14, 24, 14], channel_patches(2, 2),
                   gx=[0.25, 1, 5], gy=[0.5, 1, 2], cells={(1, 1): ("cylinder", 0.5, 20, 0.2)})
    roles = channel_mesh(case, grid, cylinder="wall")
    finish(case, roles, Flow("realizableKE", 3.33e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07 * 4,
                             start="(1 0 0)"), 1000,
           [force_coeffs(["cylinder"], (0, 0), 1, DEPTH), probes([(2, 0), (4, 1)])])


@register("bluff-body", "2-D two circular cylinders side by side, centres 2.5 D apart, in a channel, "
                        "blockage 2/9, Re 2e4, SIMPLEC")
def cylinderPairSST(case: Path) -> None:
    """bluff-body. Two circular cylinders (D = 1, O-grids) side by side across a channel of height 9 D,
    centres 2.5 D apart (a gap of 1.5 D), 4.5 D upstream, 14.5 D downstream. U 1, nu 5e-5: Re 2e4 on D.
    kOmegaSST, SIMPLEC, U 0.9, p unrelaxed, turbulence 0.9, 1e-4 on every field, endTime 3000, fields
    every 500. Function objects: forces on each cylinder (moments about its centre), probes behind the gap
    and in both wakes. 10,640 cells. Why: the gap flow between two round bodies is biased to one side
    (the wakes narrow and wide, two mirror solutions); one of the long cases."""
    fresh(case)
    grid = grid_2d([-5, -1, 1, 15], [-4.5, -2.25, -0.25, 0.25, 2.25, 4.5], [24, 20, 76], [14, 20, 6, 20, 14],
                   block_cylinders(2, 4, {(1, 1): "lowerCylinder", (1, 3): "upperCylinder"}),
                   gx=[0.25, 1, 5], gy=[0.5, 1, 1, 1, 2],
                   cells={(1, 1): ("cylinder", 0.5, 16, 0.2), (1, 3): ("cylinder", 0.5, 16, 0.2)})
    roles = channel_mesh(case, grid, lowerCylinder="wall", upperCylinder="wall")
    finish(case, roles, Flow("kOmegaSST", 5e-5, True, {"U": 0.9, "turbulence": 0.9}, ALL_1E4, 3000, 1.0,
                             0.07 * 9, start="(1 0 0)"), 500,
           [forces(["lowerCylinder"], (0, -1.25), name="lowerForces"),
            forces(["upperCylinder"], (0, 1.25), name="upperForces"),
            probes([(2, 0), (4, -1.25), (4, 1.25)])])


@register("bluff-body", "2-D circular cylinder close to the floor of a channel, gap 0.25 D, Re 4e4, SIMPLEC")
def cylinderFloorKE(case: Path) -> None:
    """bluff-body. A circular cylinder (D = 1, O-grid) a quarter diameter above the floor of a channel of
    height 4 D (the ceiling 2.5 D above it), 5.25 D upstream, 15.25 D downstream. U 1, nu 2.5e-5: Re 4e4
    on D. kEpsilon, SIMPLEC, U 0.8, p 1 (written out), turbulence 0.8, 1e-4 on every field, endTime 3000,
    fields every 1000. Function objects: forces on the cylinder (moments about its centre), probes in the
    gap under it and 3 D behind it. 8,276 cells. Why: a pipeline close to the seabed: the gap jet and the
    floor's boundary layer fight the upper shear layer, the wake leans off the floor."""
    fresh(case)
    grid = grid_2d([-6, -0.75, 0.75, 16], [-0.75, 0.75, 3.25], [34, 24, 96], [24, 26], channel_patches(2, 1),
                   gx=[0.25, 1, 5], gy=[1, 3], cells={(1, 0): ("cylinder", 0.5, 12, 0.3)})
    roles = channel_mesh(case, grid, cylinder="wall")
    finish(case, roles, Flow("kEpsilon", 2.5e-5, True, {"U": 0.8, "p": 1, "turbulence": 0.8}, ALL_1E4, 3000,
                             1.0, 0.07 * 4, start="(1 0 0)"), 1000,
           [forces(["cylinder"], (0, 0)), probes([(0, -0.625), (3, 0.25)])])


@register("bluff-body", "2-D 2:1 rectangular cylinder half a height above the floor of a channel, blockage "
                        "0.2, Re 5e4")
def rectangleGroundRKE(case: Path) -> None:
    """bluff-body. A 2:1 rectangular cylinder (chord 2 D, D = 1) with a gap of 0.5 D under it above the
    floor of a channel of height 5 D, 5 D upstream, 15 D downstream. U 1, nu 2e-5: Re 5e4 on D.
    realizableKE, plain SIMPLE "between"; 1e-5 on every field (a tight user: the lift is the answer);
    endTime 3000, fields every 500. Function objects: forceCoeffs on the body (Aref D x depth, about its
    centre), probes in the gap under it and in its wake. 8,100 cells. Why: a body in ground effect (a
    vehicle section): the gap flow and the upper shear layer make an asymmetric, unsteady wake."""
    fresh(case)
    solids = [(1, 1)]
    grid = grid_2d([-5, 0, 2, 17], [0, 0.5, 1.5, 5], [30, 30, 85], [12, 20, 28], body_patches(2, 2, solids),
                   gx=[0.25, 1, 6], gy=[TWO_SIDED, 1, 2.5], cells={solids[0]: "solid"})
    roles = channel_mesh(case, grid, obstacle="wall")
    finish(case, roles, Flow("realizableKE", 2e-5, False, BETWEEN, ALL_1E5, 3000, 1.0, 0.07 * 5,
                             start="(1 0 0)"), 500,
           [force_coeffs(["obstacle"], (1, 1), 1, DEPTH), probes([(1, 0.25), (5, 1)])])


# ---------------------------------------------------------------------------------------------------
# Tube banks


@register("tube-bank", "2-D inline bank, 5 x 3 circular tubes, pitch 1.6 D, Re 2e4, SIMPLEC")
def tubeInlineKE(case: Path) -> None:
    """tube-bank. An inline bank of 5 columns x 3 rows of circular tubes (D = 1, O-grids, pitch 1.6 D both
    ways) between channel walls, 6 D upstream, 15 D downstream. U 1, nu 5e-5: Re 2e4. kEpsilon, SIMPLEC,
    U 0.85, p unrelaxed, turbulence 0.85, 1e-4 on every field, endTime 3000, fields every 1000. Function
    objects: forces on the tubes (moments about the bank's centre), the inlet's area-averaged pressure
    (the bank's pressure drop). 10,500 cells. Why: a deeper inline bank than heldout-v2's, the standard
    model on SIMPLEC; one of the long cases."""
    roles = V2.tube_bank(case, 5, 3, 1.6, 14, 8, staggered=False, ends=(30, 60))
    finish(case, roles, Flow("kEpsilon", 5e-5, True, {"U": 0.85, "turbulence": 0.85}, ALL_1E4, 3000, 1.0,
                             0.07 * 4.8, start="(1 0 0)"), 1000,
           [forces(["cylinder"], (4, 2.4)), surface("inletPressure", "inlet", "areaAverage", ["p"])])


@register("tube-bank", "2-D staggered bank of 8 circular tubes, 4 x 4, pitch 2 D, Re 1e4")
def tubeStaggerWideSST(case: Path) -> None:
    """tube-bank. A staggered bank (checkerboard) of 8 circular tubes (D = 1, O-grids) on a 2 D grid, 4
    columns x 4 rows, between channel walls, 6 D upstream, 15 D downstream. U 1, nu 1e-4: Re 1e4.
    kOmegaSST, plain SIMPLE conservative; p 1e-3, U and turbulence 1e-4 (a bank's user settles for p
    1e-3); endTime 3000, fields every 500. Function objects: forces on the tubes (moments about the bank's
    centre), the inlet's area-averaged pressure. 10,192 cells. Why: a sparse staggered bank whose tubes
    each shed into the next row's approach flow, SST on plain SIMPLE; one of the long cases."""
    roles = V2.tube_bank(case, 4, 4, 2.0, 14, 8, staggered=True, ends=(30, 60))
    finish(case, roles, Flow("kOmegaSST", 1e-4, False, CONSERVATIVE, P_1E3, 3000, 1.0, 0.07 * 8,
                             start="(1 0 0)"), 500,
           [forces(["cylinder"], (4, 4)), surface("inletPressure", "inlet", "areaAverage", ["p"])])


@register("tube-bank", "2-D staggered bank of square tubes, 5 deep, pitches 1.8 D x 2.2 D, between "
                       "symmetry planes through tube centres, Re 1.2e4")
def squareBankStaggerRKE(case: Path) -> None:
    """tube-bank. A staggered bank of square tubes (D = 1), 5 deep, longitudinal pitch 1.8 D, transverse
    2.2 D (the strip between symmetry planes through neighbouring tubes' centres, 2.2 D apart), 6 D
    upstream, 15 D downstream. U 1, nu 8.33e-5: Re 1.2e4. realizableKE, plain SIMPLE "between", 1e-4 on
    every field, endTime 3000, fields every 1000. Function objects: forces on the tubes (moments about
    the origin), probes behind the last tube. 8,312 cells. Why: flow weaving between square tubes, each
    sheltering a cavity eddy behind it, the realizable model on plain SIMPLE."""
    roles = V2.square_tube_bank(case, 5, 0.8, 2.2, (30, 14, 12, 60), [12, 20, 12], staggered=True)
    finish(case, roles, Flow("realizableKE", 8.33e-5, False, BETWEEN, ALL_1E4, 3000, 1.0, 0.07 * 2.2,
                             start="(1 0 0)"), 1000,
           [forces(["walls"], (0, 0)), probes([(10.2, 0.6)])])


# ---------------------------------------------------------------------------------------------------
# Impinging jets (heldout-v2's confined slot jet: half domain, slot width B = 1, U 1 downwards)


@register("impinging-jet", "2-D confined slot jet on a plate, H/B 6, half domain, Re 2e4, SIMPLEC")
def jetSixKE(case: Path) -> None:
    """impinging-jet. The plate 6 B below the slot, 16 B to the outlet. U 1, nu 5e-5: Re 2e4 on B.
    kEpsilon, SIMPLEC, U 0.8, p 1 (written out), turbulence 0.8, 1e-4 on every field, endTime 3000, fields
    every 500. Function objects: the plate's area-averaged pressure, probes on the axis near the plate and
    in the wall jet. 8,272 cells. Why: a jet just past its potential core's length, with the standard model
    (its stagnation-point excess of k), on SIMPLEC at a length it holds."""
    roles = V2.slot_jet(case, 6, 16, [10, 28, 56], 88)
    finish(case, roles, Flow("kEpsilon", 5e-5, True, {"U": 0.8, "p": 1, "turbulence": 0.8}, ALL_1E4, 3000,
                             1.0, 0.07), 500,
           [surface("platePressure", "plate", "areaAverage", ["p"]), probes([(0.05, 0.4), (3.5, 0.1)])])


@register("impinging-jet", "2-D confined slot jet on a plate, H/B 9, half domain, Re 5e4")
def jetNineSST(case: Path) -> None:
    """impinging-jet. The plate 9 B below the slot, 22 B to the outlet. U 1, nu 2e-5: Re 5e4 on B.
    kOmegaSST, plain SIMPLE "between", 1e-4 on every field, endTime 3000, fields every 1000. Function
    objects: probes on the jet's axis (1 B and 4.5 B above the plate), the plate's area-averaged pressure.
    10,368 cells. Why: a long jet at a high Reynolds number, SST on plain SIMPLE; one of the long cases."""
    roles = V2.slot_jet(case, 9, 22, [12, 32, 64], 96)
    finish(case, roles, Flow("kOmegaSST", 2e-5, False, BETWEEN, ALL_1E4, 3000, 1.0, 0.07), 1000,
           [probes([(0.05, 1), (0.05, 4.5)]), surface("platePressure", "plate", "areaAverage", ["p"])])


@register("impinging-jet", "2-D confined slot jet on a plate, H/B 4, half domain, Re 1.5e4, SIMPLEC")
def jetFourRKE(case: Path) -> None:
    """impinging-jet. The plate 4 B below the slot, 15 B to the outlet. U 1, nu 6.67e-5: Re 1.5e4 on B.
    realizableKE, SIMPLEC, U 0.9, p unrelaxed, turbulence 0.9; p 1e-3, U and turbulence 1e-4; endTime
    3000, fields every 1000. No function objects (a user who looks at the fields). 5,888 cells. Why: a
    near jet (its potential core reaches the plate) with the realizable model on SIMPLEC."""
    roles = V2.slot_jet(case, 4, 15, [10, 30, 52], 64)
    finish(case, roles, Flow("realizableKE", 6.67e-5, True, {"U": 0.9, "turbulence": 0.9}, P_1E3, 3000, 1.0,
                             0.07), 1000)


# ---------------------------------------------------------------------------------------------------
# Ventilated rooms (heldout-v2's room: a ceiling slot on the left wall, a low outlet; starts from rest)


@register("ventilated-room", "2-D room 4 x 4 m, 0.08 m ceiling slot at 2.5 m/s, low outlet opposite, "
                             "Re 1.3e4, SIMPLEC")
def roomSquareSST(case: Path) -> None:
    """ventilated-room. A 4 x 4 m room (a tall square section: an atrium's bay), a slot 0.08 m high at the
    top of the left wall blowing 2.5 m/s along the ceiling, an outlet 0.2 m high at the bottom of the right
    wall. nu 1.5e-5: Re 1.3e4 on the slot. kOmegaSST, SIMPLEC, U 0.9, p unrelaxed, turbulence 0.9, 1e-4 on
    every field, endTime 3000, fields every 500. Function objects: probes at a standing occupant's head
    (1.7 m, half-way) and by the outlet wall's foot, the room's volume-averaged k. 9,792 cells. Why: a
    thin jet that must turn down a tall far wall (it may separate from it) and drive a square room's
    eddy, SST on SIMPLEC; one of the long cases."""
    roles = V2.room(case, 4, [0, 0.2, 3.92, 4], (96, (10, 84, 8)), 2.5)
    finish(case, roles, Flow("kOmegaSST", 1.5e-5, True, {"U": 0.9, "turbulence": 0.9}, ALL_1E4, 3000, 2.5,
                             0.07 * 0.08), 500,
           [probes([(2, 1.7), (3.7, 0.3)]), volume_average("roomK", ["k"])])


@register("ventilated-room", "2-D room 8 x 3 m, 0.15 m ceiling slot at 2 m/s, low outlet opposite, Re 2e4")
def roomMediumRKE(case: Path) -> None:
    """ventilated-room. An 8 x 3 m room, a slot 0.15 m high at the top of the left wall blowing 2 m/s along
    the ceiling, an outlet 0.35 m high at the bottom of the right wall. nu 1.5e-5: Re 2e4 on the slot.
    realizableKE, plain SIMPLE conservative, 1e-4 on every field, endTime 3000, fields every 1000. No
    function objects (a user who looks at the fields). 10,400 cells. Why: a room near the ceiling jet's
    reach (its far wall fed by a weakening jet), the realizable model on plain SIMPLE; one of the long
    cases."""
    roles = V2.room(case, 8, [0, 0.35, 2.85, 3], (130, (10, 60, 10)), 2.0)
    finish(case, roles, Flow("realizableKE", 1.5e-5, False, CONSERVATIVE, ALL_1E4, 3000, 2.0, 0.07 * 0.15),
           1000)


# ---------------------------------------------------------------------------------------------------
# Wall cavities (heldout-v2's: a channel of height 2 over a floor cavity, 5 upstream, 10 downstream)


@register("wall-cavity", "2-D channel over a floor cavity 1.5 long, 1 deep (L/D 1.5), Re 4e4, SIMPLEC")
def cavityMediumRKE(case: Path) -> None:
    """wall-cavity. A channel of height 2 over a cavity 1.5 long and 1 deep (L/D 1.5). U 1, nu 2.5e-5: Re
    4e4 on the depth. realizableKE, SIMPLEC, U 0.9, p 1 (written out), turbulence 0.9, 1e-4 on every
    field, endTime 3000, fields every 500. Function objects: a probe in the cavity's eddy, the inlet's
    area-averaged pressure. 7,320 cells. Why: an open cavity between square and L/D 2, its shear layer
    striking the downstream corner; the realizable model on SIMPLEC."""
    roles = V2.cavity(case, 1.5, 1, [40, 36, 80], [30, 40])
    finish(case, roles, Flow("realizableKE", 2.5e-5, True, {"U": 0.9, "p": 1, "turbulence": 0.9}, ALL_1E4,
                             3000, 1.0, 0.07 * 2, start="(1 0 0)"), 500,
           [probes([(0.75, -0.5)]), surface("inletPressure", "inlet", "areaAverage", ["p"])])


@register("wall-cavity", "2-D channel over a long floor cavity, L/D 3.5, Re 3e4")
def cavityWideKE(case: Path) -> None:
    """wall-cavity. A channel of height 2 over a cavity 3.5 long and 1 deep (L/D 3.5: the shear layer
    nearly touches the floor). U 1, nu 3.33e-5: Re 3e4 on the depth. kEpsilon, plain SIMPLE "between",
    1e-4 on every field, endTime 3000, fields every 1000. No function objects (a user who looks at the
    fields). 8,880 cells. Why: a long open cavity (one or two eddies), the standard model on plain
    SIMPLE."""
    roles = V2.cavity(case, 3.5, 1, [40, 60, 80], [28, 40])
    finish(case, roles, Flow("kEpsilon", 3.33e-5, False, BETWEEN, ALL_1E4, 3000, 1.0, 0.07 * 2,
                             start="(1 0 0)"), 1000)


# ---------------------------------------------------------------------------------------------------
# Backward-facing steps (fresh-set-2's channel that widens at x = 0; no symmetric expansion)


@register("sudden-expansion", "2-D backward-facing step, expansion ratio 1.5, Re 4e4, SIMPLEC")
def stepWideSST(case: Path) -> None:
    """sudden-expansion. A channel of height 2 h widening at a step of height h = 1 to 3 h, 4 h upstream,
    30 h downstream. U 1, nu 2.5e-5: Re 4e4 on h. kOmegaSST, SIMPLEC, U 0.85, p 1 (written out),
    turbulence 0.85, 1e-4 on every field, endTime 3000, fields every 500. Function objects: probes in the
    recirculation and near reattachment, the inlet's area-averaged pressure. 10,080 cells. Why: a step
    with a thick inflow (expansion ratio 1.5) under SST, whose separated shear layer flaps; one of the
    long cases."""
    roles = widening(case, [0, 1, 3], [0], (30, 150), [24, 36])
    finish(case, roles, Flow("kOmegaSST", 2.5e-5, True, {"U": 0.85, "p": 1, "turbulence": 0.85}, ALL_1E4,
                             3000, 1.0, 0.07 * 2, start="(1 0 0)"), 500,
           [probes([(3, 0.3), (8, 0.2)]), surface("inletPressure", "inlet", "areaAverage", ["p"])])


@register("sudden-expansion", "2-D tall backward-facing step, expansion ratio 3, Re 4e4")
def stepTallKE(case: Path) -> None:
    """sudden-expansion. A channel of height h/2 widening at a step of height h = 2 to 1.5 h (expansion
    ratio 3), 4 upstream, 30 downstream. U 1, nu 5e-5: Re 4e4 on h. kEpsilon, plain SIMPLE conservative,
    1e-4 on every field, endTime 3000, fields every 1000. Function objects: probes in the recirculation
    and near reattachment, the outlet's volume flux (sum of phi). 7,600 cells. Why: a thin jet over a tall
    step: a long recirculation with a secondary eddy in the corner, the standard model on plain SIMPLE."""
    roles = widening(case, [0, 2, 3], [0], (30, 140), [30, 20])
    finish(case, roles, Flow("kEpsilon", 5e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07,
                             start="(1 0 0)"), 1000,
           [probes([(5, 0.5), (14, 0.3)]), surface("outletFlux", "outlet", "sum", ["phi"])])
