"""Solver and worker faults: exact pauses, bounded waits, no kill by a reaped group id, no orphaned solver.

The first tests drive FoamSolver with stand-in "simpleFoam" shell scripts (shell builtins only), so a
fault can be staged exactly and cheaply; the others run the real simpleFoam on the smallest usable
mesh (0.4) with short intervals.
"""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from foam_marks import needs_openfoam
from foamlib import FoamFile
from slow_case import STOP_LIMIT_S, episode_progress, seconds_until, slow_pitz_daily, wait_until

from foam_bridge import _solver as foam_solver
from foam_bridge._backends import Request, env_dir, make_backend
from foam_bridge._backends.reaper import processes_under
from foam_bridge._batched import BatchedFoamEnv
from foam_bridge._config import U_REF, FoamEnvConfig
from foam_bridge._env import FoamCaseEnv
from foam_bridge._episode_case import CONTROL_INCLUDE, PAUSE_FUNCTION
from foam_bridge._logparse import LogParser
from foam_bridge._openfoam import OpenFOAM
from foam_bridge._solver import EXITED, HUNG, MISSED, PAUSED, FoamSolver
from jaxsimrl.envs.host import HostVecEnv

COARSE = FoamEnvConfig(mesh_scale=0.4, interval=10, max_iterations=300, step_timeout_s=60.0)
ACTION = (0.9, 0.5)
#: Shell function of the stand-ins: copy FIFO $1 line by line into the file $2 (builtins only: no PATH).
READ_FACTORS = ('read_factors() { : > "$2"; while IFS= read -r line; do printf "%s\\n" "$line" >> "$2"; '
                'done < "$1"; }')


# ----- stand-in solvers ---------------------------------------------------------------------------
def _fake_solver(tmp_path: Path, script: str, boundaries=(0, 1, 2)) -> FoamSolver:
    """A FoamSolver whose 'simpleFoam' is ``script`` (run in the case directory)."""
    bin_dir, case = tmp_path / "bin", tmp_path / "case"
    (case / "system" / "foamBridge").mkdir(parents=True)
    bin_dir.mkdir()
    for boundary in boundaries:
        os.mkfifo(_fifo(case, boundary))
    program = bin_dir / "simpleFoam"
    program.write_text("#!/bin/sh\n" + READ_FACTORS + "\n" + textwrap.dedent(script))
    program.chmod(0o755)
    parser = LogParser("foamBridgeCells", "foamBridgeInlet")
    solver = FoamSolver(case, OpenFOAM(str(bin_dir), str(tmp_path)), parser, lambda k: _fifo(case, k))
    solver.start()
    return solver


def _fifo(case: Path, boundary: int) -> Path:
    return case / "system" / "foamBridge" / f"relaxation.{boundary}"


def _iteration(k: int) -> str:
    return f"printf 'Time = {k}\\nExecutionTime = 0 s\\n'\n"


def test_every_pause_gets_its_factors_without_trusting_a_log_line(tmp_path):
    # the stand-in never prints "Re-reading object fvSolution": its reads are served all the same
    solver = _fake_solver(tmp_path, f"""
        read_factors system/foamBridge/relaxation.0 got.0
        {_iteration(1)}read_factors system/foamBridge/relaxation.1 got.1
        {_iteration(2)}""")
    _serve_two_pauses(solver)
    assert (solver.case / "got.0").read_text() == "first\n"
    assert (solver.case / "got.1").read_text() == "second\n"


def _serve_two_pauses(solver: FoamSolver) -> None:
    """Start-up pause, "first"; the pause after iteration 1, "second"; then the stand-in exits."""
    try:
        assert solver.wait(5, 0) == PAUSED
        solver.release(b"first\n")
        assert solver.wait(5, 1) == PAUSED and solver.parser.completed == 1
        solver.release(b"second\n")
        assert solver.wait(5, 2) == EXITED
    finally:
        assert solver.kill() == 0


REREAD = "printf 'Re-reading object fvSolution from file \"x\" because of modified file \"y\"\\n'\n"


