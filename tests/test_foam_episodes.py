"""foam_bridge._episodes: the episode pool under grid-foam, eval-foam and policy rollouts.

The pool test runs real simpleFoam on the coarse mesh (0.4): a queue longer than the pool, each job with
its own reset options and its own kind of controller, and one job that fails without stopping the rest.
"""

from __future__ import annotations

import numpy as np
import pytest
from foam_marks import needs_openfoam

from foam_bridge import EpisodeJob, run_episodes
from foam_bridge._config import FoamEnvConfig
from foam_bridge._episodes import check_pool

FACTORS = (0.95, 0.3)  # converges in a few hundred iterations on mesh 0.4


class Recorder:
    """A batched controller (begin / act / end) that keeps every call it gets."""

    def __init__(self) -> None:
        self.calls: list[tuple] = []

    def begin(self, uid: int) -> None:
        self.calls.append(("begin", uid))

    def act(self, uids, obs, steps) -> np.ndarray:
        self.calls.append(("act", tuple(uids), tuple(steps)))
        return np.tile(FACTORS, (len(uids), 1))

    def end(self, uid: int) -> None:
        self.calls.append(("end", uid))


@needs_openfoam
def test_a_queue_longer_than_the_pool_runs_each_job_with_its_own_options_and_controller(tmp_path):
    cfg = FoamEnvConfig(mesh_scale=0.4, max_iterations=600, interval=100)
    recorder, seen = Recorder(), []
    jobs = [EpisodeJob(0, FACTORS, seed=0, options={"inlet_velocity": 40.0}),
            EpisodeJob(1, lambda obs: (np.nan, np.nan), seed=1),  # the env rejects the action: crashed
            EpisodeJob(2, recorder, seed=2, options={"inlet_velocity": 60.0}),
            EpisodeJob(3, lambda obs: seen.append(obs) or FACTORS, seed=3, options={"inlet_velocity": 60.0})]
    ended: list[tuple[int, list[str]]] = []  # each job as it ended, and the env directories then

    def on_result(run) -> None:
        ended.append((run.job.uid, sorted(path.name for path in tmp_path.iterdir())))

    runs = run_episodes(cfg, jobs, pool=2, work_dir=tmp_path, fields=True, on_result=on_result)

    assert [run.job.uid for run in runs] == [0, 1, 2, 3] and sorted(uid for uid, _ in ended) == [0, 1, 2, 3]
    assert {name for _, names in ended for name in names} == {"env_0", "env_1"}  # two slots for four jobs
    failed = runs[1]
    assert failed.outcome == "crashed" and "finite" in failed.cause
    assert failed.record is not None and failed.record.outcome == "crashed"  # the batch core's record
    assert failed.iterations == 0 and len(failed.trace) == 1 and np.isnan(failed.trace[0].reward)
    for run in runs[:1] + runs[2:]:
        assert run.outcome == "converged", run.cause
        assert run.record is not None and run.record.seed == run.job.seed
        assert run.record.inlet_velocity == run.job.options["inlet_velocity"]
        assert run.actions == [list(FACTORS)] * len(run.trace) and run.iterations == run.record.iterations
        assert run.cost is not None and run.cost.of("p") > 0 and run.final_u is not None
    # the same options and factors make the same episode, whichever controller gave the factors
    assert runs[2].iterations == runs[3].iterations != runs[0].iterations
    assert len(seen) == len(runs[3].trace)
    steps = len(runs[2].trace)
    assert recorder.calls == [("begin", 2), *(("act", (2,), (t,)) for t in range(steps)), ("end", 2)]


def test_bad_pool_and_duplicate_uids_are_one_line_errors():
    for pool in (0, -1, 1.5, True, "2"):
        with pytest.raises(ValueError, match="pool must be an integer >= 1"):
            check_pool(pool)
    jobs = [EpisodeJob(0, FACTORS), EpisodeJob(0, FACTORS)]
    with pytest.raises(ValueError, match="its own uid"):
        run_episodes(FoamEnvConfig(), jobs, pool=1)
    assert run_episodes(FoamEnvConfig(), [], pool=1) == []
