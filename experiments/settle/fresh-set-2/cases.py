# SPDX-License-Identifier: GPL-3.0-or-later
"""The candidates of issue 56's second fresh set: one builder per case, each a plain steady simpleFoam
case, meshed, with its user's own settings and, on most, the function objects a user adds (forces or force
coefficients on a body, probes, surface and volume averages).

The first fresh set (experiments/settle/fresh-set) was evaluated once and is spent. These are new
instances, none a case of it, of heldout-v2 or of heldout-v3, of the kinds whose own settings tended not to
converge there (turbulent bluff bodies alone, in tandem, side by side and near a wall; tube banks;
impinging jets not too long for SIMPLEC; ventilated rooms; wall cavities), with two sudden expansions (a
backward-facing step and a symmetric one), one annulus and one porous obstacle (the kinds that converged
in the first set, held to one each): new dimensions, Reynolds numbers, meshes, models and users' settings.
Written down, with every case's settings and function objects, BEFORE any of them ran (README.md has the
rule that picks the set from them); no case is changed after.

Users' settings as in the first fresh set: plain SIMPLE conservative (U 0.7, p 0.3, turbulence 0.7) or
"between" (U 0.8, p 0.2, turbulence 0.8); SIMPLEC U 0.8-0.9, p unrelaxed or 1 written out, turbulence
0.8-0.9; residualControl 1e-4 on every field, or 1e-5 (a tight user), or p 1e-3 with U and turbulence
1e-4; endTime 3000, deltaT 1, fields written every 500 or 1000 iterations.

The builders reuse the first fresh set's cases.py (its function objects, ``finish``, channel patch namer,
annulus and porous block; loaded by path, not copied) and through it heldout-v2's geometry helpers and
field writers. What this file adds: two namers that give each of two bodies its own patch (forces on each
body of a tandem or a side-by-side pair), and a channel that widens at x = 0 (a step or an expansion).
"""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from types import FunctionType, ModuleType

_FIRST_SET = Path(__file__).resolve().parent.parent / "fresh-set" / "cases.py"


def _first_set() -> ModuleType:
    """The first fresh set's cases.py under a name of its own (both directories call theirs cases.py)."""
    name = "settle_fresh_set_first_cases"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, _FIRST_SET)
        sys.modules[name] = module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
        spec.loader.exec_module(module)  # type: ignore[union-attr]
    return sys.modules[name]


FIRST = _first_set()
V2, v2_module, TUTORIALS = FIRST.V2, FIRST.v2_module, FIRST.TUTORIALS
Flow, fresh, grid_2d, channel_mesh, channel_patches = (FIRST.Flow, FIRST.fresh, FIRST.grid_2d,
                                                       FIRST.channel_mesh, FIRST.channel_patches)
finish, forces, force_coeffs, probes, surface, volume_average = (FIRST.finish, FIRST.forces,
                                                                 FIRST.force_coeffs, FIRST.probes,
                                                                 FIRST.surface, FIRST.volume_average)
body_patches, rotating_annulus, porous_block = FIRST.body_patches, FIRST.rotating_annulus, FIRST.porous_block
CONSERVATIVE, BETWEEN, ALL_1E4, ALL_1E5, P_1E3 = (FIRST.CONSERVATIVE, FIRST.BETWEEN, FIRST.ALL_1E4,
                                                  FIRST.ALL_1E5, FIRST.P_1E3)
TWO_SIDED, DEPTH = FIRST.TWO_SIDED, FIRST.DEPTH

CASES: dict[str, Callable[[Path], None]] = {}
DESCRIPTIONS: dict[str, tuple[str, str, str]] = {}
#: The first set's register (add the decorated builder to CASES, its description to DESCRIPTIONS), its code
#: bound to this module's globals: it fills this set's CASES and DESCRIPTIONS, not the first set's.
register = FunctionType(FIRST.register.__code__, globals(), "register")


