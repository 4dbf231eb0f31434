# SPDX-License-Identifier: GPL-3.0-or-later
"""Small helpers for prepare.py: copy a tutorial, run an OpenFOAM utility, edit a dictionary, write a 2-D
extruded blockMeshDict and the dictionaries of a case built from scratch.

Kept apart from prepare.py so that each case's builder there reads as the tutorial's Allrun does.
"""

from __future__ import annotations

import gzip
import os
import shutil
import subprocess
from collections.abc import Sequence
from pathlib import Path

from foamlib import FoamFile

TUTORIALS = Path("/usr/share/doc/openfoam-examples/examples")
SIMPLEFOAM = TUTORIALS / "incompressible" / "simpleFoam"
HEADER = "FoamFile\n{{\n    version 2.0;\n    format ascii;\n    class {cls};\n    object {obj};\n}}\n\n"


def copy_tutorial(source: Path, dest: Path) -> None:
    """Copy ``source`` to ``dest`` and unzip its dictionaries (the Debian package gzips some of them;
    foamlib cannot edit a .gz, and a case must not hold both forms). Surfaces stay gzipped: the meshing
    utilities read them so."""
    if dest.exists():
        shutil.rmtree(dest)
    shutil.copytree(source, dest)
    for packed in sorted(dest.rglob("*.gz")):
        if "triSurface" in packed.parts:
            continue
        packed.with_suffix("").write_bytes(gzip.decompress(packed.read_bytes()))
        packed.unlink()


def foam_env() -> dict[str, str]:
    """The environment the OpenFOAM binaries need: WM_PROJECT_DIR locates their etc/ files."""
    env = dict(os.environ)
    env.setdefault("WM_PROJECT_DIR", "/usr/share/openfoam")
    return env


def run(case: Path, application: str, *args: str) -> None:
    """Run an OpenFOAM utility in ``case`` as Allrun's runApplication does: output to log.<name>, and
    stop on failure (a half-built case must not reach the evaluation)."""
    log = case / f"log.{application}"
    with open(log, "w") as out:
        code = subprocess.run([application, *args], cwd=case, env=foam_env(), stdout=out,
                              stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, check=False).returncode
    if code != 0:
        raise RuntimeError(f"{application} failed in {case} (exit {code}); see {log}")


def restore_zero(case: Path) -> None:
    """restore0Dir: 0.orig becomes 0."""
    shutil.rmtree(case / "0", ignore_errors=True)
    shutil.copytree(case / "0.orig", case / "0")


def set_entry(path: Path, keys: Sequence[str], value: object) -> None:
    """Set one (nested) entry of a dictionary file, keeping the rest as written."""
    with FoamFile(path) as foam:
        foam[tuple(keys)] = value


def replace_patch(path: Path, patch: str, body: str) -> None:
    """Replace a patch's entry in a field file's boundaryField by ``body`` (as text: foamlib would write a
    field entry such as p0 as a bare number, which the boundary condition refuses)."""
    text = path.read_text()
    start = text.index("{", text.index(f"\n    {patch}\n", text.index("boundaryField")))
    depth, end = 0, start
    for end in range(start, len(text)):
        depth += {"{": 1, "}": -1}.get(text[end], 0)
        if depth == 0:
            break
    path.write_text(f"{text[:start]}{{\n        {body}\n    }}{text[end + 1:]}")


def cell_count(case: Path) -> int:
    """Cells of the case's mesh: the owner file's note says it (nCells:...)."""
    head = (case / "constant" / "polyMesh" / "owner").read_bytes()[:2000].decode("ascii", "replace")
    return int(head.split("nCells:")[1].split()[0])


def blockmesh_2d(points: Sequence[tuple[float, float]], blocks: Sequence[tuple[tuple[int, ...], str]],
                 patches: dict[str, tuple[str, Sequence[tuple[int, int]]]], depth: float = 0.1,
                 arcs: Sequence[tuple[int, int, tuple[float, float]]] = ()) -> str:
    """The body of a blockMeshDict for a one-cell-thick 2-D domain. ``points``: (x, y); ``blocks``: (the
    four point indices counter-clockwise, "(nx ny 1) simpleGrading (...)"); ``patches``: name -> (type,
    edges), each edge (a, b) taken in the counter-clockwise sense of the domain so that its face points out.
    Front and back are one empty patch. ``arcs``: (a, b, a point of the arc) edges, on both faces."""
    n = len(points)
    vertices = [f"    ({x:.9g} {y:.9g} 0)" for x, y in points]
    vertices += [f"    ({x:.9g} {y:.9g} {depth:.9g})" for x, y in points]
    hexes = []
    sides = []
    for corners, cells in blocks:
        a, b, c, d = corners
        hexes.append(f"    hex ({a} {b} {c} {d} {a + n} {b + n} {c + n} {d + n}) {cells}")
        sides += [f"({a} {d} {c} {b})", f"({a + n} {b + n} {c + n} {d + n})"]
    curves = [f"    arc {a} {b} ({x:.9g} {y:.9g} 0)\n    arc {a + n} {b + n} ({x:.9g} {y:.9g} {depth:.9g})"
              for a, b, (x, y) in arcs]
    boundary = []
    for name, (kind, edges) in patches.items():
        faces = " ".join(f"({a} {b} {b + n} {a + n})" for a, b in edges)
        boundary.append(f"    {name} {{ type {kind}; faces ({faces}); }}")
    boundary.append(f"    frontAndBack {{ type empty; faces ({' '.join(sides)}); }}")
    return ("scale 1;\n\nvertices\n(\n" + "\n".join(vertices) + "\n);\n\nblocks\n(\n" + "\n".join(hexes)
            + "\n);\n\nedges\n(\n" + "\n".join(curves) + "\n);\n\nboundary\n(\n" + "\n".join(boundary)
            + "\n);\n")


def write_dict(path: Path, body: str, cls: str = "dictionary") -> None:
    """Write a dictionary file with its FoamFile header."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(HEADER.format(cls=cls, obj=path.name) + body)


def write_field(case: Path, name: str, internal: str, boundary: dict[str, str],
                empty: str = "frontAndBack") -> None:
    """Write 0/<name>: a uniform internal value, one boundary condition per patch (its body), and the
    ``empty`` patch of a 2-D case."""
    cls = "volVectorField" if name == "U" else "volScalarField"
    dims = {"U": "[0 1 -1 0 0 0 0]", "p": "[0 2 -2 0 0 0 0]", "k": "[0 2 -2 0 0 0 0]",
            "epsilon": "[0 2 -3 0 0 0 0]", "omega": "[0 0 -1 0 0 0 0]", "nut": "[0 2 -1 0 0 0 0]"}[name]
    patches = "\n".join(f"    {patch} {{ {bc} }}" for patch, bc in boundary.items())
    write_dict(case / "0" / name, f"dimensions {dims};\n\ninternalField uniform {internal};\n\n"
               f"boundaryField\n{{\n{patches}\n    {empty} {{ type empty; }}\n}}\n", cls)
