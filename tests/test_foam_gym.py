"""The gymnasium ids registered by ``import foam_bridge``: the single env passes check_env, the pooled
vector env auto-resets in SAME_STEP mode. Real simpleFoam on the smallest usable mesh (mesh_scale 0.4), low
iteration cap."""

from __future__ import annotations

import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from foam_marks import needs_openfoam
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode

import foam_bridge
from foam_bridge._errors import OpenFOAMNotFoundError

COARSE = {"mesh_scale": 0.4, "simple_variant": "SIMPLEC", "relax_k_omega": 0.8, "max_iterations": 200,
          "step_timeout_s": 60.0}


def test_import_registers_the_id_without_jax():
    code = "import sys, gymnasium, foam_bridge; assert foam_bridge.ENV_ID in gymnasium.registry; " \
           "assert 'jax' not in sys.modules; print(gymnasium.spec(foam_bridge.ENV_ID).vector_entry_point)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "foam_bridge._gym_envs:RelaxationControlVecEnv"


@pytest.mark.parametrize("maker", [gym.make, lambda *a, **k: gym.make_vec(*a, num_envs=2, **k)])
def test_unknown_kwarg_is_a_value_error_naming_it(maker):
    with pytest.raises(ValueError, match="mesh_scal"):
        maker(foam_bridge.ENV_ID, mesh_scal=0.5)
    with pytest.raises(ValueError, match="mesh_scale"):
        maker(foam_bridge.ENV_ID, mesh_scale=-1.0)


def test_failed_construction_leaves_no_directory(tmp_path):
    with pytest.raises(ValueError, match="pool"):
        gym.make_vec(foam_bridge.ENV_ID, num_envs=2, pool=5, work_dir=str(tmp_path))
    with pytest.raises(OpenFOAMNotFoundError):
        gym.make(foam_bridge.ENV_ID, work_dir=str(tmp_path), openfoam_path=str(tmp_path / "no_openfoam"))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow  # gymnasium's checker: many real episodes
@needs_openfoam
def test_single_env_passes_check_env(tmp_path):
    env = gym.make(foam_bridge.ENV_ID, work_dir=str(tmp_path), **COARSE)
    try:
        check_env(env.unwrapped, skip_render_check=True)
        obs, info = env.reset(seed=3)
        assert env.observation_space.contains(obs)
        obs, reward, terminated, truncated, info = env.step(np.array([0.9, 0.5], np.float32))
        assert {"iterations", "residuals", "outcome"} <= set(info)
        assert info["iterations"] == 100 and reward == -100.0 and info["outcome"] == "running"
        assert set(info["residuals"]) >= {"U", "p"}
    finally:
        env.close()


@pytest.mark.slow  # real episodes to their end
@needs_openfoam
def test_vector_env_autoresets_in_the_same_step(tmp_path):
    envs = gym.make_vec(foam_bridge.ENV_ID, num_envs=2, pool=2, seed=0, work_dir=str(tmp_path), **COARSE)
    # The episode statistics wrapper CleanRL-style trainers use must understand the autoreset mode.
    envs = gym.wrappers.vector.RecordEpisodeStatistics(envs)
    try:
        assert envs.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
        assert envs.observation_space.shape == (2, 1) and envs.action_space.shape == (2, 2)
        first, infos = envs.reset(seed=5)
        assert first.shape == (2, 1) and envs.observation_space.contains(first)
        actions = np.tile(np.array([0.9, 0.5], np.float32), (2, 1))
        obs, reward, terminated, truncated, infos = envs.step(actions)
        assert not (terminated | truncated).any() and "final_info" not in infos
        assert infos["iterations"].tolist() == [100, 100]
        obs, reward, terminated, truncated, infos = envs.step(actions)
        # The 200-iteration cap ends both episodes (unless the solver converged first: terminated).
        done = terminated | truncated
        assert done.all() and infos["_final_info"].all() and infos["_final_obs"].all()
        assert set(infos["final_info"]["outcome"]) <= {"truncated", "converged"}
        assert (infos["final_info"]["iterations"] <= 200).all()
        assert all(final.shape == (1,) for final in infos["final_obs"])
        np.testing.assert_array_equal(infos["episode"]["r"], -infos["final_info"]["iterations"])
        assert infos["episode"]["l"].tolist() == [2, 2]
        # obs are the new episodes' first observations: the state at rest, |U_inlet|^2 / U_ref^2.
        velocities = infos["inlet_velocity"]
        np.testing.assert_allclose(obs[:, 0], velocities**2 / 44.2**2, rtol=1e-3)
        assert not np.allclose(obs[:, 0], [f[0] for f in infos["final_obs"]])
        obs, reward, terminated, truncated, infos = envs.step(actions)
        assert infos["iterations"].tolist() == [100, 100] and reward.tolist() == [-100.0, -100.0]
    finally:
        envs.close()
