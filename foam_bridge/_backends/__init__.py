"""Where the envs of a BatchedFoamEnv run: a local process pool ("local") or Ray actors ("ray").

Both implement ``base.Backend``: ``run(requests) -> replies``, ``worker_pid(env_id)``, ``node_of(env_id)``,
``close()``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from foam_bridge._backends.base import WORKER_DIED, Backend, validate_pool
from foam_bridge._backends.local import LocalBackend
from foam_bridge._backends.ray_backend import RayBackend
from foam_bridge._backends.worker import BAD_INPUT_ERRORS, EnvFactory, Reply, Request, env_dir

BACKENDS = ("local", "ray")

__all__ = [
    "BACKENDS", "BAD_INPUT_ERRORS", "WORKER_DIED", "Backend", "EnvFactory", "Reply", "Request", "env_dir",
    "make_backend", "validate_pool",
]


def make_backend(
    name: str, cfg: Any, num_envs: int, pool: int, work_dir: Path, ray_address: str | None = None,
    make_env: EnvFactory | None = None,
) -> Backend:
    """Start ``pool`` workers of backend ``name`` for ``num_envs`` envs with case dirs under ``work_dir``;
    each worker builds its envs with ``make_env`` (None: FoamCaseEnv)."""
    if name == "local":
        if ray_address is not None:
            raise ValueError("ray_address is only meaningful with backend='ray'")

        return LocalBackend(cfg, num_envs, pool, work_dir, make_env=make_env)
    if name == "ray":
        return RayBackend(cfg, num_envs, pool, work_dir, ray_address, make_env)
    raise ValueError(f"backend must be one of {BACKENDS}, got {name!r}")
