"""Case families: N variants of one OpenFOAM simpleFoam case, each varied by what varies in practice.

A controller trained on one case learns that case; a family of cases (faster and slower inflows, other
angles of attack, other fluids, coarser and finer meshes, other starting fields) is what it meets in
use. :func:`build_family` writes, from a base case, one plain OpenFOAM case per :class:`Variation`
(``dest/<base name>-<k>/``) and a manifest ``dest/family.json``; :func:`sample_variations` draws the
variations from ranges, reproducibly from a seed. What each variation does (docs/family.md):

- ``speed``: the inlet velocity times the factor (fixedValue, freestream[Velocity] and the data of a
  timeVaryingMappedFixedValue inlet), the inlet turbulence with it (k ~ U^2, epsilon ~ U^3,
  omega, nut, nuTilda ~ U: foam_bridge._family_fields), and 0/U's uniform internalField;
- ``angle``: degrees added to the flow angle in the x-y plane (external flows: freestream patches);
- ``viscosity``: ``nu`` in constant/transportProperties times the factor;
- ``mesh``: the cells per block direction times the factor (blockMesh), or refineMesh for a case that
  ships its mesh (factor 2, 4, ...: foam_bridge._family_mesh);
- ``initial``: 0/U's uniform internalField times the factor (0: from rest).

A variation that cannot apply to the base (an angle on an internal flow, a mesh scale of 1.5 on a
shipped mesh) is a one-line ValueError naming the case and the reason, raised before any variant is
written. The base is only read and copied, never modified.
"""

from __future__ import annotations

import dataclasses
import json
import math
import shutil
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from foamlib import FoamFile

from atomicfile import atomic_write_text
from foam_bridge import _family_fields as fields
from foam_bridge import _family_mesh as mesh
from foam_bridge._openfoam import OpenFOAM, find_openfoam
from foam_bridge._template import cell_count, copy_case, run_application

__all__ = ["MANIFEST", "VARIATION_NAMES", "FamilyCase", "Variation", "build_family", "read_manifest",
           "sample_variations"]

MANIFEST = "family.json"
#: The variations, in the order sample_variations draws them.
VARIATION_NAMES = ("speed", "angle", "viscosity", "mesh", "initial")
_FORMAT = 1


@dataclass(frozen=True)
class Variation:
    """How one variant differs from its base; every field's default leaves the base as it is.

    ``speed``, ``viscosity``, ``mesh``: factors (> 0) on the inlet velocity, ``nu`` and the cells per
    direction; ``angle``: degrees added to the flow angle in the x-y plane (counter-clockwise);
    ``initial``: factor (>= 0) on 0/U's uniform internalField.
    """

    speed: float = 1.0
    angle: float = 0.0
    viscosity: float = 1.0
    mesh: float = 1.0
    initial: float = 1.0

    def __post_init__(self) -> None:
        for name in VARIATION_NAMES:
            value = getattr(self, name)
            low = -90.0 if name == "angle" else 0.0
            if not (isinstance(value, int | float) and math.isfinite(value)):
                raise ValueError(f"variation {name}={value!r}: expected a finite number")
            if value < low or (value == low and name in ("speed", "viscosity", "mesh")) or \
                    (name == "angle" and value > 90):
                bound = "in [-90, 90] degrees" if name == "angle" else ">= 0" if name == "initial" else "> 0"
                raise ValueError(f"variation {name}={value!r}: expected {bound}")
            object.__setattr__(self, name, float(value))  # the manifest says 2.0 for 2, alike for any input

    @property
    def reynolds_ratio(self) -> float:
        """The variant's Reynolds number over the base's: U L / nu with the geometry (L) unchanged."""
        return self.speed / self.viscosity


@dataclass(frozen=True)
class FamilyCase:
    """One variant as built (an entry of the manifest). ``name``: its directory under the family's
    ``dest``; ``inlet_velocity``: the first inlet's mean velocity after the variation (None for a
    mapped inlet); ``nu``: the viscosity after it (None if the case has no plain ``nu``)."""

    name: str
    path: Path
    base: Path
    variation: Variation
    reynolds_ratio: float
    cells: int
    algorithm: str
    inlet_patches: tuple[str, ...]
    inlet_velocity: tuple[float, float, float] | None
    nu: float | None

    def to_json(self) -> dict[str, Any]:
        """The manifest entry (the path relative to the family directory: a family can be moved)."""
        entry = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "path"}
        return {**entry, "base": str(self.base), "variation": dataclasses.asdict(self.variation),
                "inlet_patches": list(self.inlet_patches),
                "inlet_velocity": None if self.inlet_velocity is None else list(self.inlet_velocity)}


def sample_variations(ranges: Mapping[str, tuple[float, float]], n: int, seed: int) -> list[Variation]:
    """``n`` variations, each named variation drawn uniformly from its ``(low, high)`` range (others
    neutral), rounded to 4 decimals. Each variation has its own seeded stream: adding an ``angle`` range
    does not change the speeds a seed gives."""
    unknown = sorted(set(ranges) - set(VARIATION_NAMES))
    if unknown:
        raise ValueError(f"unknown variation(s) {', '.join(unknown)}; known: {', '.join(VARIATION_NAMES)}")
    if n < 1:
        raise ValueError(f"n = {n}: expected at least one variant")
    drawn: dict[str, list[float]] = {}
    for index, name in enumerate(VARIATION_NAMES):
        if name in ranges:
            low, high = (float(v) for v in ranges[name])
            if not low <= high:
                raise ValueError(f"range of {name}: low {low:g} > high {high:g}")
            values = np.random.default_rng([seed, index]).uniform(low, high, size=n)
            drawn[name] = [round(float(v), 4) for v in values]
    return [Variation(**{name: values[k] for name, values in drawn.items()}) for k in range(n)]


