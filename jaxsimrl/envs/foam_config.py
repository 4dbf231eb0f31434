"""A FoamEnvConfig as JSON and back: the ``"foam"`` section of a train-foam run's config.json.

``foam_config_to_json(cfg)`` gives a JSON-ready dict with every FoamEnvConfig field by name (tuples as
lists, ``convergence`` as a plain dict, paths as strings); ``foam_config_from_json(d)`` rebuilds the
config, turning the lists back into tuples. Fields missing from ``d`` take FoamEnvConfig's defaults (a
run written before a field existed still loads); an unknown key or a value of the wrong kind is a
one-line ValueError. The fields are read from the dataclass itself, so a field added to FoamEnvConfig
round-trips without a change here.

A config.json always names every field, its convergence criterion and action box included, so a run
keeps the MDP it was written with. :func:`user_case_config` gives a user's case (``case_dir``) the case's
own criterion and action box (foam_bridge.user_case) where they are not set explicitly.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from foam_bridge.config import FoamEnvConfig
from foam_bridge.errors import OpenFOAMNotFoundError

#: Fields stored as JSON lists that FoamEnvConfig holds as tuples.
_TUPLE_FIELDS = ("action_low", "action_high", "turbulence_fields", "inlet_turbulence")
#: Fields of the built-in case's geometry only: a user's case keeps its own mesh.
BUILTIN_ONLY = ("mesh_scale", "step_height")


def builtin_only_set(section: Mapping[str, Any]) -> list[str]:
    """The BUILTIN_ONLY fields that ``section`` (a --config "foam" section) sets to other than their default
    (a config.json of an earlier run names them all, at their defaults for a user's case)."""
    defaults = FoamEnvConfig()
    return [name for name in BUILTIN_ONLY if name in section and section[name] != getattr(defaults, name)]


def user_case_config(cfg: FoamEnvConfig, explicit: Iterable[str]) -> FoamEnvConfig:
    """``cfg`` of a user's case with the case's own convergence criterion and action box, for each of
    them not in ``explicit`` (the fields the user set); one-line CaseError if the case cannot run."""
    from foam_bridge.user_case import CASE_DEFAULT_FIELDS, case_defaults

    given = set(explicit)
    if given & {"action_low", "action_high"}:  # the box is set as a whole
        given |= {"action_low", "action_high"}
    wanted = [name for name in CASE_DEFAULT_FIELDS if name not in given]
    if not wanted:  # nothing to read: no OpenFOAM needed here (e.g. a Ray driver without it)
        return cfg.validate()
    try:
        own = case_defaults(cfg, fields=wanted)
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
    """Every field of ``cfg`` as JSON-ready values (the inverse of :func:`foam_config_from_json`)."""
    out: dict[str, Any] = {}
    for item in dataclasses.fields(cfg):
        out[item.name] = _to_json(getattr(cfg, item.name))
    return out


def foam_config_from_json(data: Any) -> FoamEnvConfig:
    """The FoamEnvConfig of a config.json ``"foam"`` section, validated; one-line ValueError if bad."""
    if not isinstance(data, Mapping):
        raise ValueError(f"the foam config must be a JSON object, got {type(data).__name__}")
    known = {item.name for item in dataclasses.fields(FoamEnvConfig)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ValueError(f"unknown foam config key(s): {', '.join(unknown)}")
    values = dict(data)
    for name in _TUPLE_FIELDS:
        if values.get(name) is not None:
            values[name] = _as_tuple(name, values[name])
    for name in ("inlet_velocity", "step_height"):  # a number, or a range as a list
        if isinstance(values.get(name), list):
            values[name] = _as_tuple(name, values[name])
    if "convergence" in values:
        if not isinstance(values["convergence"], Mapping):
            raise ValueError(f"foam config convergence: expected {{field: threshold}}, got "
                             f"{values['convergence']!r}")
        values["convergence"] = dict(values["convergence"])
    try:
        return FoamEnvConfig(**values).validate()
    except TypeError as err:  # e.g. a string where a number belongs, met inside validate()
        raise ValueError(f"foam config: {err}") from None


def _to_json(value: Any) -> Any:
    if isinstance(value, tuple | list):
        return [_to_json(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): _to_json(v) for k, v in value.items()}
    if isinstance(value, Path):
        return str(value)
    return value


def _as_tuple(name: str, value: Any) -> tuple:
    if not isinstance(value, list | tuple):
        raise ValueError(f"foam config {name}: expected a list, got {value!r}")
    return tuple(value)
