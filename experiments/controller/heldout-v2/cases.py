# SPDX-License-Identifier: GPL-3.0-or-later
"""The heldout-v2 cases (issue 46): one builder per case, each a plain steady simpleFoam case, meshed.

Every geometry is of a kind reserved for this set (reserved_kinds.json): bluff-body, tube-bank,
impinging-jet, wall-cavity, annulus, ventilated-room, porous-obstacle. Each builder's docstring says the
geometry, its kind, the Reynolds number, the model, the algorithm, the case's own factors and criterion,
and why. A case's factors, criterion, model, mesh and endTime were written down here BEFORE its first
run, as a user would set them: plain SIMPLE conservative (U 0.7, p 0.3, turbulence 0.7) or "between" (U
0.8 p 0.2 turbulence 0.8, U 0.5 p 0.3); SIMPLEC with U 0.8-0.9, p unrelaxed (or 1), turbulence 0.7-0.9;
1e-4 on every field for the turbulent cases but one looser (tubeBankInline, p 1e-3) and one tighter
(slotJetConfined, 1e-5), 1e-5 for the two laminar ones. The cases came in batches (the README says which
and why); no case was changed after its first run.

The helpers of heldout-v1 (foamcase.py, steady.py) are imported, not copied.
"""

from __future__ import annotations

import math
import re
import shutil
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NamedTuple

sys.path.insert(1, str(Path(__file__).resolve().parent.parent / "heldout-v1"))

from foamcase import TUTORIALS, blockmesh_2d, copy_tutorial, run, write_dict, write_field  # noqa: E402
from steady import SCHEMES, SOLVERS, write_physics, write_system  # noqa: E402

#: The fields of each model besides U and p.
MODEL_FIELDS = {"kEpsilon": ("k", "epsilon"), "realizableKE": ("k", "epsilon"), "kOmegaSST": ("k", "omega"),
                "SpalartAllmaras": ("nuTilda",), "laminar": ()}
TURBULENCE = '"(k|epsilon|omega|nuTilda)"'

#: A patch's role: "wall", "outlet", "symmetry", "wedge", ("inlet", (ux, uy)),
#: or ("rotating", (x0, y0), omega[, axis]) (axis z unless given).
Role = str | tuple


# ---------------------------------------------------------------------------------------------------
# Meshes


def grid_2d(xs: Sequence[float], ys: Sequence[float], nx: Sequence[int], ny: Sequence[int],
            patch: Callable[[int, int, str], str], gx: Sequence[object] | None = None,
            gy: Sequence[object] | None = None, cells: dict | None = None,
            zones: dict | None = None) -> tuple[list, list, dict, list]:
    """A 2-D multi-block grid on the lines ``xs`` x ``ys``: block (i, j) spans [xs[i], xs[i+1]] x
    [ys[j], ys[j+1]] with nx[i] x ny[j] cells, graded gx[i], gy[j] (a number or a multi-grading text).
    ``cells[(i, j)]``: "solid" (no block: a hole, its sides walls) or ("cylinder", R, nr, ratio): a circular
    cylinder of radius R at the block's centre, meshed as an O-grid of 4 blocks with nr cells from the
    block's sides to the cylinder, graded ``ratio`` (the block must be ungraded). ``patch(i, j, side)``
    names the patch of a boundary side ("bottom", "right", "top", "left", "cylinder") of block (i, j).
    ``zones[(i, j)]``: the cellZone of a block. Returns blockmesh_2d's points, blocks, patch edges, arcs."""
    gx = gx or [1] * len(nx)
    gy = gy or [1] * len(ny)
    cells, zones = cells or {}, zones or {}
    index: dict[tuple[int, int], int] = {}
    points: list[tuple[float, float]] = []

    def point(i: int, j: int) -> int:
        if (i, j) not in index:
            index[(i, j)] = len(points)
            points.append((xs[i], ys[j]))
        return index[(i, j)]

    def fluid(i: int, j: int) -> bool:
        return 0 <= i < len(nx) and 0 <= j < len(ny) and cells.get((i, j)) != "solid"

    blocks, edges, arcs = [], {}, []
    for j in range(len(ny)):
        for i in range(len(nx)):
            if not fluid(i, j):
                continue
            corners = (point(i, j), point(i + 1, j), point(i + 1, j + 1), point(i, j + 1))
            zone = f"{zones[(i, j)]} " if (i, j) in zones else ""
            for side, (a, b), (di, dj) in (("bottom", (0, 1), (0, -1)), ("right", (1, 2), (1, 0)),
                                          ("top", (2, 3), (0, 1)), ("left", (3, 0), (-1, 0))):
                if not fluid(i + di, j + dj):
                    edges.setdefault(patch(i, j, side), []).append((corners[a], corners[b]))
            kind = cells.get((i, j))
            if kind is None:
                blocks.append((corners, f"{zone}({nx[i]} {ny[j]} 1) simpleGrading ({gx[i]} {gy[j]} 1)"))
                continue
            _, radius, nr, ratio = kind
            assert gx[i] == 1 and gy[j] == 1, "a cylinder's block must be ungraded"
            cx, cy = (xs[i] + xs[i + 1]) / 2, (ys[j] + ys[j + 1]) / 2
            ring = []
            for angle in (225, 315, 45, 135):
                ring.append(len(points))
                points.append((cx + radius * math.cos(math.radians(angle)),
                               cy + radius * math.sin(math.radians(angle))))
            for k, count in enumerate((nx[i], ny[j], nx[i], ny[j])):
                s0, s1, c0, c1 = corners[k], corners[(k + 1) % 4], ring[k], ring[(k + 1) % 4]
                blocks.append(((s0, s1, c1, c0), f"({count} {nr} 1) simpleGrading (1 {ratio} 1)"))
                edges.setdefault(patch(i, j, "cylinder"), []).append((c1, c0))
                middle = math.radians(270 + 90 * k)
                arcs.append((c0, c1, (cx + radius * math.cos(middle), cy + radius * math.sin(middle))))
    return points, blocks, edges, arcs


def annulus_2d(inner: float, outer: float, offset: float, radial: int, around: int) -> str:
    """blockMeshDict of a 2-D annulus: inner circle of radius ``inner`` centred at (offset, 0), outer of
    radius ``outer`` at the origin; 4 blocks of ``radial`` x ``around`` cells, clustered towards both walls.
    Patches: innerWall, outerWall."""
    angles = [math.radians(a) for a in (45, 135, 225, 315)]
    points = [(offset + inner * math.cos(a), inner * math.sin(a)) for a in angles]
    points += [(outer * math.cos(a), outer * math.sin(a)) for a in angles]
    across = "((0.5 0.5 4) (0.5 0.5 0.25))"
    blocks, arcs, inner_edges, outer_edges = [], [], [], []
    for k in range(4):
        n = (k + 1) % 4
        blocks.append(((k, 4 + k, 4 + n, n), f"({radial} {around} 1) simpleGrading ({across} 1 1)"))
        inner_edges.append((n, k))
        outer_edges.append((4 + k, 4 + n))
        middle = math.radians(90 + 90 * k)
        arcs.append((k, n, (offset + inner * math.cos(middle), inner * math.sin(middle))))
        arcs.append((4 + k, 4 + n, (outer * math.cos(middle), outer * math.sin(middle))))
    patches = {"innerWall": ("wall", inner_edges), "outerWall": ("wall", outer_edges)}
    return blockmesh_2d(points, blocks, patches, arcs=arcs)


def wedge_2d(points: Sequence[tuple[float, float]], blocks: Sequence[tuple[tuple[int, ...], str]],
             patches: dict[str, tuple[str, Sequence[tuple[int, int]]]], angle: float = 5.0) -> str:
    """blockmesh_2d's dictionary made an axisymmetric wedge about the x axis (y is the radius): the z = 0
    face turned -angle/2, the other +angle/2, each its own wedge patch (front, back)."""
    text = blockmesh_2d(points, blocks, patches)
    half = math.radians(angle / 2)
    vertices = [f"    ({x:.9g} {y * math.cos(half):.9g} {sign * y * math.sin(half):.9g})"
                for sign in (-1, 1) for x, y in points]
    start = text.index("vertices\n(\n") + len("vertices\n(\n")
    text = text[:start] + "\n".join(vertices) + text[text.index("\n);", start):]
    line = next(row for row in text.splitlines() if row.startswith("    frontAndBack"))
    faces = re.findall(r"\([\d ]+\)", line.split("faces (", 1)[1])
    front = [face for face in faces if max(map(int, face[1:-1].split())) < len(points)]
    back = [face for face in faces if face not in front]
    return text.replace(line, f"    front {{ type wedge; faces ({' '.join(front)}); }}\n"
                        f"    back {{ type wedge; faces ({' '.join(back)}); }}")


PATCH_TYPES = {"wall": "wall", "rotating": "wall", "symmetry": "symmetryPlane"}
#: The roles every field treats alike: a constraint patch.
CONSTRAINTS = {"symmetry": "type symmetryPlane;", "wedge": "type wedge;"}


def role_name(role: Role) -> str:
    return role if isinstance(role, str) else role[0]


def write_mesh(case: Path, grid: tuple[list, list, dict, list], roles: dict[str, Role],
               wedge: bool = False) -> None:
    """blockMeshDict from grid_2d's output, each patch's type from its role; ``wedge``: axisymmetric."""
    points, blocks, edges, arcs = grid
    patches = {name: (PATCH_TYPES.get(role_name(roles[name]), "patch"), found)
               for name, found in edges.items()}
    write_dict(case / "system" / "blockMeshDict", wedge_2d(points, blocks, patches) if wedge
               else blockmesh_2d(points, blocks, patches, arcs=arcs))


