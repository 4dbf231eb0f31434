"""The box description foam_bridge's envs return, and clipping an action into a box.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

BoxSpec has the same fields as jaxsimrl's (``jaxsimrl.envs.protocol``), so code written for either reads
both, but foam_bridge does not import jaxsimrl: the solver plugin stands on its own. Users meet it as
``FoamCaseEnv.action_space_spec``; the gymnasium envs turn it into a ``gymnasium.spaces.Box``.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

__all__ = ["BoxSpec", "clip_to_box"]


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
