"""What a generated case is drawn from (foam_bridge._generator): :class:`CaseSpec` and :func:`sample_specs`.

A spec holds everything that makes a case: its geometry kind and parameters, its Reynolds number, and the
user's part (turbulence model, plain SIMPLE or SIMPLEC, the relaxation factors, the residualControl
criterion, endTime). The user's part is drawn as users set it (docs/generator.md): half plain SIMPLE
with conservative (U 0.7, p 0.3, turbulence 0.7) or "between" factors, half SIMPLEC with U 0.8-0.95 and
p unrelaxed; 1e-3 or 1e-4 on every field, sometimes p a decade looser. Case k is drawn from its own
stream ``default_rng([seed, k])``: asking for more cases never changes the earlier ones.

The kinds are channel flows only; none is of the geometry kinds reserved for the held-out set
(experiments/controller/heldout-v2/reserved_kinds.json: bluff bodies, tube banks, impinging jets, wall
cavities, annuli, ventilated rooms, porous zones), so a controller trained on generated cases is still
tested on geometry it never saw.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["ALGORITHMS", "CHANNEL_HEIGHT", "GEOMETRY_KINDS", "KIND_DESCRIPTIONS", "NU", "TURBULENCE_MODELS",
           "CaseSpec", "draw_spec", "sample_specs"]

GEOMETRY_KINDS = ("step", "rib", "bump", "contraction", "diffuser", "bend")
#: What each kind is (docs/generator.md; tests/test_generator.py holds them apart from the reserved kinds).
KIND_DESCRIPTIONS = {
    "step": "a channel with a backward- or forward-facing step on one or both walls",
    "rib": "a channel with one or two rectangular ribs mounted on its lower wall",
    "bump": "a channel with a smooth bump (arc, spline or polyLine hill) on its lower wall",
    "contraction": "a channel narrowing over a straight taper, one- or two-sided",
    "diffuser": "a channel widening over a straight taper, one- or two-sided",
    "bend": "a channel turning 30-180 degrees through a curved section, straight legs before and after",
}
TURBULENCE_MODELS = ("kEpsilon", "realizableKE", "kOmegaSST")
ALGORITHMS = ("SIMPLE", "SIMPLEC")
#: The inlet channel height H (m) every geometry is scaled by, and the kinematic viscosity (m^2/s, air).
CHANNEL_HEIGHT = 0.1
NU = 1.5e-5

Params = tuple[tuple[str, Any], ...]


def _significant(value: float, digits: int = 4) -> float:
    return float(f"{value:.{digits}g}")


@dataclass(frozen=True)
class CaseSpec:
    """One case. ``geometry``: (name, value) pairs, lengths in units of H (the inlet channel height);
    ``reynolds``: on H and the inlet's bulk velocity; ``factors``: U, p, turbulence (p 1: unrelaxed);
    ``criterion``: residualControl of p, U and the turbulence fields; ``end_time``: the iteration budget;
    ``intensity``: the inlet turbulence intensity."""

    name: str
    kind: str
    geometry: Params
    reynolds: float
    model: str
    algorithm: str
    factors: tuple[tuple[str, float], ...]
    criterion: tuple[tuple[str, float], ...]
    end_time: int
    intensity: float

    @property
    def params(self) -> dict[str, Any]:
        return dict(self.geometry)

    @property
    def speed(self) -> float:
        """The inlet's bulk velocity (m/s) that gives ``reynolds`` on H with NU."""
        return self.reynolds * NU / CHANNEL_HEIGHT

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "kind": self.kind, "geometry": dict(self.geometry),
                "reynolds": self.reynolds, "model": self.model, "algorithm": self.algorithm,
                "factors": dict(self.factors),
                "criterion": dict(self.criterion), "end_time": self.end_time, "intensity": self.intensity}

    @classmethod
    def from_json(cls, entry: Mapping[str, Any]) -> CaseSpec:
        pairs = {key: tuple(entry[key].items()) for key in ("geometry", "factors", "criterion")}
        return cls(name=entry["name"], kind=entry["kind"], reynolds=float(entry["reynolds"]),
                   model=entry["model"], algorithm=entry["algorithm"], end_time=int(entry["end_time"]),
                   intensity=float(entry["intensity"]), **pairs)


# ---- each kind's geometry: lengths in H, ranges in docs/generator.md ---------------------------------


def _step(rng: np.random.Generator) -> dict[str, Any]:
    direction = "backward" if rng.random() < 0.75 else "forward"
    walls = 1 if rng.random() < 0.7 else 2
    expansion = rng.uniform(1.2, 2.5)
    rise = expansion - 1 if direction == "backward" else 1 - 1 / expansion  # all steps' height together
    return {"direction": direction, "walls": walls, "expansion": expansion, "upstream": rng.uniform(2, 5),
            "downstream": max(4.0, rise * rng.uniform(10, 20))}


def _rib(rng: np.random.Generator) -> dict[str, Any]:
    height = rng.uniform(0.1, 0.4)
    return {"ribs": 1 if rng.random() < 0.65 else 2, "height": height,
            "width": height * rng.uniform(0.5, 2), "gap": height * rng.uniform(4, 10),
            "upstream": rng.uniform(2, 4), "downstream": rng.uniform(8, 14)}


