"""Field and property edits of a case-family variant (foam_bridge._family): the inlet's speed and
direction, the inlet turbulence, the initial velocity, the viscosity.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

Every edit is *appended* to the variant's own copy of the file (OpenFOAM merges a later entry into an
earlier one of the same name, as in foam_bridge._episode_case), never a re-serialisation: ``#include``,
``$var``, comments and everything not varied stay the base's. An inlet's entry is written complete
(from OpenFOAM's own expansion) under the patch's exact name, so it also overrides a regular-expression
entry that matched the patch.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from foamlib import FoamFile

from foam_bridge import foamdict
from foam_bridge._openfoam import OpenFOAM

__all__ = ["FIXED_INLETS", "FREESTREAM_INLETS", "MAPPED_INLETS", "TURBULENCE_EXPONENTS", "Flow",
           "apply_flow", "check_flow", "read_flow", "rotate", "scale_viscosity"]

FIXED_INLETS = ("fixedValue",)
FREESTREAM_INLETS = ("freestream", "freestreamVelocity")
MAPPED_INLETS = ("timeVaryingMappedFixedValue",)
#: The power of the inlet speed each turbulence quantity scales with. The inflow keeps its turbulence
#: intensity I and length scale l (properties of the inflow, not of its speed), so k = 1.5 (I U)^2 goes
#: as U^2, epsilon = Cmu^0.75 k^1.5 / l as U^3, omega = k^0.5 / (Cmu^0.25 l) as U, and the eddy
#: viscosity nut ~ k^0.5 l (and Spalart-Allmaras' nuTilda, which is nut away from walls) as U. A
#: variant is then the base's inflow at another speed, not a more or less turbulent one. (Fields such as
#: T3A's ReThetat depend on I alone and are left.)
TURBULENCE_EXPONENTS = {"k": 2, "epsilon": 3, "omega": 1, "nuTilda": 1, "nut": 1}
#: Keys of an inlet's boundary condition that hold its (field) value.
_VALUE_KEYS = ("value", "freestreamValue")
#: Mesh patch types that are never an inlet.
_NOT_INLETS = ("wall", "empty", "wedge", "symmetry", "symmetryPlane", "cyclic", "cyclicAMI", "processor")
_NUMBER = re.compile(r"(?<![\w.+-])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])")


@dataclass(frozen=True)
class Flow:
    """What a base case's 0/ fields say about its inflow, read once per base (OpenFOAM's expansion).

    ``inlets``: inlet patch -> its 0/U type (fixedValue with a non-zero value, freestream[Velocity],
    timeVaryingMappedFixedValue); ``fields``: the expanded 0/U and turbulence fields present;
    ``inlet_velocity``: the mean velocity of the first inlet (None for a mapped one);
    ``algorithm``: SIMPLE or SIMPLEC (fvSolution's ``SIMPLE.consistent``).
    """

    name: str
    inlets: dict[str, str]
    fields: dict[str, dict[str, Any]]
    inlet_velocity: tuple[float, float, float] | None
    algorithm: str
    nu: float | None = None

    @property
    def external(self) -> bool:
        """An external flow: every inlet is a freestream patch."""
        return bool(self.inlets) and all(t in FREESTREAM_INLETS for t in self.inlets.values())

    @property
    def initial_velocity(self) -> np.ndarray | None:
        """0/U's internalField if uniform, else None."""
        value = self.fields["U"].get("internalField")
        array = np.asarray(value, dtype=float) if not isinstance(value, str) else None
        return array if array is not None and array.shape == (3,) else None


def read_flow(case: Path, openfoam: OpenFOAM, name: str, patch_types: dict[str, str]) -> Flow:
    """The inflow of the meshed ``case`` (``patch_types``: its mesh's patches and their types)."""
    fields = {"U": foamdict.expand(openfoam, case, "0/U")}
    for quantity in TURBULENCE_EXPONENTS:
        if (case / "0" / quantity).is_file():
            fields[quantity] = foamdict.expand(openfoam, case, f"0/{quantity}")
    inlets = {patch: kind for patch, mesh_type in patch_types.items() if mesh_type not in _NOT_INLETS
              and (kind := _inlet_kind(_entry(fields["U"], patch)))}
    first = next(iter(inlets), None)
    velocity = None if first is None or inlets[first] in MAPPED_INLETS else \
        tuple(float(c) for c in _inlet_value(_entry(fields["U"], first)).reshape(-1, 3).mean(axis=0))
    solution = foamdict.expand(openfoam, case, "system/fvSolution").get("SIMPLE", {})
    consistent = solution.get("consistent", False) if isinstance(solution, dict) else False
    algorithm = "SIMPLEC" if str(consistent).lower() in ("true", "yes", "on", "1") else "SIMPLE"
    return Flow(name, inlets, fields, velocity, algorithm, _viscosity(case, openfoam))  # type: ignore[arg-type]


def _entry(expanded: dict[str, Any], patch: str) -> dict[str, Any]:
    try:
        entry = foamdict.lookup(expanded, f"boundaryField/{patch}")
    except KeyError:
        return {}
    return entry if isinstance(entry, dict) else {}


def _inlet_kind(entry: dict[str, Any]) -> str | None:
    kind = entry.get("type")
    if kind in FREESTREAM_INLETS or kind in MAPPED_INLETS:
        return str(kind)
    if kind in FIXED_INLETS and "value" in entry and not isinstance(entry["value"], str):
        return str(kind) if np.any(np.asarray(entry["value"], dtype=float) != 0) else None
    return None


def _inlet_value(entry: dict[str, Any]) -> np.ndarray:
    key = "freestreamValue" if entry.get("type") in FREESTREAM_INLETS else "value"
    return np.asarray(entry[key], dtype=float)


def check_flow(flow: Flow, speed: float, angle: float, initial: float) -> None:
    """One-line ValueError if a variation cannot apply to the base ``flow`` (never a silent no-op)."""
    inlets = ", ".join(f"{p} ({t})" for p, t in flow.inlets.items())
    if (speed != 1 or angle != 0) and not flow.inlets:
        raise ValueError(f"case {flow.name}: no inlet to vary: 0/U has no fixedValue (non-zero), freestream, "
                         f"freestreamVelocity or timeVaryingMappedFixedValue patch")
    if angle != 0 and not flow.external:
        raise ValueError(f"case {flow.name}: the angle of attack applies to external flows (freestream "
                         f"patches only); its inlets are {inlets}, an internal flow")
    if initial != 1:
        start = flow.initial_velocity
        if start is None:
            raise ValueError(f"case {flow.name}: the initial-field variation scales a uniform internalField "
                             f"of 0/U; this one is not uniform")
        if not np.any(start):
            raise ValueError(f"case {flow.name}: 0/U starts from rest (internalField uniform (0 0 0)); "
                             f"scaling the initial field would change nothing")


def apply_flow(case: Path, flow: Flow, speed: float, angle: float, initial: float) -> None:
    """Write the speed, angle and initial-field variation into the variant ``case`` (a copy of the base)."""
    texts: dict[str, list[str]] = {}
    for patch, kind in flow.inlets.items():
        if kind in MAPPED_INLETS:
            _scale_mapped(case, patch, "U", speed)
        elif speed != 1 or angle != 0:
            entry = _scaled_entry(_entry(flow.fields["U"], patch), lambda v: rotate(v * speed, angle))
            texts.setdefault("U", []).append(_patch_text(patch, entry, vector=True))
    start = flow.initial_velocity
    if start is not None and np.any(start) and (speed, angle, initial) != (1, 0, 1):
        velocity = rotate(start * speed * initial, angle)
        texts.setdefault("U", []).append(f"internalField {_field_text(velocity)};")
    for quantity, power in TURBULENCE_EXPONENTS.items():
        if quantity in flow.fields and speed != 1:
            texts[quantity] = _scaled_turbulence(case, flow, quantity, speed**power)
    for name, parts in texts.items():
        _append(case / "0" / name, "\n".join(parts))


def _scaled_turbulence(case: Path, flow: Flow, quantity: str, factor: float) -> list[str]:
    """Entries scaling ``quantity``'s inlet values (fixed and freestream; mapped data in place) and its
    uniform internalField (the initial guess stays consistent with the inflow, as the base's was)."""
    expanded = flow.fields[quantity]
    parts = []
    for patch in flow.inlets:
        entry = _entry(expanded, patch)
        if entry.get("type") in MAPPED_INLETS:
            _scale_mapped(case, patch, quantity, factor)
        elif entry.get("type") in (*FIXED_INLETS, *FREESTREAM_INLETS):
            parts.append(_patch_text(patch, _scaled_entry(entry, lambda v: v * factor), vector=False))
        # other inlet types (turbulentIntensityKineticEnergyInlet, ...) derive their value from U already
    internal = expanded.get("internalField")
    if internal is not None and not isinstance(internal, str) and np.ndim(internal) == 0:
        parts.append(f"internalField {_field_text(np.asarray(internal, dtype=float) * factor, False)};")
    return parts


def _scaled_entry(entry: dict[str, Any], change: Any) -> dict[str, Any]:
    return {key: change(np.asarray(value, dtype=float)) if key in _VALUE_KEYS and not isinstance(value, str)
            else value for key, value in entry.items()}


def rotate(vectors: np.ndarray, degrees: float) -> np.ndarray:
    """``vectors`` (..., 3) rotated by ``degrees`` about z (x-y plane; counter-clockwise)."""
    if degrees == 0:
        return vectors
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    rotated = np.array(vectors, dtype=float)
    rotated[..., 0] = c * vectors[..., 0] - s * vectors[..., 1]
    rotated[..., 1] = s * vectors[..., 0] + c * vectors[..., 1]
    return rotated


def _patch_text(patch: str, entry: dict[str, Any], vector: bool) -> str:
    """``boundaryField { patch { ... } }`` with field values written as OpenFOAM fields (uniform or
    nonuniform List<...>); foamlib's dumps would write a nonuniform list without its type and size."""
    lines = []
    for key, value in entry.items():
        if key in _VALUE_KEYS and not isinstance(value, str):
            lines.append(f"        {key} {_field_text(value, vector)};")
        else:
            lines.append("        " + FoamFile.dumps({key: value}, ensure_header=False).decode().strip())
    body = "\n".join(lines)
    return f"boundaryField\n{{\n    {patch}\n    {{\n{body}\n    }}\n}}"


def _field_text(value: np.ndarray, vector: bool = True) -> str:
    array = np.asarray(value, dtype=float)
    uniform = array.ndim == (1 if vector else 0)
    items = array.reshape(-1, 3) if vector else array.reshape(-1)
    text = [f"({' '.join(repr(float(c)) for c in item)})" if vector else repr(float(item)) for item in items]
    if uniform:
        return f"uniform {text[0]}"
    return f"nonuniform List<{'vector' if vector else 'scalar'}> {len(text)}({' '.join(text)})"


def _scale_mapped(case: Path, patch: str, quantity: str, factor: float) -> None:
    """Scale a timeVaryingMappedFixedValue inlet's data, ``constant/boundaryData/<patch>/<time>/<quantity>``
    (a count and a list, no header), number by number; comment lines are kept as they are."""
    if factor == 1:
        return
    for data in sorted((case / "constant" / "boundaryData" / patch).glob(f"*/{quantity}")):
        head, count, body = re.split(r"^\s*(\d+)\s*$", data.read_text(), maxsplit=1, flags=re.MULTILINE)
        lines = [line if line.lstrip().startswith("//") else
                 _NUMBER.sub(lambda m: repr(float(m.group()) * factor), line) for line in body.splitlines()]
        data.write_text(f"{head}{count}\n" + "\n".join(lines) + "\n")


def _viscosity(case: Path, openfoam: OpenFOAM) -> float | None:
    """The case's plain kinematic viscosity ``nu`` (constant/transportProperties), None without one."""
    match = _nu_entry(case, openfoam)
    numbers = _NUMBER.findall(match) if match else []
    return float(numbers[-1]) if numbers else None


def _nu_entry(case: Path, openfoam: OpenFOAM) -> str | None:
    if not (case / "constant" / "transportProperties").is_file():
        return None
    text = foamdict.expanded_text(openfoam, case, "constant/transportProperties")
    match = re.search(r"^nu\s+(.+);\s*$", text, re.MULTILINE)
    return match.group(1) if match else None


def scale_viscosity(case: Path, openfoam: OpenFOAM, name: str, factor: float) -> None:
    """``nu`` in constant/transportProperties times ``factor``, its dimensions kept (the value is the
    entry's last number: ``nu 1e-05;``, ``nu [0 2 -1 0 0 0 0] 1e-05;`` and ``nu nu [...] 1e-05;``)."""
    entry = _nu_entry(case, openfoam)
    numbers = list(_NUMBER.finditer(entry)) if entry else []
    if not numbers or entry is None:
        raise ValueError(f"case {name}: constant/transportProperties has no plain entry 'nu' (a Newtonian "
                         f"fluid's kinematic viscosity) to scale")
    last = numbers[-1]
    scaled = entry[:last.start()] + repr(float(last.group()) * factor) + entry[last.end():]
    _append(case / "constant" / "transportProperties", f"nu {scaled};")


def _append(path: Path, text: str) -> None:
    with open(path, "a") as out:
        out.write(f"\n// ----- appended by foam_bridge._family for this variant -----\n{text}\n")
