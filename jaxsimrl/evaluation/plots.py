"""Figures of an evaluation, in the paper's style (matplotlib, Agg backend: no display needed).

Left: the 3-D trajectories, uncontrolled in black, controlled in blue, the fixed point P- marked.
Right: |velocity| against time for both, with the reward threshold V_th.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # before pyplot: headless machines and tests have no display

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from jaxsimrl.runs.atomic import atomic_write_bytes  # noqa: E402

CONTROLLED, UNCONTROLLED = "tab:blue", "black"


def plot_trajectories(path: Path, controlled_xyz: np.ndarray, uncontrolled_xyz: np.ndarray,
                      controlled_speed: np.ndarray, uncontrolled_speed: np.ndarray, dt: float,
                      v_threshold: float, fixed_point: Sequence[float]) -> None:
    """Save the two-panel figure to ``path`` (PNG, written atomically)."""
    fig = plt.figure(figsize=(13, 5.5))
    space = fig.add_subplot(1, 2, 1, projection="3d")
    _trajectories(space, controlled_xyz, uncontrolled_xyz, fixed_point)
    speed = fig.add_subplot(1, 2, 2)
    _speeds(speed, controlled_speed, uncontrolled_speed, dt, v_threshold)
    start = ", ".join(f"{v:g}" for v in np.round(controlled_xyz[0], 3))
    fig.suptitle(f"Lorenz system, (sigma, rho, beta) = (10, 20, 8/3), start ({start})")
    fig.tight_layout()
    save_figure(fig, path)


def save_figure(fig: plt.Figure, path: str | Path, dpi: int = 120) -> None:
    """Write ``fig`` to ``path`` as PNG, atomically, and close it."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    plt.close(fig)
    atomic_write_bytes(path, buffer.getvalue())


def _trajectories(ax: plt.Axes, controlled: np.ndarray, uncontrolled: np.ndarray,
                  fixed_point: Sequence[float]) -> None:
    ax.plot(*controlled.T, color=CONTROLLED, lw=0.5, alpha=0.8, label="controlled (RL agent)")
    ax.plot(*uncontrolled.T, color=UNCONTROLLED, lw=1.0, label="uncontrolled")
    ax.scatter(*np.asarray(fixed_point)[:, None], color="red", marker="*", s=160, depthshade=False,
               label="P- = ({:g}, {:g}, {:g})".format(*fixed_point), zorder=5)
    ax.scatter(*controlled[0][:, None], color="green", marker="o", s=40, depthshade=False, label="start")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")
    ax.legend(loc="upper left", fontsize=8)


def _speeds(ax: plt.Axes, controlled: np.ndarray, uncontrolled: np.ndarray, dt: float,
            v_threshold: float) -> None:
    time = dt * np.arange(1, len(controlled) + 1)
    ax.plot(time, controlled, color=CONTROLLED, lw=0.6, label="controlled")
    ax.plot(time, uncontrolled, color=UNCONTROLLED, lw=1.0, label="uncontrolled")
    ax.axhline(v_threshold, color="red", ls="--", lw=1.0, label=f"V_th = {v_threshold:g}")
    ax.set_xlabel("time")
    ax.set_ylabel("|velocity|")
    ax.set_xlim(0, time[-1])
    ax.set_ylim(bottom=0)
    ax.legend(loc="upper right", fontsize=8)
    above = np.mean(controlled > v_threshold)
    ax.set_title(f"controlled: {above:.0%} of steps above V_th, uncontrolled: "
                 f"{np.mean(uncontrolled > v_threshold):.0%}", fontsize=10)
