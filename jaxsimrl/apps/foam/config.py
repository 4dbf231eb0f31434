"""A FoamEnvConfig for a run: a user's case's own defaults, and the built-in-only fields.

The JSON codec of the ``"foam"`` section of a config.json is on the class
(``FoamEnvConfig.to_json()`` / ``FoamEnvConfig.from_json(d)``); ``foam_config_to_json`` and
``foam_config_from_json`` here are thin aliases of it, kept for the docs and older callers.

A config.json always names every field, its convergence criterion and action box included, so a run
keeps the MDP it was written with. :func:`user_case_config` gives a user's case (``case_dir``) the case's
own criterion and action box (foam_bridge._user_case) where they are not set explicitly.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from foam_bridge import CASE_DEFAULT_FIELDS, FoamEnvConfig, OpenFOAMNotFoundError, case_defaults

if TYPE_CHECKING:
    from foam_bridge import CaseInfo

#: Fields of the built-in case's geometry only: a user's case keeps its own mesh.
BUILTIN_ONLY = ("mesh_scale", "step_height")


def builtin_only_set(section: Mapping[str, Any]) -> list[str]:
    """The BUILTIN_ONLY fields that ``section`` (a --config "foam" section) sets to other than their default
    (a config.json of an earlier run names them all, at their defaults for a user's case)."""
    defaults = FoamEnvConfig()
    return [name for name in BUILTIN_ONLY if name in section and section[name] != getattr(defaults, name)]


def user_case_config(cfg: FoamEnvConfig, explicit: Iterable[str],
                     checked: tuple[Path, CaseInfo] | None = None) -> FoamEnvConfig:
    """``cfg`` of a user's case with the case's own convergence criterion and action box, for each of
    them not in ``explicit`` (the fields the user set); one-line CaseError if the case cannot run.
    ``checked``: the case already built and checked (foam_bridge._user_case.case_defaults)."""
    given = set(explicit)
    if given & {"action_low", "action_high"}:  # the box is set as a whole
        given |= {"action_low", "action_high"}
    wanted = [name for name in CASE_DEFAULT_FIELDS if name not in given]
    if not wanted:  # nothing to read: no OpenFOAM needed here (e.g. a Ray driver without it)
        return cfg.validate()
    try:
        own = case_defaults(cfg, fields=wanted, checked=checked)
    except OpenFOAMNotFoundError as err:
        raise OpenFOAMNotFoundError(f"{err} (it reads the case's own criterion and action box; without "
                                    f"OpenFOAM here, set convergence, action_low and action_high in "
                                    f'--config\'s "foam" section)') from None
    return dataclasses.replace(cfg, **_with_alpha_t_bounds(own, cfg.action_size)).validate()


def _with_alpha_t_bounds(own: dict[str, Any], size: int) -> dict[str, Any]:
    """The case's own (alpha_u, alpha_p) box with alpha_t's bounds for a 3-entry action: alpha_u's (the
    turbulence fields followed alpha_u in the paper's setup, so its tolerated range is the one known)."""
    if size != 3 or "action_low" not in own:
        return own
    return {**own, "action_low": (*own["action_low"], own["action_low"][0]),
            "action_high": (*own["action_high"], own["action_high"][0])}


def foam_config_to_json(cfg: FoamEnvConfig) -> dict[str, Any]:
    """Alias of :meth:`FoamEnvConfig.to_json` (kept for the docs and older callers)."""
    return cfg.to_json()


def foam_config_from_json(data: Any) -> FoamEnvConfig:
    """Alias of :meth:`FoamEnvConfig.from_json` (kept for the docs and older callers)."""
    return FoamEnvConfig.from_json(data)