def _bump(rng: np.random.Generator) -> dict[str, Any]:
    return {"shape": str(rng.choice(["arc", "spline", "polyLine"])), "height": rng.uniform(0.05, 0.3),
            "length": rng.uniform(1.5, 4), "upstream": rng.uniform(2, 4), "downstream": rng.uniform(6, 12)}


def _contraction(rng: np.random.Generator) -> dict[str, Any]:
    return {"ratio": rng.uniform(1.5, 4), "angle": rng.uniform(10, 30),
            "sides": 1 if rng.random() < 0.5 else 2, "upstream": rng.uniform(2, 4),
            "downstream": rng.uniform(3, 6)}


def _diffuser(rng: np.random.Generator) -> dict[str, Any]:
    ratio = rng.uniform(1.3, 3)
    return {"ratio": ratio, "angle": rng.uniform(3, 15), "sides": 1 if rng.random() < 0.5 else 2,
            "upstream": rng.uniform(2, 4), "downstream": ratio * rng.uniform(3, 6)}


def _bend(rng: np.random.Generator) -> dict[str, Any]:
    return {"angle": rng.uniform(30, 180), "radius": rng.uniform(0.5, 3), "upstream": rng.uniform(2, 5),
            "downstream": rng.uniform(5, 10)}


_GEOMETRY: dict[str, Callable[[np.random.Generator], dict[str, Any]]] = {
    "step": _step, "rib": _rib, "bump": _bump, "contraction": _contraction, "diffuser": _diffuser,
    "bend": _bend,
}


def _settings(rng: np.random.Generator) -> dict[str, Any]:
    """The user's part: algorithm and factors, criterion, endTime (see the module docstring)."""
    if rng.random() < 0.5:
        algorithm = "SIMPLE"
        if rng.random() < 0.5:
            factors = {"U": 0.7, "p": 0.3, "turbulence": 0.7}
        else:
            factors = {"U": rng.uniform(0.5, 0.9), "p": rng.uniform(0.2, 0.5),
                       "turbulence": rng.uniform(0.5, 0.9)}
    else:
        algorithm = "SIMPLEC"
        factors = {"U": rng.uniform(0.8, 0.95), "p": 1.0, "turbulence": rng.uniform(0.7, 0.95)}
    tight = float(rng.choice([1e-3, 1e-4]))
    loose_p = rng.random() < 0.25
    criterion = {"p": tight * 10 if loose_p else tight, "U": tight, "turbulence": tight}
    return {"algorithm": algorithm, "factors": tuple((k, round(float(v), 2)) for k, v in factors.items()),
            "criterion": tuple(criterion.items()), "end_time": int(rng.choice([2000, 3000, 4000]))}


def check_kinds(kinds: Sequence[str]) -> tuple[str, ...]:
    """``kinds`` as a tuple; ValueError (one line) for none or an unknown one."""
    unknown = [kind for kind in kinds if kind not in GEOMETRY_KINDS]
    if unknown or not kinds:
        raise ValueError(f"unknown geometry kind(s) {', '.join(unknown) or '(none given)'}; known: "
                         f"{', '.join(GEOMETRY_KINDS)}")
    return tuple(kinds)


def draw_spec(seed: int, index: int, kinds: Sequence[str] = GEOMETRY_KINDS,
              models: Sequence[str] = TURBULENCE_MODELS) -> CaseSpec:
    """Case ``index`` of ``seed``: kind ``kinds[index % len(kinds)]``, drawn from
    ``default_rng([seed, index])``."""
    kind = kinds[index % len(kinds)]
    rng = np.random.default_rng([seed, index])
    geometry = {key: _significant(value) if isinstance(value, float) else value
                for key, value in _GEOMETRY[kind](rng).items()}
    reynolds = _significant(math.exp(rng.uniform(math.log(1e4), math.log(2e5))), 3)
    model = str(rng.choice(list(models)))
    settings = _settings(rng)
    return CaseSpec(name=f"{kind}-{index}", kind=kind, geometry=tuple(geometry.items()), reynolds=reynolds,
                    model=model, intensity=round(float(rng.uniform(0.02, 0.08)), 3), **settings)


def sample_specs(n: int, seed: int, kinds: Sequence[str] = GEOMETRY_KINDS,
                 models: Sequence[str] = TURBULENCE_MODELS) -> list[CaseSpec]:
    """``n`` specs, case k of kind ``kinds[k % len(kinds)]`` (cycled), each from its own seeded stream."""
    kinds = check_kinds(kinds)
    bad = [model for model in models if model not in TURBULENCE_MODELS]
    if bad or not models:
        raise ValueError(f"unknown turbulence model(s) {', '.join(bad) or '(none given)'}; known: "
                         f"{', '.join(TURBULENCE_MODELS)}")
    if n < 1:
        raise ValueError(f"n = {n}: expected at least one case")
    return [draw_spec(seed, k, kinds, models) for k in range(n)]