def two_bodies(last_column: int, last_row: int, first: tuple[int, int], second: tuple[int, int],
               names: tuple[str, str]) -> Callable[[int, int, str], str]:
    """body_patches's channel with two solid blocks, ``first``'s sides one patch, ``second``'s another."""
    one = body_patches(last_column, last_row, [first])
    two = body_patches(last_column, last_row, [second])

    def patch(i: int, j: int, side: str) -> str:
        if one(i, j, side) == "obstacle":
            return names[0]
        return names[1] if two(i, j, side) == "obstacle" else one(i, j, side)
    return patch


def named_cylinders(last_column: int, last_row: int, names: dict[int, str]) -> Callable[[int, int, str], str]:
    """channel_patches, but the cylinder of column i is its own patch ``names[i]``."""
    plain = channel_patches(last_column, last_row)
    return lambda i, j, side: names[i] if side == "cylinder" else plain(i, j, side)


def widening(case: Path, ys: Sequence[float], solids: Sequence[int], nx: tuple[int, int],
             ny: Sequence[int]) -> dict:
    """A walled channel that widens at x = 0: upstream (4 long) the rows ``solids`` of ``ys`` are solid,
    downstream (30 long) the whole height is open; U 1 at the inlet, an outlet at x = 30."""
    fresh(case)
    grid = grid_2d([-4, 0, 30], ys, nx, ny, channel_patches(1, len(ny) - 1), gx=[0.25, 8],
                   gy=[TWO_SIDED] * len(ny), cells={(0, j): "solid" for j in solids})
    return channel_mesh(case, grid)


# ---------------------------------------------------------------------------------------------------
# Bluff bodies


@register("bluff-body", "2-D two square cylinders in tandem, spacing 4 D, in a channel, blockage 1/6, "
                        "Re 2e4, SIMPLEC")
def squareTandemSST(case: Path) -> None:
    """bluff-body. Two square cylinders (D = 1) one behind the other, centres 4 D apart, on the centre line
    of a channel of height 6 D, 5.5 D upstream of the first, 15 D downstream of the second. U 1, nu 5e-5:
    Re 2e4 on D. kOmegaSST, SIMPLEC, U 0.9, p unrelaxed, turbulence 0.9, 1e-4 on every field, endTime
    3000, fields every 500. Function objects: forceCoeffs on each cylinder (Aref D x depth, about its
    centre), probes in the gap and the wake. 11,200 cells. Why: the rear body sits in the front body's
    wake (at 4 D the gap's shear layers roll up and strike it); one of the long cases."""
    fresh(case)
    grid = grid_2d([-6, -0.5, 0.5, 3.5, 4.5, 19.5], [-3, -0.5, 0.5, 3], [30, 20, 40, 20, 90], [20, 20, 20],
                   two_bodies(4, 2, (1, 1), (3, 1), ("front", "rear")), gx=[0.25, 1, 1, 1, 6],
                   gy=[0.5, 1, 2], cells={(1, 1): "solid", (3, 1): "solid"})
    roles = channel_mesh(case, grid, front="wall", rear="wall")
    finish(case, roles, Flow("kOmegaSST", 5e-5, True, {"U": 0.9, "turbulence": 0.9}, ALL_1E4, 3000, 1.0,
                             0.07 * 6, start="(1 0 0)"), 500,
           [force_coeffs(["front"], (0, 0), 1, DEPTH, name="frontCoeffs"),
            force_coeffs(["rear"], (4, 0), 1, DEPTH, name="rearCoeffs"), probes([(2, 0), (7, 0.5)])])


@register("bluff-body", "2-D two circular cylinders in tandem, spacing 4 D, in a channel, blockage 1/6, "
                        "Re 4e4, SIMPLEC")
