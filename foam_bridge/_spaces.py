"""The boxes foam_bridge's envs act and observe in: their description, clipping an action into one, an
action's factors (absolute, or shares of a case's box around its own factors) and a bounded observation.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

BoxSpec has the same fields as jaxsimrl's (``jaxsimrl.envs.protocol``), so code written for either reads
both, but foam_bridge does not import jaxsimrl: the solver plugin stands on its own. Users meet it as
``FoamCaseEnv.action_space_spec``; the gymnasium envs turn it into a ``gymnasium.spaces.Box``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from foam_bridge._config import ACTION_NAMES, OBSERVATION_BOUND

if TYPE_CHECKING:
    from foam_bridge._config import FoamEnvConfig

__all__ = ["BoxSpec", "action_spec", "action_values", "bounded_observation", "clip_to_box", "factors_of",
           "observation_spec", "shares_of"]


class BoxSpec(NamedTuple):
    """A bounded box of shape ``shape`` (``low``/``high`` broadcast to it)."""

    low: Any
    high: Any
    shape: tuple[int, ...]


def clip_to_box(action: Any, low: Any, high: Any) -> np.ndarray:
    """``action`` clipped into [low, high] in float64, and a value equal to a bound in float32 snapped to
    that bound exactly.

    Boxes travel as float32 (gymnasium's Box, the trainer's jitted policy) and float32(0.95) is
    0.949999988: without the snap an action on the box's edge would reach the solver a hair inside it,
    never as the edge itself that constant-factor baselines (0.95) use.
    """
    low, high = np.asarray(low, np.float64), np.asarray(high, np.float64)
    alpha = np.clip(np.asarray(action, np.float64), low, high)
    for bound in (low, high):
        alpha = np.where(alpha.astype(np.float32) == bound.astype(np.float32), bound, alpha)
    return alpha


def action_values(action: Any, size: int = 2) -> np.ndarray:
    """The action as ``size`` finite floats; a one-line ValueError otherwise."""
    names = f"({', '.join(ACTION_NAMES[:size])})"
    try:
        alpha = np.asarray(action, dtype=float).reshape(size)
    except (TypeError, ValueError):
        raise ValueError(f"action: expected {names}, got {action!r}") from None
    if not np.all(np.isfinite(alpha)):
        raise ValueError(f"action: expected finite {names}, got {alpha.tolist()}")
    return alpha


def observation_spec(cfg: FoamEnvConfig) -> BoxSpec:
    """Box of the observation (float32): the scaled state in [0, B], the log10 residual features in
    [-B, B], then the progress and the factors in [0, B], B = OBSERVATION_BOUND."""
    n, state = cfg.observation_size, int(cfg.observe_state)
    features = cfg.residual_features * len(cfg.observed)
    low = np.array([0.0] * state + [-OBSERVATION_BOUND] * features + [0.0] * (n - state - features),
                   dtype=np.float32)
    return BoxSpec(low=low, high=np.full(n, OBSERVATION_BOUND, dtype=np.float32), shape=(n,))


def bounded_observation(values: np.ndarray) -> np.ndarray:
    """float32, finite, every entry in [-OBSERVATION_BOUND, OBSERVATION_BOUND] (NaN -> the upper bound)."""
    clean = np.nan_to_num(np.asarray(values, dtype=np.float64), nan=OBSERVATION_BOUND,
                          posinf=OBSERVATION_BOUND, neginf=-OBSERVATION_BOUND)
    return np.clip(clean, -OBSERVATION_BOUND, OBSERVATION_BOUND).astype(np.float32)


def action_spec(cfg: FoamEnvConfig) -> BoxSpec:
    """Box of (alpha_u, alpha_p[, alpha_t]): ``[action_low, action_high]`` (float32); [0, 1] per factor
    with ``action_share``."""
    if cfg.action_share:
        return BoxSpec(low=np.zeros(cfg.action_size, np.float32), high=np.ones(cfg.action_size, np.float32),
                       shape=(cfg.action_size,))
    return BoxSpec(low=np.asarray(cfg.action_low, dtype=np.float32),
                   high=np.asarray(cfg.action_high, dtype=np.float32), shape=(cfg.action_size,))


def factors_of(cfg: FoamEnvConfig, action: Any) -> np.ndarray:
    """The factors an action sets, in the box: the action itself, or with ``action_share`` the point
    that share of the way from action_low to action_high (shares clipped into [0, 1]), through
    ``action_pivot`` at 0.5 where it is set; with ``action_radius``, the pivot moved by (2 share - 1) x
    that radius, clipped into the box."""
    low, high = np.asarray(cfg.action_low, np.float64), np.asarray(cfg.action_high, np.float64)
    if not cfg.action_share:
        return clip_to_box(action, low, high)
    share = np.clip(np.asarray(action, np.float64), 0.0, 1.0)
    if cfg.action_radius is not None:
        return clip_to_box(_pivot(cfg, low, high) + (2 * share - 1) * cfg.action_radius, low, high)
    if cfg.action_pivot is None:
        return clip_to_box(low + share * (high - low), low, high)
    pivot = np.asarray(cfg.action_pivot, np.float64)
    below, above = low + 2 * share * (pivot - low), pivot + (2 * share - 1) * (high - pivot)
    return clip_to_box(np.where(share < 0.5, below, above), low, high)


def shares_of(cfg: FoamEnvConfig, factors: Any) -> np.ndarray:
    """The action that sets ``factors`` (the inverse of :func:`factors_of`; a fallback's own factors)."""
    if not cfg.action_share:
        return np.asarray(factors, np.float64)
    low, high = np.asarray(cfg.action_low, np.float64), np.asarray(cfg.action_high, np.float64)
    factors = np.clip(np.asarray(factors, np.float64), low, high)
    if cfg.action_radius is not None:
        return np.clip(0.5 + (factors - _pivot(cfg, low, high)) / (2 * cfg.action_radius), 0.0, 1.0)
    if cfg.action_pivot is None:
        return (factors - low) / np.where(high > low, high - low, 1.0)
    pivot = np.asarray(cfg.action_pivot, np.float64)
    below = 0.5 * (factors - low) / np.where(pivot > low, pivot - low, 1.0)
    above = 0.5 + 0.5 * (factors - pivot) / np.where(high > pivot, high - pivot, 1.0)
    return np.clip(np.where(factors < pivot, below, above), 0.0, 1.0)


def _pivot(cfg: FoamEnvConfig, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """The factors at share 0.5: ``action_pivot``, else the box's centre."""
    return (low + high) / 2 if cfg.action_pivot is None else np.asarray(cfg.action_pivot, np.float64)
