"""The trainer's side of foam_bridge: OpenFOAM cases as a VecEnv, and FoamEnvConfig <-> JSON.

foam_bridge knows nothing of JAX or of this trainer; this module holds the adapter that drives it:
:func:`foam_vec_env` builds a ``foam_bridge.batched.BatchedFoamEnv`` (cases on a process pool or Ray)
and wraps it in a :class:`jaxsimrl.envs.host.HostVecEnv`, stepped from the jitted rollout through one
``io_callback`` per step.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from jaxsimrl.envs.host import EpisodeHook, HostVecEnv

# FoamEnvConfig fields that are tuples in the dataclass and lists in JSON.
_TUPLE_FIELDS = ("action_low", "action_high", "turbulence_fields")


def foam_config_to_json(cfg: Any) -> dict[str, Any]:
    """Every FoamEnvConfig field, JSON-ready (tuples as lists, paths as strings)."""
    out: dict[str, Any] = {}
    for item in dataclasses.fields(cfg):
        value = getattr(cfg, item.name)
        if isinstance(value, tuple):
            value = list(value)
        elif isinstance(value, Path):
            value = str(value)
        elif isinstance(value, Mapping):
            value = {str(k): float(v) for k, v in value.items()}
        out[item.name] = value
    return out


def foam_config_from_json(data: Mapping[str, Any]) -> Any:
    """The FoamEnvConfig of :func:`foam_config_to_json`'s output; unknown keys or bad values are a
    one-line ValueError naming them."""
    from foam_bridge.config import FoamEnvConfig

    if not isinstance(data, Mapping):
        raise ValueError(f"a foam config must be a JSON object, got {type(data).__name__}")
    known = {item.name for item in dataclasses.fields(FoamEnvConfig)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ValueError(f"unknown foam config key(s): {', '.join(unknown)}")
    values = dict(data)
    for name in _TUPLE_FIELDS:
        if isinstance(values.get(name), list):
            values[name] = tuple(values[name])
    if isinstance(values.get("inlet_velocity"), list):
        values["inlet_velocity"] = tuple(values["inlet_velocity"])
    try:
        return FoamEnvConfig(**values).validate()
    except TypeError as err:
        raise ValueError(f"invalid foam config: {err}") from None


def foam_vec_env(cfg: Any, num_envs: int, pool: int, seed: int, backend: str = "local",
                 ray_address: str | None = None, work_dir: str | Path | None = None,
                 on_episode: EpisodeHook | None = None) -> HostVecEnv:
    """``num_envs`` cases of ``cfg`` on ``pool`` workers, as a VecEnv (close it with ``.batch.close()``)."""
    from foam_bridge.batched import BatchedFoamEnv

    batch = BatchedFoamEnv(cfg, num_envs=num_envs, backend=backend, pool=pool, ray_address=ray_address,
                           work_dir=work_dir, seed=seed)
    return HostVecEnv(batch, on_episode)
