"""The Ray backend against a real local Ray instance: same seeds and actions -> same iteration counts
as the local process pool. Real simpleFoam, the smallest usable mesh (0.4)."""

from __future__ import annotations

import numpy as np
import pytest
from foam_marks import needs_openfoam

from foam_bridge._batched import BatchedFoamEnv
from foam_bridge._config import FoamEnvConfig

pytestmark = pytest.mark.slow  # a local Ray instance and its workers: tens of seconds

COARSE = FoamEnvConfig(mesh_scale=0.4, simple_variant="SIMPLEC", relax_k_omega=0.8, max_iterations=200,
                       step_timeout_s=60.0)
# Different factors per env and per step, so a mix-up of envs or steps would change the residuals; all
# in the region that neither crashes nor diverges on this mesh within the cap.
ACTIONS = np.array([[[0.9, 0.5], [0.8, 0.5]], [[0.95, 0.5], [0.85, 0.6]], [[0.9, 0.55], [0.9, 0.5]]])


def rollout(backend: str, work_dir) -> dict[str, list]:
    """Iterations, rewards, outcomes and inlet velocities over ACTIONS (the cap forces an auto-reset)."""
    seen: dict[str, list] = {"iterations": [], "reward": [], "velocity": [], "final": [], "residuals": []}
    with BatchedFoamEnv(COARSE, 2, backend=backend, pool=2, work_dir=work_dir, seed=11) as env:
        _, infos = env.reset()
        seen["velocity"].append(infos["inlet_velocity"].tolist())
        for actions in ACTIONS:
            _, reward, _, _, infos = env.step(actions)
            seen["iterations"].append(infos["iterations"].tolist())
            seen["reward"].append(reward.tolist())
            seen["velocity"].append(infos["inlet_velocity"].tolist())
            seen["residuals"].append({k: v.tolist() for k, v in infos["residuals"].items() if k[0] != "_"})
            if "final_info" in infos:
                seen["final"].append(infos["final_info"]["iterations"].tolist())
    return seen


@needs_openfoam
def test_ray_backend_matches_the_local_pool(tmp_path):
    ray = pytest.importorskip("ray")
    local = rollout("local", tmp_path / "local")
    # "local": a Ray instance of its own, even where another (a cluster test's) runs on the machine
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        remote = rollout("ray", tmp_path / "ray")
    finally:
        ray.shutdown()
    assert remote == local
    assert local["final"], "the 200-iteration cap should have ended the first episodes"
    assert local["iterations"][-1] == [100, 100]  # the new episodes after the auto-reset
