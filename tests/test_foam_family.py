"""What the foam env offers a controller (issue 18, section 1), on the real simpleFoam (mesh 0.4):
the k/omega factor as a third action, the closed-loop observation, and a family of step heights."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import numpy as np
import pytest
from foam_marks import needs_openfoam
from foamlib import FoamFile

from foam_bridge import _episode_case as episode_case
from foam_bridge import _template as template
from foam_bridge._config import STEP_HEIGHT_H, FoamEnvConfig
from foam_bridge._confirm import _checked_fields, confirm, meets
from foam_bridge._env import FoamCaseEnv, observation_spec

H, H2 = STEP_HEIGHT_H, 2 * STEP_HEIGHT_H


def _cfg(tmp_path, **overrides) -> FoamEnvConfig:
    base = dict(mesh_scale=0.4, inlet_velocity=50.0, max_iterations=1500, step_timeout_s=60.0,
                work_dir=tmp_path)
    return FoamEnvConfig(**{**base, **overrides})


def _history(cfg: FoamEnvConfig, action, steps: int = 1) -> list[dict]:
    with FoamCaseEnv(cfg) as env:
        env.reset(seed=0)
        for _ in range(steps):
            env.step(action)
        return list(env.parser.history)


def _episode(env: FoamCaseEnv, action) -> dict:
    env.reset(seed=0)
    while True:
        _, _, terminated, _, info = env.step(action)
        if terminated:
            return info["episode"]


def test_the_third_action_sets_the_box_and_its_text():
    cfg = FoamEnvConfig(relax_k_omega="action").validate()
    assert cfg.action_size == 3 and cfg.action_low == (0.2,) * 3 and cfg.action_high == (0.95,) * 3
    text = FoamFile.loads(episode_case.relaxation_text(cfg, 0.9, 0.5, alpha_t=0.3))["relaxationFactors"]
    assert text["equations"] == {"U": 0.9, "k": 0.3, "omega": 0.3} and text["fields"] == {"p": 0.5}
    own = FoamFile.loads(episode_case.relaxation_text(cfg, 0.9, 0.5))["relaxationFactors"]  # no alpha_t
    assert "k" not in own["equations"]
    with pytest.raises(ValueError, match="3 values each"):
        FoamEnvConfig(relax_k_omega="action", action_low=(0.2, 0.3)).validate()
    assert FoamEnvConfig().action_size == 2 and FoamEnvConfig().action_low == (0.2, 0.2)


@pytest.mark.slow  # real runs
@needs_openfoam
def test_alpha_t_reaches_the_solver(tmp_path):
    """The same seed and (alpha_u, alpha_p): k's residuals differ between alpha_t 0.3 and 0.9 from the
    first k solve on, U's first one does not; and alpha_t 0.3 as an action is exactly k/omega fixed at 0.3."""
    three = _cfg(tmp_path / "a", relax_k_omega="action", max_iterations=200)
    low = _history(three, (0.9, 0.8, 0.3))
    high = _history(dataclasses.replace(three, work_dir=tmp_path / "b"), (0.9, 0.8, 0.9))
    assert low[0]["Ux"] == high[0]["Ux"]
    assert low[0]["k"] != high[0]["k"] and low[5]["omega"] != high[5]["omega"]
    fixed = _history(_cfg(tmp_path / "c", relax_k_omega=0.3, max_iterations=200), (0.9, 0.8))
    assert fixed == low


