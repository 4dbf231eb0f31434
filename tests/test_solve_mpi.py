"""``jaxsimrl solve --np N``: the case on N MPI ranks, handed back reconstructed; no rank outlives a stop.

Real mpirun and simpleFoam (Open MPI, OpenFOAM v1912). The quick tests check the pieces a parallel run
rests on (a rank escaping a process-group kill, bad input); the slow ones run pitzDaily on 2 ranks and
stop solves mid-step on tests/slow_case.py's pitzDaily, whose steps last over a minute, so that a rank
left running would still be seen after the 5 s allowed.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from foam_marks import needs_openfoam
from slow_case import STOP_LIMIT_S, TUTORIALS, iterations_in, seconds_until, slow_pitz_daily, wait_until

from foam_bridge._parallel import _write_decompose_dict, kill_session, session_processes
from jaxsimrl.apps.foam.solve.agreement import compare_results
from jaxsimrl.apps.foam.solve.own import run_own

PYTHON = sys.executable
FOAM_ENV = {**os.environ, "WM_PROJECT_DIR": os.environ.get("WM_PROJECT_DIR", "/usr/share/openfoam")}
MPI_ENV = {**FOAM_ENV, "OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1"}
needs_mpirun = pytest.mark.skipif(shutil.which("mpirun") is None, reason="no mpirun")


def _alive(pids: set[int]) -> set[int]:
    """Those of ``pids`` that still run (a zombie has finished)."""
    alive = set()
    for pid in pids:
        try:
            if Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z":
                alive.add(pid)
        except (OSError, IndexError):
            pass
    return alive


def _solvers_under(path: Path) -> list[int]:
    """Live simpleFoam/mpirun processes whose command line names a case under ``path``."""
    found = []
    for entry in Path("/proc").iterdir():
        try:
            words = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        text = b" ".join(words).decode(errors="replace")
        if ("simpleFoam" in text or "mpirun" in text) and str(path) in text and _alive({int(entry.name)}):
            found.append(int(entry.name))
    return found


def _cli(*args: str, cwd: Path) -> subprocess.Popen:
    return subprocess.Popen([PYTHON, "-m", "jaxsimrl", "solve", *args], cwd=cwd, env=FOAM_ENV,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_kill_session_reaches_children_in_process_groups_of_their_own() -> None:
    """What mpirun does to its ranks (setpgid), done by a small launcher: killpg misses them."""
    launcher = ("import os, subprocess, time\n"
                "children = [subprocess.Popen(['sleep', '300'], preexec_fn=os.setpgrp) for _ in range(2)]\n"
                "time.sleep(300)\n")
    shell = subprocess.Popen([PYTHON, "-c", launcher], start_new_session=True)
    try:
        wait_until(lambda: len(session_processes(shell.pid)) >= 3, 10, "the shell's two children")
        children = session_processes(shell.pid) - {shell.pid}
        assert all(os.getpgid(pid) != shell.pid for pid in children)
        os.killpg(shell.pid, signal.SIGKILL)
        time.sleep(0.2)
        assert _alive(children) == children  # the group kill left them
        kill_session(shell.pid)
        assert seconds_until(lambda: not _alive(children), 5.0) < STOP_LIMIT_S
    finally:
        kill_session(shell.pid)
        shell.wait()


@needs_mpirun
def test_mpirun_ranks_have_their_own_groups_and_kill_session_stops_them() -> None:
    mpirun = subprocess.Popen(["mpirun", "-np", "2", "--oversubscribe", "sleep", "300"], env=MPI_ENV,
                              start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        def ranks() -> set[int]:
            return {pid for pid in _alive(session_processes(mpirun.pid)) if pid != mpirun.pid
                    and Path(f"/proc/{pid}/comm").read_text().strip() == "sleep"}

        wait_until(lambda: len(ranks()) == 2, 30, "mpirun's two ranks")
        started = ranks()
        assert all(os.getpgid(pid) != mpirun.pid for pid in started)  # a killpg of mpirun misses them
        kill_session(mpirun.pid)
        assert seconds_until(lambda: not _alive(started), 5.0) < STOP_LIMIT_S
    finally:
        kill_session(mpirun.pid)
        mpirun.wait()


def test_decompose_dict_kept_when_it_asks_for_n_else_simple_slabs(tmp_path: Path) -> None:
    (tmp_path / "system").mkdir()
    path = tmp_path / "system" / "decomposeParDict"
    path.write_text("numberOfSubdomains 2;\nmethod hierarchical;\n")
    _write_decompose_dict(tmp_path, 2)
    assert "hierarchical" in path.read_text()
    _write_decompose_dict(tmp_path, 3)
    assert "numberOfSubdomains 3;" in path.read_text() and "n (3 1 1)" in path.read_text()


@needs_openfoam
@pytest.mark.slow  # CLI subprocesses
def test_bad_np_input_is_one_line_and_exit_2(tmp_path: Path) -> None:
    case = Path(shutil.copytree(TUTORIALS / "pitzDaily", tmp_path / "pitzDaily"))
    cases = {("--np", "0"): "positive integer", ("--keep-decomposed",): "--np"}
    for args, said in cases.items():
        process = _cli(str(case), "--out", str(tmp_path / "out"), *args, cwd=tmp_path)
        _, err = process.communicate(timeout=120)
        assert process.returncode == 2 and said in err, err
    for name in ("processor0", "processor1", "processor2"):
        (case / name).mkdir()
    for args, said in {(): "--np 3", ("--np", "2"): "not --np 2"}.items():
        process = _cli(str(case), "--out", str(tmp_path / "out"), *args, cwd=tmp_path)
        _, err = process.communicate(timeout=120)
        assert process.returncode == 2 and err.count("\n") == 1 and said in err, err
    assert not (tmp_path / "out").exists()
    bare = tmp_path / "bin"  # OpenFOAM without MPI
    bare.mkdir()
    for tool in ("simpleFoam", "blockMesh", "foamDictionary"):
        (bare / tool).symlink_to(shutil.which(tool))
    process = subprocess.Popen([PYTHON, "-m", "jaxsimrl", "solve", str(TUTORIALS / "pitzDaily"), "--out",
                                str(tmp_path / "out"), "--np", "2"], cwd=tmp_path,
                               env={**FOAM_ENV, "PATH": str(bare)}, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 2 and err.count("\n") == 1 and "mpirun not found" in err, err


@needs_openfoam
@needs_mpirun
@pytest.mark.slow  # pitzDaily on 2 ranks, the case's own settings serial: minutes on a loaded machine
def test_solve_np_2_converges_to_the_serial_fields_and_takes_a_decomposed_case(tmp_path: Path) -> None:
    case = Path(shutil.copytree(TUTORIALS / "pitzDaily", tmp_path / "pitzDaily"))
    out = tmp_path / "out"
    process = _cli(str(case), "--out", str(out), "--np", "2", "--keep-decomposed", "--quiet", "--controller",
                   "learned", cwd=tmp_path)
    _, err = process.communicate(timeout=1200)
    assert process.returncode == 0, err
    data = json.loads((out / "solve.json").read_text())
    assert data["result"]["converged"] and data["settings"]["ranks"] == 2
    assert "nProcs : 2" in (out / "log.simpleFoam").read_text()
    time_name = data["result"]["time_directory"]
    assert (out / time_name / "U").is_file() and (out / "processor1" / time_name / "U").is_file()
    serial = run_own(case, tmp_path / "serial", "own", 1200.0)
    criterion = data["settings"]["criterion"]
    agreement = compare_results(out, Path(serial.case), list(criterion), criterion, (True, serial.converged),
                                "serial")
    assert agreement["agree"], agreement
    decomposed = Path(shutil.copytree(case, tmp_path / "decomposed"))  # the user's decomposition of 2
    for name in ("processor0", "processor1"):
        shutil.copytree(out / name, decomposed / name)
    process = _cli(str(decomposed), "--out", str(tmp_path / "out2"), "--np", "2", "--quiet", cwd=tmp_path)
    _, err = process.communicate(timeout=1200)
    assert process.returncode == 0, err  # processor* holds a later time: solved on from it
    assert not list((tmp_path / "out2").glob("processor*"))


def _slow_solve(tmp_path: Path) -> tuple[subprocess.Popen, Path]:
    """solve --np 2 on the slow pitzDaily, waited for until its ranks are 3 iterations into the step."""
    case = slow_pitz_daily(tmp_path / "slow")
    out = tmp_path / "out"
    process = _cli(str(case), "--out", str(out), "--np", "2", "--controller", "learned", cwd=tmp_path)
    log = out / ".solve-work" / "env_0" / "episode" / "log.simpleFoam"
    wait_until(lambda: iterations_in(log) >= 3 or process.poll() is not None, 300, "3 iterations")
    assert process.poll() is None, process.communicate()
    assert iterations_in(log) < 60 and len(_solvers_under(out)) >= 3  # mpirun and 2 ranks, mid-step
    return process, out


@needs_openfoam
@needs_mpirun
@pytest.mark.slow  # slow_case: steps over a minute
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL])
def test_a_stopped_np_2_solve_leaves_no_rank_within_5_s(tmp_path: Path, sig: signal.Signals) -> None:
    process, out = _slow_solve(tmp_path)
    try:
        process.send_signal(sig)
        took = seconds_until(lambda: not _solvers_under(tmp_path), 30.0)
        process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    assert took < STOP_LIMIT_S, f"a rank ran on for {took:.1f} s after {sig.name}"


@needs_openfoam
@needs_mpirun
@pytest.mark.slow  # slow_case: steps over a minute
def test_a_killed_rank_ends_its_run_within_5_s(tmp_path: Path) -> None:
    """One rank SIGKILLed: the run's mpirun and other rank are gone within 5 s (the solve then goes on
    with the case's own settings, stopped here by SIGTERM, which leaves nothing either)."""
    process, out = _slow_solve(tmp_path)
    episode = out / ".solve-work" / "env_0" / "episode"
    try:
        rank = next(pid for pid in _solvers_under(episode)
                    if Path(f"/proc/{pid}/comm").read_text().strip() == "simpleFoam")
        os.kill(rank, signal.SIGKILL)
        took = seconds_until(lambda: not _solvers_under(episode), 30.0)
        assert took < STOP_LIMIT_S, f"the run's processes lasted {took:.1f} s after a rank died"
        _terminated_leaving_no_solver(process, tmp_path)
    finally:
        if process.poll() is None:
            process.kill()