def test_a_re_read_of_the_served_fifo_gets_the_same_factors_again(tmp_path):
    # OpenFOAM watches fvSolution's includes: a FIFO's changed mtime can make it re-read fvSolution
    solver = _fake_solver(tmp_path, f"""
        read_factors system/foamBridge/relaxation.0 got.0
        {REREAD}read_factors system/foamBridge/relaxation.0 got.again
        {_iteration(1)}read_factors system/foamBridge/relaxation.1 got.1""")
    _serve_two_pauses(solver)
    assert (solver.case / "got.again").read_text() == "first\n"
    assert (solver.case / "got.1").read_text() == "second\n"


def test_serving_a_fifo_leaves_its_mtime_as_it_was(tmp_path):
    solver = _fake_solver(tmp_path, f"read_factors system/foamBridge/relaxation.0 got.0\n{_iteration(1)}")
    fifo = solver.fifo(0)
    before = os.stat(fifo).st_mtime_ns
    time.sleep(0.02)
    try:
        assert solver.wait(5, 0) == PAUSED
        solver.release(b"first\n")
        assert solver.wait(5, 1) == EXITED
    finally:
        solver.kill()
    assert os.stat(fifo).st_mtime_ns == before and (solver.case / "got.0").read_text() == "first\n"


def test_a_reader_without_a_re_read_line_gets_nothing_and_the_step_hangs(tmp_path):
    solver = _fake_solver(tmp_path, """
        read_factors system/foamBridge/relaxation.0 got.0
        read_factors system/foamBridge/relaxation.0 got.again""")
    try:
        assert solver.wait(5, 0) == PAUSED
        solver.release(b"first\n")
        assert solver.wait(1.0, 1) == HUNG  # a failure with a cause, never an unexplained read
    finally:
        solver.kill()
    assert not (solver.case / "got.again").exists() or (solver.case / "got.again").read_text() == ""


def test_a_solver_that_runs_past_its_pause_is_stopped_as_missed(tmp_path):
    solver = _fake_solver(tmp_path, f"""
        read_factors system/foamBridge/relaxation.0 got.0
        {_iteration(1)}{_iteration(2)}read_factors system/foamBridge/relaxation.2 got.2""")
    try:
        assert solver.wait(5, 0) == PAUSED
        solver.release(b"first\n")
        assert solver.wait(5, 1) == MISSED  # not a silent step of 2 x interval
        assert solver.parser.completed == 2
    finally:
        solver.kill()


def test_a_solver_that_closes_its_output_but_lives_on_is_hung_at_the_deadline(tmp_path):
    solver = _fake_solver(tmp_path, "exec >&- 2>&-\nread_factors system/foamBridge/relaxation.1 never\n")
    start = time.monotonic()
    try:
        assert solver.wait(1.0, 0) == HUNG
        assert time.monotonic() - start < 3.0  # the wait after EOF obeys the watchdog
    finally:
        assert solver.kill() == -signal.SIGKILL


def test_the_group_is_killed_before_its_leader_is_reaped(tmp_path, monkeypatch):
    solver = _fake_solver(tmp_path, _iteration(1) + "exit 3\n")
    assert solver.wait(5, 1) == EXITED
    pid = solver.process.pid
    states, real_killpg = [], os.killpg

    def recording_killpg(pgid, sig):
        with open(f"/proc/{pid}/stat") as handle:  # FileNotFoundError if the leader were reaped
            states.append(handle.read().split(")")[-1].split()[0])
        real_killpg(pgid, sig)

    monkeypatch.setattr(foam_solver.os, "killpg", recording_killpg)
    assert solver.kill() == 3
    assert states == ["Z"]  # a zombie holds the group id: it cannot belong to anyone else yet