# ---------------------------------------------------------------------------------------------------
# Fields and dictionaries


def write_fields(case: Path, model: str, roles: dict[str, Role], speed: float, length: float,
                 start: str = "(0 0 0)") -> None:
    """0/U, 0/p, the model's fields and nut. Inlet turbulence: 5 % intensity of ``speed``, mixing length
    ``length``; wall functions at the walls (Spalding's for Spalart-Allmaras); inletOutlet at outlets."""
    k = 1.5 * (0.05 * speed) ** 2
    values = {"k": k, "epsilon": 0.09**0.75 * k**1.5 / length, "omega": math.sqrt(k) / (0.09**0.25 * length),
              "nuTilda": math.sqrt(1.5) * 0.05 * speed * length}
    walls = {"k": "type kqRWallFunction; value uniform {v};", "epsilon": "type epsilonWallFunction; value "
             "uniform {v};", "omega": "type omegaWallFunction; value uniform {v};",
             "nuTilda": "type fixedValue; value uniform 0;"}
    u, p, nut = {}, {}, {}
    wall_nut = ("type nutUSpaldingWallFunction; value uniform 0;" if model == "SpalartAllmaras"
                else "type nutkWallFunction; value uniform 0;")
    for name, role in roles.items():
        kind = role_name(role)
        if kind in CONSTRAINTS:
            u[name] = p[name] = nut[name] = CONSTRAINTS[kind]
            continue
        p[name] = "type fixedValue; value uniform 0;" if kind == "outlet" else "type zeroGradient;"
        nut[name] = wall_nut if kind in ("wall", "rotating") else "type calculated; value uniform 0;"
        if kind == "inlet":
            u[name] = f"type fixedValue; value uniform ({role[1][0]:g} {role[1][1]:g} 0);"
        elif kind == "outlet":
            u[name] = "type inletOutlet; inletValue uniform (0 0 0); value uniform (0 0 0);"
        elif kind == "wall":
            u[name] = "type noSlip;"
        else:
            (x0, y0), omega = role[1], role[2]
            axis = " ".join(f"{a:g}" for a in (role[3] if len(role) > 3 else (0, 0, 1)))
            u[name] = (f"type rotatingWallVelocity; origin ({x0:g} {y0:g} 0); axis ({axis}); "
                       f"omega {omega:g}; value uniform (0 0 0);")
    write_field(case, "U", start, u)
    write_field(case, "p", "0", p)
    if model == "laminar":
        return
    for field in MODEL_FIELDS[model]:
        value = f"{values[field]:.6g}"
        bcs = {}
        for name, role in roles.items():
            kind = role_name(role)
            bcs[name] = {**CONSTRAINTS,
                         "inlet": f"type fixedValue; value uniform {value};",
                         "outlet": f"type inletOutlet; inletValue uniform {value}; value uniform {value};"
                         }.get(kind) or walls[field].format(v=value)
        if field == "nuTilda":  # heldout-v1's write_field knows nut's dimensions, which nuTilda shares
            write_field(case, "nut", value, bcs)
            text = (case / "0" / "nut").read_text().replace("object nut;", "object nuTilda;")
            (case / "0" / "nuTilda").write_text(text)
            continue
        write_field(case, field, value, bcs)
    write_field(case, "nut", "0", nut)


def write_settings(case: Path, model: str, nu: float, consistent: bool, factors: dict[str, float],
                   criterion: dict[str, float], end_time: int, closed: bool = False) -> None:
    """controlDict (heldout-v1's), fvSchemes, fvSolution and the physics. ``factors``: U, turbulence and,
    if relaxed, p; ``criterion``: p, U, turbulence (residualControl on the initial residuals);
    ``closed``: no fixed-pressure boundary, so a reference cell."""
    write_system(case, consistent=consistent, end_time=end_time)
    write_physics(case, model, nu)
    if model == "laminar":
        write_dict(case / "constant" / "turbulenceProperties", "simulationType laminar;\n")
    if model == "SpalartAllmaras":
        write_dict(case / "system" / "fvSchemes", SCHEMES.replace(
            "    div((nuEff", "    div(phi,nuTilda) bounded Gauss limitedLinear 1;\n    div((nuEff"))
    reference = "    pRefCell 0;\n    pRefValue 0;\n" if closed else ""
    control = f"p {criterion['p']:g}; U {criterion['U']:g}; {TURBULENCE} {criterion['turbulence']:g};"
    fields = f"    fields {{ p {factors['p']:g}; }}\n" if "p" in factors else ""
    write_dict(case / "system" / "fvSolution",
               SOLVERS.replace("(U|k|epsilon|omega)", "(U|k|epsilon|omega|nuTilda)")
               + "SIMPLE\n{\n    nNonOrthogonalCorrectors 0;\n"
               f"    consistent {'yes' if consistent else 'no'};\n"
               f"{reference}    residualControl {{ {control} }}\n}}\n"
               f"relaxationFactors\n{{\n{fields}    equations {{ U {factors['U']:g}; "
               f"{TURBULENCE} {factors['turbulence']:g}; }}\n}}\n")


def fresh(case: Path) -> None:
    if case.exists():
        shutil.rmtree(case)
    case.mkdir(parents=True)


#: name -> builder, every case built and measured (heldout.json says which are in the set, and why); and
#: name -> (source, reserved kind, geometry): what heldout.json says of each case. Filled by @register.
CASES: dict[str, Callable[[Path], None]] = {}
DESCRIPTIONS: dict[str, tuple[str, str, str]] = {}


def register(kind: str, geometry: str, source: str = "built") -> Callable:
    """Add the decorated builder to CASES and its description to DESCRIPTIONS."""
    def add(builder: Callable[[Path], None]) -> Callable[[Path], None]:
        CASES[builder.__name__] = builder
        DESCRIPTIONS[builder.__name__] = (source, kind, geometry)
        return builder
    return add


class Flow(NamedTuple):
    """A case's physics and its user's settings: the model, nu, SIMPLEC or not, the relaxation factors
    (U, turbulence and, if relaxed, p), the residualControl (p, U, turbulence), endTime; the inlet speed
    and mixing length for the turbulence at the inlets, the initial velocity, and whether no boundary fixes
    the pressure (closed: a reference cell)."""

    model: str
    nu: float
    consistent: bool
    factors: dict[str, float]
    criterion: dict[str, float]
    end_time: int
    speed: float
    length: float
    start: str = "(0 0 0)"
    closed: bool = False


def finish(case: Path, roles: dict[str, Role], flow: Flow, *after: tuple[str, ...]) -> None:
    """The case's dictionaries and fields from ``flow``, then blockMesh and the ``after`` utilities (the
    blockMeshDict written already)."""
    write_settings(case, flow.model, flow.nu, flow.consistent, flow.factors, flow.criterion, flow.end_time,
                   closed=flow.closed)
    write_fields(case, flow.model, roles, flow.speed, flow.length, start=flow.start)
    run(case, "blockMesh")
    for application in after:
        run(case, *application)


CONSERVATIVE = {"U": 0.7, "p": 0.3, "turbulence": 0.7}
ALL_1E4 = {"p": 1e-4, "U": 1e-4, "turbulence": 1e-4}
TWO_SIDED = "((0.5 0.5 4) (0.5 0.5 0.25))"


def channel_mesh(case: Path, grid: tuple[list, list, dict, list],
                 porosity: dict[str, tuple[str, str]] | None = None, **others: Role) -> dict[str, Role]:
    """blockMeshDict of a channel from grid_2d's output: a uniform 1 m/s inlet along x, an outlet, walls
    and ``others``; ``porosity``: cellZone -> (d, f) of write_porosity, in order. Returns the roles."""
    roles = {"inlet": ("inlet", (1, 0)), "outlet": "outlet", "walls": "wall", **others}
    write_mesh(case, grid, roles)
    for zone, (darcy, forchheimer) in (porosity or {}).items():
        write_porosity(case, darcy, forchheimer, zone)
    return roles


def channel_patches(last_column: int, last_row: int, inlet: str = "inlet") -> Callable[[int, int, str], str]:
    """Patches of a channel along x: the left side an inlet, the right an outlet, all else walls (holes
    and cylinders included: "walls", "cylinder")."""
    def patch(i: int, j: int, side: str) -> str:
        if side == "left" and i == 0:
            return inlet
        if side == "right" and i == last_column:
            return "outlet"
        return "cylinder" if side == "cylinder" else "walls"
    return patch


# ---------------------------------------------------------------------------------------------------
# The cases


@register("bluff-body", "2-D square cylinder in a channel, blockage 0.2, Re 2.2e4")
def squareCylinder(case: Path) -> None:
    """bluff-body. A square cylinder (side D = 1) centred in a channel of height 5 D (blockage 0.2), 4.5 D
    of channel upstream of it, 14.5 D downstream; U 1, nu 4.5e-5: Re 2.2e4 on D (Lyn et al.'s square
    cylinder). kEpsilon with wall functions (its excess production at the front face damps shedding: a
    steady RANS user's usual choice), plain SIMPLE, U 0.7 p 0.3 turbulence 0.7, 1e-4 on every field,
    endTime 3000. Why: the canonical bluff body, a steady RANS user's first check."""
    fresh(case)
    grid = grid_2d([-5, -0.5, 0.5, 15], [-2.5, -0.5, 0.5, 2.5], [30, 20, 80], [20, 20, 20],
                   channel_patches(2, 2), gx=[0.25, 1, 6], gy=[0.5, 1, 2], cells={(1, 1): "solid"})
    roles = channel_mesh(case, grid)
    finish(case, roles, Flow("kEpsilon", 4.5e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07 * 5,
                             start="(1 0 0)"))


