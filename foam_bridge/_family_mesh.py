"""The mesh of a case-family variant (foam_bridge._family): block cell counts scaled and blockMesh run,
or a shipped mesh refined by refineMesh.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

A case with ``system/blockMeshDict``: every block's cell counts ``hex (...) (nx ny nz)`` are multiplied
by the mesh scale and rounded (at least 1); a count of 1 stays 1 (the single cell layer of a 2-D case),
the gradings stay (they are ratios). The new ``blocks`` entry is appended to the variant's
blockMeshDict, from OpenFOAM's expansion of it (``$nx`` variables and ``#include``s resolved), and
blockMesh is run. A case that ships only ``constant/polyMesh`` (airFoil2D): ``refineMesh -overwrite``
halves every cell in each direction of the mesh (x and y of a 2-D one), so its mesh scales are 1, 2,
4, ...; anything else is a one-line ValueError.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

from foam_bridge import foamdict
from foam_bridge._openfoam import OpenFOAM
from foam_bridge._template import run_application

__all__ = ["check_mesh", "has_block_mesh", "scale_blocks", "scale_mesh"]

_BLOCK = re.compile(r"(hex\s*\([\d\s]+\)\s*(?:[A-Za-z_]\w*\s*)?)\(\s*(\d+)\s+(\d+)\s+(\d+)\s*\)")


def has_block_mesh(case: Path) -> bool:
    return (case / "system" / "blockMeshDict").is_file() or (case / "system" / "blockMeshDict.gz").is_file()


def check_mesh(case: Path, name: str, scale: float) -> None:
    """One-line ValueError if ``case`` cannot take the mesh scale ``scale``."""
    if scale == 1:
        return
    if not has_block_mesh(case) and _refinements(scale) is None:
        raise ValueError(f"case {name} ships a finished mesh (constant/polyMesh, no system/blockMeshDict): "
                         f"its mesh scale can be 1, 2, 4, ... (refineMesh), not {scale:g}")
    for path in sorted((case / "0").glob("*")):
        if path.is_file() and re.search(r"internalField\s+nonuniform", path.read_text(errors="replace")):
            raise ValueError(f"case {name}: 0/{path.name} holds a nonuniform internalField, which a new "
                             f"mesh cannot take; only mesh scale 1 applies")


def _refinements(scale: float) -> int | None:
    """n with 2**n == scale (n >= 1), else None."""
    n = round(math.log2(scale)) if scale > 1 else 0
    return n if n >= 1 and math.isclose(2.0**n, scale) else None


def scale_mesh(case: Path, openfoam: OpenFOAM, scale: float) -> None:
    """Remesh the variant ``case`` (a copy of the meshed base) at ``scale`` (checked by check_mesh)."""
    if scale == 1:
        return
    if has_block_mesh(case):
        text = foamdict.expanded_text(openfoam, case, "system/blockMeshDict")
        match = re.search(r"^blocks\s+(.+);\s*$", text, re.MULTILINE)
        blocks = scale_blocks(match.group(1) if match else "", scale)
        with open(case / "system" / "blockMeshDict", "a") as out:
            out.write(f"\n// ----- appended by foam_bridge._family: cell counts x {scale:g} -----\n"
                      f"blocks {blocks};\n")
        run_application(openfoam, "blockMesh", case)
        return
    for _ in range(_refinements(scale) or 0):
        run_application(openfoam, "refineMesh", case, "-overwrite")
    mesh = case / "constant" / "polyMesh"
    for packed in mesh.glob("*.gz"):  # the shipped files refineMesh rewrote uncompressed
        if packed.with_suffix("").is_file():
            packed.unlink()


def scale_blocks(blocks: str, scale: float) -> str:
    """The expanded ``blocks`` list with every count times ``scale``, rounded, at least 1; 1 stays 1."""
    def scaled(match: re.Match[str]) -> str:
        counts = [int(c) if int(c) == 1 else max(1, round(int(c) * scale)) for c in match.groups()[1:]]
        return f"{match.group(1)}({' '.join(map(str, counts))})"

    result, found = _BLOCK.subn(scaled, blocks)
    if not found:
        raise ValueError(f"no 'hex (...) (nx ny nz)' block in the blockMeshDict's blocks: {blocks[:80]!r}")
    return result
