"""Episodes drawn from a family of cases: one env that runs, at each reset, one of several cases.

One controller for the cases users bring is trained on many cases, and every env of the batch should see
them all (one case per env would tie a case's share of the data to the batch size). ``CaseFamilyEnv`` holds
a FoamCaseEnv per case, built on first use under this env's own directory (so a worker's clean-up of that
directory reaches their solvers too), draws each episode's case from its seeded RNG, and names it in the
info (``info["case"]``) and in the episode record (episodes.csv's ``case`` column).

Every case's config must give observations and actions of one shape (the same observation options and
action size); each keeps its own box, criterion, budget and reward scale. ``FamilyFactory`` is the
picklable ``make_env`` that the batch's workers build it with.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from foam_bridge._config import FoamEnvConfig
from foam_bridge._env import FoamCaseEnv

__all__ = ["CaseFamilyEnv", "FamilyFactory"]


class CaseFamilyEnv:
    """Each episode one case of ``cases`` (name -> config), drawn uniformly from the seeded RNG, or named
    by ``reset(options={"case": name})``."""

    def __init__(self, cases: Mapping[str, FoamEnvConfig], work_dir: Path | str, env_id: int = 0) -> None:
        if not cases:
            raise ValueError("a case family needs at least one case")
        shapes = {(cfg.observation_size, cfg.action_size) for cfg in cases.values()}
        if len(shapes) != 1:
            raise ValueError(f"the family's cases give observations and actions of different sizes: "
                             f"{sorted(shapes)} (one controller needs one shape)")
        self.cases, self.names = dict(cases), sorted(cases)
        self.root = Path(work_dir) / f"env_{env_id}"
        self.env_id = env_id
        self._envs: dict[str, FoamCaseEnv] = {}
        self._rng = np.random.default_rng()
        self._env: FoamCaseEnv | None = None
        self._name = ""

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        """A new episode of the drawn (or named) case; its env is seeded from this env's RNG."""
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        options = dict(options or {})
        name = str(options.pop("case", None) or self.names[int(self._rng.integers(len(self.names)))])
        if name not in self.cases:
            raise ValueError(f"no case {name!r} in the family (its cases: {', '.join(self.names)})")
        self._name, self._env = name, self._built(name)
        obs, info = self._env.reset(seed=int(self._rng.integers(2**31)), options=options)
        return obs, {**info, "case": name}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """The current case's step; its info (and final episode record) name the case."""
        if self._env is None:
            raise RuntimeError("step() before reset()")
        obs, reward, terminated, truncated, info = self._env.step(action)
        info = {**info, "case": self._name}
        if isinstance(info.get("episode"), dict):
            info["episode"] = {**info["episode"], "case": self._name}
        return obs, reward, terminated, truncated, info

    def close(self) -> None:
        """Close every case's env (their solvers die)."""
        for env in self._envs.values():
            env.close()
        self._envs.clear()
        self._env = None

    def _built(self, name: str) -> FoamCaseEnv:
        if name not in self._envs:  # each case its own directory: base case, episode case, lock
            index = self.names.index(name)
            self._envs[name] = FoamCaseEnv(self.cases[name], work_dir=self.root / f"case_{index}", env_id=0)
        return self._envs[name]


class FamilyFactory:
    """``make_env`` for foam_bridge's backends: every env of the batch a :class:`CaseFamilyEnv` of
    ``cases`` (the batch's own config only gives the shapes)."""

    def __init__(self, cases: Mapping[str, FoamEnvConfig]) -> None:
        self.cases = dict(cases)

    def __call__(self, cfg: Any, work_dir: Path, env_id: int) -> CaseFamilyEnv:
        return CaseFamilyEnv(self.cases, work_dir, env_id)