@register("bluff-body", "2-D circular cylinder in a channel, blockage 0.25, Re 1e5")
def circularCylinder(case: Path) -> None:
    """bluff-body. A circular cylinder (D = 1) centred in a channel of height 4 D (blockage 0.25), 4.5 D
    upstream, 14.5 D downstream; O-grid around it. U 1, nu 1e-5: Re 1e5 on D. realizableKE with wall
    functions, SIMPLEC, U 0.9, p unrelaxed, turbulence 0.8, 1e-4 on every field, endTime 4000. Sized to be
    one of the long cases. Why: a curved bluff body whose separation point is free (unlike the square's)."""
    fresh(case)
    grid = grid_2d([-5, -1, 1, 15], [-2, -1, 1, 2], [60, 40, 160], [30, 40, 30], channel_patches(2, 2),
                   gx=[0.2, 1, 8], gy=[0.5, 1, 2], cells={(1, 1): ("cylinder", 0.5, 30, 0.1)})
    roles = channel_mesh(case, grid, cylinder="wall")
    finish(case, roles, Flow("realizableKE", 1e-5, True, {"U": 0.9, "turbulence": 0.8}, ALL_1E4, 4000, 1.0,
                             0.07 * 4, start="(1 0 0)"))


def tube_bank(case: Path, columns: int, rows: int, pitch: float, n: int, nr: int, staggered: bool,
              ends: tuple[int, int]) -> dict[str, Role]:
    """A bank of circular tubes (D = 1) between two walls touching its outer rows, pitch ``pitch`` both
    ways (staggered: a checkerboard of tubes); 6 D upstream, 15 D downstream with ``ends`` cells."""
    fresh(case)
    xs = [-6.0] + [pitch * c for c in range(columns + 1)] + [pitch * columns + 15]
    ys = [pitch * r for r in range(rows + 1)]
    tubes = {(1 + c, r): ("cylinder", 0.5, nr, 0.25) for c in range(columns) for r in range(rows)
             if not staggered or (c + r) % 2 == 0}
    grid = grid_2d(xs, ys, [ends[0], *[n] * columns, ends[1]], [n] * rows,
                   channel_patches(columns + 1, rows - 1), gx=[0.25, *[1] * columns, 5], cells=tubes)
    roles = channel_mesh(case, grid, cylinder="wall")
    return roles


@register("tube-bank", "2-D inline bank, 4 x 3 circular tubes, pitch 1.5 D, Re 1e4")
def tubeBankInline(case: Path) -> None:
    """tube-bank. An inline bank of 4 columns x 3 rows of circular tubes (D = 1, pitch 1.5 D both ways) in
    a channel whose walls touch the outer rows' cells (0.25 D from the tubes); 6 D upstream, 15 D
    downstream. U 1 (inlet), nu 1e-4: Re 1e4 on D. kEpsilon with wall functions, plain SIMPLE with the
    "between" factors U 0.8, p 0.2, turbulence 0.8; a looser criterion: p 1e-3, U and k/epsilon 1e-4
    (the pressure of a bank drops across many tubes: users settle for p 1e-3); endTime 2000. Why: the
    heat-exchanger geometry, many wakes interacting."""
    roles = tube_bank(case, 4, 3, 1.5, 16, 8, staggered=False, ends=(30, 60))
    finish(case, roles, Flow("kEpsilon", 1e-4, False, {"U": 0.8, "p": 0.2, "turbulence": 0.8},
                             {"p": 1e-3, "U": 1e-4, "turbulence": 1e-4}, 2000, 1.0, 0.07 * 4.5,
                             start="(1 0 0)"))


@register("tube-bank", "2-D staggered bank, 12 circular tubes, pitches 2.5 D x 1.25 D, Re 2e4")
def tubeBankStaggered(case: Path) -> None:
    """tube-bank. A staggered bank (checkerboard) of 12 circular tubes (D = 1) on a 1.25 D grid, 6 columns
    x 4 rows (transverse pitch 2.5 D, longitudinal 1.25 D), between channel walls; 6 D upstream, 15 D
    downstream. U 1, nu 5e-5: Re 2e4 on D. kOmegaSST with omega wall functions, SIMPLEC, U 0.9, p
    unrelaxed, turbulence 0.9, 1e-4 on every field, endTime 4000. Sized to be one of the long cases. Why:
    the other common arrangement, with a different model and algorithm from the inline bank."""
    roles = tube_bank(case, 6, 4, 1.25, 24, 16, staggered=True, ends=(30, 90))
    finish(case, roles, Flow("kOmegaSST", 5e-5, True, {"U": 0.9, "turbulence": 0.9}, ALL_1E4, 4000, 1.0,
                             0.07 * 5, start="(1 0 0)"))


def slot_jet(case: Path, height: float, width: float, nx: Sequence[int], ny: int) -> dict[str, Role]:
    """Half of a confined slot jet (slot width B = 1, its centre plane a symmetry plane at x = 0): the
    jet enters downwards through the top (x < 0.5) at 1 m/s, strikes the plate (bottom wall) ``height``
    below, and leaves at x = ``width``; the rest of the top is the confining wall."""
    fresh(case)
    def patch(i: int, j: int, side: str) -> str:
        if side == "left":
            return "symmetry"
        if side == "right":
            return "outlet"
        if side == "top":
            return "jet" if i == 0 else "top"
        return "plate"
    grid = grid_2d([0, 0.5, 3, width], [0, height], nx, [ny], patch, gx=[1, 2, 4], gy=[6])
    roles = {"jet": ("inlet", (0, -1)), "outlet": "outlet", "symmetry": "symmetry", "plate": "wall",
             "top": "wall"}
    write_mesh(case, grid, roles)
    return roles


@register("impinging-jet", "2-D confined slot jet on a plate, H/B 4, half domain, Re 1e4")
def slotJetConfined(case: Path) -> None:
    """impinging-jet. A confined 2-D slot jet (B = 1) 4 B above a plate, half domain (symmetry plane on
    the jet axis), 15 B to the outlet. U 1, nu 1e-4: Re 1e4 on B. kOmegaSST with omega wall functions,
    SIMPLEC, U 0.9, p 1 (written out), turbulence 0.9; a tight criterion, 1e-5 on every field (heat
    transfer users converge impingement further); endTime 3000. Why: stagnation flow and a wall jet."""
    roles = slot_jet(case, 4, 15, [10, 30, 60], 80)
    finish(case, roles, Flow("kOmegaSST", 1e-4, True, {"U": 0.9, "p": 1, "turbulence": 0.9},
                             {"p": 1e-5, "U": 1e-5, "turbulence": 1e-5}, 3000, 1.0, 0.07))


@register("impinging-jet", "2-D confined slot jet on a plate, H/B 8, half domain, Re 2e4")
def slotJetFar(case: Path) -> None:
    """impinging-jet. The same confined slot jet with the plate 8 B away, 20 B to the outlet. U 1, nu
    5e-5: Re 2e4 on B. realizableKE with wall functions, plain SIMPLE, U 0.7 p 0.3 turbulence 0.7, 1e-4
    on every field, endTime 3000. Why: a jet that develops before it strikes; another model and
    algorithm than slotJetConfined."""
    roles = slot_jet(case, 8, 20, [10, 30, 60], 100)
    finish(case, roles, Flow("realizableKE", 5e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07))


def cavity(case: Path, length: float, depth: float, nx: Sequence[int], ny: Sequence[int]) -> dict[str, Role]:
    """A channel of height 2 over an open rectangular cavity (``length`` x ``depth``) in its floor, 5
    upstream and 10 downstream of it."""
    fresh(case)
    grid = grid_2d([-5, 0, length, length + 10], [-depth, 0, 2], nx, ny, channel_patches(2, 1),
                   gx=[0.25, 1, 5], gy=[1, TWO_SIDED], cells={(0, 0): "solid", (2, 0): "solid"})
    roles = channel_mesh(case, grid)
    return roles


@register("wall-cavity", "2-D channel over a floor cavity, L/D 2, Re 5e4")
def openCavity(case: Path) -> None:
    """wall-cavity. A channel of height 2 D over an open cavity of depth D = 1 and length 2 D (L/D 2, a
    shallow open cavity) in its floor. U 1, nu 2e-5: Re 5e4 on D. kEpsilon with wall functions, plain
    SIMPLE, U 0.7 p 0.3 turbulence 0.7, 1e-4 on every field, endTime 3000. Why: a shear layer over a
    recess driving one large eddy."""
    roles = cavity(case, 2, 1, [40, 40, 80], [30, 40])
    finish(case, roles, Flow("kEpsilon", 2e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07 * 2,
                             start="(1 0 0)"))