def cylinderTandemRKE(case: Path) -> None:
    """bluff-body. Two circular cylinders (D = 1, O-grids) in tandem, centres 4 D apart, on the centre line
    of a channel of height 6 D, 5.5 D upstream of the first, 15.5 D downstream of the second. U 1, nu 2.5e-5:
    Re 4e4 on D. realizableKE, SIMPLEC, U 0.8, p 1 (written out), turbulence 0.8, 1e-4 on every field,
    endTime 3000, fields every 1000. Function objects: forces on each cylinder (moments about its centre),
    probes in the gap and 3 D behind the rear one. 12,448 cells. Why: two curved bodies whose separation
    points are free, the rear one buffeted by the front one's wake; one of the long cases."""
    fresh(case)
    cylinder = ("cylinder", 0.5, 16, 0.2)
    grid = grid_2d([-6, -1, 1, 3, 5, 20], [-3, -1, 1, 3], [30, 24, 20, 24, 90], [16, 24, 16],
                   named_cylinders(4, 2, {1: "front", 3: "rear"}), gx=[0.25, 1, 1, 1, 5], gy=[0.5, 1, 2],
                   cells={(1, 1): cylinder, (3, 1): cylinder})
    roles = channel_mesh(case, grid, front="wall", rear="wall")
    finish(case, roles, Flow("realizableKE", 2.5e-5, True, {"U": 0.8, "p": 1, "turbulence": 0.8}, ALL_1E4,
                             3000, 1.0, 0.07 * 6, start="(1 0 0)"), 1000,
           [forces(["front"], (0, 0), name="frontForces"), forces(["rear"], (4, 0), name="rearForces"),
            probes([(2, 0), (7, 0)])])


@register("bluff-body", "2-D circular cylinder near the floor of a channel, gap 0.5 D, Re 2e4")
def cylinderGapSST(case: Path) -> None:
    """bluff-body. A circular cylinder (D = 1, O-grid) half a diameter above the floor of a channel of
    height 5 D (the ceiling 3.5 D above it), 5.5 D upstream, 15.5 D downstream. U 1, nu 5e-5: Re 2e4 on D.
    kOmegaSST, plain SIMPLE conservative (U 0.7, p 0.3, turbulence 0.7), 1e-4 on every field, endTime
    3000, fields every 1000. Function objects: forceCoeffs on the cylinder (Aref D x depth, about its
    centre), probes in the gap under it and 3 D behind it. 9,984 cells. Why: a pipeline near the seabed:
    at a gap of 0.5 D the cylinder still sheds, the floor's boundary layer makes its wake asymmetric."""
    fresh(case)
    grid = grid_2d([-6, -1, 1, 16], [-1, 1, 4], [36, 28, 100], [28, 24], channel_patches(2, 1),
                   gx=[0.25, 1, 5], gy=[1, 3], cells={(1, 0): ("cylinder", 0.5, 20, 0.2)})
    roles = channel_mesh(case, grid, cylinder="wall")
    finish(case, roles, Flow("kOmegaSST", 5e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07 * 5,
                             start="(1 0 0)"), 1000,
           [force_coeffs(["cylinder"], (0, 0), 1, DEPTH), probes([(0, -0.75), (3, 0)])])


@register("bluff-body", "2-D flat plate normal to the flow (thickness 0.2 D) in a channel, blockage 1/6, "
                        "Re 1.5e4")
def plateNormalKE(case: Path) -> None:
    """bluff-body. A flat plate of height D = 1 and thickness 0.2 D across the flow, centred in a channel
    of height 6 D, 5 D upstream, 15 D downstream. U 1, nu 6.67e-5: Re 1.5e4 on D. kEpsilon, plain SIMPLE
    "between" (U 0.8, p 0.2, turbulence 0.8), 1e-4 on every field, endTime 3000, fields every 500.
    Function objects: forceCoeffs on the plate (Aref D x depth, about its centre), a probe 2 D behind it.
    9,192 cells. Why: the bluffest section, fixed separation at sharp edges and the widest wake; the
    standard model on plain SIMPLE."""
    fresh(case)
    solids = [(1, 1)]
    grid = grid_2d([-5, 0, 0.2, 15.2], [-3, -0.5, 0.5, 3], [30, 8, 100], [22, 24, 22],
                   body_patches(2, 2, solids), gx=[0.25, 1, 6], gy=[0.5, 1, 2], cells={solids[0]: "solid"})
    roles = channel_mesh(case, grid, obstacle="wall")
    finish(case, roles, Flow("kEpsilon", 6.67e-5, False, BETWEEN, ALL_1E4, 3000, 1.0, 0.07 * 6,
                             start="(1 0 0)"), 500,
           [force_coeffs(["obstacle"], (0.1, 0), 1, DEPTH), probes([(2.2, 0.5)])])