def build_family(base: Path, dest: Path, variations: Sequence[Variation], openfoam: OpenFOAM | None = None,
                 progress: Callable[[FamilyCase], None] | None = None) -> list[FamilyCase]:
    """Write ``dest/<base name>-<k>/`` for each variation k and add them to ``dest/family.json``.

    Each variant is a plain OpenFOAM case, meshed. Every variation is checked against the base before
    anything is written (one-line ValueError); an existing variant of the same name is replaced, the
    manifest keeps other bases' entries. ``progress`` is called with each case built.
    """
    openfoam = openfoam or find_openfoam()
    base = Path(base).resolve()
    if not (base / "system" / "controlDict").is_file():
        raise ValueError(f"case {base}: not an OpenFOAM case (no system/controlDict)")
    dest = Path(dest).resolve()
    created = not dest.exists()
    dest.mkdir(parents=True, exist_ok=True)
    try:
        with tempfile.TemporaryDirectory(dir=dest, prefix=".family-") as scratch:  # same file system
            prepared = Path(scratch) / base.name
            flow = _prepare(base, prepared, openfoam)
            for variation in variations:
                _check(prepared, flow, variation)
            _check_names(dest, base, [f"{base.name}-{k}" for k in range(len(variations))])
            cases = []
            for k, variation in enumerate(variations):
                cases.append(_build_one(prepared, dest, f"{base.name}-{k}", base, flow, variation, openfoam))
                if progress is not None:
                    progress(cases[-1])
    except BaseException:
        if created and not any(dest.iterdir()):  # a refused family leaves no empty directory behind
            dest.rmdir()
        raise
    _write_manifest(dest, base, cases)
    return cases


def _prepare(base: Path, prepared: Path, openfoam: OpenFOAM) -> fields.Flow:
    """The base copied to ``prepared`` and meshed at its own resolution; its inflow read."""
    copy_case(base, prepared)
    if not (prepared / "constant" / "polyMesh" / "boundary").is_file():
        run_application(openfoam, "blockMesh", prepared)
    boundary = FoamFile(prepared / "constant" / "polyMesh" / "boundary")[None] or []
    patch_types = {name: str(entry.get("type", "")) for name, entry in boundary}
    return fields.read_flow(prepared, openfoam, base.name, patch_types)


def _check(prepared: Path, flow: fields.Flow, variation: Variation) -> None:
    fields.check_flow(flow, variation.speed, variation.angle, variation.initial)
    mesh.check_mesh(prepared, flow.name, variation.mesh)
    if variation.viscosity != 1 and flow.nu is None:
        raise ValueError(f"case {flow.name}: constant/transportProperties has no plain entry 'nu' (a "
                         f"Newtonian fluid's kinematic viscosity) to scale")


def _build_one(prepared: Path, dest: Path, name: str, base: Path, flow: fields.Flow, variation: Variation,
               openfoam: OpenFOAM) -> FamilyCase:
    """One variant, written beside its final place and renamed into it when complete."""
    partial = dest / f".{name}.partial"
    try:
        _write_variant(prepared, partial, flow, variation, openfoam)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    final = dest / name
    if final.exists():
        shutil.rmtree(final)
    partial.rename(final)
    velocity = None if flow.inlet_velocity is None else tuple(
        round(float(c), 10) for c in fields.rotate(np.asarray(flow.inlet_velocity) * variation.speed,
                                                    variation.angle))
    nu = None if flow.nu is None else flow.nu * variation.viscosity
    return FamilyCase(name, final, base, variation, round(variation.reynolds_ratio, 10), cell_count(final),
                      flow.algorithm, tuple(flow.inlets), velocity, nu)  # type: ignore[arg-type]


def _others(dest: Path, base: Path) -> list[dict[str, Any]]:
    """The manifest entries of ``dest`` that other bases wrote."""
    return [entry for entry in read_manifest(dest).get("cases", []) if entry["base"] != str(base)]


def _check_names(dest: Path, base: Path, names: Sequence[str]) -> None:
    clash = {entry["name"] for entry in _others(dest, base)} & set(names)
    if clash:
        raise ValueError(f"{dest}: variants {', '.join(sorted(clash))} belong to another base of the same "
                         f"name; use another output directory")


def _write_variant(prepared: Path, case: Path, flow: fields.Flow, variation: Variation,
                   openfoam: OpenFOAM) -> None:
    copy_case(prepared, case)
    for log in case.glob("log.*"):
        log.unlink()
    mesh.scale_mesh(case, openfoam, variation.mesh)
    fields.apply_flow(case, flow, variation.speed, variation.angle, variation.initial)
    if variation.viscosity != 1:
        fields.scale_viscosity(case, openfoam, flow.name, variation.viscosity)


def _write_manifest(dest: Path, base: Path, cases: Sequence[FamilyCase]) -> None:
    """``dest/family.json`` (atomic): this base's cases replace its earlier ones, others' stay."""
    kept = _others(dest, base)
    manifest = {"format": _FORMAT, "cases": [*kept, *(case.to_json() for case in cases)]}
    atomic_write_text(dest / MANIFEST, json.dumps(manifest, indent=1) + "\n")


def read_manifest(dest: Path) -> dict[str, Any]:
    """The family manifest of ``dest`` ({} if there is none yet)."""
    path = Path(dest) / MANIFEST
    return json.loads(path.read_text()) if path.is_file() else {}
