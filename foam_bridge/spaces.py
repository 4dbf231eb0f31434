"""The two small value types foam_bridge returns: a box description and one step's result.

They have the same fields as jaxsimrl's protocol types (``jaxsimrl.envs.protocol``), so code written for
either reads both, but foam_bridge does not import jaxsimrl: the solver plugin stands on its own, and
the trainer holds the adapter that drives it.
"""

from __future__ import annotations

from typing import Any, NamedTuple


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