@register("bluff-body", "2-D two square cylinders side by side, gap 1 D, in a channel, blockage 0.25, "
                        "Re 2.5e4")
def squarePairKE(case: Path) -> None:
    """bluff-body. Two square cylinders (D = 1) side by side across a channel of height 8 D, a gap of 1 D
    between them (centres 2 D apart), 4.5 D upstream, 14.5 D downstream. U 1, nu 4e-5: Re 2.5e4 on D.
    kEpsilon, plain SIMPLE conservative, 1e-4 on every field, endTime 3000, fields every 1000. Function
    objects: forceCoeffs on each cylinder (Aref D x depth, about its centre), probes behind the gap and in
    both wakes. 11,456 cells. Why: the gap's jet is biased to one side and may flip (two mirror
    solutions); one of the long cases."""
    fresh(case)
    grid = grid_2d([-5, -0.5, 0.5, 15], [-4, -1.5, -0.5, 0.5, 1.5, 4], [30, 16, 90], [20, 16, 16, 16, 20],
                   two_bodies(2, 4, (1, 1), (1, 3), ("lowerSquare", "upperSquare")), gx=[0.25, 1, 6],
                   gy=[0.5, 1, 1, 1, 2], cells={(1, 1): "solid", (1, 3): "solid"})
    roles = channel_mesh(case, grid, lowerSquare="wall", upperSquare="wall")
    finish(case, roles, Flow("kEpsilon", 4e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07 * 8,
                             start="(1 0 0)"), 1000,
           [force_coeffs(["lowerSquare"], (0, -1), 1, DEPTH, name="lowerCoeffs"),
            force_coeffs(["upperSquare"], (0, 1), 1, DEPTH, name="upperCoeffs"),
            probes([(1.5, 0), (5, -1), (5, 1)])])


@register("bluff-body", "2-D fence on the floor of a channel (height h, thickness 0.15 h), blockage 0.25, "
                        "Re 5e4, SIMPLEC")
def fenceRKE(case: Path) -> None:
    """bluff-body. A fence (a thin wall-mounted plate) of height h = 1 and thickness 0.15 h standing on the
    floor of a channel of height 4 h, 5 h upstream, 20 h downstream. U 1, nu 2e-5: Re 5e4 on h.
    realizableKE, SIMPLEC, U 0.9, p unrelaxed, turbulence 0.8; 1e-5 on every field (a tight user);
    endTime 3000, fields every 500. Function objects: forces on the fence (moments about its centre),
    probes in the separated region behind it. 8,580 cells. Why: a long separation bubble behind a sharp
    edge on a wall (reattachment some 10-15 h behind), whose shear layer flaps."""
    fresh(case)
    solids = [(1, 0)]
    grid = grid_2d([-5, 0, 0.15, 20.15], [0, 1, 4], [30, 6, 110], [30, 30], body_patches(2, 1, solids),
                   gx=[0.25, 1, 6], gy=[TWO_SIDED, TWO_SIDED], cells={solids[0]: "solid"})
    roles = channel_mesh(case, grid, obstacle="wall")
    finish(case, roles, Flow("realizableKE", 2e-5, True, {"U": 0.9, "turbulence": 0.8}, ALL_1E5, 3000, 1.0,
                             0.07 * 4, start="(1 0 0)"), 500,
           [forces(["obstacle"], (0.075, 0.5)), probes([(3, 0.5), (10, 0.2)])])


# ---------------------------------------------------------------------------------------------------
# Tube banks