@register("wall-cavity", "2-D channel over a floor cavity, L/D 0.5, Re 1e5")
def deepCavity(case: Path) -> None:
    """wall-cavity. The same channel over a deep cavity, length 1 and depth 2 (L/D 0.5: two stacked
    eddies). U 1, nu 1e-5: Re 1e5 on the length. kOmegaSST with omega wall functions, SIMPLEC, U 0.8, p
    unrelaxed, turbulence 0.8, 1e-4 on every field, endTime 3000. Why: a deep recess whose lower eddy is
    weak, with another model and algorithm."""
    roles = cavity(case, 1, 2, [40, 30, 80], [50, 40])
    finish(case, roles, Flow("kOmegaSST", 1e-5, True, {"U": 0.8, "turbulence": 0.8}, ALL_1E4, 3000, 1.0,
                             0.07 * 2, start="(1 0 0)"))


@register("annulus", "2-D concentric annulus, radius ratio 2/3, inner wall rotating, Re 5e4")
def taylorCouette(case: Path) -> None:
    """annulus. Taylor-Couette flow: a 2-D concentric annulus, inner radius 1 rotating at 1 rad/s, outer
    radius 1.5 at rest; nu 1e-5: Re 5e4 on the inner wall's speed and the gap. kOmegaSST with omega wall
    functions, SIMPLEC, U 0.9, p unrelaxed, turbulence 0.7, 1e-4 on every field, endTime 3000. A closed
    domain: pRefCell 0. Why: a flow driven by a moving wall, no inlet at all."""
    fresh(case)
    write_dict(case / "system" / "blockMeshDict", annulus_2d(1, 1.5, 0, 40, 60))
    roles = {"innerWall": ("rotating", (0, 0), 1), "outerWall": "wall"}
    finish(case, roles, Flow("kOmegaSST", 1e-5, True, {"U": 0.9, "turbulence": 0.7}, ALL_1E4, 3000, 1.0,
                             0.07 * 0.5, closed=True))


@register("annulus", "2-D eccentric annulus (journal bearing), radius ratio 0.5, eccentricity 0.4, inner "
                     "wall rotating, Re 1e5")
def eccentricAnnulus(case: Path) -> None:
    """annulus. A journal-bearing geometry: inner radius 1 centred 0.4 off the centre of an outer radius 2
    (eccentricity 0.4, gaps 0.6 to 1.4), the inner wall rotating at 1 rad/s. nu 1e-5: Re 1e5 on the inner
    wall's speed and the mean gap. kEpsilon with wall functions, plain SIMPLE with U 0.5, p 0.3,
    turbulence 0.7 (a user's "safe" choice for a closed rotating flow), 1e-4 on every field, endTime
    3000. pRefCell 0. Why: a rotating flow with a recirculation in its wide gap."""
    fresh(case)
    write_dict(case / "system" / "blockMeshDict", annulus_2d(1, 2, 0.4, 40, 50))
    roles = {"innerWall": ("rotating", (0.4, 0), 1), "outerWall": "wall"}
    finish(case, roles, Flow("kEpsilon", 1e-5, False, {"U": 0.5, "p": 0.3, "turbulence": 0.7}, ALL_1E4, 3000,
                             1.0, 0.07, closed=True))


def room(case: Path, length: float, ys: Sequence[float], cells: tuple[int, Sequence[int]], speed: float,
         outlet_wall: str = "right") -> dict[str, Role]:
    """A 2-D room [0, length] x [ys[0], ys[3]]: the inlet slot is the top band of the left wall (ys[2] to
    ys[3]), blowing ``speed`` along the ceiling, the outlet the bottom band (ys[0] to ys[1]) of
    ``outlet_wall``; ``cells``: (across, (bottom band, middle, top band)), clustered towards the walls."""
    fresh(case)
    def patch(i: int, j: int, side: str) -> str:
        if side == "left" and j == 2:
            return "inlet"
        if side == outlet_wall and j == 0:
            return "outlet"
        return "walls"
    grid = grid_2d([0, length], ys, [cells[0]], list(cells[1]), patch,
                   gx=["((0.2 0.3 4) (0.6 0.4 1) (0.2 0.3 0.25))"], gy=[1, TWO_SIDED, 1])
    roles = {"inlet": ("inlet", (speed, 0)), "outlet": "outlet", "walls": "wall"}
    write_mesh(case, grid, roles)
    return roles


def annex20_room(case: Path, speed: float) -> dict[str, Role]:
    """The IEA Annex 20 2-D room (9 x 3 m, inlet slot 0.168 m at the top of the left wall blowing
    ``speed`` along the ceiling, outlet 0.48 m at the bottom of the right wall), 180 x 132 cells."""
    return room(case, 9, [0, 0.48, 2.832, 3], (180, (20, 100, 12)), speed)


@register("ventilated-room", "2-D IEA Annex 20 room, ceiling slot inlet, low outlet opposite, Re 5.1e3")
def annex20Room(case: Path) -> None:
    """ventilated-room. The IEA Annex 20 2-D room: 9 m long, 3 m high, a slot inlet 0.168 m high at the
    top of the left wall blowing 0.455 m/s along the ceiling, an outlet 0.48 m high at the bottom of the
    right wall. nu 1.5e-5 (air): Re 5.1e3 on the slot. kEpsilon with wall functions, plain SIMPLE, U 0.7
    p 0.3 turbulence 0.7, 1e-4 on every field, endTime 5000 (rooms converge slowly). Starts from rest.
    Sized to be one of the long cases. Why: the standard ventilation benchmark."""
    roles = annex20_room(case, 0.455)
    finish(case, roles, Flow("kEpsilon", 1.5e-5, False, CONSERVATIVE, ALL_1E4, 5000, 0.455, 0.07 * 0.168))


@register("ventilated-room", "2-D room, floor-level slot inlet, ceiling outlet, Re 6.7e3")
def displacementRoom(case: Path) -> None:
    """ventilated-room. A 2-D room 4 m long, 3 m high, supplied low (a slot 0.2 m high at the floor of the
    left wall, 0.5 m/s), exhausted through a 0.4 m opening in the ceiling at the right wall. nu 1.5e-5:
    Re 6.7e3 on the slot. SpalartAllmaras with Spalding's wall function, SIMPLEC, U 0.9, p unrelaxed,
    nuTilda 0.9, 1e-4 on every field, endTime 3000. Starts from rest. Why: a floor-level supply (wall jet
    along the floor), the one-equation model of the set."""
    fresh(case)
    def patch(i: int, j: int, side: str) -> str:
        if side == "left" and j == 0:
            return "inlet"
        if side == "top" and i == 1:
            return "outlet"
        return "walls"
    grid = grid_2d([0, 3.6, 4], [0, 0.2, 3], [100, 16], [12, 100], patch,
                   gx=["((0.2 0.3 4) (0.8 0.7 1))", 1], gy=[1, "((0.2 0.3 4) (0.6 0.4 1) (0.2 0.3 0.25))"])
    roles = {"inlet": ("inlet", (0.5, 0)), "outlet": "outlet", "walls": "wall"}
    write_mesh(case, grid, roles)
    finish(case, roles, Flow("SpalartAllmaras", 1.5e-5, True, {"U": 0.9, "turbulence": 0.9}, ALL_1E4, 3000,
                             0.5, 0.07 * 0.2))


def annular_duct(case: Path, inner: Role) -> dict[str, Role]:
    """A concentric annular duct, radii 0.5 and 1, 40 long, as a 5-degree wedge about x, 400 x 40 cells;
    ``inner``: the inner wall's role."""
    fresh(case)
    def patch(i: int, j: int, side: str) -> str:
        return {"left": "inlet", "right": "outlet", "bottom": "innerWall", "top": "outerWall"}[side]
    grid = grid_2d([0, 40], [0.5, 1], [400], [40], patch, gx=[1], gy=[TWO_SIDED])
    roles = {"inlet": ("inlet", (1, 0)), "outlet": "outlet", "innerWall": inner, "outerWall": "wall",
             "front": "wedge", "back": "wedge"}
    write_mesh(case, grid, roles, wedge=True)
    return roles


@register("annulus", "axisymmetric concentric annular duct, radius ratio 0.5, 40 Dh long, axial flow, Re 1e5")
def annularDuct(case: Path) -> None:
    """annulus. Axial flow through a concentric annular duct, inner radius 0.5, outer 1 (hydraulic
    diameter Dh 1), 40 Dh long, as an axisymmetric 5-degree wedge; a uniform inlet U 1 develops along it.
    nu 1e-5: Re 1e5 on Dh. kEpsilon with wall functions, plain SIMPLE, U 0.7 p 0.3 turbulence 0.7, 1e-4
    on every field, endTime 3000. Added in the second batch, after the first sizing runs
    (eccentricAnnulus did not converge), its settings fixed before its first run. Why: the annulus as
    a duct, a flow along the walls instead of around them."""
    roles = annular_duct(case, "wall")
    finish(case, roles, Flow("kEpsilon", 1e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07,
                             start="(1 0 0)"))


@register("ventilated-room", "2-D room, ceiling slot inlet and low extract on the same wall, Re 1e4")
def officeRoom(case: Path) -> None:
    """ventilated-room. A 2-D room 4 m long, 2.5 m high, supplied through a slot 0.05 m high at the top
    of the left wall (3 m/s along the ceiling) and extracted through a grille 0.2 m high at the bottom of
    the same wall. nu 1.5e-5: Re 1e4 on the slot. realizableKE with wall functions, SIMPLEC, U 0.9, p
    unrelaxed, turbulence 0.8, 1e-4 on every field, endTime 3000. Starts from rest. Added after the first
    sizing runs (annex20Room and displacementRoom did not converge), its settings fixed before its first
    run. Why: supply and extract on one wall, a room-filling eddy."""
    roles = room(case, 4, [0, 0.2, 2.45, 2.5], (100, (10, 80, 8)), 3, outlet_wall="left")
    finish(case, roles, Flow("realizableKE", 1.5e-5, True, {"U": 0.9, "turbulence": 0.8}, ALL_1E4, 3000, 3.0,
                             0.07 * 0.05))


