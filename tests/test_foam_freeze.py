"""Factors frozen near the criterion (FoamEnvConfig.freeze_decades): the env holds the factors in force
once a step ends within that many decades of the criterion, whatever the policy asks; solve's learned
actor does the same while its watchdog's fallback still reaches the solver."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from foam_marks import needs_openfoam

from foam_bridge import criterion_distance
from foam_bridge._config import FoamEnvConfig
from foam_bridge._env import FoamCaseEnv
from jaxsimrl.apps.foam.solve.drive import LearnedActor


def test_the_distance_is_the_worst_field_s_decades_above_its_threshold() -> None:
    criterion = {"p": 1e-3, "U": 1e-4}
    assert criterion_distance({"p": 1e-2, "U": 1e-4}, criterion) == pytest.approx(1.0)
    assert criterion_distance({"p": 1e-4, "U": 1e-6}, criterion) == pytest.approx(-1.0)
    assert criterion_distance({"p": 1e-2, "U": math.nan}, criterion) == math.inf
    assert math.isnan(criterion_distance({"k": 1.0}, criterion))  # no criterion field reported


def test_freeze_decades_is_checked_and_left_out_of_old_configs_json() -> None:
    assert "freeze_decades" not in FoamEnvConfig().to_json()
    frozen = FoamEnvConfig(freeze_decades=1.0)
    assert FoamEnvConfig.from_json(frozen.to_json()) == frozen
    for bad in (-0.5, math.inf, True, "1"):
        with pytest.raises(ValueError, match="freeze_decades"):
            FoamEnvConfig(freeze_decades=bad).validate()


class _Counting:
    """A policy whose action is its call count: each call acts differently."""

    def __init__(self) -> None:
        self.calls = 0

    def act(self, obs, state, deterministic: bool):
        self.calls += 1
        return np.array([0.1 * self.calls, 0.5]), state


def test_the_learned_actor_holds_its_action_once_near_the_criterion() -> None:
    policy = _Counting()
    actor = LearnedActor(policy, 1.0, freeze_decades=1.0, criterion={"p": 1e-3})
    obs = np.zeros(3)
    assert actor.act(obs, None) == pytest.approx([0.1, 0.5])
    assert actor.act(obs, {"p": 1e-1}) == pytest.approx([0.2, 0.5])  # 2 decades away: it acts
    assert actor.act(obs, {"p": 5e-3}) == pytest.approx([0.2, 0.5])  # 0.7 decade: held
    assert actor.act(obs, {"p": 1e-1}) == pytest.approx([0.2, 0.5])  # for good, as in training
    assert policy.calls == 2
    free = LearnedActor(_Counting(), 1.0)
    assert [free.act(obs, {"p": 1e-9})[0] for _ in range(3)] == pytest.approx([0.1, 0.2, 0.3])


@needs_openfoam
@pytest.mark.parametrize("freeze", [None, 100.0])
def test_the_env_holds_the_factors_once_within_freeze_decades(tmp_path: Path, freeze: float | None) -> None:
    """100 decades: frozen after the first step; None: every action reaches the solver."""
    cfg = FoamEnvConfig(mesh_scale=0.4, simple_variant="SIMPLEC", interval=10, max_iterations=1000,
                        step_timeout_s=60.0, work_dir=tmp_path, freeze_decades=freeze)
    env = FoamCaseEnv(cfg)
    try:
        env.reset(seed=0, options={"inlet_velocity": 50.0})
        asked = [[0.9, 0.5], [0.4, 0.7], [0.6, 0.3]]
        told = [env.step(np.array(action))[4]["factors"] for action in asked]
        applied = env._episode["actions"]
    finally:
        env.close()
    expected = asked if freeze is None else [asked[0]] * 3
    assert np.allclose(told, expected) and np.allclose(applied, expected)
