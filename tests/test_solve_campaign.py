"""``jaxsimrl solve CASE [CASE ...] --pool N``: a campaign of cases (jaxsimrl.apps.foam.solve.campaign).

The real runs are campaigns of 6 coarse variants of the built-in step (tests/test_solve.py's
``_coarse_step`` at three step heights, two of them sharing a directory name), solved by the residual rule
(no JAX in the workers: the campaign is under test, not the controller). On the local pool a worker is
killed mid-solve, then the whole campaign with kill -9, then it is resumed; on a 2-node local Ray
cluster a node is lost mid-campaign. Either way every case is solved exactly once and none is lost.
Every wait is bounded.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from foam_marks import needs_openfoam
from foamlib import FoamFile
from slow_case import STOP_LIMIT_S, iterations_in, seconds_until, wait_until
from test_solve import _coarse_step

from foam_bridge import _template as template
from foam_bridge._backends import Request
from foam_bridge._backends.base import _batch_deadline_s, start_deadline_s
from foam_bridge._backends.reaper import processes_under
from jaxsimrl.apps.foam.solve.campaign import CASE_TIMEOUT_S, CampaignSettings, find_cases, plan_campaign
from jaxsimrl.apps.foam.solve.campaign_table import (
    FAILED,
    failed_row,
    finished_line,
    row_of,
    write_plot,
    write_table,
)

FOAM_ENV = {**os.environ, "WM_PROJECT_DIR": os.environ.get("WM_PROJECT_DIR", "/usr/share/openfoam")}
#: The rule and the pool every real campaign here runs with.
RULE = ["--controller", "residual-rule", "--pool", "2"]


def _fake_case(path: Path) -> Path:
    (path / "system").mkdir(parents=True)
    (path / "system" / "controlDict").write_text("")
    return path


def test_cases_are_found_in_a_directory_and_a_non_case_is_refused(tmp_path: Path) -> None:
    a, b = _fake_case(tmp_path / "set" / "b"), _fake_case(tmp_path / "set" / "a")
    (tmp_path / "set" / "notes").mkdir()
    single = _fake_case(tmp_path / "single")
    assert find_cases([tmp_path / "set", single]) == [b, a, single]  # a directory's cases sorted by name
    with pytest.raises(ValueError, match="notes is not a simpleFoam case"):
        find_cases([single, tmp_path / "set" / "notes"])
    with pytest.raises(ValueError, match="given twice"):
        find_cases([tmp_path / "set", a])


def test_output_names_are_unique_and_a_resume_keeps_them(tmp_path: Path) -> None:
    first, second = _fake_case(tmp_path / "x" / "step"), _fake_case(tmp_path / "y" / "step")
    out = tmp_path / "out"
    jobs = plan_campaign([first, second], out)
    assert [job.out.name for job in jobs] == ["step.solved", "step-2.solved"]
    assert jobs[1].log == out / "logs" / "step-2.log"
    with pytest.raises(ValueError, match="not empty.*--resume"):
        plan_campaign([first, second], out)
    third = _fake_case(tmp_path / "z" / "step")  # the same cases in another order, one more
    again = plan_campaign([third, second, first], out, resume=True)
    assert [job.out.name for job in again] == ["step-3.solved", "step-2.solved", "step.solved"]
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "file").write_text("")
    with pytest.raises(ValueError, match="no campaign to resume"):
        plan_campaign([first], tmp_path / "other", resume=True)
    with pytest.raises(ValueError, match="contain each other"):
        plan_campaign([first], first / "out")


def test_a_solve_on_the_pool_has_the_case_deadline_and_a_worker_start_the_step_watchdog() -> None:
    settings = CampaignSettings(step_timeout_s=300.0)  # a whole solve is one request: not 2 steps' time
    assert _batch_deadline_s(settings, [Request(0, "reset", {})]) == CASE_TIMEOUT_S
    assert start_deadline_s(settings) == 300.0


def _report(converged: bool, own: int | None = None) -> dict:
    """The parts of a solve.json a campaign row reads."""
    data = {"result": {"converged": converged, "iterations": 150, "wall_time_s": 3.0,
                       "cause": "" if converged else "reached the budget"},
            "controller": {"rule": "residual-rule"}, "compare": {}}
    if own is not None:
        data["compare"]["own"] = {"iterations": own, "wall_time_s": 2.0, "ratio_iterations": 150 / own,
                                  "ratio_wall_time": 1.5}
    return data


def test_the_table_and_plot_hold_each_case_and_the_own_run_with_compare(tmp_path: Path) -> None:
    rows = [row_of(Path("/c/a"), tmp_path / "a.solved", _report(True, own=200)),
            row_of(Path("/c/b"), tmp_path / "b.solved", _report(False, own=100)),
            failed_row(Path("/c/c"), tmp_path / "c.solved", "ValueError: case /c/c has no\n residualControl")]
    write_table(tmp_path, rows, compare=True)
    write_plot(tmp_path, rows, compare=True)
    table = list(csv.DictReader((tmp_path / "campaign.csv").open()))
    assert list(table[0]) == ["case", "out", "status", "iterations", "wall_s", "iterative_error",
                              "own_iterations", "ratio_iterations", "own_wall_s", "ratio_wall", "controller",
                              "cause"]
    assert [(r["out"], r["status"], r["ratio_iterations"]) for r in table] == [
        ("a.solved", "converged", "0.75"), ("b.solved", "not converged", "1.5"), ("c.solved", FAILED, "")]
    assert table[1]["cause"] == "reached the budget" and table[2]["cause"].endswith("has no residualControl")
    assert (tmp_path / "campaign.png").read_bytes()[:4] == b"\x89PNG"
    line = "a.solved: converged after 150 iterations, 3.0 s; own 200 iterations (x0.75)"
    assert finished_line(rows[0]) == line
    write_table(tmp_path, rows[:1], compare=False)  # without --compare, no own columns
    assert "own_iterations" not in (tmp_path / "campaign.csv").read_text()


def test_a_case_stopped_on_its_answer_has_its_verdict_and_error_in_the_table(tmp_path: Path) -> None:
    """Settled counts as an answer (no cause); oscillating does not; the worst estimated error is shown."""
    rows = []
    for outcome in ("settled", "oscillating"):
        data = _report(False)
        data["result"].update(outcome=outcome, iterative_error={"U": 2e-4, "p": 8e-4, "probe/0/p": None})
        rows.append(row_of(Path(f"/c/{outcome}"), tmp_path / f"{outcome}.solved", data))
    assert [(row["status"], row["iterative_error"], row["cause"]) for row in rows] == [
        ("settled", "8.0e-04", ""), ("oscillating", "8.0e-04", "reached the budget")]
    line = "settled.solved: settled after 150 iterations, 3.0 s, iterative error 8.0e-04"
    assert finished_line(rows[0]) == line


def _cli(*args: str, cwd: Path, stderr: Path | None = None) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "jaxsimrl", "solve", *args], cwd=cwd, env=FOAM_ENV,
                            stdout=subprocess.PIPE, text=True,
                            stderr=subprocess.PIPE if stderr is None else stderr.open("w"))


def test_bad_input_is_one_line_and_exit_2(tmp_path: Path) -> None:
    case = _fake_case(tmp_path / "case")
    (tmp_path / "notes").mkdir()
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("")
    for args, says in (([str(case), "notes", "--pool", "2"], "notes is not a simpleFoam case"),
                       ([str(case), "--pool", "2", "--out", "full"], "not empty"),
                       ([str(case), "--ray-address", "x:1"], "--ray-address needs --backend ray")):
        process = _cli(*args, cwd=tmp_path)
        _, err = process.communicate(timeout=120)
        assert process.returncode == 2 and err.count("\n") == 1 and says in err, (args, err)
    assert not (tmp_path / "campaign").exists()  # nothing started


def _variants(root: Path) -> list[Path]:
    """6 coarse step cases at 3 step heights; x/step and y/step share a name."""
    cases = []
    for index, (folder, height) in enumerate([("x", 1.0), ("y", 1.0), ("a", 1.25), ("b", 1.25),
                                              ("c", 1.5), ("d", 1.5)]):
        case = _coarse_step(root / folder / ("step" if index < 2 else f"step{index}"))
        with FoamFile(case / "system" / "meshParameters") as params:
            params.update(template.mesh_parameters(0.4, 0.0127 * height))
        cases.append(case)
    return cases


def _solving(out: Path) -> dict[str, int]:
    """{case output directory: iterations its controlled run has started} for the solves running now."""
    logs = out.glob("*.solved/.solve-work/env_0/episode/log.simpleFoam")
    return {log.parents[3].name: iterations_in(log) for log in logs}


def _complete(out: Path) -> dict[str, str]:
    """{case output directory: its solve.json text} for the finished cases."""
    found = {}
    for path in out.glob("*.solved/solve.json"):
        text = path.read_text()
        if json.loads(text)["status"] == "complete":
            found[path.parent.name] = text
    return found


def _finished_lines(stderr: str) -> list[str]:
    """The output directories named by the "[i/n] NAME.solved: ..." lines."""
    return [line.split("] ", 1)[1].split(":", 1)[0] for line in stderr.splitlines() if line.startswith("[")]


def _table(out: Path) -> list[dict[str, str]]:
    return list(csv.DictReader((out / "campaign.csv").open()))


def _check_every_case_once(out: Path, cases: list[Path], before: dict[str, str], resumed: str) -> None:
    """Every case in the table once, converged; the cases finished before the resume untouched by it,
    and the resume solved each other case once."""
    table = _table(out)
    assert sorted(row["case"] for row in table) == sorted(map(str, cases)), table
    assert all(row["status"] == "converged" for row in table), table
    names = [row["out"] for row in table]
    assert len(set(names)) == 6 and {"step.solved", "step-2.solved"} <= set(names)
    done = _complete(out)
    assert sorted(done) == sorted(names)
    assert all(done[name] == text for name, text in before.items())  # kept, not solved again
    assert sorted(_finished_lines(resumed)) == sorted(set(names) - set(before)), resumed
    assert (out / "campaign.png").read_bytes()[:4] == b"\x89PNG"


def _parent(pid: int) -> int:
    try:
        return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
    except (OSError, IndexError, ValueError):
        return 0


@pytest.mark.slow  # two campaigns of 6 real solves
@needs_openfoam
def test_a_campaign_survives_a_lost_worker_and_kill_9_then_resumes_every_case_once(tmp_path: Path) -> None:
    cases = _variants(tmp_path / "cases")
    out = tmp_path / "out"
    args = [str(tmp_path / "cases" / "x" / "step"), str(tmp_path / "cases" / "y" / "step"),
            *(str(p) for p in cases[2:]), *RULE, "--out", str(out)]
    log = tmp_path / "first.err"
    process = _cli(*args, cwd=tmp_path, stderr=log)
    try:
        # a worker killed mid-solve (its case 3 iterations in): the case is solved again by the next one free
        wait_until(lambda: any(n >= 3 for n in _solving(out).values()) or process.poll() is not None, 180,
                   "a solve under way")
        victim_case, _ = max(_solving(out).items(), key=lambda item: item[1])
        solver = processes_under(out / victim_case / ".solve-work")[0]
        worker = _parent(_parent(solver))  # simpleFoam <- solve's env worker <- the campaign's worker
        assert _parent(worker) == process.pid
        os.kill(worker, signal.SIGKILL)
        wait_until(lambda: "worker died; solving it again" in log.read_text() or process.poll() is not None,
                   60, "the lost worker's case sent out again")
        # then kill -9 of the campaign itself, mid-campaign: no solver left within 5 s
        wait_until(lambda: (out / "campaign.csv").is_file() and _solving(out) or process.poll() is not None,
                   180, "a case finished and another under way")
        assert process.poll() is None, log.read_text()
        process.kill()
        took = seconds_until(lambda: not processes_under(out), 30.0)
        process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    assert took < STOP_LIMIT_S, f"a solver ran on for {took:.1f} s after kill -9 of the campaign"
    first = log.read_text()
    assert first.count("worker died; solving it again") == 1 and f"{victim_case}: worker died" in first
    before = _complete(out)
    assert 1 <= len(before) < 6 and set(_finished_lines(first)) <= set(before), (before, first)
    resumed = _cli(*args, "--resume", cwd=tmp_path)
    stdout, stderr = resumed.communicate(timeout=300)
    assert resumed.returncode == 0, stderr
    assert f"{len(before)} of 6 cases finished before" in stderr and "6 of 6 cases converged" in stdout
    _check_every_case_once(out, cases, before, stderr)


@pytest.mark.slow  # a Ray cluster, 6 real solves
@needs_openfoam
def test_a_campaign_on_a_ray_cluster_that_loses_a_node_solves_every_case_once(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    from test_foam_ray_cluster import kill_node, ray_cluster

    cases = _variants(tmp_path / "cases")
    out = tmp_path / "out"
    log = tmp_path / "campaign.err"
    with ray_cluster(1, 1) as (cluster, (doomed,), processes):  # an actor on each node (one CPU each)
        process = _cli(*map(str, cases), *RULE, "--out", str(out), "--backend", "ray", "--ray-address",
                       cluster.address, cwd=tmp_path, stderr=log)
        processes.append(process)

        def both_mid_solve() -> bool:
            return sum(n >= 3 for n in _solving(out).values()) == 2 or process.poll() is not None

        wait_until(both_mid_solve, 240, "both workers 3 iterations into a solve")
        assert process.poll() is None, log.read_text()
        kill_node(cluster, doomed)
        stdout, _ = process.communicate(timeout=300)
    err = log.read_text()
    assert process.returncode == 0, err
    again = [line for line in err.splitlines() if line.endswith("; solving it again")]
    assert len(again) == 1 and ": node lost: " in again[0], err  # the lost node's case alone is solved again
    assert "the pool goes on with 1 of 2 workers" in err  # no room for another: the survivor did the rest
    _check_every_case_once(out, cases, {}, err)