@register("annulus", "axisymmetric annular duct of annularDuct, inner wall rotating (swirl), Re 1e5")
def swirlAnnularDuct(case: Path) -> None:
    """annulus. The annular duct of annularDuct (radii 0.5 and 1, 40 Dh long, 5-degree wedge) with its
    inner wall rotating about the axis at 2 rad/s (surface speed 1, the bulk axial speed): a swirling
    Taylor-Couette-Poiseuille flow. nu 1e-5: Re 1e5 on Dh. kOmegaSST with omega wall functions, SIMPLEC,
    U 0.9, p unrelaxed, turbulence 0.9, 1e-4 on every field, endTime 3000. Added in the third batch
    (after annularDuct stalled on its swirl component, which is pure noise without swirl), its settings
    fixed before its first run. Why: an annulus with both a through-flow and a moving wall."""
    roles = annular_duct(case, ("rotating", (0, 0), 2, (1, 0, 0)))
    finish(case, roles, Flow("kOmegaSST", 1e-5, True, {"U": 0.9, "turbulence": 0.9}, ALL_1E4, 3000, 1.0,
                             0.07))


@register("bluff-body", "2-D 5:1 rectangular cylinder (BARC section) in a channel, blockage 0.1, Re 2.6e4")
def barcCylinder(case: Path) -> None:
    """bluff-body. A 5:1 rectangular cylinder (chord 5 D, D = 1, the BARC benchmark's section) centred in
    a channel of height 10 D (blockage 0.1), 10 D upstream, 25 D downstream. U 1, nu 3.85e-5: Re 2.6e4
    on D (BARC's). realizableKE with wall functions, plain SIMPLE, U 0.7 p 0.3 turbulence 0.7, 1e-4 on
    every field, endTime 3000. Added in the third batch (circularCylinder shed), its settings fixed
    before its first run. Why: an elongated bluff body whose side shear layers reattach."""
    fresh(case)
    grid = grid_2d([-10, 0, 5, 30], [-5, -0.5, 0.5, 5], [40, 60, 90], [30, 20, 30], channel_patches(2, 2),
                   gx=[0.2, 1, 6], gy=[0.2, 1, 5], cells={(1, 1): "solid"})
    roles = channel_mesh(case, grid)
    finish(case, roles, Flow("realizableKE", 3.85e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07 * 10,
                             start="(1 0 0)"))


@register("tube-bank", "2-D inline bank, 5 x 4 circular tubes, pitch 1.25 D, Re 1e4")
def tubeBankDense(case: Path) -> None:
    """tube-bank. A tightly packed inline bank, 5 columns x 4 rows of circular tubes (D = 1, pitch 1.25 D
    both ways: gaps of D/4), between channel walls; 6 D upstream, 15 D downstream. U 1, nu 1e-4: Re 1e4
    on D and the approach speed. realizableKE with wall functions, SIMPLEC, U 0.9, p unrelaxed,
    turbulence 0.8, 1e-4 on every field, endTime 3000. Added in the third batch (tubeBankInline shed),
    its settings fixed before its first run. Why: a compact heat-exchanger bank, jets between tubes and
    eddies trapped between rows."""
    roles = tube_bank(case, 5, 4, 1.25, 16, 6, staggered=False, ends=(30, 60))
    finish(case, roles, Flow("realizableKE", 1e-4, True, {"U": 0.9, "turbulence": 0.8}, ALL_1E4, 3000, 1.0,
                             0.07 * 5, start="(1 0 0)"))


@register("wall-cavity", "2-D channel over a floor cavity, L/D 4, Re 5e4")
def shallowCavity(case: Path) -> None:
    """wall-cavity. The channel of openCavity over a shallow cavity, length 4 and depth 1 (L/D 4). U 1,
    nu 2e-5: Re 5e4 on the depth. realizableKE with wall functions, SIMPLEC, U 0.9, p unrelaxed,
    turbulence 0.8, 1e-4 on every field, endTime 3000. Added in the third batch (openCavity and
    deepCavity did not converge), its settings fixed before its first run. Why: a longer recess whose
    shear layer nears the floor."""
    roles = cavity(case, 4, 1, [40, 60, 80], [25, 40])
    finish(case, roles, Flow("realizableKE", 2e-5, True, {"U": 0.9, "turbulence": 0.8}, ALL_1E4, 3000, 1.0,
                             0.07 * 2, start="(1 0 0)"))


@register("ventilated-room", "the Annex 20 room of annex20Room at Re 2e4")
def annex20Fast(case: Path) -> None:
    """ventilated-room. The Annex 20 room of annex20Room (9 x 3 m, the same mesh) supplied 4x faster:
    1.82 m/s through the 0.168 m slot, Re 2e4. realizableKE with wall functions, SIMPLEC, U 0.9, p
    unrelaxed, turbulence 0.8, 1e-4 on every field, endTime 3000. Starts from rest. Added in the second
    batch (annex20Room and displacementRoom did not converge), its settings fixed before its first run.
    Why: the benchmark room at a higher Reynolds number, another model and algorithm."""
    roles = annex20_room(case, 1.82)
    finish(case, roles, Flow("realizableKE", 1.5e-5, True, {"U": 0.9, "turbulence": 0.8}, ALL_1E4, 3000, 1.82,
                             0.07 * 0.168))


def symmetric_patches(last_column: int, last_row: int) -> Callable[[int, int, str], str]:
    """Patches of a half channel along x: inlet left, outlet right, the bottom a symmetry plane
    (symmetryLower), the top another (symmetryUpper) when ``last_row`` is negative, else a wall; holes
    are walls."""
    def patch(i: int, j: int, side: str) -> str:
        if side == "left" and i == 0:
            return "inlet"
        if side == "right" and i == last_column:
            return "outlet"
        if side == "bottom" and j == 0:
            return "symmetryLower"
        if side == "top" and last_row < 0 and j == -last_row - 1:
            return "symmetryUpper"
        return "walls"
    return patch


@register("bluff-body", "2-D square cylinder in a channel, blockage 0.2, half domain (symmetry plane on "
                        "the wake's centre line), Re 2.2e4")
def halfSquareCylinder(case: Path) -> None:
    """bluff-body. A square cylinder (D = 1) in a channel of height 5 D, as a user models it for a steady
    drag estimate: the half domain above the wake's centre plane (a symmetry plane), 4.5 D upstream, 14.5
    D downstream. U 1, nu 4.5e-5: Re 2.2e4. kOmegaSST with omega wall functions, SIMPLEC, U 0.9, p
    unrelaxed, turbulence 0.8, 1e-4 on every field, endTime 3000. Added in the fourth batch
    (squareCylinder and circularCylinder shed), its settings fixed before its first run. Why: the
    symmetric steady model of a bluff body."""
    fresh(case)
    grid = grid_2d([-5, -0.5, 0.5, 15], [0, 0.5, 2.5], [30, 20, 80], [10, 20], symmetric_patches(2, 1),
                   gx=[0.25, 1, 6], gy=[1, 2], cells={(1, 0): "solid"})
    roles = channel_mesh(case, grid, symmetryLower="symmetry")
    finish(case, roles, Flow("kOmegaSST", 4.5e-5, True, {"U": 0.9, "turbulence": 0.8}, ALL_1E4, 3000, 1.0,
                             0.07 * 5, start="(1 0 0)"))


def square_tube_bank(case: Path, columns: int, gap: float, height: float, nx: tuple[int, int, int, int],
                     ny: Sequence[int], staggered: bool) -> dict[str, Role]:
    """A bank of square tubes (side 1) ``columns`` deep, ``gap`` apart along x, between symmetry planes
    through tube centres ``height`` apart (an infinitely wide bank): inline, half tubes on both planes
    in every column; staggered, on the lower plane in even columns and the upper in odd ones. 6
    upstream, 15 downstream. ``nx``: cells upstream, across a tube, across a gap, downstream."""
    fresh(case)
    xs, counts, grades = [-6.0], [nx[0]], [0.25]
    for c in range(columns):
        xs += [c * (1 + gap), c * (1 + gap) + 1]
        counts += [nx[1], nx[2]]
        grades += [1, 1]
    xs.append(xs[-1] + 15)
    counts[-1], grades[-1] = nx[3], 5
    rows = len(ny)
    ys = [0, 0.5, height] if rows == 2 else [0, 0.5, height - 0.5, height]
    solid = {}
    for c in range(columns):
        if not staggered or c % 2 == 0:
            solid[(1 + 2 * c, 0)] = "solid"
        if not staggered or c % 2 == 1:
            solid[(1 + 2 * c, rows - 1)] = "solid"
    grid = grid_2d(xs, ys, counts, ny, symmetric_patches(len(counts) - 1, -rows), gx=grades, cells=solid)
    roles = channel_mesh(case, grid, symmetryLower="symmetry", symmetryUpper="symmetry")
    return roles


