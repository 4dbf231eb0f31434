"""A foam policy's relaxation factors along its episodes: alpha_u and alpha_p against the SIMPLE
iteration and against the residual they answered, per inlet velocity.

From a record of :meth:`LoadedPolicy.rollout` on a train-foam run (one row per step). Action t takes
over at iteration ``iterations_before`` and holds until the next action; it was chosen on the
observation at that boundary, i.e. after the residuals of the previous step (none before the first
step: NaN there).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from foam_bridge import ACTION_NAMES
from jaxsimrl.introspect.figure import new_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure


class FactorHistory(NamedTuple):
    velocity: np.ndarray  # (E,) inlet velocity of each episode, in the record's order
    final_iterations: np.ndarray  # (E,) iterations when each episode ended
    outcome: tuple[str, ...]  # (E,) how each ended
    iteration: tuple[np.ndarray, ...]  # E x (T_e,): the iteration at which action t took over
    factors: tuple[np.ndarray, ...]  # E x (T_e, 2): (alpha_u, alpha_p) of each step
    residual: tuple[np.ndarray, ...]  # E x (T_e,): ``residual_field``'s residual it answered (NaN at t=0)
    residual_field: str
    action_names: tuple[str, ...]


def factor_history(record: dict[str, np.ndarray], residual: str = "p") -> FactorHistory:
    """Per episode of ``record``: where each action took over, the factors, the residual they answered."""
    key = f"residual.{residual}"
    if key not in record:
        fields = sorted(k.removeprefix("residual.") for k in record if k.startswith("residual."))
        have = ", ".join(fields) or "none"
        raise ValueError(f"the record has no residual of {residual!r} (it has: {have})")
    episodes = np.unique(record["episode"])
    rows = [np.flatnonzero(record["episode"] == e) for e in episodes]
    answered = [np.concatenate([[np.nan], record[key][r][:-1]]) for r in rows]
    return FactorHistory(np.array([record["velocity"][r[0]] for r in rows]),
                         np.array([record["iterations"][r[-1]] for r in rows]),
                         tuple(str(record["outcome"][r[-1]]) for r in rows),
                         tuple(record["iterations_before"][r] for r in rows),
                         tuple(record["action"][r] for r in rows), tuple(answered), residual,
                         ACTION_NAMES[:2])


def plot_factor_history(data: FactorHistory) -> Figure:
    """alpha_u (top) and alpha_p (bottom) against the iteration (left, as held from step to step) and
    against the residual each answered (right, log scale); one colour per inlet velocity."""
    fig = new_figure(11, 6)
    axes = fig.subplots(2, 2, sharey="row")
    speeds = sorted(set(data.velocity.tolist()))
    colours = {v: f"C{i % 10}" for i, v in enumerate(speeds)}
    labelled: set[float] = set()
    for e, velocity in enumerate(data.velocity.tolist()):
        label = None if velocity in labelled else f"V = {velocity:g} m/s"
        labelled.add(velocity)
        edges = np.append(data.iteration[e], max(data.final_iterations[e], data.iteration[e][-1]))
        for row in range(2):
            values = data.factors[e][:, row]
            axes[row, 0].step(edges, np.append(values, values[-1]), where="post", color=colours[velocity],
                              label=label)
            axes[row, 1].plot(data.residual[e], values, "o-", ms=3, color=colours[velocity], label=label)
    for row, name in enumerate(data.action_names):
        axes[row, 0].set_ylabel(name)
        for ax in axes[row]:
            ax.grid(alpha=0.3)
        axes[row, 1].set_xscale("log")
    axes[1, 0].set_xlabel("SIMPLE iteration")
    axes[1, 1].set_xlabel(f"initial residual of {data.residual_field} the action answered")
    axes[0, 0].legend(fontsize=8)
    return fig
