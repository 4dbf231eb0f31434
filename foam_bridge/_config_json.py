"""The JSON codec of FoamEnvConfig: the "foam" section of a train-foam run's config.json.

Internal to foam_bridge (its users call ``FoamEnvConfig.to_json`` / ``FoamEnvConfig.from_json``); names
here may change.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Collection, Mapping
from pathlib import Path
from typing import Any


def config_to_json(cfg: Any) -> dict[str, Any]:
    """FoamEnvConfig.to_json: every field of ``cfg`` (a FoamEnvConfig) by name as JSON-ready values."""
    return {item.name: _to_json(getattr(cfg, item.name)) for item in dataclasses.fields(cfg)
            if not (item.name in _OMITTED_WHEN_NONE and getattr(cfg, item.name) is None
                    or item.name in _OMITTED_AT_DEFAULT and getattr(cfg, item.name) == item.default)}


def config_values(data: Any, names: Collection[str]) -> dict[str, Any]:
    """FoamEnvConfig.from_json: the config's keyword arguments of a to_json dict (``names``: its fields'
    names), tuples where it holds tuples; one-line ValueError if bad."""
    if not isinstance(data, Mapping):
        raise ValueError(f"the foam config must be a JSON object, got {type(data).__name__}")
    unknown = sorted(set(data) - set(names))
    if unknown:
        raise ValueError(f"unknown foam config key(s): {', '.join(unknown)}")
    values = dict(data)
    for name in _JSON_TUPLE_FIELDS:
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
    return values


#: Fields stored as JSON lists that FoamEnvConfig holds as tuples.
_JSON_TUPLE_FIELDS = ("action_low", "action_high", "turbulence_fields", "inlet_turbulence", "observed_fields",
                      "action_pivot")
#: Fields to_json leaves out at None (added after runs were written; their JSON stays byte-identical).
_OMITTED_WHEN_NONE = ("observed_fields", "action_pivot", "freeze_decades", "action_radius", "confirm_alpha_t")
#: Fields to_json leaves out at their default, for the same reason.
_OMITTED_AT_DEFAULT = ("observe_state", "observe_algorithm", "action_share", "reward_scale", "observe_gain",
                       "pivot_at", "state_interval")


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