@register("tube-bank", "2-D inline bank of square tubes, 5 deep, pitch 2 D, between symmetry planes "
                       "through tube centres, Re 1e4")
def squareTubeRow(case: Path) -> None:
    """tube-bank. An inline bank of square tubes (side D = 1), 5 deep, pitch 2 D both ways, infinitely
    wide: one row between symmetry planes through the tube centres. 6 D upstream, 15 D downstream. U 1
    (approach), nu 1e-4: Re 1e4. kEpsilon with wall functions, plain SIMPLE, U 0.7 p 0.3 turbulence 0.7,
    1e-4 on every field, endTime 3000. Added in the fourth batch (tubeBankInline and tubeBankStaggered
    shed), its settings fixed before its first run. Why: the periodic-in-width model of a bank."""
    roles = square_tube_bank(case, 5, 1.0, 2.0, (30, 12, 12, 60), [6, 12, 6], staggered=False)
    finish(case, roles, Flow("kEpsilon", 1e-4, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07 * 2,
                             start="(1 0 0)"))


@register("tube-bank", "2-D staggered bank of square tubes, 6 deep, pitches 1.5 D x 2 D, between symmetry "
                       "planes through tube centres, Re 2e4")
def squareTubeStaggered(case: Path) -> None:
    """tube-bank. A staggered bank of square tubes (side D = 1), 6 deep, longitudinal pitch 1.5 D,
    transverse pitch 2 D, infinitely wide: the strip between symmetry planes through the centres of
    neighbouring tubes (half tubes on the lower plane in even columns, on the upper in odd ones). 6 D
    upstream, 15 D downstream. U 1, nu 5e-5: Re 2e4. kOmegaSST with omega wall functions, SIMPLEC, U 0.9,
    p unrelaxed, turbulence 0.9, 1e-4 on every field, endTime 3000. Sized to be one of the long cases.
    Added in the fourth batch, its settings fixed before its first run. Why: flow weaving between tubes."""
    roles = square_tube_bank(case, 6, 0.5, 1.0, (60, 30, 16, 150), [40, 40], staggered=True)
    finish(case, roles, Flow("kOmegaSST", 5e-5, True, {"U": 0.9, "turbulence": 0.9}, ALL_1E4, 3000, 1.0, 0.07,
                             start="(1 0 0)"))


@register("impinging-jet", "2-D confined slot jet on a plate, H/B 6, half domain, fine mesh, Re 1e4")
def slotJetFine(case: Path) -> None:
    """impinging-jet. The confined slot jet with the plate 6 B away, 20 B to the outlet, on a fine mesh
    (30 000 cells). U 1, nu 1e-4: Re 1e4 on B. kEpsilon with wall functions, SIMPLEC, U 0.9, p unrelaxed,
    turbulence 0.9, 1e-4 on every field, endTime 3000. Sized to be one of the long cases. Added in the
    fourth batch, its settings fixed before its first run. Why: a finely resolved impingement, the
    standard k-epsilon model and SIMPLEC (slotJetConfined and slotJetFar use others)."""
    roles = slot_jet(case, 6, 20, [20, 60, 120], 150)
    finish(case, roles, Flow("kEpsilon", 1e-4, True, {"U": 0.9, "turbulence": 0.9}, ALL_1E4, 3000, 1.0, 0.07))


@register("impinging-jet", "2-D confined slot jet on a plate, H/B 2, half domain, Re 2e4")
def slotJetNear(case: Path) -> None:
    """impinging-jet. The confined slot jet with the plate 2 B away, 15 B to the outlet. U 1, nu 5e-5:
    Re 2e4 on B. kEpsilon with wall functions, plain SIMPLE with the "between" factors U 0.8, p 0.2,
    turbulence 0.8, 1e-4 on every field, endTime 3000. Added in the fifth batch (too few plain SIMPLE
    cases converged), its settings fixed before its first run. Why: a short jet, its potential core
    reaching the plate."""
    roles = slot_jet(case, 2, 15, [10, 30, 60], 50)
    finish(case, roles, Flow("kEpsilon", 5e-5, False, {"U": 0.8, "p": 0.2, "turbulence": 0.8}, ALL_1E4, 3000,
                             1.0, 0.07))


@register("annulus", "2-D concentric annulus, radius ratio 0.5, inner wall rotating, Re 1e5")
def taylorCouetteWide(case: Path) -> None:
    """annulus. Taylor-Couette flow in a wide gap: inner radius 1 rotating at 1 rad/s, outer radius 2 at
    rest; nu 1e-5: Re 1e5 on the inner wall's speed and the gap. kEpsilon with wall functions, plain
    SIMPLE, U 0.7 p 0.3 turbulence 0.7, 1e-4 on every field, endTime 3000. pRefCell 0. Added in the fourth
    batch, its settings fixed before its first run. Why: taylorCouette's flow with another gap, model
    and algorithm."""
    fresh(case)
    write_dict(case / "system" / "blockMeshDict", annulus_2d(1, 2, 0, 40, 60))
    roles = {"innerWall": ("rotating", (0, 0), 1), "outerWall": "wall"}
    finish(case, roles, Flow("kEpsilon", 1e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07, closed=True))


@register("porous-obstacle", "2-D walled channel with an anisotropic porous plug across its height, Re 1e5")
def porousPlug(case: Path) -> None:
    """porous-obstacle. A walled channel of height 1 with a porous plug across its whole height (0.5 long,
    a filter pad), 4 upstream, 9 downstream; a Darcy-Forchheimer explicitPorositySource in
    system/fvOptions, d 1e5 1/m2 and f 20 1/m along x, 10x more across (an oriented pad). U 1, nu 1e-5:
    Re 1e5 on the height. kEpsilon with wall functions, plain SIMPLE, U 0.7 p 0.3 turbulence 0.7, 1e-4 on
    every field, endTime 3000. Added in the fifth batch, its settings fixed before its first run. Why: a
    pressure drop through a porous medium, the flow re-forming its boundary layers behind it."""
    fresh(case)
    grid = grid_2d([-4, 0, 0.5, 10], [0, 1], [60, 20, 120], [50], channel_patches(2, 0), gx=[0.25, 1, 5],
                   gy=[TWO_SIDED], zones={(1, 0): "porous"})
    roles = channel_mesh(case, grid, porosity={"porous": ("(1e5 1e6 1e6)", "(20 200 200)")})
    finish(case, roles, Flow("kEpsilon", 1e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07,
                             start="(1 0 0)"))


@register("ventilated-room", "the Annex 20 room of annex20Room at Re 1e4")
def annex20Mid(case: Path) -> None:
    """ventilated-room. The Annex 20 room of annex20Room (same mesh) at 0.91 m/s through the slot, Re 1e4.
    kEpsilon with wall functions, plain SIMPLE, U 0.7 p 0.3 turbulence 0.7, 1e-4 on every field, endTime
    3000. Starts from rest. Added in the fifth batch, its settings fixed before its first run. Why: the
    benchmark room between annex20Room's and annex20Fast's Reynolds numbers, with plain SIMPLE."""
    roles = annex20_room(case, 0.91)
    finish(case, roles, Flow("kEpsilon", 1.5e-5, False, CONSERVATIVE, ALL_1E4, 3000, 0.91, 0.07 * 0.168))


@register("bluff-body", "2-D 4:1 elliptic cylinder at zero incidence in a channel, blockage 1/6, Re 1e5")
def ellipseCylinder(case: Path) -> None:
    """bluff-body. An elliptic cylinder, 4:1 (chord 4 D, thickness D = 1), at zero incidence, centred in
    a channel of height 6 D, about 8 D of channel upstream of its nose, 22 D downstream of its tail: the
    O-grid of a circular cylinder (grid_2d, its box 1.2 x 2 so that the stretched cells stay within 56
    degrees of orthogonal) stretched 4x along x by transformPoints. U 1, nu 1e-5: Re 1e5 on D.
    kOmegaSST with omega wall functions, plain SIMPLE, U 0.7 p 0.3 turbulence 0.7, 1e-4 on every field,
    endTime 3000. Added in the fifth batch (the square, circular, half-square and 5:1 cylinders did not
    converge or were still running), its settings fixed before its first run. Why: a rounded bluff body
    with a trailing-edge separation (the shape of pimpleFoam's ellipsekkLOmega)."""
    fresh(case)
    grid = grid_2d([-2.5, -0.6, 0.6, 6], [-3, -1, 1, 3], [30, 40, 80], [25, 40, 25], channel_patches(2, 2),
                   gx=[0.25, 1, 5], gy=[0.3, 1, 1 / 0.3], cells={(1, 1): ("cylinder", 0.5, 20, 0.15)})
    roles = channel_mesh(case, grid, cylinder="wall")
    finish(case, roles, Flow("kOmegaSST", 1e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07 * 6,
                             start="(1 0 0)"), ("transformPoints", "-scale", "(4 1 1)"))


@register("wall-cavity", "2-D channel over a floor cavity, L/D 3, Re 2e5")
def cavityLong(case: Path) -> None:
    """wall-cavity. The channel of openCavity (height 2) over a cavity of length 3 and depth 1 (L/D 3), at
    a higher speed: U 1, nu 5e-6, Re 2e5 on the depth. realizableKE with wall functions, plain SIMPLE, U
    0.7 p 0.3 turbulence 0.7, 1e-4 on every field, endTime 3000. Added in the sixth batch (no cavity had
    converged, and few plain SIMPLE cases), its settings fixed before its first run. Why: an open cavity
    at a Reynolds number closer to a duct's."""
    roles = cavity(case, 3, 1, [40, 50, 80], [30, 40])
    finish(case, roles, Flow("realizableKE", 5e-6, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07 * 2,
                             start="(1 0 0)"))


