"""The trainer's side of foam_bridge: OpenFOAM cases as a VecEnv (config JSON: foam_config.py).

foam_bridge knows nothing of JAX or of this trainer; this module holds the adapter that drives it:
:func:`foam_vec_env` builds a ``foam_bridge._batched.BatchedFoamEnv`` (cases on a process pool or Ray)
and wraps it in a :class:`jaxsimrl.envs.host.HostVecEnv`, stepped from the jitted rollout through one
``io_callback`` per step.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from foam_bridge import BatchedFoamEnv
from jaxsimrl.envs.host import EpisodeHook, HostVecEnv


def foam_vec_env(cfg: Any, num_envs: int, pool: int, seed: int, backend: str = "local",
                 ray_address: str | None = None, work_dir: str | Path | None = None,
                 on_episode: EpisodeHook | None = None, make_env: Any = None) -> HostVecEnv:
    """``num_envs`` cases of ``cfg`` on ``pool`` workers, as a VecEnv (close it with ``.batch.close()``);
    ``make_env``: what each worker builds instead of a FoamCaseEnv (tests: foam_bridge._standin)."""
    batch = BatchedFoamEnv(cfg, num_envs=num_envs, backend=backend, pool=pool, ray_address=ray_address,
                           work_dir=work_dir, seed=seed, make_env=make_env)
    return HostVecEnv(batch, on_episode)
