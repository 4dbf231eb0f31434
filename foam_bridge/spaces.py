"""The two small value types foam_bridge returns: a box description and one step's result.

They have the same fields as jaxsimrl's protocol types (``jaxsimrl.envs.protocol``), so code written for
either reads both, but foam_bridge does not import jaxsimrl: the solver plugin stands on its own, and
the trainer holds the adapter that drives it.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np


class BoxSpec(NamedTuple):
    """A bounded box of shape ``shape`` (``low``/``high`` broadcast to it)."""

    low: Any
    high: Any
    shape: tuple[int, ...]


class Step(NamedTuple):
    """What one environment step returns (fields are arrays, batched or not)."""

    obs: Any
    state: Any
    reward: Any
    terminated: Any
    truncated: Any
    info: dict[str, Any]


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