@register("tube-bank", "2-D staggered bank of square tubes, 4 deep, pitches 2 D x 2 D, between symmetry "
                       "planes through tube centres, Re 1e4")
def squareTubeSparse(case: Path) -> None:
    """tube-bank. A staggered bank of square tubes (side D = 1), 4 deep, both pitches 2 D (gaps of D),
    infinitely wide: the strip between symmetry planes through neighbouring tubes' centres. 6 D upstream,
    15 D downstream. U 1, nu 1e-4: Re 1e4. realizableKE with wall functions, plain SIMPLE with the
    "between" factors U 0.8, p 0.2, turbulence 0.8, 1e-4 on every field, endTime 3000. Added in the sixth
    batch, its settings fixed before its first run. Why: a sparse staggered bank, plain SIMPLE."""
    roles = square_tube_bank(case, 4, 1.0, 1.0, (30, 12, 12, 60), [12, 12], staggered=True)
    finish(case, roles, Flow("realizableKE", 1e-4, False, {"U": 0.8, "p": 0.2, "turbulence": 0.8}, ALL_1E4,
                             3000, 1.0, 0.07, start="(1 0 0)"))


@register("bluff-body", "2-D square cylinder in a channel, blockage 0.5, Re 2e4")
def squareCylinderConfined(case: Path) -> None:
    """bluff-body. A square cylinder (D = 1) centred in a narrow channel of height 2 D (blockage 0.5),
    4.5 D upstream, 14.5 D downstream. U 1, nu 5e-5: Re 2e4 on D. realizableKE with wall functions, plain
    SIMPLE, U 0.7 p 0.3 turbulence 0.7, 1e-4 on every field, endTime 3000. Added in the sixth batch (no
    bluff body had converged yet), its settings fixed before its first run. Why: a confined bluff body,
    the walls close to its wake."""
    fresh(case)
    grid = grid_2d([-5, -0.5, 0.5, 15], [-1, -0.5, 0.5, 1], [30, 20, 80], [12, 20, 12], channel_patches(2, 2),
                   gx=[0.25, 1, 6], cells={(1, 1): "solid"})
    roles = channel_mesh(case, grid)
    finish(case, roles, Flow("realizableKE", 5e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07 * 2,
                             start="(1 0 0)"))


@register("porous-obstacle", "2-D walled channel with two porous blocks of different resistance side by "
                             "side, Re 1e5")
def porousTwoBlocks(case: Path) -> None:
    """porous-obstacle. A walled channel of height 1 with two porous blocks side by side across it: the
    lower half 1 long (d 1e5 1/m2, f 20 1/m), the upper half 0.5 long further on (d 1e4, f 5), 4 upstream
    of the first, 9 downstream; the flow splits and crosses between them. U 1, nu 1e-5: Re 1e5 on the
    height. realizableKE with wall functions, plain SIMPLE, U 0.7 p 0.3 turbulence 0.7, 1e-4 on every
    field, endTime 3000. Added in the seventh batch (few plain SIMPLE cases converged), its settings fixed
    before its first run. Why: porous zones of two resistances steering the flow across the channel."""
    fresh(case)
    grid = grid_2d([-4, 0, 1, 1.5, 10], [0, 0.5, 1], [60, 30, 16, 110], [25, 25], channel_patches(3, 1),
                   gx=[0.25, 1, 1, 5], gy=["((0.5 0.5 4) (0.5 0.5 1))", "((0.5 0.5 1) (0.5 0.5 0.25))"],
                   zones={(1, 0): "porous", (2, 1): "porousUpper"})
    roles = channel_mesh(case, grid, porosity={"porous": ("(1e5 1e5 1e5)", "(20 20 20)"),
                                               "porousUpper": ("(1e4 1e4 1e4)", "(5 5 5)")})
    finish(case, roles, Flow("realizableKE", 1e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07,
                             start="(1 0 0)"))


@register("impinging-jet", "2-D confined slot jet on a plate, H/B 3, half domain, Re 3e4")
def slotJetShort(case: Path) -> None:
    """impinging-jet. The confined slot jet with the plate 3 B away, 15 B to the outlet. U 1, nu 3.33e-5:
    Re 3e4 on B. realizableKE with wall functions, plain SIMPLE with the "between" factors U 0.8, p 0.2,
    turbulence 0.8, 1e-4 on every field, endTime 3000. Added in the seventh batch, its settings fixed
    before its first run. Why: a higher-Reynolds-number short jet."""
    roles = slot_jet(case, 3, 15, [10, 30, 60], 60)
    finish(case, roles, Flow("realizableKE", 3.33e-5, False, {"U": 0.8, "p": 0.2, "turbulence": 0.8}, ALL_1E4,
                             3000, 1.0, 0.07))


@register("ventilated-room", "the Annex 20 room of annex20Room at Re 2e4")
def annex20FastSIMPLE(case: Path) -> None:
    """ventilated-room. annex20Fast's room and flow (Annex 20, Re 2e4, realizableKE, the same mesh) set
    up by a plain SIMPLE user: U 0.7 p 0.3 turbulence 0.7, 1e-4 on every field, endTime 3000. Added in the
    seventh batch, its settings fixed before its first run. Why: the same room under the other algorithm."""
    roles = annex20_room(case, 1.82)
    finish(case, roles, Flow("realizableKE", 1.5e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.82, 0.07 * 0.168))


@register("annulus", "2-D concentric annulus, radius ratio 0.83, inner wall rotating, Re 2e4")
def taylorCouetteNarrow(case: Path) -> None:
    """annulus. Taylor-Couette flow in a narrow gap: inner radius 1 rotating at 1 rad/s, outer radius 1.2
    at rest; nu 1e-5: Re 2e4 on the inner wall's speed and the gap. realizableKE with wall functions,
    plain SIMPLE, U 0.7 p 0.3 turbulence 0.7, 1e-4 on every field, endTime 3000. pRefCell 0. Added in the
    seventh batch, its settings fixed before its first run. Why: a narrow rotating gap, plain SIMPLE."""
    fresh(case)
    write_dict(case / "system" / "blockMeshDict", annulus_2d(1, 1.2, 0, 30, 80))
    roles = {"innerWall": ("rotating", (0, 0), 1), "outerWall": "wall"}
    finish(case, roles, Flow("realizableKE", 1e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07 * 0.2,
                             closed=True))


@register("impinging-jet", "2-D confined slot jet on a plate, H/B 10, half domain, Re 5e4")
def slotJetLong(case: Path) -> None:
    """impinging-jet. The confined slot jet with the plate 10 B away, 25 B to the outlet. U 1, nu 2e-5:
    Re 5e4 on B. realizableKE with wall functions, plain SIMPLE, U 0.7 p 0.3 turbulence 0.7, 1e-4 on every
    field, endTime 3000. Added in the eighth batch, its settings fixed before its first run. Why: a long
    jet at a higher Reynolds number."""
    roles = slot_jet(case, 10, 25, [10, 30, 70], 110)
    finish(case, roles, Flow("realizableKE", 2e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07))


@register("porous-obstacle", "2-D walled channel with two staggered porous blocks, Re 1e5")
def porousStaggered(case: Path) -> None:
    """porous-obstacle. A walled channel of height 1 with two porous blocks (each 1 long, 0.4 high, d 1e5
    1/m2, f 20 1/m) staggered: the first near the lower wall (0.1 above it), the second 2 further on near
    the upper wall; 4 upstream, 9 downstream of the last. U 1, nu 1e-5: Re 1e5 on the height.
    realizableKE with wall functions, plain SIMPLE, U 0.7 p 0.3 turbulence 0.7, 1e-4 on every field,
    endTime 3000. Added in the eighth batch, its settings fixed before its first run. Why: a flow weaving
    between porous obstacles."""
    fresh(case)
    grid = grid_2d([-4, 0, 1, 3, 4, 13], [0, 0.1, 0.5, 0.9, 1], [50, 25, 40, 25, 100], [8, 20, 20, 8],
                   channel_patches(4, 3), gx=[0.25, 1, 1, 1, 5],
                   zones={(1, 1): "porous", (3, 2): "porous"})
    roles = channel_mesh(case, grid, porosity={"porous": ("(1e5 1e5 1e5)", "(20 20 20)")})
    finish(case, roles, Flow("realizableKE", 1e-5, False, CONSERVATIVE, ALL_1E4, 3000, 1.0, 0.07,
                             start="(1 0 0)"))


@register("ventilated-room", "2-D Annex 20 room shortened to 6 m, Re 2e4")
def annex20Short(case: Path) -> None:
    """ventilated-room. A shorter Annex 20 room: 6 m long (instead of 9), 3 m high, the same slot (0.168 m,
    top of the left wall) at 1.82 m/s and outlet (0.48 m, bottom of the right wall); Re 2e4.
    realizableKE with wall functions, SIMPLEC, U 0.9, p unrelaxed, turbulence 0.8, 1e-4 on every field,
    endTime 3000. Starts from rest. Added in the eighth batch, its settings fixed before its first run.
    Why: a room whose jet reaches the far wall."""
    roles = room(case, 6, [0, 0.48, 2.832, 3], (120, (20, 100, 12)), 1.82)
    finish(case, roles, Flow("realizableKE", 1.5e-5, True, {"U": 0.9, "turbulence": 0.8}, ALL_1E4, 3000, 1.82,
                             0.07 * 0.168))


