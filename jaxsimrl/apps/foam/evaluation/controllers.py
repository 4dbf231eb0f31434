"""The controllers eval-foam compares: who chooses (alpha_u, alpha_p) at every step of an episode.

Every controller acts for a batch of running episodes, each named by its ``uid`` (its index in the
evaluation plan), and its actions depend only on (seed, uid, step) and the episode's own observations,
never on the batch it shares: so the same command gives the same numbers whatever the pool size.

- :class:`ConstantController`: the same factors at every step (best constant, the tutorial's defaults).
- :class:`CaseGridController`: a grid of constant factors, one cell per episode (the per-case oracle:
  every cell of its grid on the test case; its best is chosen afterwards, see foam_oracle).
- :class:`RandomController`: factors uniform in the action box at every step (the paper's baseline).
- :class:`RuleController`: a no-training rule of ``jaxsimrl solve`` (jaxsimrl.apps.foam.solve.rules), one per
  episode, acting on the residuals of its episode's last step.
- :class:`LearnedController`: the trained policy, deterministic (its mean action) or stochastic: a thin
  adapter from this protocol (begin/act/end per uid) to a :class:`jaxsimrl.policy.BatchActor`.

``repeats`` says whether more than one run per (geometry, velocity) is informative: a deterministic
controller on a deterministic solver gives the same episode every time.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from foam_bridge import ConstantFactors, StatelessController, StepRecord
from jaxsimrl.apps.foam.solve.rules import RULES

if TYPE_CHECKING:  # only a type: the controllers themselves need no JAX
    from jaxsimrl.policy import BatchActor


class ConstantController(ConstantFactors):
    """The same factors (alpha_u, alpha_p[, alpha_t]) at every step (the pool's ConstantFactors, named)."""

    repeats = False

    def __init__(self, name: str, factors: Sequence[float]) -> None:
        super().__init__(factors)
        self.name = name


class CaseGridController(StatelessController):
    """Constant factors per episode: ``cells[i]`` at every step of the episodes assigned cell i."""

    repeats = False

    def __init__(self, name: str, cells: Sequence[Sequence[float]]) -> None:
        self.name = name
        self.cells = [np.asarray(cell, np.float64).reshape(-1) for cell in cells]
        self._cell_of: dict[int, int] = {}

    def assign(self, uid: int, cell: int) -> None:
        """Episode ``uid`` runs ``cells[cell]``."""
        self._cell_of[uid] = cell

    def act(self, uids: Sequence[int], obs: np.ndarray, steps: Sequence[int]) -> np.ndarray:
        return np.stack([self.cells[self._cell_of[uid]] for uid in uids])


class RandomController:
    """Factors drawn uniformly in [low, high] at every step, from a stream seeded by (seed, uid)."""

    repeats = True

    def __init__(self, name: str, low: Sequence[float], high: Sequence[float], seed: int) -> None:
        self.name = name
        self.low, self.high = np.asarray(low, np.float64), np.asarray(high, np.float64)
        self.seed = seed
        self._streams: dict[int, np.random.Generator] = {}

    def begin(self, uid: int) -> None:
        self._streams[uid] = np.random.default_rng([self.seed, uid])

    def act(self, uids: Sequence[int], obs: np.ndarray, steps: Sequence[int]) -> np.ndarray:
        return np.stack([self._streams[uid].uniform(self.low, self.high) for uid in uids])

    def end(self, uid: int) -> None:
        self._streams.pop(uid, None)


class RuleController:
    """A rule of jaxsimrl.apps.foam.solve.rules (``rule``: its name) in every episode, each its own instance:
    built for the case's ``criterion``, ``own`` factors (where it starts, and goes back to), box (``low``,
    ``high``) and algorithm (``simplec``), and shown the residuals of its episode's steps (``observe``)."""

    repeats = False

    def __init__(self, name: str, rule: str, criterion: dict[str, float], own: Sequence[float],
                 box: tuple[Sequence[float], Sequence[float]], simplec: bool) -> None:
        self.name, self.rule = name, rule
        self.case = (dict(criterion), tuple(own), tuple(box[0]), tuple(box[1]), simplec)
        self._rules: dict[int, Any] = {}
        self._residuals: dict[int, dict[str, float] | None] = {}

    def begin(self, uid: int) -> None:
        self._rules[uid], self._residuals[uid] = RULES[self.rule](*self.case), None

    def observe(self, uid: int, step: StepRecord) -> None:
        self._residuals[uid] = dict(step.residuals) or None

    def act(self, uids: Sequence[int], obs: np.ndarray, steps: Sequence[int]) -> np.ndarray:
        return np.array([self._rules[uid].act(None, self._residuals[uid]) for uid in uids], np.float64)

    def end(self, uid: int) -> None:
        self._rules.pop(uid, None)
        self._residuals.pop(uid, None)


class LearnedController:
    """The trained policy: its mean action (``deterministic``) or a sample of it at every step, drawn
    with the keys of ``seed`` (see BatchActor)."""

    def __init__(self, name: str, actor: BatchActor, deterministic: bool, seed: int = 0) -> None:
        self.name = name
        self.actor = actor
        self.deterministic = deterministic
        self.seed = seed
        self.repeats = not deterministic
        self._carries: dict[int, Any] = {}

    def begin(self, uid: int) -> None:
        self._carries[uid] = self.actor.initial_carry()

    def act(self, uids: Sequence[int], obs: np.ndarray, steps: Sequence[int]) -> np.ndarray:
        actions, carries = self.actor.act(obs, [self._carries[uid] for uid in uids], list(uids), list(steps),
                                          self.deterministic, self.seed)
        self._carries.update(zip(uids, carries, strict=True))
        return actions

    def end(self, uid: int) -> None:
        self._carries.pop(uid, None)
