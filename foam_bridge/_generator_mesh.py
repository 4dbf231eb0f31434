"""The blockMesh geometry of the generated cases (foam_bridge._generator): one builder per kind.

Each builder turns a kind's parameters (lengths in units of the inlet channel height H) into a
:class:`Sketch`, a 2-D block layout: corner points, blocks with their cell counts and gradings, curved
edges and the boundary edges of each patch. :func:`blockmesh_dict` extrudes a sketch one cell thick (the
front and back an ``empty`` patch: a 2-D case). Kept apart from the physics (foam_bridge._generator_physics)
because the geometry alone decides the mesh: the same parameters at two resolutions are the same shape
with other cell counts.

Cell counts come from a :class:`Sizer`: cells across a channel of height H are fixed (about
``ACROSS``), cells along follow from a target total (``TARGET_CELLS`` at resolution 1), and every count is
multiplied by the resolution. Walls are graded so that the first cell's y+ is about ``Y_PLUS`` (wall
functions), capped at ``MAX_RATIO``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

__all__ = ["ACROSS", "BUILDERS", "TARGET_CELLS", "Sizer", "Sketch", "blockmesh_dict", "build_sketch",
           "first_cell"]

#: Cells across a channel of height H at resolution 1.
ACROSS = 26
#: Cells of a case at resolution 1 (about: counts are rounded, and curved features get finer cells).
TARGET_CELLS = 8000
#: Wall functions' sweet spot (first cell centre), and the largest grading towards a wall.
Y_PLUS = 40.0
MAX_RATIO = 8.0

Point = tuple[float, float]


@dataclass
class Sketch:
    """A 2-D block layout. ``blocks``: (four corner indices counter-clockwise, (nx, ny), (x grading, y
    grading) as blockMesh text); ``curves``: (kind ``arc``/``spline``/``polyLine``, start, end, interior
    points); ``patches``: name -> boundary edges (a, b), each taken counter-clockwise around the fluid so
    that its face points out. Patch ``walls`` is a wall, the others plain patches."""

    points: list[Point] = field(default_factory=list)
    blocks: list[tuple[tuple[int, int, int, int], tuple[int, int], tuple[str, str]]] = field(
        default_factory=list)
    curves: list[tuple[str, int, int, list[Point]]] = field(default_factory=list)
    patches: dict[str, list[tuple[int, int]]] = field(default_factory=dict)

    def add(self, point: Point) -> int:
        self.points.append((float(point[0]), float(point[1])))
        return len(self.points) - 1

    def edge(self, patch: str, a: int, b: int) -> None:
        self.patches.setdefault(patch, []).append((a, b))

    def area(self) -> float:
        """The blocks' area with straight edges (enough to size the mesh)."""
        total = 0.0
        for corners, _, _ in self.blocks:
            ring = [self.points[i] for i in corners]
            pairs = zip(ring, ring[1:] + ring[:1], strict=True)
            total += 0.5 * abs(sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in pairs))
        return total


