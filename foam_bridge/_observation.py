"""What FoamCaseEnv observes: one episode's observation vector in FoamEnvConfig's layout (state, residual
features, progress, algorithm, factors in force, gain), taken in at every step boundary.

Internal to foam_bridge; names here may change.
"""

from __future__ import annotations

from collections import deque
from typing import TYPE_CHECKING

import numpy as np

from foam_bridge._logparse import criterion_distance, field_residual
from foam_bridge._outcomes import FAILURES
from foam_bridge._spaces import bounded_observation, shares_of

if TYPE_CHECKING:
    from foam_bridge._config import FoamEnvConfig
    from foam_bridge._logparse import LogParser

#: The observed gain's bound in decades (FoamEnvConfig.observe_gain): a blow-up or a restart's jump says
#: no more than "a great loss" or "a great gain".
GAIN_BOUND = 5.0


class EpisodeObservation:
    """One episode's observed quantities: the flow state (scaled at reset), the residual features of the
    last step boundaries and the last step's gain; :meth:`vector` lays them out."""

    def __init__(self, cfg: FoamEnvConfig, inlet: float, cells: float) -> None:
        """``inlet``, ``cells``: the initial state's mean |U|^2 over the inlet and over the cells."""
        self.cfg = cfg
        self._features: deque[np.ndarray] = deque(
            [np.zeros(len(cfg.observed))] * cfg.residual_features,
            maxlen=cfg.residual_features or None)
        self._distance: float | None = None  # the criterion distance at the last step boundary
        self._gain = 0.0
        # the scale-free state is relative to this episode's inlet (state_scale if it has none)
        self._scale = inlet if cfg.scale_free_state and inlet > 0 else cfg.state_scale
        self._state = (inlet + cells) / self._scale

    def update(self, outcome: str, residuals: dict[str, float], parser: LogParser) -> None:
        """Take in a step boundary: its residual features, its gain and its state (a failed step keeps
        the last state)."""
        if self.cfg.residual_features:
            # the observed fields, which need not be the criterion's (FoamEnvConfig.observed_fields): the
            # parser holds every solved field's residual; a field not solved reads as 1 (log 0)
            solved = parser.residuals
            levels = [residuals.get(name, field_residual(solved, name)) for name in self.cfg.observed]
            logs = [np.log10(max(level, 1e-30)) if level is not None and np.isfinite(level) else 0.0
                    for level in levels]
            self._features.append(np.asarray(logs))
        self._note_gain(residuals)
        # a failed step keeps the last state read (the solver's last one may be a blow-up)
        inlet = parser.inlet_state if self.cfg.inlet_patch is not None else 0.0  # no inlet: the cells alone
        if outcome not in FAILURES and inlet is not None and parser.cells_state is not None:
            self._state = (inlet + parser.cells_state) / self._scale

    def _note_gain(self, residuals: dict[str, float]) -> None:
        """The last step's gain (FoamEnvConfig.observe_gain); a step without residuals keeps the last."""
        if not residuals:
            return
        distance = criterion_distance(residuals, self.cfg.convergence)
        if not np.isfinite(distance):
            return
        if self._distance is not None:
            self._gain = float(np.clip(self._distance - distance, -GAIN_BOUND, GAIN_BOUND))
        self._distance = distance

    def vector(self, iterations: int, factors: np.ndarray) -> np.ndarray:
        """state, residual features, progress, factors in force (FoamEnvConfig's observation layout)."""
        cfg = self.cfg
        parts = [np.array([self._state])] if cfg.observe_state else []
        parts += list(self._features) if cfg.residual_features else []
        if cfg.observe_progress:
            parts.append(np.array([iterations / cfg.max_iterations]))
        if cfg.observe_algorithm:
            parts.append(np.array([float(cfg.variant == "SIMPLEC")]))
        if cfg.observe_action:  # as the policy acts: a share of the box with action_share
            parts.append(shares_of(cfg, factors))
        if cfg.observe_gain:
            parts.append(np.array([self._gain]))
        return bounded_observation(np.concatenate(parts))