@register("tube-bank", "2-D inline bank, 4 x 3 circular tubes, pitch 1.8 D, Re 1.2e4, SIMPLEC")
def tubeRowsSST(case: Path) -> None:
    """tube-bank. An inline bank of 4 columns x 3 rows of circular tubes (D = 1, O-grids, pitch 1.8 D both
    ways) between channel walls, 6 D upstream, 15 D downstream. U 1, nu 8.33e-5: Re 1.2e4. kOmegaSST,
    SIMPLEC, U 0.9, p unrelaxed, turbulence 0.9, 1e-4 on every field, endTime 3000, fields every 1000.
    Function objects: forces on the tubes (moments about the bank's centre), the inlet's area-averaged
    pressure (the bank's pressure drop). 12,000 cells. Why: a wider-spaced inline bank than heldout-v2's
    (the eddies between rows may not lock), under SST; one of the long cases."""
    roles = V2.tube_bank(case, 4, 3, 1.8, 16, 10, staggered=False, ends=(30, 60))
    finish(case, roles, Flow("kOmegaSST", 8.33e-5, True, {"U": 0.9, "turbulence": 0.9}, ALL_1E4, 3000, 1.0,
                             0.07 * 5.4, start="(1 0 0)"), 1000,
           [forces(["cylinder"], (3.6, 2.7)), surface("inletPressure", "inlet", "areaAverage", ["p"])])


@register("tube-bank", "2-D staggered bank of 9 circular tubes, 6 x 3, pitch 1.5 D, Re 2.5e4")
def tubesStaggeredKE(case: Path) -> None:
    """tube-bank. A staggered bank (checkerboard) of 9 circular tubes (D = 1, O-grids) on a 1.5 D grid, 6
    columns x 3 rows, between channel walls, 6 D upstream, 15 D downstream. U 1, nu 4e-5: Re 2.5e4.
    kEpsilon, plain SIMPLE "between", p 1e-3, U and turbulence 1e-4 (a bank's user settles for p 1e-3),
    endTime 3000, fields every 500. Function objects: forces on the tubes (moments about the bank's
    centre), the inlet's area-averaged pressure. 9,576 cells. Why: a long shallow staggered bank with the
    standard model, plain SIMPLE."""
    roles = V2.tube_bank(case, 6, 3, 1.5, 14, 8, staggered=True, ends=(30, 60))
    finish(case, roles, Flow("kEpsilon", 4e-5, False, BETWEEN, P_1E3, 3000, 1.0, 0.07 * 4.5, start="(1 0 0)"),
           500, [forces(["cylinder"], (4.5, 2.25)), surface("inletPressure", "inlet", "areaAverage", ["p"])])


@register("tube-bank", "2-D inline bank of square tubes, 6 deep, pitches 1.6 D x 1.8 D, between symmetry "
                       "planes through tube centres, Re 1.5e4, SIMPLEC")
def squareBankSixRKE(case: Path) -> None:
    """tube-bank. An inline bank of square tubes (D = 1), 6 deep, longitudinal pitch 1.6 D, transverse
    1.8 D, infinitely wide (one row between symmetry planes through the tube centres), 6 D upstream, 15 D
    downstream. U 1, nu 6.67e-5: Re 1.5e4. realizableKE, SIMPLEC, U 0.8, p unrelaxed, turbulence 0.8; p
    1e-3, U and turbulence 1e-4; endTime 3000, fields every 1000. No function objects (a user who looks
    at the fields). 6,384 cells. Why: a deep, tight inline bank of square tubes (the cavities between
    them hold eddies fed by the gap flow)."""
    roles = V2.square_tube_bank(case, 6, 0.6, 1.8, (30, 14, 10, 60), [10, 16, 10], staggered=False)
    finish(case, roles, Flow("realizableKE", 6.67e-5, True, {"U": 0.8, "turbulence": 0.8}, P_1E3, 3000, 1.0,
                             0.07 * 1.8, start="(1 0 0)"), 1000)


# ---------------------------------------------------------------------------------------------------
# Impinging jets (heldout-v2's confined slot jet: half domain, slot width B = 1, U 1 downwards)


@register("impinging-jet", "2-D confined slot jet on a plate, H/B 5, half domain, Re 2.5e4, SIMPLEC")
def jetFiveSST(case: Path) -> None:
    """impinging-jet. The plate 5 B below the slot, 18 B to the outlet. U 1, nu 4e-5: Re 2.5e4 on B.
    kOmegaSST, SIMPLEC, U 0.8, p 1 (written out), turbulence 0.8, 1e-4 on every field, endTime 3000,
    fields every 500. Function objects: the plate's area-averaged pressure, probes on the axis near the
    plate and in the wall jet. 8,000 cells. Why: a jet whose potential core ends near the plate, SST on
    SIMPLEC (a length SIMPLEC holds)."""
    roles = V2.slot_jet(case, 5, 18, [10, 30, 60], 80)
    finish(case, roles, Flow("kOmegaSST", 4e-5, True, {"U": 0.8, "p": 1, "turbulence": 0.8}, ALL_1E4, 3000,
                             1.0, 0.07), 500,
           [surface("platePressure", "plate", "areaAverage", ["p"]), probes([(0.05, 0.3), (3, 0.1)])])


