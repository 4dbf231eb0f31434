"""The env options that let one controller act on many cases (foam_bridge._config): an observation without
the flow state and with the algorithm, actions as shares of each case's own box, a reward scaled per case.
Logic first, then one real episode of the coarse built-in case."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from foam_marks import needs_openfoam

from foam_bridge._config import FoamEnvConfig
from foam_bridge._env import FoamCaseEnv, action_spec, factors_of, observation_spec, shares_of
from foam_bridge._family_env import CaseFamilyEnv
from jaxsimrl.apps.foam.solve.settings import CaseSettings, around_own

SHARED = dict(observe_state=False, observe_algorithm=True, action_share=True, residual_features=2,
              observe_progress=True, observe_action=True)


def test_shares_map_onto_the_box_and_back() -> None:
    cfg = FoamEnvConfig(action_low=(0.2, 0.3), action_high=(0.9, 0.5), action_share=True)
    assert factors_of(cfg, [0.0, 1.0]) == pytest.approx([0.2, 0.5])
    assert factors_of(cfg, [0.5, 0.25]) == pytest.approx([0.55, 0.35])
    assert factors_of(cfg, [1.7, -3.0]) == pytest.approx([0.9, 0.3])  # a share outside [0, 1] is clipped
    assert shares_of(cfg, [0.55, 0.35]) == pytest.approx([0.5, 0.25])
    assert shares_of(cfg, [1.0, 0.1]) == pytest.approx([1.0, 0.0])  # factors outside the box: its edges
    spec = action_spec(cfg)
    assert spec.low.tolist() == [0.0, 0.0] and spec.high.tolist() == [1.0, 1.0]
    absolute = FoamEnvConfig(action_low=(0.2, 0.3), action_high=(0.9, 0.5))
    assert factors_of(absolute, [0.55, 0.7]) == pytest.approx([0.55, 0.5])
    assert action_spec(absolute).low == pytest.approx([0.2, 0.3])


def test_a_pivot_puts_the_case_s_own_factors_at_one_half() -> None:
    cfg = FoamEnvConfig(action_low=(0.2, 0.2), action_high=(0.95, 1.0), action_share=True,
                        action_pivot=(0.9, 1.0))
    assert factors_of(cfg, [0.5, 0.5]) == pytest.approx([0.9, 1.0])
    assert factors_of(cfg, [0.0, 0.25]) == pytest.approx([0.2, 0.6])
    assert factors_of(cfg, [1.0, 1.0]) == pytest.approx([0.95, 1.0])
    assert factors_of(cfg, [0.75, 0.0]) == pytest.approx([0.925, 0.2])
    for factors in ([0.9, 1.0], [0.2, 0.6], [0.925, 0.3], [0.55, 0.95]):
        assert factors_of(cfg, shares_of(cfg, factors)) == pytest.approx(factors)
    assert FoamEnvConfig.from_json(cfg.to_json()) == cfg and "action_pivot" not in FoamEnvConfig().to_json()
    with pytest.raises(ValueError, match="action_pivot"):
        FoamEnvConfig(action_low=(0.2, 0.2), action_high=(0.95, 0.95), action_pivot=(0.9, 1.0)).validate()


def test_around_own_pivots_each_algorithm_at_its_family_constant_inside_the_case_s_box() -> None:
    template = FoamEnvConfig(action_low=(0.35, 0.15, 0.35), action_high=(0.875, 0.375, 0.875),
                             relax_k_omega="action", action_share=True)
    plain = around_own(template, CaseSettings((0.7, 0.3, 0.7), False, None, "SIMPLE")).validate()
    assert plain.action_low == template.action_low and plain.action_high == template.action_high
    assert plain.action_pivot == (0.8, 0.3, 0.875)  # (0.8, 0.3, 0.9), the turbulence clipped to the box
    assert factors_of(plain, [0.5] * 3) == pytest.approx([0.8, 0.3, 0.875])
    assert factors_of(plain, [0.0] * 3) == pytest.approx([0.35, 0.15, 0.35])
    simplec = around_own(template, CaseSettings((0.9, None, 0.9), False, None, "SIMPLEC")).validate()
    assert simplec.action_high == (0.95, 1.0, 0.95) and simplec.action_pivot == simplec.action_high
    assert simplec.action_low == (0.9, 0.5, 0.5)  # never below its own alpha_u
    assert factors_of(simplec, [0.5] * 3) == pytest.approx([0.95, 1.0, 0.95])
    assert factors_of(simplec, [0.0] * 3) == pytest.approx([0.9, 0.5, 0.5])
    assert shares_of(simplec, [0.95, 1.0, 0.95]) == pytest.approx([0.5] * 3)
    high_own = around_own(template, CaseSettings((0.97, 0.3, 0.4), False, None, "SIMPLEC")).validate()
    assert high_own.action_low == (0.97, 0.3, 0.4) and high_own.action_high == (0.97, 1.0, 0.95)


def test_the_options_size_the_observation_and_leave_old_configs_json_alone() -> None:
    plain = FoamEnvConfig(residual_features=2, observe_progress=True, observe_action=True)
    shared = FoamEnvConfig(simple_variant="SIMPLEC", **SHARED)
    features = 2 * len(plain.observed)
    assert plain.observation_size == 1 + features + 1 + 2
    assert shared.observation_size == features + 1 + 1 + 2  # no state; the algorithm
    spec = observation_spec(shared)
    assert spec.shape == (shared.observation_size,) and spec.low[0] < 0  # the first entry is a residual
    for name in ("observe_state", "observe_algorithm", "action_share", "reward_scale"):
        assert name not in plain.to_json()  # a run's config.json and cache keys as before
    assert FoamEnvConfig.from_json(shared.to_json()) == shared
    with pytest.raises(ValueError, match="reward_scale"):
        FoamEnvConfig(reward_scale=0.0).validate()
    with pytest.raises(ValueError, match="observe_algorithm"):
        FoamEnvConfig(case_dir=Path("c"), observe_algorithm=True).validate()  # the case's own: unknown


@needs_openfoam
def test_an_episode_acts_in_shares_observes_the_algorithm_and_scales_its_reward(tmp_path: Path) -> None:
    cfg = FoamEnvConfig(mesh_scale=0.4, simple_variant="SIMPLEC", interval=25, max_iterations=1000,
                        step_timeout_s=60.0, work_dir=tmp_path, reward_scale=0.5, **SHARED)
    env = FoamCaseEnv(cfg)
    try:
        obs, _ = env.reset(seed=0, options={"inlet_velocity": 50.0})
        features = 2 * len(cfg.observed)
        assert obs.shape == (cfg.observation_size,)
        assert obs[features + 1] == 1.0  # SIMPLEC
        assert obs[-2:] == pytest.approx([0.5, 0.5])  # before any action: the box's centre, as shares
        obs, reward, terminated, _, info = env.step(np.array([1.0, 0.0]))
        assert not terminated and info["iterations"] == 25
        assert reward == pytest.approx(-25 * 0.5)
        assert obs[-2:] == pytest.approx([1.0, 0.0])
        assert env._episode["actions"][-1] == pytest.approx([cfg.action_high[0], cfg.action_low[1]])
        latest = obs[features // 2:features]  # the older block is 0 until a second boundary
        assert np.all(latest < 0) and np.all(obs[:features // 2] == 0)  # log10 residuals below 1
    finally:
        env.close()


def _family(tmp_path: Path, **overrides) -> dict[str, FoamEnvConfig]:
    """The coarse built-in step under both algorithms, acting in shares of one box."""
    base = dict(mesh_scale=0.4, interval=25, max_iterations=50, step_timeout_s=60.0, inlet_velocity=50.0,
                **SHARED)
    return {variant: FoamEnvConfig(**{**base, "simple_variant": variant, **overrides})
            for variant in ("SIMPLE", "SIMPLEC")}


def test_a_family_refuses_cases_of_different_shapes(tmp_path: Path) -> None:
    cases = _family(tmp_path)
    cases["SIMPLE"] = FoamEnvConfig(mesh_scale=0.4, simple_variant="SIMPLE")  # a state, no algorithm
    with pytest.raises(ValueError, match="different sizes"):
        CaseFamilyEnv(cases, tmp_path)
    with pytest.raises(ValueError, match="at least one case"):
        CaseFamilyEnv({}, tmp_path)


@needs_openfoam
def test_a_family_env_draws_its_cases_from_its_seed_and_names_them(tmp_path: Path) -> None:
    env = CaseFamilyEnv(_family(tmp_path), tmp_path / "work", env_id=3)
    try:
        drawn = [env.reset(seed=seed)[1]["case"] for seed in range(6)]
        assert drawn == [env.reset(seed=seed)[1]["case"] for seed in range(6)]  # the seed decides
        assert set(drawn) == {"SIMPLE", "SIMPLEC"}
        features = 2 * len(env.cases["SIMPLE"].observed)
        for name, flag in (("SIMPLE", 0.0), ("SIMPLEC", 1.0)):
            obs, info = env.reset(seed=0, options={"case": name})
            assert info["case"] == name and obs[features + 1] == flag
            done, info = False, {}
            while not done:
                _, _, terminated, truncated, info = env.step(np.array([0.5, 0.5]))
                done = terminated or truncated
            assert info["case"] == name and info["episode"]["case"] == name
            assert info["episode"]["iterations"] == 50  # the budget of this coarse family
        assert sorted(p.name for p in (tmp_path / "work" / "env_3").iterdir()) == ["case_0", "case_1"]
        with pytest.raises(ValueError, match="no case 'cavity'"):
            env.reset(options={"case": "cavity"})
    finally:
        env.close()


def test_the_gain_is_one_entry_last_and_old_configs_json_stays_as_it_was() -> None:
    cfg = FoamEnvConfig(simple_variant="SIMPLEC", **SHARED)
    gained = FoamEnvConfig(simple_variant="SIMPLEC", observe_gain=True, **SHARED)
    assert gained.observation_size == cfg.observation_size + 1
    assert "observe_gain" not in cfg.to_json() and gained.to_json()["observe_gain"] is True
    assert FoamEnvConfig.from_json(gained.to_json()) == gained
    with pytest.raises(ValueError, match="observe_gain"):
        FoamEnvConfig(observe_gain=1).validate()


@needs_openfoam
def test_the_gain_is_the_fall_of_the_criterion_distance_over_the_last_step(tmp_path: Path) -> None:
    from foam_bridge._logparse import criterion_distance

    cfg = FoamEnvConfig(mesh_scale=0.4, simple_variant="SIMPLEC", interval=25, max_iterations=1000,
                        step_timeout_s=60.0, work_dir=tmp_path, observe_gain=True, **SHARED)
    env = FoamCaseEnv(cfg)
    try:
        obs, _ = env.reset(seed=0, options={"inlet_velocity": 50.0})
        assert obs[-1] == 0.0 and obs[-3:-1] == pytest.approx([0.5, 0.5])  # the factors, then the gain
        distances, gains = [], []
        for _ in range(3):
            obs, _, terminated, _, info = env.step(np.array([0.8, 0.8]))
            assert not terminated
            distances.append(criterion_distance(info["residuals"], cfg.convergence))
            gains.append(float(obs[-1]))
        assert gains[0] == 0.0  # no earlier boundary to gain on
        falls = [distances[0] - distances[1], distances[1] - distances[2]]
        assert gains[1:] == pytest.approx(falls, abs=1e-5)
        assert any(abs(g) > 1e-3 for g in gains[1:])  # the residuals moved: a gain that says something
    finally:
        env.close()


def test_pivot_at_own_puts_share_one_half_at_the_case_s_own_factors() -> None:
    template = FoamEnvConfig(action_low=(0.35, 0.15, 0.35), action_high=(0.875, 0.375, 0.875),
                             relax_k_omega="action", action_share=True, pivot_at="own")
    plain = around_own(template, CaseSettings((0.7, 0.3, 0.7), False, None, "SIMPLE")).validate()
    assert plain.action_pivot == (0.7, 0.3, 0.7)
    assert factors_of(plain, [0.5] * 3) == pytest.approx([0.7, 0.3, 0.7])
    simplec = around_own(template, CaseSettings((0.9, None, 0.9), False, None, "SIMPLEC")).validate()
    assert simplec.action_pivot == (0.9, 1.0, 0.9)  # p unrelaxed: 1
    assert factors_of(simplec, [0.0, 0.5, 1.0]) == pytest.approx([0.9, 1.0, 0.95])  # never below own alpha_u
    assert "pivot_at" not in FoamEnvConfig().to_json() and FoamEnvConfig.from_json(plain.to_json()) == plain
    with pytest.raises(ValueError, match="pivot_at"):
        FoamEnvConfig(pivot_at="mine").validate()


def test_a_radius_moves_every_factor_alike_both_ways_from_the_pivot() -> None:
    cfg = FoamEnvConfig(action_low=(0.2, 0.2, 0.2), action_high=(0.95, 0.95, 0.95), relax_k_omega="action",
                        action_share=True, action_pivot=(0.7, 0.3, 0.9), action_radius=0.2)
    assert factors_of(cfg, [0.5] * 3) == pytest.approx([0.7, 0.3, 0.9])
    # a share of 0.25 either way of one half is 0.1 either way of the pivot (the piecewise map: 0.25 down
    # and 0.0625 up for alpha_u), and the box still bounds it
    assert factors_of(cfg, [0.25, 0.25, 0.75]) == pytest.approx([0.6, 0.2, 0.95])
    assert factors_of(cfg, [0.75, 0.0, 1.0]) == pytest.approx([0.8, 0.2, 0.95])
    for factors in ([0.7, 0.3, 0.9], [0.55, 0.45, 0.75], [0.85, 0.2, 0.95]):
        assert factors_of(cfg, shares_of(cfg, factors)) == pytest.approx(factors)
    assert shares_of(cfg, [0.2, 0.95, 0.9]) == pytest.approx([0.0, 1.0, 0.5])  # beyond the radius: its edge
    centred = FoamEnvConfig(action_low=(0.2, 0.4), action_high=(0.6, 1.0), action_share=True,
                            action_radius=0.1)
    assert factors_of(centred, [0.5, 1.0]) == pytest.approx([0.4, 0.8])  # no pivot: the box's centre
    assert FoamEnvConfig.from_json(cfg.to_json()) == cfg and "action_radius" not in FoamEnvConfig().to_json()
    for bad in (0.0, -0.1, 1.5, True):
        with pytest.raises(ValueError, match="action_radius"):
            FoamEnvConfig(action_radius=bad).validate()
