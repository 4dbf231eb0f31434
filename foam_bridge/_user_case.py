"""What a user's own case brings to its MDP: its convergence criterion and an action box it tolerates.

The built-in case's MDP is the paper's: its training criterion (U, k, omega < 1e-3, p < 5e-2) and the
box [0.2, 0.95]^2 that SIMPLEC tolerates. A user's case has its own: :func:`case_defaults` reads them,
for whatever the user does not set explicitly (train-foam applies them to ``--case``):

- ``convergence``: the case's own ``SIMPLE.residualControl``, every field it lists with its own
  threshold. A regular-expression key (``"(k|epsilon|omega)" 1e-3;``) stands for the fields the case
  actually solves (read from one SIMPLE iteration, :func:`foam_bridge._base_case.dry_run`), with OpenFOAM's
  rule: an exact key first, else the last matching pattern. A case without one is a one-line CaseError
  (the episodes would all run to the cap).
- ``action_low``/``action_high``: for SIMPLEC (the case's ``consistent yes`` or ``simple_variant``)
  the built-in box; for plain SIMPLE a box around the case's own factors, ``[own / 2, min(1.25 own,
  0.95)]`` per factor. Measured on OpenFOAM's pitzDailyExptInlet (plain SIMPLE, own (0.7, 0.3), its
  own criterion, episodes of up to 2,000 iterations, a new action every 100): in [0.2, 0.95]^2 the
  corners (0.95, 0.2) and (0.95, 0.95) and 3 of 4 episodes of uniformly random actions died of SIGFPE;
  in its own box [0.35, 0.875] x [0.15, 0.375] none of the 4 corners and none of 4 random episodes
  failed (the corner (0.875, 0.375) ran to the cap). Without own factors for U and p the built-in
  box applies.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from foam_bridge import foamdict
from foam_bridge._base_case import check_case, check_case_files
from foam_bridge._config import FoamEnvConfig
from foam_bridge._episode_case import CaseInfo
from foam_bridge._errors import CaseError, NoResidualControl
from foam_bridge._logparse import solved_field_names
from foam_bridge._openfoam import OpenFOAM, find_openfoam

__all__ = ["BOX_CEILING", "BUILTIN_BOX", "CASE_DEFAULT_FIELDS", "OWN_FACTOR_SPAN", "Box", "action_box",
           "case_defaults", "solved_field_names"]

#: The built-in box (the paper's, for SIMPLEC): (action_low, action_high).
BUILTIN_BOX = ((0.2, 0.2), (0.95, 0.95))
#: Plain SIMPLE: the box spans these multiples of the case's own factors, capped at BOX_CEILING.
OWN_FACTOR_SPAN = (0.5, 1.25)
BOX_CEILING = 0.95
#: FoamEnvConfig fields that case_defaults sets.
CASE_DEFAULT_FIELDS = ("convergence", "action_low", "action_high")


def case_defaults(cfg: FoamEnvConfig, openfoam: OpenFOAM | None = None,
                  fields: Iterable[str] = CASE_DEFAULT_FIELDS,
                  checked: tuple[Path, CaseInfo] | None = None) -> dict[str, Any]:
    """The case's own values of ``fields`` (some of CASE_DEFAULT_FIELDS) for ``cfg.case_dir``.

    Checks the case as an env does at creation (mesh and one SIMPLE iteration, in a temporary copy):
    one-line CaseError if it cannot run, or if the criterion is wanted and it has no residualControl.
    ``checked``: the case as :func:`check_case` already built it (its directory and CaseInfo), not
    checked again.
    """
    if cfg.case_dir is None:
        raise ValueError("case_defaults: the built-in case has the paper's defaults (case_dir is None)")
    source = Path(cfg.case_dir)
    check_case_files(source, cfg, need_mesh=False)  # a wrong path says so, OpenFOAM or not
    openfoam = openfoam or find_openfoam(cfg.openfoam_path)
    with tempfile.TemporaryDirectory(prefix="foam_bridge_defaults_") as scratch:
        if checked is None:
            checked = (Path(scratch) / "checked", check_case(source, cfg, openfoam, Path(scratch)))
        info = checked[1]
        solution = foamdict.expand(openfoam, checked[0], "system/fvSolution")
    wanted = set(fields)
    values: dict[str, Any] = {}
    if "convergence" in wanted:
        where = source / "system" / "fvSolution"
        values["convergence"] = _own_criterion(solution["SIMPLE"], info.solved_fields, where)
    values["action_low"], values["action_high"] = action_box(solution, cfg, info)
    return {name: value for name, value in values.items() if name in wanted}


def _own_criterion(simple: dict[str, Any], solved: tuple[str, ...], where: Path) -> dict[str, float]:
    """The case's residualControl as {field: threshold}: its exact keys, then the solved fields that
    only a regular-expression key names."""
    control = simple.get("residualControl")
    if not isinstance(control, dict) or not control:
        raise NoResidualControl(f"{where}: SIMPLE has no residualControl, so its runs never converge; add "
                                'one, or set a criterion in --config: {"foam": {"convergence": {"U": 1e-3, '
                                '"p": 1e-2}}}', where)
    criterion = {key: _threshold(value, key, where) for key, value in control.items() if not _is_pattern(key)}
    for name in solved_field_names(solved):
        if name not in criterion:
            try:
                criterion[name] = _threshold(foamdict.lookup(control, name), name, where)
            except KeyError:
                continue  # a solved field the case does not test
    return criterion


Box = tuple[tuple[float, float], tuple[float, float]]


def action_box(solution: dict[str, Any], cfg: FoamEnvConfig, info: CaseInfo) -> Box:
    """(action_low, action_high) the case's algorithm tolerates (see the module docstring)."""
    simple = solution.get("SIMPLE", {})
    variant = cfg.variant or ("SIMPLEC" if _is_true(simple.get("consistent", False)) else "SIMPLE")
    own = info.own_factors
    if variant == "SIMPLEC" or own is None:
        return BUILTIN_BOX
    low = tuple(round(factor * OWN_FACTOR_SPAN[0], 6) for factor in own)
    high = tuple(round(min(factor * OWN_FACTOR_SPAN[1], BOX_CEILING), 6) for factor in own)
    return (low[0], low[1]), (high[0], high[1])


def _threshold(value: Any, key: str, where: Path) -> float:
    try:
        threshold = float(value)
    except (TypeError, ValueError):
        raise CaseError(f"{where}: SIMPLE/residualControl/{key} is {value!r}; expected a number") from None
    if not (math.isfinite(threshold) and threshold > 0):
        raise CaseError(f"{where}: SIMPLE/residualControl/{key} = {threshold!r}; expected a threshold > 0")
    return threshold


def _is_pattern(key: str) -> bool:
    return key.startswith('"') and key.endswith('"')


def _is_true(value: Any) -> bool:
    """An OpenFOAM switch (``yes``/``on``/``true``, as foamlib parses it or as text)."""
    return value is True or (isinstance(value, str) and value.lower() in ("yes", "on", "true", "y", "t"))