@pytest.mark.slow  # real runs
@needs_openfoam
def test_the_convergence_check_reads_k_and_omega_at_its_own_fixed_factor(tmp_path):
    """With alpha_t an action the agent moves the k/omega residuals the criterion reads, as alpha_u moves
    U's: the check relaxes k and omega at confirm_alpha_u, whatever the step's alpha_t, and checks them
    when the step relaxed them below it (tests/test_foam_confirm.py). An episode at alpha_t 0.95 is
    checked as if k/omega were fixed at confirm_alpha_u (0.9), and a check at another fixed factor reads
    other residuals (so the comparison could fail)."""
    cfg = _cfg(tmp_path / "three", relax_k_omega="action", confirm_alpha_u=0.9)
    with FoamCaseEnv(cfg) as env:
        record = _episode(env, (0.95, 0.875, 0.95))
        check = record["confirmations"][-1]
        at_09, at_03 = (confirm(env.case_dir, env.base, dataclasses.replace(env.cfg, relax_k_omega=fixed),
                                env.openfoam, check["iteration"], 0.875, {}, turbulence=("k", "omega"))
                        for fixed in (0.9, 0.3))
    assert record["outcome"] == "converged" and record["actions"][0] == [0.95, 0.875, 0.95]
    assert at_09.residuals == check["residuals"]  # the step's alpha_t (0.95) does not count
    assert at_03.residuals["k"] != check["residuals"]["k"] and at_03.residuals["U"] == check["residuals"]["U"]
    assert _checked_fields(cfg, ("k", "omega")) == ("U", "k", "omega")
    assert _checked_fields(dataclasses.replace(cfg, relax_k_omega=0.9)) == ("U",)
    # a k residual over the criterion fails the check even when U meets it
    assert not meets(cfg, {**check["residuals"], "k": 2 * cfg.convergence["k"]}, ("U", "k", "omega"))


@pytest.mark.slow  # real runs
@needs_openfoam
def test_the_closed_loop_observation(tmp_path):
    cfg = _cfg(tmp_path, relax_k_omega="action", residual_features=1, observe_progress=True,
               observe_action=True, scale_free_state=True, max_iterations=300)
    fields = len(cfg.convergence)
    assert cfg.observation_size == 1 + fields + 1 + 3
    spec = observation_spec(cfg)
    with FoamCaseEnv(cfg) as env:
        obs, _ = env.reset(seed=0, options={"inlet_velocity": 25.0})
        assert obs.shape == (cfg.observation_size,)
        np.testing.assert_allclose(obs[0], 1.0, rtol=1e-6)  # the cells start at rest: inlet / inlet
        assert obs[1 + fields] == 0.0  # no iteration yet
        np.testing.assert_allclose(obs[-3:], [0.575] * 3)  # before any action: the box centre
        slow = obs.copy()
        fast, _ = env.reset(seed=0, options={"inlet_velocity": 60.0})
        np.testing.assert_array_equal(slow, fast)  # scale-free: 25 and 60 m/s look alike at iteration 0
        progress = []
        for action in [(0.9, 0.8, 0.7), (1.5, 0.1, 0.5)]:  # the second is clipped into the box
            obs, _, _, _, info = env.step(action)
            progress.append(obs[1 + fields])
            assert np.all(obs >= spec.low) and np.all(obs <= spec.high) and np.all(np.isfinite(obs))
        np.testing.assert_allclose(obs[-3:], np.float32([0.95, 0.2, 0.5]))
        assert progress == [np.float32(100 / 300), np.float32(200 / 300)]
        assert np.all(obs[1:1 + fields] < 0)  # log10 residuals of the last boundary
        assert obs[0] > 1.0  # the cells have picked up speed
    paper = _cfg(tmp_path / "paper")
    with FoamCaseEnv(paper) as env:
        slow, _ = env.reset(seed=0, options={"inlet_velocity": 25.0})
        fast, _ = env.reset(seed=0, options={"inlet_velocity": 60.0})
    assert slow.shape == (1,) and fast[0] > 5 * slow[0]  # the paper's state names the speed