@register("annulus", "the wide annulus of taylorCouetteWide, Re 1e5")
def taylorCouetteWideSST(case: Path) -> None:
    """annulus. taylorCouetteWide's wide gap (radius ratio 0.5, Re 1e5) with taylorCouette's user: kOmegaSST
    with omega wall functions, SIMPLEC, U 0.9, p unrelaxed, turbulence 0.7, 1e-4 on every field, endTime
    3000. pRefCell 0. Added in the eighth batch, its settings fixed before its first run. Why: the wide
    gap under the other model and algorithm."""
    fresh(case)
    write_dict(case / "system" / "blockMeshDict", annulus_2d(1, 2, 0, 40, 60))
    roles = {"innerWall": ("rotating", (0, 0), 1), "outerWall": "wall"}
    finish(case, roles, Flow("kOmegaSST", 1e-5, True, {"U": 0.9, "turbulence": 0.7}, ALL_1E4, 3000, 1.0, 0.07,
                             closed=True))


@register("tube-bank", "2-D staggered bank of square tubes, 5 deep, pitches 1.5 D x 2 D, between symmetry "
                       "planes through tube centres, Re 1e4")
def squareTubeBankRKE(case: Path) -> None:
    """tube-bank. A staggered bank of square tubes (side D = 1), 5 deep, longitudinal pitch 1.5 D,
    transverse 2 D, infinitely wide (between symmetry planes through tube centres), coarser than
    squareTubeStaggered. U 1, nu 1e-4: Re 1e4. realizableKE with wall functions, SIMPLEC, U 0.9, p
    unrelaxed, turbulence 0.8, 1e-4 on every field, endTime 3000. Added in the eighth batch, its settings
    fixed before its first run. Why: the staggered bank at another Reynolds number, with another model."""
    roles = square_tube_bank(case, 5, 0.5, 1.0, (30, 16, 8, 60), [16, 16], staggered=True)
    finish(case, roles, Flow("realizableKE", 1e-4, True, {"U": 0.9, "turbulence": 0.8}, ALL_1E4, 3000, 1.0,
                             0.07, start="(1 0 0)"))


@register("bluff-body", "2-D circular cylinder in a channel, blockage 0.25, Re 40, laminar")
def cylinderLaminar(case: Path) -> None:
    """bluff-body. A circular cylinder (D = 1) in a channel of height 4 D (blockage 0.25), 4.5 D upstream,
    14.5 D downstream, at Re 40 (U 1, nu 0.025): a laminar steady flow with two attached eddies. Laminar,
    plain SIMPLE, U 0.7 p 0.3, 1e-5 on p and U (a laminar user converges further), endTime 2000. Added in
    the eighth batch (no turbulent bluff body converged: they shed or stall), its settings fixed before
    its first run. Why: the steady bluff-body flow, the set's one laminar case."""
    fresh(case)
    grid = grid_2d([-5, -1, 1, 15], [-2, -1, 1, 2], [40, 30, 100], [20, 30, 20], channel_patches(2, 2),
                   gx=[0.25, 1, 5], gy=[0.5, 1, 2], cells={(1, 1): ("cylinder", 0.5, 20, 0.2)})
    roles = channel_mesh(case, grid, cylinder="wall")
    finish(case, roles, Flow("laminar", 0.025, False, {"U": 0.7, "p": 0.3, "turbulence": 0.7},
                             {"p": 1e-5, "U": 1e-5, "turbulence": 1e-5}, 2000, 1.0, 0.07, start="(1 0 0)"))


@register("wall-cavity", "2-D channel over a floor cavity, L/D 2, Re 100, laminar")
def cavityLaminar(case: Path) -> None:
    """wall-cavity. openCavity's channel and cavity (height 2 over a cavity of length 2, depth 1, L/D 2)
    at Re 100 on the depth (U 1, nu 0.01): a laminar steady flow, one eddy filling the cavity. Laminar,
    SIMPLEC, U 0.9, p unrelaxed, 1e-5 on p and U (as cylinderLaminar's user), endTime 2000. Added in the
    ninth batch (no turbulent cavity converged: they stall between 1e-4 and 1e-3), its settings fixed
    before its first run. Why: the recess flow without the turbulence model's stall."""
    roles = cavity(case, 2, 1, [40, 40, 80], [30, 40])
    finish(case, roles, Flow("laminar", 0.01, True, {"U": 0.9, "turbulence": 0.9},
                             {"p": 1e-5, "U": 1e-5, "turbulence": 1e-5}, 2000, 1.0, 0.07, start="(1 0 0)"))


@register("porous-obstacle", "2-D porous square block between symmetry planes, Re 1e5",
                             source="tutorial incompressible/pisoFoam/laminar/porousBlockage")
def porousBlockage(case: Path) -> None:
    """porous-obstacle. pisoFoam/laminar/porousBlockage (a 1 x 1 porous block, explicitPorositySource in
    constant/fvOptions, in a 8 x 4 box with symmetry planes top and bottom) made a steady turbulent case.
    Allrun: blockMesh, topoSet. Edits: simpleFoam with steady schemes; nu 5e-3 -> 1e-5 (Re 200 -> 1e5 on
    the block: turbulent) and kEpsilon with its fields (5 % intensity); the porosity's Darcy coefficient
    1000 kept and a Forchheimer coefficient 5 added (f 0 -> 5 5 5: at nu 1e-5 the Darcy term alone, nu D
    = 0.01 1/s, would make the block transparent; 0.5 f |U| = 2.5 1/s at U 1 keeps it a blockage, as the
    laminar nu D = 5 1/s did); the mesh 64 x 32 -> 128 x 64 (the block 16 cells across). Plain SIMPLE with
    the "between" factors U 0.8, p 0.2, turbulence 0.7; 1e-4 on every field; endTime 3000. Why: the
    reserved kind's own tutorial."""
    copy_tutorial(TUTORIALS / "incompressible" / "pisoFoam" / "laminar" / "porousBlockage", case)
    mesh = case / "system" / "blockMeshDict"
    mesh.write_text(mesh.read_text().replace("(64 32 1)", "(128 64 1)"))
    options = case / "constant" / "fvOptions"
    options.write_text(options.read_text().replace("f   (0 0 0);", "f   (5 5 5);"))
    for name in ("U", "p"):
        (case / "0" / name).unlink()
    roles = {"inlet": ("inlet", (1, 0)), "outlet": "outlet", "top": "symmetry", "bottom": "symmetry"}
    finish(case, roles, Flow("kEpsilon", 1e-5, False, {"U": 0.8, "p": 0.2, "turbulence": 0.7}, ALL_1E4, 3000,
                             1.0, 0.07 * 4, start="(1 0 0)"), ("topoSet", ))


def write_porosity(case: Path, darcy: str, forchheimer: str, zone: str = "porous") -> None:
    """system/fvOptions: a Darcy-Forchheimer explicitPorositySource on ``zone`` ("porous": the source is
    named porosity; another zone's source is added to the file, named porosity_<zone>)."""
    path = case / "system" / "fvOptions"
    entry = "porosity" if zone == "porous" else f"porosity_{zone}"
    entry += ("\n{\n    type explicitPorositySource;\n    explicitPorositySourceCoeffs\n    {\n"
              "        selectionMode cellZone;\n"
              f"        cellZone {zone};\n"
              f"        type DarcyForchheimer;\n        d {darcy};\n        f {forchheimer};\n"
              "        coordinateSystem { origin (0 0 0); rotation { type none; } }\n    }\n}\n")
    if zone == "porous":
        write_dict(path, entry)
    else:
        path.write_text(path.read_text() + entry)


@register("porous-obstacle", "2-D porous block on a walled channel's centre line, Re 1e5")
def porousChannel(case: Path) -> None:
    """porous-obstacle. A walled channel of height 1 with a porous block (1 long, 0.4 high) on its centre
    line, 4 upstream, 9 downstream; the block a cellZone of the blockMesh, a Darcy-Forchheimer
    explicitPorositySource in system/fvOptions (d 1e5 1/m2, f 20 1/m: nu d = 1 1/s, 0.5 f |U| = 10 1/s,
    most of the flow goes round it). U 1, nu 1e-5: Re 1e5 on the height. realizableKE with wall
    functions, SIMPLEC, U 0.9, p unrelaxed, turbulence 0.7, 1e-4 on every field, endTime 4000. Sized to
    be one of the long cases. Why: a porous obstacle with walls, a flow split between bypass and bleed."""
    fresh(case)
    grid = grid_2d([-4, 0, 1, 10], [0, 0.3, 0.7, 1], [80, 50, 180], [40, 40, 40], channel_patches(2, 2),
                   gx=[0.25, 1, 5], gy=["((0.5 0.5 4) (0.5 0.5 1))", 1, "((0.5 0.5 1) (0.5 0.5 0.25))"],
                   zones={(1, 1): "porous"})
    roles = channel_mesh(case, grid, porosity={"porous": ("(1e5 1e5 1e5)", "(20 20 20)")})
    finish(case, roles, Flow("realizableKE", 1e-5, True, {"U": 0.9, "turbulence": 0.7}, ALL_1E4, 4000, 1.0,
                             0.07, start="(1 0 0)"))
