"""gymnasium front-ends: one case (RelaxationControlEnv) and a batch on the pool (RelaxationControlVecEnv).

    import gymnasium as gym, foam_bridge
    env = gym.make("foam_bridge/RelaxationControl-v0", mesh_scale=0.5)
    envs = gym.make_vec("foam_bridge/RelaxationControl-v0", num_envs=4, pool=2, mesh_scale=0.5)

Keyword arguments map one to one onto FoamEnvConfig fields (lists are accepted for tuple fields); an
unknown one is a ValueError naming it. The vector env also takes ``pool``, ``backend`` ("local" or
"ray"), ``ray_address`` and ``seed`` (see foam_bridge._batched.BatchedFoamEnv) and auto-resets in
gymnasium's SAME_STEP mode: ``infos["final_obs"]`` / ``infos["final_info"]`` hold the ended episode.
``info`` carries "iterations", "residuals", "outcome" (and "cause", "inlet_velocity", "episode").
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import shutil
import tempfile
from collections.abc import Iterator
from typing import Any

import gymnasium
import numpy as np
from gymnasium.spaces import Box
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from foam_bridge._batched import SEED_BOUND, BatchedFoamEnv
from foam_bridge._config import FoamEnvConfig
from foam_bridge._env import FoamCaseEnv
from foam_bridge._spaces import BoxSpec

__all__ = ["CONFIG_FIELDS", "RelaxationControlEnv", "RelaxationControlVecEnv", "box", "_config_from_kwargs"]

CONFIG_FIELDS = tuple(f.name for f in dataclasses.fields(FoamEnvConfig))
_TUPLE_FIELDS = ("inlet_velocity", "step_height", "action_low", "action_high", "turbulence_fields",
                 "inlet_turbulence", "observed_fields")


def _config_from_kwargs(kwargs: dict[str, Any]) -> FoamEnvConfig:
    """A validated FoamEnvConfig from keyword arguments; ValueError naming an unknown or bad one."""
    unknown = sorted(set(kwargs) - set(CONFIG_FIELDS))
    if unknown:
        known = ", ".join(CONFIG_FIELDS)
        raise ValueError(f"unknown FoamEnvConfig field(s) {', '.join(unknown)}; known: {known}")
    values = {k: tuple(v) if k in _TUPLE_FIELDS and isinstance(v, list) else v for k, v in kwargs.items()}
    return FoamEnvConfig(**values).validate()


def box(spec: BoxSpec) -> Box:
    """A float32 gymnasium Box from a protocol BoxSpec."""
    low = np.broadcast_to(np.asarray(spec.low, np.float32), spec.shape)
    high = np.broadcast_to(np.asarray(spec.high, np.float32), spec.shape)
    return Box(low=low, high=high, shape=spec.shape, dtype=np.float32)


@contextlib.contextmanager
def _private_dir(cfg: FoamEnvConfig) -> Iterator[str]:
    """A fresh directory under ``cfg.work_dir`` (or the temp dir) for one gym env instance.

    gymnasium makes several instances from the same kwargs (check_env, make_vec): a directory of
    their own keeps one instance's close() from deleting another's cases. It is removed again if the
    ``with`` body raises (the env could not be built); otherwise the env's close() removes it.
    """
    if cfg.work_dir is not None:
        os.makedirs(cfg.work_dir, exist_ok=True)
    path = tempfile.mkdtemp(prefix="foam_bridge_", dir=cfg.work_dir)
    try:
        yield path
    except BaseException:
        _remove_private_dir(cfg, path)
        raise


def _remove_private_dir(cfg: FoamEnvConfig, path: str | None) -> None:
    if path is not None and not cfg.keep_cases:
        shutil.rmtree(path, ignore_errors=True)


def _no_render(render_mode: str | None) -> None:
    if render_mode is not None:
        raise ValueError(f"render_mode: foam_bridge envs do not render, got {render_mode!r}")


class RelaxationControlEnv(gymnasium.Env):
    """One simpleFoam case (foam_bridge._env.FoamCaseEnv) as a gymnasium Env.

    Episodes are seeded from the env's ``np_random`` (seeded by ``reset(seed=...)``), so the same seed
    gives the same inlet velocities. The case lives in a fresh directory under ``work_dir`` (default:
    the system's temporary directory) that ``close()`` removes unless ``keep_cases``.
    """

    metadata = {"render_modes": []}

    def __init__(self, render_mode: str | None = None, **config: Any) -> None:
        _no_render(render_mode)
        self.cfg = _config_from_kwargs(config)
        self._dir: str | None
        with _private_dir(self.cfg) as self._dir:
            self.case_env = FoamCaseEnv(self.cfg, work_dir=self._dir, env_id=0)
        self.observation_space = box(self.case_env.observation_space_spec)
        self.action_space = box(self.case_env.action_space_spec)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        obs, info = self.case_env.reset(seed=int(self.np_random.integers(SEED_BOUND)), options=options)
        return np.asarray(obs, np.float32), info

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.case_env.step(np.asarray(action, np.float64))
        return np.asarray(obs, np.float32), float(reward), bool(terminated), bool(truncated), info

    def close(self) -> None:
        self.case_env.close()
        _remove_private_dir(self.cfg, self._dir)
        self._dir = None


class RelaxationControlVecEnv(VectorEnv):
    """``num_envs`` cases on a worker pool (foam_bridge._batched.BatchedFoamEnv) as a gymnasium VectorEnv."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": []}

    def __init__(
        self,
        num_envs: int = 1,
        pool: int | None = None,
        backend: str = "local",
        ray_address: str | None = None,
        seed: int | None = None,
        render_mode: str | None = None,
        **config: Any,
    ) -> None:
        _no_render(render_mode)
        self.cfg = _config_from_kwargs(config)
        self._dir: str | None
        with _private_dir(self.cfg) as self._dir:
            self.batch = BatchedFoamEnv(self.cfg, num_envs, backend=backend, pool=pool,
                                        ray_address=ray_address, work_dir=self._dir, seed=seed)
        self.num_envs = num_envs
        self.single_observation_space = box(self.batch.observation_spec)
        self.single_action_space = box(self.batch.action_spec)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        return self.batch.reset(seed=seed, options=options)

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        return self.batch.step(actions)

    def close_extras(self, **kwargs: Any) -> None:
        self.batch.close()
        _remove_private_dir(self.cfg, self._dir)
        self._dir = None
