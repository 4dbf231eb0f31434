"""What a reset draws for its episode: the inlet speed and the step height, each fixed by the reset's
options, else drawn from the config's range with the env's seeded RNG (the velocity first: see
FoamEnvConfig.step_height), else the case's own.

Internal to foam_bridge; names here may change.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from foam_bridge import _base_case as base_case

if TYPE_CHECKING:
    from foam_bridge._config import FoamEnvConfig
    from foam_bridge._openfoam import OpenFOAM


def episode_velocity(cfg: FoamEnvConfig, rng: np.random.Generator, options: dict[str, Any], base: Path,
                     openfoam: OpenFOAM) -> float | None:
    """This episode's inlet speed: the option, else drawn from the config's range; None: the case's."""
    if options.get("inlet_velocity") is not None:
        velocity = float(options["inlet_velocity"])
        if not (math.isfinite(velocity) and velocity > 0):
            raise ValueError(f"options['inlet_velocity']: expected a speed > 0, got {velocity!r}")
        if cfg.case_dir is not None and cfg.velocity_range is None:
            base_case.check_inlet_settable(base, cfg, openfoam)
        return velocity
    if cfg.velocity_range is None:
        return None
    return float(rng.uniform(*cfg.velocity_range))


def episode_height(cfg: FoamEnvConfig, rng: np.random.Generator, options: dict[str, Any]) -> float | None:
    """This episode's step height: the option, else drawn from the config's range, else the fixed
    one (None: a user's case, whose mesh is its own)."""
    if options.get("step_height") is not None:
        height = float(options["step_height"])
        if not cfg.builtin:
            raise ValueError("options['step_height'] applies to the built-in backward-facing step only "
                             "(a case of your own keeps its own mesh)")
        if not (math.isfinite(height) and height > 0):
            raise ValueError(f"options['step_height']: expected a height > 0 in m, got {height!r}")
        return height
    if cfg.height_range is None:
        return cfg.fixed_height if cfg.builtin else None
    return float(rng.uniform(*cfg.height_range))