@needs_openfoam
def test_a_family_of_step_heights(tmp_path):
    family = _cfg(tmp_path / "family", inlet_velocity=None, step_height=(H, H2))
    with FoamCaseEnv(family) as env:
        drawn = []
        for seed in (1, 2, 3, 1):
            _, info = env.reset(seed=seed)
            cells = template.cell_count(env.base)
            floor = FoamFile(env.base / "system" / "meshParameters")["yFloor"]
            drawn.append((info["step_height"], info["inlet_velocity"], cells, floor))
        _, info = env.reset(seed=1, options={"step_height": H2})
        fixed = (info["step_height"], template.cell_count(env.base))
        with pytest.raises(ValueError, match="step_height"):
            env.reset(options={"step_height": -1.0})
    heights = [d[0] for d in drawn]
    assert all(H <= h <= H2 for h in heights) and len(set(heights[:3])) == 3
    assert drawn[0] == drawn[3]  # reproducible per seed, the mesh with it
    assert len({d[2] for d in drawn[:3]}) == 3 and len({d[3] for d in drawn[:3]}) == 3
    assert all(floor == pytest.approx(1 - height / H) for height, _, _, floor in drawn)
    rng = np.random.default_rng(1)  # the height is drawn after the velocity, from the same stream
    assert drawn[0][1] == rng.uniform(35.0, 65.0) and drawn[0][0] == rng.uniform(H, H2)
    with FoamCaseEnv(_cfg(tmp_path / "2h", step_height=H2)) as env:
        assert fixed == (H2, template.cell_count(env.base))


@needs_openfoam
def test_a_fixed_height_draws_the_velocities_it_always_drew(tmp_path):
    """Today's stream (HEAD): one uniform draw in [35, 65] per reset; a fixed height adds none."""
    with FoamCaseEnv(_cfg(tmp_path, inlet_velocity=None)) as env:
        env.reset(seed=7)
        velocities = [env.reset()[1]["inlet_velocity"] for _ in range(5)]
        _, info = env.reset()
    rng = np.random.default_rng(7)
    expected = [rng.uniform(35.0, 65.0) for _ in range(6)][1:]
    assert velocities == expected and info["step_height"] == H


TUTORIALS = Path("/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam")


@pytest.mark.slow  # real runs
@needs_openfoam
@pytest.mark.skipif(not (TUTORIALS / "pitzDaily").is_dir(), reason="openfoam-examples not installed")
def test_alpha_t_relaxes_a_users_own_turbulence_fields(tmp_path):
    """pitzDaily runs k-epsilon: alpha_t relaxes k and epsilon, found from its dry run; its box gains
    alpha_u's bounds for alpha_t; a step height is refused."""
    from jaxsimrl.apps.foam.config import user_case_config

    case = tmp_path / "pitzDaily"
    shutil.copytree(TUTORIALS / "pitzDaily", case)
    cfg = FoamEnvConfig(case_dir=case, relax_k_omega="action", interval=5, max_iterations=10,
                        action_low=(0.2,) * 3, action_high=(0.95,) * 3, work_dir=tmp_path / "work")
    histories = []
    for alpha_t in (0.3, 0.7):
        with FoamCaseEnv(dataclasses.replace(cfg, work_dir=tmp_path / f"work{alpha_t}")) as env:
            assert sorted(env._turbulence) == ["epsilon", "k"]
            env.reset(seed=0)
            env.step((0.7, 0.3, alpha_t))
            histories.append(list(env.parser.history))
            with pytest.raises(ValueError, match="built-in"):
                env.reset(options={"step_height": H})
    low, high = histories
    assert low[0]["Ux"] == high[0]["Ux"]
    assert low[3]["k"] != high[3]["k"] and low[3]["epsilon"] != high[3]["epsilon"]  # (1.0 at iteration 1)
    own = user_case_config(cfg, explicit=["convergence"])  # the box: the case's own, with alpha_t
    assert len(own.action_low) == 3 and own.action_low[2] == own.action_low[0]


@pytest.mark.slow  # real runs
@needs_openfoam
def test_the_gym_env_takes_the_new_fields(tmp_path):
    import gymnasium

    import foam_bridge

    env = gymnasium.make(foam_bridge.ENV_ID, mesh_scale=0.4, max_iterations=200, relax_k_omega="action",
                         step_height=[H, H2], observe_progress=True, observe_action=True,
                         work_dir=str(tmp_path))
    try:
        assert env.action_space.shape == (3,) and env.observation_space.shape == (1 + 1 + 3,)
        obs, info = env.reset(seed=4)
        assert H <= info["step_height"] <= H2 and env.observation_space.contains(obs)
        obs, _, _, _, info = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs) and info["iterations"] == 100
    finally:
        env.close()
