"""The LSTM hidden state over a trajectory, on its leading principal components.

Plain PCA (numpy SVD of the centred hidden states of one episode); the points are coloured by
|velocity| (``"speed"``: the norm of the env state's velocity at each step), ``"reward"`` or any key
of the rollout record holding one number per step.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from jaxsimrl.introspect.figure import new_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure


class HiddenPCA(NamedTuple):
    scores: np.ndarray  # (T, k): the hidden states projected on the components
    explained_variance_ratio: np.ndarray  # (k,)
    components: np.ndarray  # (k, H): unit principal directions
    mean: np.ndarray  # (H,)
    color: np.ndarray  # (T,)
    color_name: str


def hidden_pca(record: dict[str, np.ndarray], episode: int = 0, components: int = 2,
               color: str = "speed") -> HiddenPCA:
    """PCA of ``record["hidden"][episode]`` (T, H) with ``components`` components."""
    if "hidden" not in record:
        raise ValueError("the record has no 'hidden' entry: the policy is not recurrent (network='mlp')")
    hidden = np.asarray(record["hidden"][episode], np.float64)
    if not 1 <= components <= min(hidden.shape):
        raise ValueError(f"components must be in 1..{min(hidden.shape)}, got {components}")
    mean = hidden.mean(axis=0)
    _, singular, directions = np.linalg.svd(hidden - mean, full_matrices=False)
    variance = singular**2
    ratio = variance[:components] / variance.sum() if variance.sum() > 0 else np.zeros(components)
    basis = directions[:components]
    return HiddenPCA((hidden - mean) @ basis.T, ratio, basis, mean, _color(record, episode, color), color)


def plot_hidden_pca(data: HiddenPCA) -> Figure:
    """The trajectory in the plane of the first two components, coloured by ``data.color``."""
    fig = new_figure(6.5, 5)
    ax = fig.subplots()
    second = data.scores[:, 1] if data.scores.shape[1] > 1 else np.zeros(len(data.scores))
    ax.plot(data.scores[:, 0], second, color="0.8", lw=0.4, zorder=1)
    points = ax.scatter(data.scores[:, 0], second, c=data.color, s=3, cmap="viridis", zorder=2)
    fig.colorbar(points, ax=ax, label=data.color_name)
    ratio = data.explained_variance_ratio
    ax.set_xlabel(f"PC 1 ({ratio[0]:.0%} of variance)")
    ax.set_ylabel(f"PC 2 ({ratio[1]:.0%})" if len(ratio) > 1 else "")
    return fig


def _color(record: dict[str, np.ndarray], episode: int, name: str) -> np.ndarray:
    if name == "speed" and "state.velocity" in record:
        return np.linalg.norm(record["state.velocity"][episode], axis=-1)
    if name not in record or np.ndim(record[name][episode]) != 1:
        scalars = sorted(k for k, v in record.items() if np.ndim(v) == 2)
        raise ValueError(f"cannot colour by {name!r}: choose 'speed' or one of {', '.join(scalars)}")
    return np.asarray(record[name][episode], np.float64)
