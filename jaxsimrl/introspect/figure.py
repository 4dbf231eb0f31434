"""The introspection plots' blank figure, with matplotlib imported only when a plot is drawn.

Importing :mod:`jaxsimrl.introspect` (and so ``jaxsimrl.load_policy``) must stay free of matplotlib, which
costs most of a second: loading and acting are also what ``jaxsimrl solve`` does on every case.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def new_figure(width: float, height: float) -> Figure:
    """An empty constrained-layout figure of ``width`` x ``height`` inches (no pyplot, no global state)."""
    from matplotlib.figure import Figure  # lazily: see the module docstring

    return Figure(figsize=(width, height), layout="constrained")
