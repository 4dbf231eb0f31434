"""Which of a user's case's fields a closed-loop controller observes: its own fields, mapped by role.

A controller with residual features (FoamEnvConfig.residual_features > 0) was trained observing the
residuals of some fields in some order (FoamEnvConfig.observed: e.g. U, k, omega, p). A user's case
solves its own fields (U, p, epsilon, k for kEpsilon; ReThetat and gammaInt too for kOmegaSSTLM;
p_rgh for a buoyant one) and keeps its own criterion. :func:`map_fields` gives each observed field of
the policy, in the policy's order, the case field with the same role: the same name first, then pressure
p <-> p_rgh, then the remaining turbulence fields in the case's solve order (the policy's k, omega -> the
case's k, epsilon). Case fields left over are not observed. A role the case cannot fill (two turbulence
fields observed, only nuTilda solved) makes the controller not applicable to the case.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from foam_bridge import solved_field_names

VELOCITY = "velocity"
PRESSURE = "pressure"
TURBULENCE = "turbulence"
#: Names of the pressure role (simpleFoam's kinematic p, a buoyant solver's p_rgh).
PRESSURE_FIELDS = ("p", "p_rgh")
VELOCITY_FIELDS = ("U",)


class UnmappedField(LookupError):
    """A field the policy observes has no counterpart in the case (its message says which)."""


def role(name: str) -> str:
    """VELOCITY, PRESSURE or TURBULENCE (every field solved besides the velocity and the pressure)."""
    if name in VELOCITY_FIELDS:
        return VELOCITY
    return PRESSURE if name in PRESSURE_FIELDS else TURBULENCE


def map_fields(observed: Sequence[str], solved: Sequence[str]) -> dict[str, str]:
    """{policy field: case field} for every field in ``observed``, in its order (see the module
    docstring); ``solved``: the case's solved field names in solve order. UnmappedField if a role is
    left unfilled."""
    taken = {name for name in observed if name in solved}
    mapped = {name: name for name in observed if name in taken}
    for name in observed:
        if name in mapped:
            continue
        free = [field for field in solved if field not in taken and role(field) == role(name)]
        if not free:
            raise UnmappedField(f"the controller observes the {role(name)} field {name}'s residual and the "
                                f"case solves no {role(name)} field left for it (it solves "
                                f"{', '.join(solved)})")
        mapped[name] = free[0]
        taken.add(free[0])
    return {name: mapped[name] for name in observed}


def observed_mapping(policy_cfg: Any, solved: Sequence[str]) -> tuple[dict[str, str] | None, str | None]:
    """(mapping, None) for a policy that observes residuals, (None, why not) if the case cannot give
    them, (None, None) for a policy that observes none. ``solved``: the case's dry run's solved fields
    as the log names them (``Ux``, ``Uy``, ``p``...; CaseInfo.solved_fields)."""
    if not getattr(policy_cfg, "residual_features", 0):
        return None, None
    try:
        return map_fields(policy_cfg.observed, solved_field_names(tuple(solved))), None
    except UnmappedField as err:
        return None, (f"{err}: the observation it was trained on cannot be formed, so the case runs with "
                      f"its own settings")