@register("impinging-jet", "2-D confined slot jet on a plate, H/B 3.5, half domain, Re 1.2e4")
def jetShortKE(case: Path) -> None:
    """impinging-jet. The plate 3.5 B below the slot, 14 B to the outlet. U 1, nu 8.33e-5: Re 1.2e4.
    kEpsilon, plain SIMPLE conservative, 1e-4 on every field, endTime 3000, fields every 1000. No function
    objects (a user who looks at the fields). 4,800 cells. Why: a short jet with the standard model (its
    stagnation-point excess of k), plain SIMPLE."""
    roles = V2.slot_jet(case, 3.5, 14, [10, 30, 56], 50)
    finish(case, roles, Flow("kEpsilon", 8.33e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07), 1000)


@register("impinging-jet", "2-D confined slot jet on a plate, H/B 11, half domain, Re 3.5e4")
def jetElevenRKE(case: Path) -> None:
    """impinging-jet. The plate 11 B below the slot, 24 B to the outlet. U 1, nu 2.86e-5: Re 3.5e4.
    realizableKE, plain SIMPLE "between", 1e-4 on every field, endTime 3000, fields every 1000. Function
    objects: probes on the jet's axis (1 B and 5.5 B above the plate), the plate's area-averaged pressure.
    11,800 cells. Why: a long jet, fully developed before it strikes, on plain SIMPLE (SIMPLEC diverged
    on a longer one); one of the long cases."""
    roles = V2.slot_jet(case, 11, 24, [12, 36, 70], 100)
    finish(case, roles, Flow("realizableKE", 2.86e-5, False, BETWEEN, ALL_1E4, 3000, 1.0, 0.07), 1000,
           [probes([(0.05, 1), (0.05, 5.5)]), surface("platePressure", "plate", "areaAverage", ["p"])])


# ---------------------------------------------------------------------------------------------------
# Ventilated rooms (heldout-v2's room: a ceiling slot on the left wall, a low outlet; starts from rest)


@register("ventilated-room", "2-D room 5 x 3.2 m, 0.05 m ceiling slot at 4 m/s, low outlet opposite, "
                             "Re 1.3e4, SIMPLEC")
def roomNarrowSlotKE(case: Path) -> None:
    """ventilated-room. A 5 x 3.2 m room, a slot 0.05 m high at the top of the left wall blowing 4 m/s
    along the ceiling, an outlet 0.25 m high at the bottom of the right wall. nu 1.5e-5: Re 1.3e4 on the
    slot. kEpsilon, SIMPLEC, U 0.85, p unrelaxed, turbulence 0.85, 1e-4 on every field, endTime 3000,
    fields every 500. No function objects. 10,780 cells. Why: a thin fast wall jet that turns down the far
    wall and drives the room's eddy."""
    roles = V2.room(case, 5, [0, 0.25, 3.15, 3.2], (110, (10, 80, 8)), 4.0)
    finish(case, roles, Flow("kEpsilon", 1.5e-5, True, {"U": 0.85, "turbulence": 0.85}, ALL_1E4, 3000, 4.0,
                             0.07 * 0.05), 500)


@register("ventilated-room", "2-D room 6 x 2.7 m, 0.25 m ceiling slot at 1 m/s, low outlet opposite, "
                             "Re 1.7e4")