@dataclass(frozen=True)
class Sizer:
    """Cell counts of a case: ``dx`` / ``dy`` the cell sizes at resolution 1, ``first`` the wall-adjacent
    cell height wanted (in H), ``resolution`` the factor on every count."""

    dx: float
    dy: float
    first: float
    resolution: float

    def along(self, length: float, fine: float = 1.0) -> int:
        """Cells along a length (``fine``: that many times finer, for curved walls and tapers)."""
        return max(2, round(length * fine / self.dx * self.resolution))

    def across(self, height: float) -> int:
        return max(2, round(height / self.dy * self.resolution))

    def walls(self, height: float, cells: int) -> str:
        """Grading across a channel of ``height`` with walls (or shear layers) on both sides."""
        ratio = _expansion(self.first, height / 2, max(1, cells // 2))
        return f"((0.5 0.5 {ratio:.4g}) (0.5 0.5 {1 / ratio:.4g}))" if ratio > 1.01 else "1"


def _expansion(first: float, length: float, cells: int) -> float:
    """blockMesh's expansion ratio (last cell / first) of ``cells`` geometric cells over ``length`` whose
    first cell is ``first`` high: 1 when uniform cells are already that small, at most MAX_RATIO."""
    if cells < 2 or first >= length / cells:
        return 1.0
    low, high = 1.0, MAX_RATIO
    for _ in range(60):  # bisect on the last/first ratio: the first cell shrinks as it grows
        ratio = (low + high) / 2
        growth = ratio ** (1 / (cells - 1))
        size = length * (growth - 1) / (growth**cells - 1)
        low, high = (ratio, high) if size > first else (low, ratio)
    return high


def first_cell(reynolds: float) -> float:
    """The wall-adjacent cell height (in H) that puts its centre at y+ ~ Y_PLUS: friction velocity from
    a channel's friction coefficient (Cf = 0.079 Re^-0.25, Blasius)."""
    friction = math.sqrt(0.079 * reynolds**-0.25 / 2)
    return 2 * Y_PLUS / (reynolds * friction)


# ---- building blocks shared by the kinds ---------------------------------------------------------


def lattice(xs: Sequence[float], ys: Sequence[float], sizer: Sizer, holes: set[tuple[int, int]],
            x_grading: Sequence[str], fine: Sequence[float]) -> Sketch:
    """Rectangular blocks on the lines ``xs`` x ``ys``, less the ``holes`` (column, row): solid obstacles
    whose sides are walls. The left of column 0 is the inlet, the right of the last column the outlet.
    Column i has ``x_grading[i]`` and ``fine[i]`` times the usual cells along (Sizer.along)."""
    sketch = Sketch()
    index: dict[tuple[int, int], int] = {}

    def point(i: int, j: int) -> int:
        if (i, j) not in index:
            index[(i, j)] = sketch.add((xs[i], ys[j]))
        return index[(i, j)]

    columns, rows = len(xs) - 1, len(ys) - 1
    nx = [sizer.along(xs[i + 1] - xs[i], fine[i]) for i in range(columns)]
    ny = [sizer.across(ys[j + 1] - ys[j]) for j in range(rows)]
    fluid = {(i, j) for i in range(columns) for j in range(rows)} - holes
    for j in range(rows):
        grading = sizer.walls(ys[j + 1] - ys[j], ny[j])
        for i in range(columns):
            if (i, j) not in fluid:
                continue
            corners = (point(i, j), point(i + 1, j), point(i + 1, j + 1), point(i, j + 1))
            sketch.blocks.append((corners, (nx[i], ny[j]), (x_grading[i], grading)))
            sides = zip(((0, 1), (1, 2), (2, 3), (3, 0)), ((0, -1), (1, 0), (0, 1), (-1, 0)), strict=True)
            for (a, b), (di, dj) in sides:
                if (i + di, j + dj) in fluid:
                    continue
                name = "inlet" if i + di < 0 else "outlet" if i + di == columns else "walls"
                sketch.edge(name, corners[a], corners[b])
    return sketch


def strip(xs: Sequence[float], bottoms: Sequence[float], tops: Sequence[float], sizer: Sizer,
          x_grading: Sequence[str], fine: Sequence[float]) -> Sketch:
    """A channel of one row of blocks: column line i runs from (xs[i], bottoms[i]) to (xs[i], tops[i])
    (tapers between them). Inlet on the left, outlet on the right, walls below and above."""
    sketch = Sketch()
    lower = [sketch.add((x, y)) for x, y in zip(xs, bottoms, strict=True)]
    upper = [sketch.add((x, y)) for x, y in zip(xs, tops, strict=True)]
    heights = [t - b for b, t in zip(bottoms, tops, strict=True)]
    ny = sizer.across(math.sqrt(min(heights) * max(heights)))  # one count: the blocks share their sides
    grading = sizer.walls(min(heights), ny)
    for i in range(len(xs) - 1):
        cells = (sizer.along(xs[i + 1] - xs[i], fine[i]), ny)
        corners = (lower[i], lower[i + 1], upper[i + 1], upper[i])
        sketch.blocks.append((corners, cells, (x_grading[i], grading)))
        sketch.edge("walls", lower[i], lower[i + 1])
        sketch.edge("walls", upper[i + 1], upper[i])
    sketch.edge("inlet", upper[0], lower[0])
    sketch.edge("outlet", lower[-1], upper[-1])
    return sketch


#: x gradings: cells shrinking towards a feature downstream, growing away from one upstream, uniform.
INTO, OUT_OF, EVEN = "0.25", "5", "1"


# ---- the kinds ----------------------------------------------------------------------------------


def step(p: Mapping[str, float | str], sizer: Sizer) -> Sketch:
    """Backward- (or forward-) facing step(s) at x = 0 on one or both walls; the inlet channel is 1 high.
    ``expansion``: the wide channel's height over the narrow one's."""
    both = p["walls"] == 2
    narrow = 1.0 if p["direction"] == "backward" else 1.0 / float(p["expansion"])
    rise = narrow * (float(p["expansion"]) - 1) / (2 if both else 1)  # each step's height
    ys = [0.0, rise, rise + narrow, rise + narrow + rise] if both else [0.0, rise, rise + narrow]
    cut = 0 if p["direction"] == "backward" else 1  # the column whose corner rows are solid
    holes = {(cut, 0)} | ({(cut, 2)} if both else set())
    xs = [-float(p["upstream"]), 0.0, float(p["downstream"])]
    grading = [INTO, OUT_OF] if cut == 0 else [INTO, "2"]
    return lattice(xs, ys, sizer, holes, grading, [1, 1])


def rib(p: Mapping[str, float | str], sizer: Sizer) -> Sketch:
    """One or two rectangular ribs (``height`` x ``width``, ``gap`` apart) on the lower wall at x = 0."""
    h, w, gap = float(p["height"]), float(p["width"]), float(p["gap"])
    xs, holes, grading, fine = [-float(p["upstream"]), 0.0, w], {(1, 0)}, [INTO, EVEN], [1.0, 2.0]
    if p["ribs"] == 2:
        xs += [w + gap, w + gap + w]
        holes.add((3, 0))
        grading += [EVEN, EVEN]
        fine += [1.5, 2.0]
    xs.append(xs[-1] + float(p["downstream"]))
    grading.append(OUT_OF)
    fine.append(1.0)
    return lattice(xs, [0.0, h, 1.0], sizer, holes, grading, fine)


def _bump_curve(shape: str, length: float, height: float) -> tuple[str, list[Point]]:
    """The bump's wall between (0, 0) and (length, 0): a circular arc, or a cosine-squared hill through
    a spline or a polyLine."""
    if shape == "arc":
        return "arc", [(length / 2, height)]
    count = 7 if shape == "spline" else 11
    xs = [length * (k + 1) / (count + 1) for k in range(count)]
    return shape, [(x, height * math.sin(math.pi * x / length) ** 2) for x in xs]


def bump(p: Mapping[str, float | str], sizer: Sizer) -> Sketch:
    """A smooth bump (``height``, ``length``) on the lower wall from x = 0, a straight upper wall."""
    length = float(p["length"])
    xs = [-float(p["upstream"]), 0.0, length, length + float(p["downstream"])]
    sketch = strip(xs, [0.0] * 4, [1.0] * 4, sizer, [INTO, EVEN, OUT_OF], [1, 2, 1])
    kind, inside = _bump_curve(str(p["shape"]), length, float(p["height"]))
    sketch.curves.append((kind, 1, 2, inside))
    return sketch


def _taper(p: Mapping[str, float | str], outlet: float) -> tuple[list[float], list[float], float]:
    """Bottoms, tops and length of a taper from height 1 to ``outlet`` whose wall(s) turn ``angle``
    degrees: the lower wall alone (one side) or both walls alike."""
    sides = int(p["sides"])
    shift = (1.0 - outlet) / sides  # upwards for a contraction, downwards for a diffuser
    length = abs(shift) / math.tan(math.radians(float(p["angle"])))
    bottoms = [0.0, 0.0, shift, shift]
    tops = [1.0, 1.0, 1.0 - (shift if sides == 2 else 0.0), 1.0 - (shift if sides == 2 else 0.0)]
    return bottoms, tops, length


def contraction(p: Mapping[str, float | str], sizer: Sizer) -> Sketch:
    """Height 1 narrowing to 1 / ``ratio`` over a taper at ``angle`` degrees from x = 0."""
    bottoms, tops, length = _taper(p, 1.0 / float(p["ratio"]))
    xs = [-float(p["upstream"]), 0.0, length, length + float(p["downstream"])]
    return strip(xs, bottoms, tops, sizer, [EVEN, EVEN, "3"], [1, 2, 1])


def diffuser(p: Mapping[str, float | str], sizer: Sizer) -> Sketch:
    """Height 1 widening to ``ratio`` over a taper whose wall(s) open at ``angle`` degrees from x = 0."""
    bottoms, tops, length = _taper(p, float(p["ratio"]))
    xs = [-float(p["upstream"]), 0.0, length, length + float(p["downstream"])]
    return strip(xs, bottoms, tops, sizer, [INTO, EVEN, "3"], [1, 1.5, 1])


def bend(p: Mapping[str, float | str], sizer: Sizer) -> Sketch:
    """A channel of width 1 turning left by ``angle`` degrees about the origin (inner radius ``radius``),
    a straight leg along x before it and one along the turned direction after it."""
    inner, angle = float(p["radius"]), float(p["angle"])
    outer, pieces = inner + 1.0, max(1, math.ceil(angle / 45))  # blocks of <= 45 degrees keep cells square
    turns = [math.radians(-90 + angle * k / pieces) for k in range(pieces + 1)]
    end = turns[-1]
    leg = float(p["downstream"])
    lines = [((-float(p["upstream"]), -outer), (-float(p["upstream"]), -inner))]
    lines += [((outer * math.cos(t), outer * math.sin(t)), (inner * math.cos(t), inner * math.sin(t)))
              for t in turns]
    along = (-math.sin(end) * leg, math.cos(end) * leg)  # the tangent of the turn's end, counter-clockwise
    lines.append(tuple((x + along[0], y + along[1]) for x, y in lines[-1]))  # type: ignore[arg-type]
    sketch = Sketch()
    ids = [(sketch.add(o), sketch.add(i)) for o, i in lines]
    ny = sizer.across(1.0)
    grading = sizer.walls(1.0, ny)
    arc = math.radians(angle) / pieces * (inner + 0.5)
    lengths = [float(p["upstream"]), *[arc] * pieces, leg]
    for k in range(len(ids) - 1):
        (o0, i0), (o1, i1) = ids[k], ids[k + 1]
        x_grading = INTO if k == 0 else OUT_OF if k == len(ids) - 2 else EVEN
        fine = 1.0 if x_grading != EVEN else 2.0
        sketch.blocks.append(((o0, o1, i1, i0), (sizer.along(lengths[k], fine), ny), (x_grading, grading)))
        sketch.edge("walls", o0, o1)
        sketch.edge("walls", i1, i0)
        if 0 < k < len(ids) - 2:
            middle = (turns[k - 1] + turns[k]) / 2
            for radius, a, b in ((outer, o0, o1), (inner, i0, i1)):
                sketch.curves.append(("arc", a, b, [(radius * math.cos(middle), radius * math.sin(middle))]))
    sketch.edge("inlet", ids[0][1], ids[0][0])
    sketch.edge("outlet", ids[-1][0], ids[-1][1])
    return sketch


BUILDERS: dict[str, Callable[[Mapping[str, float | str], Sizer], Sketch]] = {
    "step": step, "rib": rib, "bump": bump, "contraction": contraction, "diffuser": diffuser, "bend": bend,
}


def build_sketch(kind: str, params: Mapping[str, float | str], reynolds: float, resolution: float) -> Sketch:
    """The kind's sketch with its cell counts: ``ACROSS`` cells per H across, cells along sized so that
    the whole has about TARGET_CELLS at resolution 1 (from its area; never longer than 10 across), and
    every count times ``resolution``."""
    builder = BUILDERS[kind]
    dy = 1.0 / ACROSS
    area = builder(params, Sizer(1.0, 1.0, 1.0, 1.0)).area()
    dx = min(10 * dy, max(dy, area / (TARGET_CELLS * dy)))
    return builder(params, Sizer(dx, dy, first_cell(reynolds), resolution))


# ---- the dictionary -----------------------------------------------------------------------------


def blockmesh_dict(sketch: Sketch, scale: float, depth: float) -> str:
    """The body of a blockMeshDict: ``sketch`` (lengths times ``scale``) extruded ``depth`` in z (before
    scaling), front and back one empty patch."""
    n = len(sketch.points)

    def vertex(point: Point, z: float) -> str:
        return f"({point[0]:.8g} {point[1]:.8g} {z:.8g})"

    vertices = [vertex(pt, 0.0) for pt in sketch.points] + [vertex(pt, depth) for pt in sketch.points]
    hexes, sides = [], []
    for (a, b, c, d), (nx, ny), (gx, gy) in sketch.blocks:
        hexes.append(f"hex ({a} {b} {c} {d} {a + n} {b + n} {c + n} {d + n}) ({nx} {ny} 1) "
                     f"simpleGrading ({gx} {gy} 1)")
        sides += [f"({a} {d} {c} {b})", f"({a + n} {b + n} {c + n} {d + n})"]
    edges = []
    for kind, a, b, inside in sketch.curves:
        for offset, z in ((0, 0.0), (n, depth)):
            through = " ".join(vertex(pt, z) for pt in inside)
            shown = through if kind == "arc" else f"({through})"  # an arc takes one point, others a list
            edges.append(f"{kind} {a + offset} {b + offset} {shown}")
    boundary = []
    for name, found in sketch.patches.items():
        faces = " ".join(f"({a} {b} {b + n} {a + n})" for a, b in found)
        boundary.append(f"{name} {{ type {'wall' if name == 'walls' else 'patch'}; faces ({faces}); }}")
    boundary.append(f"frontAndBack {{ type empty; faces ({' '.join(sides)}); }}")

    def listed(title: str, rows: list[str]) -> str:
        return f"{title}\n(\n" + "".join(f"    {row}\n" for row in rows) + ");\n\n"

    return (f"scale {scale:g};\n\n" + listed("vertices", vertices) + listed("blocks", hexes)
            + listed("edges", edges) + listed("boundary", boundary) + "mergePatchPairs\n(\n);\n")