def _terminated_leaving_no_solver(process: subprocess.Popen, under: Path) -> None:
    """SIGTERM to the solve: no solver under ``under`` within the stop limit, and the solve ends."""
    process.send_signal(signal.SIGTERM)
    assert seconds_until(lambda: not _solvers_under(under), 30.0) < STOP_LIMIT_S
    process.communicate(timeout=30)


@needs_openfoam
@needs_mpirun
@pytest.mark.slow  # slow_case: steps over a minute
def test_a_hung_parallel_step_is_stopped_with_every_rank(tmp_path: Path) -> None:
    """--step-timeout 15 on a step that needs over 35 s: the watchdog's stop leaves no rank of the
    controlled run within 5 s of its deadline (the solve then goes on with the case's own settings,
    stopped here by SIGTERM)."""
    case = slow_pitz_daily(tmp_path / "slow")
    out = tmp_path / "out"
    process = _cli(str(case), "--out", str(out), "--np", "2", "--step-timeout", "15", "--controller",
                   "learned", cwd=tmp_path)
    episode = out / ".solve-work" / "env_0" / "episode"
    try:
        wait_until(lambda: iterations_in(episode / "log.simpleFoam") >= 1 or process.poll() is not None, 300,
                   "the controlled run's first iteration")
        took = seconds_until(lambda: not _solvers_under(episode), 60.0)  # the step started before this
        assert took < 15 + STOP_LIMIT_S, f"the hung run's processes lasted {took:.1f} s"
        assert iterations_in(episode / "log.simpleFoam") < 100  # stopped mid-step, not at its end
        assert process.poll() is None  # the solve goes on (the case's own settings)
        _terminated_leaving_no_solver(process, tmp_path)
    finally:
        if process.poll() is None:
            process.kill()