def roomWideSlotSST(case: Path) -> None:
    """ventilated-room. A 6 x 2.7 m room, a slot 0.25 m high at the top of the left wall blowing 1 m/s
    along the ceiling, an outlet 0.3 m high at the bottom of the right wall. nu 1.5e-5: Re 1.7e4 on the
    slot. kOmegaSST, plain SIMPLE "between", 1e-4 on every field, endTime 3000, fields every 1000.
    Function objects: probes at a seated occupant's head (1.1 m, half-way) and by the outlet wall's foot,
    the room's volume-averaged k. 11,180 cells. Why: a thick, slow ceiling jet in a low room (the jet
    fills a tenth of the height) under SST; one of the long cases."""
    roles = V2.room(case, 6, [0, 0.3, 2.45, 2.7], (130, (10, 64, 12)), 1.0)
    finish(case, roles, Flow("kOmegaSST", 1.5e-5, False, BETWEEN, ALL_1E4, 3000, 1.0, 0.07 * 0.25), 1000,
           [probes([(3, 1.1), (5.5, 0.3)]), volume_average("roomK", ["k"])])


# ---------------------------------------------------------------------------------------------------
# Wall cavities (heldout-v2's: a channel of height 2 over a floor cavity, 5 upstream, 10 downstream)


@register("wall-cavity", "2-D channel over a floor cavity 2.5 long, 1.25 deep (L/D 2), Re 5e4, SIMPLEC")
def cavityMidKE(case: Path) -> None:
    """wall-cavity. A channel of height 2 over a cavity 2.5 long and 1.25 deep (L/D 2). U 1, nu 2.5e-5: Re
    5e4 on the depth. kEpsilon, SIMPLEC, U 0.9, p 1 (written out), turbulence 0.9, 1e-4 on every field,
    endTime 3000, fields every 500. No function objects. 8,600 cells. Why: an open cavity deeper than
    heldout-v2's L/D 2 one, relative to the channel, with SIMPLEC."""
    roles = V2.cavity(case, 2.5, 1.25, [40, 50, 80], [36, 40])
    finish(case, roles, Flow("kEpsilon", 2.5e-5, True, {"U": 0.9, "p": 1, "turbulence": 0.9}, ALL_1E4, 3000,
                             1.0, 0.07 * 2, start="(1 0 0)"), 500)


@register("wall-cavity", "2-D channel over a tall floor cavity, L/D 0.4, Re 8e4")
def cavityTallSST(case: Path) -> None:
    """wall-cavity. A channel of height 2 over a cavity 1 long and 2.5 deep (L/D 0.4: a stack of eddies,
    the lowest weak). U 1, nu 1.25e-5: Re 8e4 on the length. kOmegaSST, plain SIMPLE conservative, 1e-4 on
    every field, endTime 3000, fields every 1000. Function objects: probes in the top and bottom eddies,
    the inlet's area-averaged pressure. 7,800 cells. Why: the deepest cavity yet, whose lower eddies are
    driven by ever weaker ones above; SST on plain SIMPLE."""
    roles = V2.cavity(case, 1, 2.5, [40, 30, 80], [60, 40])
    finish(case, roles, Flow("kOmegaSST", 1.25e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07 * 2,
                             start="(1 0 0)"), 1000,
           [probes([(0.5, -0.5), (0.5, -2)]), surface("inletPressure", "inlet", "areaAverage", ["p"])])


# ---------------------------------------------------------------------------------------------------
# Sudden expansions (a walled channel that widens at x = 0)


@register("sudden-expansion", "2-D backward-facing step, expansion ratio 2, Re 3e4")
def stepTightRKE(case: Path) -> None:
    """sudden-expansion. A channel of height h = 1 widening at a step of height h to 2 h, 4 h upstream,
    30 h downstream. U 1, nu 3.33e-5: Re 3e4 on h. realizableKE, plain SIMPLE conservative; 1e-5 on every
    field (a tight user: the reattachment length is the answer); endTime 3000, fields every 500. Function
    objects: probes in the recirculation and near reattachment, the inlet's area-averaged pressure.
    10,500 cells. Why: a step whose separated shear layer is long and may flap, its user's criterion
    tight."""
    roles = widening(case, [0, 1, 2], [0], (30, 160), [30, 30])
    finish(case, roles, Flow("realizableKE", 3.33e-5, False, CONSERVATIVE, ALL_1E5, 3000, 1.0, 0.07,
                             start="(1 0 0)"), 500,
           [probes([(3, 0.2), (7, 0.1)]), surface("inletPressure", "inlet", "areaAverage", ["p"])])