def test_a_solver_dies_with_the_process_that_started_it(tmp_path):
    """PR_SET_PDEATHSIG: SIGKILL the owner, and its solver goes with it, whoever else noticed."""
    script = tmp_path / "owner.py"
    script.write_text(textwrap.dedent(f"""
        import sys, time
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from pathlib import Path
        from test_foam_faults import _fake_solver
        solver = _fake_solver(Path(sys.argv[1]), "read_factors system/foamBridge/relaxation.0 got.0\\n")
        print(solver.process.pid, flush=True)
        time.sleep(600)
    """))
    owner = subprocess.Popen([sys.executable, str(script), str(tmp_path)], stdout=subprocess.PIPE, text=True,
                             env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    try:
        solver_pid = int(owner.stdout.readline())
        assert _alive(solver_pid)
        owner.kill()
        owner.wait()
        assert _gone_within(lambda: not _alive(solver_pid), 5.0)
    finally:
        owner.kill()
        owner.wait()


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as handle:
            return handle.read().split(")")[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def _gone_within(condition, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True


# ----- real simpleFoam ----------------------------------------------------------------------------
@needs_openfoam
def test_a_missed_pause_ends_the_episode_with_a_cause(tmp_path):
    with FoamCaseEnv(dataclasses.replace(COARSE, work_dir=tmp_path)) as env:
        env.reset(seed=0)
        with FoamFile(env.case_dir / "system" / CONTROL_INCLUDE) as control:  # drop the pause at 20
            pauses = control["functions"][PAUSE_FUNCTION]["timeVsFile"]
            control["functions"][PAUSE_FUNCTION]["timeVsFile"] = [p for p in pauses if p[0] != 20]
        _, reward, _, _, info = env.step(ACTION)
        assert (reward, info["iterations"], info["outcome"]) == (-10.0, 10, "running")
        _, reward, terminated, _, info = env.step(ACTION)
    assert terminated and info["outcome"] == "crashed" and info["iterations"] == 20
    assert info["cause"].startswith("missed the pause after iteration 20")
    assert reward == -(COARSE.max_iterations - 10)


@needs_openfoam
def test_an_interrupted_batch_does_not_poison_the_next(tmp_path):
    backend = make_backend("local", COARSE, 1, 1, tmp_path)
    try:
        real_receive = backend._receive

        def interrupted(*args, **kwargs):
            raise KeyboardInterrupt

        backend._receive = interrupted
        with pytest.raises(KeyboardInterrupt):
            backend.run([Request(0, "reset", {"seed": 0, "options": {"inlet_velocity": 40.0}})])
        backend._receive = real_receive
        (reply,) = backend.run([Request(0, "reset", {"seed": 0, "options": {"inlet_velocity": 50.0}})])
        assert reply.ok and reply.value[1]["inlet_velocity"] == 50.0  # its own reply, not the stale one
        assert reply.value[0][0] == pytest.approx(50.0**2 / U_REF**2)
        (reply,) = backend.run([Request(0, "step", {"action": np.array(ACTION)})])
        assert reply.ok and reply.value[4]["iterations"] == 10
    finally:
        backend.close()


def _dying_start(backend, worker: int) -> None:
    """A stand-in for LocalBackend._start whose worker dies at once (a node out of memory, say)."""
    parent_end, child_end = backend._ctx.Pipe()
    proc = backend._ctx.Process(target=os._exit, args=(3,), daemon=True)
    proc.start()
    child_end.close()
    backend._procs[worker], backend._conns[worker] = proc, parent_end


@pytest.mark.slow  # a fault test of many episodes
@needs_openfoam
def test_failed_auto_resets_never_raise_nor_misplace_an_action(tmp_path, monkeypatch):
    actions = np.tile(ACTION, (2, 1))
    with BatchedFoamEnv(COARSE, 2, pool=2, work_dir=tmp_path, seed=4) as env:
        env.reset()
        env.step(actions)
        monkeypatch.setattr(env.backend, "_start", lambda worker: _dying_start(env.backend, worker))
        os.kill(env.worker_pids()[0], signal.SIGKILL)
        # the step's worker death, then every replacement dies in the auto-reset: no exception
        obs, reward, terminated, truncated, infos = env.step(actions)
        assert terminated.tolist() == [True, False] and infos["final_info"]["cause"][0] == "worker died"
        assert reward[1] == -10.0 and infos["iterations"][1] == 20  # the other env went on
        # still no episode for env 0: its next step is a failed one of 0 iterations, again no exception
        obs, reward, terminated, truncated, infos = env.step(actions)
        assert terminated[0] and infos["final_info"]["cause"][0].startswith("reset failed: worker died")
        assert reward[0] == -COARSE.max_iterations and infos["final_info"]["iterations"][0] == 0
        monkeypatch.undo()  # workers start again: env 0 is reset before its next step ...
        _the_retried_reset_is_a_non_transition(env, stale=obs[0])
        obs, reward, terminated, truncated, infos = env.step(actions)  # its first action, chosen from obs[0]
        assert infos["outcome"].tolist() == ["running", "running"]
        assert infos["iterations"].tolist() == [10, 50] and reward.tolist() == [-10.0, -10.0]
        assert env.snapshot()[0]["actions"] == [list(ACTION)]


def _the_retried_reset_is_a_non_transition(env: BatchedFoamEnv, stale: np.ndarray) -> None:
    """... but the action its policy chose from ``stale`` (the ended episode's last observation) is not
    applied: what the trainer stores (HostVecEnv) is reward 0, truncated (bootstrapped from ``stale``),
    and no episode; the next observation is the new episode's first."""
    episodes: list[int] = []
    host = HostVecEnv(env, on_episode=lambda i, info: episodes.append(i))
    out = host._host_step(np.zeros(2, np.int32), np.array([(0.3, 0.3), ACTION]))
    assert host.error is None and episodes == [] and out.state.tolist() == [0, 0]
    assert (out.reward[0], out.terminated[0], out.truncated[0]) == (0.0, False, True)
    np.testing.assert_array_equal(out.final_obs[0], stale)
    # the new episode's first observation: the internal field at rest, so the state is the inlet's |U|^2
    assert out.obs[0][0] == pytest.approx(env._tallies[0].inlet_velocity ** 2 / COARSE.state_scale, rel=1e-3)
    assert env.iterations().tolist() == [0, 40] and env.snapshot()[0]["actions"] == []


DRIVER = """
import json, sys
from foam_bridge._async_batch import AsyncFoamEnv
from foam_bridge._batched import BatchedFoamEnv
from foam_bridge._config import FoamEnvConfig

if __name__ == "__main__":
    cfg = FoamEnvConfig(mesh_scale=0.4, interval=10, max_iterations=300, step_timeout_s=60.0)
    if sys.argv[2] == "lock-step":
        env = BatchedFoamEnv(cfg, 2, pool=2, work_dir=sys.argv[1], seed=0)
        env.reset()
        env.step([[0.9, 0.5]] * 2)  # both solvers now wait at their pause after iteration 10
    else:  # the asynchronous batch: both envs sent a step, both results back
        env = AsyncFoamEnv(cfg, 2, 2, pool=2, work_dir=sys.argv[1], seed=0)
        env.async_reset()
        ids, *_ = env.recv()
        env.send([[0.9, 0.5]] * 2, ids)
        env.recv()
    print(json.dumps(env.worker_pids()), flush=True)
    sys.stdin.read()
"""


def _solvers_under(path: Path) -> list[int]:
    found = []
    for pid in processes_under(path):
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as handle:
                if b"simpleFoam" in handle.read() and _alive(pid):
                    found.append(pid)
        except FileNotFoundError:
            pass
    return found


@pytest.mark.slow  # a fault test: processes killed mid-step
@needs_openfoam
@pytest.mark.parametrize("batch", ["lock-step", "async"])
@pytest.mark.parametrize("victims", [("worker",), ("driver",), ("driver", "workers")])
def test_kill_9_leaves_no_solver_behind(tmp_path, victims, batch):
    script = tmp_path / "driver.py"
    script.write_text(DRIVER)
    work = tmp_path / "work"
    driver = subprocess.Popen([sys.executable, str(script), str(work), batch], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True,
                              env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    try:
        workers = json.loads(driver.stdout.readline())
        assert len(_solvers_under(work)) == 2
        if "worker" in victims:
            os.kill(workers[0], signal.SIGKILL)
            assert _gone_within(lambda: not _solvers_under(env_dir(work, 0)), 5.0)
            assert len(_solvers_under(env_dir(work, 1))) == 1  # the other worker's solver is untouched
            return
        os.kill(driver.pid, signal.SIGKILL)
        if "workers" in victims:
            for pid in workers:
                os.kill(pid, signal.SIGKILL)
        assert _gone_within(lambda: not _solvers_under(work), 5.0)
    finally:
        driver.kill()
        driver.wait()
        for pid in _solvers_under(work):  # never leave one running, whatever failed
            os.killpg(pid, signal.SIGKILL)


@needs_openfoam
def test_close_after_an_interrupted_step_kills_the_busy_worker_at_once(tmp_path):
    """A batch interrupted mid-step (Ctrl-C, SIGTERM): close() does not wait for the step, which on a big
    mesh lasts minutes; it kills the worker and its solver. The solver is stopped here, so a close that
    waited for the step would wait for the env's own watchdog (30 s)."""
    cfg = dataclasses.replace(COARSE, step_timeout_s=30.0)
    env = BatchedFoamEnv(cfg, 1, pool=1, seed=0)  # a temporary work_dir, removed by close()
    env.reset()
    env.step(np.array([ACTION]))
    (solver,) = _solvers_under(env.work_dir)
    os.killpg(solver, signal.SIGSTOP)  # the next step hangs until the env's own watchdog fires
    real_receive = env.backend._receive

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    env.backend._receive = interrupted
    with pytest.raises(KeyboardInterrupt):
        env.step(np.array([ACTION]))
    env.backend._receive = real_receive
    worker = env.backend._procs[0]
    assert env.backend.busy() == {0}
    start = time.monotonic()
    env.close()
    assert time.monotonic() - start < STOP_LIMIT_S
    assert worker.exitcode == -signal.SIGKILL  # killed, not asked
    # the kill reaches the (stopped) solver through its parent-death signal; the kernel tears it down a
    # moment later (seen mid-exit, memory released and parent gone, 0.2 s after close returned): a solver
    # that close() missed stays stopped, and alive, for good
    assert _gone_within(lambda: not _alive(solver), 1.0)
    assert not env.work_dir.exists()


@needs_openfoam
def test_an_idle_worker_closes_its_envs_itself(tmp_path):
    env = BatchedFoamEnv(COARSE, 1, pool=1, seed=0)
    env.reset()
    env.step(np.array([ACTION]))
    (solver,) = _solvers_under(env.work_dir)
    worker = env.backend._procs[0]
    assert env.backend.busy() == set()
    env.close()
    assert worker.exitcode == 0  # it closed its env and left: not killed
    assert not _alive(solver) and not env.work_dir.exists()


MID_STEP_DRIVER = """
import json, sys
from foam_bridge._batched import BatchedFoamEnv
from foam_bridge._config import FoamEnvConfig

if __name__ == "__main__":
    cfg = FoamEnvConfig(case_dir=sys.argv[2], interval=100, max_iterations=300, step_timeout_s=600.0)
    env = BatchedFoamEnv(cfg, 1, pool=1, work_dir=sys.argv[1], seed=0)
    env.reset()
    print(json.dumps(env.worker_pids()), flush=True)
    env.step([[0.9, 0.9]])  # over a minute on the slowed case: the driver is killed in it
"""


@pytest.mark.slow  # slow_case: steps over a minute
@needs_openfoam
def test_a_driver_killed_mid_step_leaves_no_solver_after_5_s(tmp_path):
    """kill -9 of the driver while its worker is inside a step that lasts over a minute: the worker
    watches its driver, kills its solver and exits (the pipe alone would tell it only after the step)."""
    case = slow_pitz_daily(tmp_path / "slow")
    script = tmp_path / "driver.py"
    script.write_text(MID_STEP_DRIVER)
    work = tmp_path / "work"
    driver = subprocess.Popen([sys.executable, str(script), str(work), str(case)], stdout=subprocess.PIPE,
                              text=True, env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    try:
        (worker,) = json.loads(driver.stdout.readline())
        wait_until(lambda: max(episode_progress(work), default=0) >= 3, 120, "the step to be under way")
        assert max(episode_progress(work)) < 90 and len(_solvers_under(work)) == 1
        os.kill(driver.pid, signal.SIGKILL)
        assert seconds_until(lambda: not _solvers_under(work), 30.0) < STOP_LIMIT_S
        assert _gone_within(lambda: not _alive(worker), 5.0)
    finally:
        driver.kill()
        driver.wait()
        for pid in _solvers_under(work):  # never leave one running, whatever failed
            os.killpg(pid, signal.SIGKILL)