@register("sudden-expansion", "2-D symmetric sudden expansion, expansion ratio 3, Re 2e4, SIMPLEC")
def expansionSymRKE(case: Path) -> None:
    """sudden-expansion. A channel of height h = 1 opening symmetrically into one of height 3 h (a step of
    h on both sides), 4 h upstream, 30 h downstream. U 1, nu 5e-5: Re 2e4 on h. realizableKE, SIMPLEC, U
    0.9, p unrelaxed, turbulence 0.9, 1e-4 on every field, endTime 3000, fields every 1000. Function
    objects: probes in the upper and lower recirculations, the outlet's volume flux (sum of phi). 10,920
    cells. Why: the symmetric expansion's jet attaches to one wall (two mirror solutions, the Coanda
    effect)."""
    roles = widening(case, [0, 1, 2, 3], [0, 2], (30, 150), [22, 24, 22])
    finish(case, roles, Flow("realizableKE", 5e-5, True, {"U": 0.9, "turbulence": 0.9}, ALL_1E4, 3000, 1.0,
                             0.07, start="(1 0 0)"), 1000,
           [probes([(4, 0.5), (4, 2.5)]), surface("outletFlux", "outlet", "sum", ["phi"])])


# ---------------------------------------------------------------------------------------------------
# The annulus and the porous obstacle (one each: their kinds converged in the first fresh set)


@register("annulus", "2-D eccentric annulus (journal bearing), radius ratio 0.63, eccentricity 0.4, Re 4e4")
def journalKE(case: Path) -> None:
    """annulus. A journal bearing: inner radius 1 centred 0.4 off the centre of an outer radius 1.6 (gaps
    0.2 to 1), the inner wall rotating at 1 rad/s. nu 1.5e-5: Re 4e4 on the inner wall's speed and the
    mean gap. kEpsilon, plain SIMPLE "between", 1e-4 on every field, endTime 3000, fields every 1000.
    pRefCell 0. Function objects: forces on the journal (the torque about its centre, and the load).
    9,216 cells. Why: a heavily loaded bearing (the narrowest gap a third of the mean), the standard model
    on plain SIMPLE (heldout-v2's eccentric annulus with it did not converge)."""
    roles = rotating_annulus(case, 1.6, 0.4, (36, 64))
    finish(case, roles, Flow("kEpsilon", 1.5e-5, False, BETWEEN, ALL_1E4, 3000, 1.0, 0.07 * 0.6,
                             closed=True), 1000, [forces(["innerWall"], (0.4, 0))])


@register("porous-obstacle", "2-D walled channel, a thin dense porous windbreak on the floor, 0.6 of the "
                             "height, Re 1e5, SIMPLEC")
def windbreakSST(case: Path) -> None:
    """porous-obstacle. A walled channel of height 1 with a thin porous screen standing on its floor (a
    windbreak), 0.2 thick, 0.6 high (d 2e6 1/m2, f 200 1/m: most of the flow goes over it), 4 upstream,
    12 downstream. U 1, nu 1e-5: Re 1e5 on the height. kOmegaSST, SIMPLEC, U 0.85, p 1 (written out),
    turbulence 0.85, 1e-4 on every field, endTime 3000, fields every 500. Function objects: the inlet's
    area-averaged pressure, probes in the bleed flow behind the screen. 9,072 cells. Why: a porous
    fence: the bleed through it feeds a long separation behind its top edge."""
    roles = porous_block(case, [-4, 0, 0.2, 12.2], [0, 0.6, 1], [40, 8, 120], [30, 24], [TWO_SIDED] * 2,
                         (1, 0), ("(2e6 2e6 2e6)", "(200 200 200)"), 1)
    finish(case, roles, Flow("kOmegaSST", 1e-5, True, {"U": 0.85, "p": 1, "turbulence": 0.85}, ALL_1E4, 3000,
                             1.0, 0.07, start="(1 0 0)"), 500,
           [surface("inletPressure", "inlet", "areaAverage", ["p"]), probes([(1, 0.3), (4, 0.3)])])
