"""train-foam faults of issue 16 (section 2 and 3.3): the episode target governs the run's length, a run
killed before its first checkpoint resumes, --init-from carries its source's input handling and action
mapping, and bad combinations of flags are one line and exit code 2."""

from __future__ import annotations

import io
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from foam_marks import needs_openfoam
from rich.console import Console
from slow_case import (
    STOP_LIMIT_S,
    all_into_a_step,
    episode_progress,
    seconds_until,
    slow_pitz_daily,
    wait_until,
)
from test_train_foam import TINY  # the cheap real runs: smallest mesh, 4 steps per env per update

from foam_bridge._config import FoamEnvConfig
from jaxsimrl.apps.foam.episodes import EpisodeLog
from jaxsimrl.apps.foam.plan import episode_steps_bound, total_steps_for
from jaxsimrl.cli.main import main


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    try:
        code = main(["train-foam", *argv])
    except SystemExit as exit_:
        code = exit_.code
    out, err = capsys.readouterr()
    return code, out, err


def printed_config(capsys, *argv: str) -> dict:
    code, out, err = run_cli(capsys, *argv, "--print-config")
    assert code == 0, err
    return json.loads(out)


def fake_run(capsys, path: Path, *argv: str, checkpoint: int | None = None, episodes_per_update: int = 0,
             target: int = 20) -> Path:
    """A train-foam run directory as a run of ``argv`` leaves it: config.json, and with ``checkpoint`` an
    (empty) checkpoint folder of that many updates and episodes.csv rows up to it. Enough for every
    check made before anything heavy starts (--print-config)."""
    printed = printed_config(capsys, *argv)
    path.mkdir()
    record = {"env": "foam", "seed": 0, "ppo": printed["ppo"], "foam": printed["foam"],
              "episodes_target": target, "pool": printed["pool"], "backend": "local"}
    (path / "config.json").write_text(json.dumps(record))
    if checkpoint is not None:
        (path / "checkpoints" / str(checkpoint)).mkdir(parents=True)
        log = EpisodeLog(path / "episodes.csv")
        for update in range(1, checkpoint + 1):
            for env in range(episodes_per_update):
                log.add(env % 2, update, {"episode": {"actions": [[0.9, 0.9]] * 3, "iterations": 250,
                                                      "outcome": "converged", "return": -250.0}})
        log.flush()
    return path


# ---- 2.1: the episode target governs -------------------------------------------------------------
@pytest.mark.parametrize("episodes, max_iterations, pool", [(100_000, 20_000, 2), (2000, 4000, 16),
                                                            (7, 1500, 3)])
def test_total_steps_cover_the_episode_target_whatever_its_size(capsys, episodes, max_iterations, pool):
    printed = printed_config(capsys, "--episodes", str(episodes), "--max-iterations", str(max_iterations),
                             "--pool", str(pool))
    ppo, foam = printed["ppo"], printed["foam"]
    # every env ends an episode at least every ceil(max_iterations / interval) steps
    longest = math.ceil(max_iterations / foam["interval"])
    assert ppo["total_steps"] >= math.ceil(episodes / pool) * longest * pool
    assert ppo["total_steps"] % ppo["steps_per_update"] == 0  # whole updates


def test_the_bound_holds_in_the_worst_case_and_on_resume():
    foam = FoamEnvConfig(max_iterations=1000, interval=100)
    longest = episode_steps_bound(foam)
    for episodes, num_envs, per_update in [(1, 1, 4), (20, 2, 8), (2000, 16, 192), (33, 4, 128)]:
        total = total_steps_for(episodes, per_update, num_envs, foam)
        per_env = total // num_envs
        assert num_envs * (per_env // longest) >= episodes  # every episode as long as it can be
        # resumed after 5 updates with 3 episodes ended: 5 more updates' worth of room at least
        resumed = total_steps_for(episodes - 3, per_update, num_envs, foam, updates_done=5)
        assert resumed >= 5 * per_update + num_envs * math.ceil((episodes - 3) / num_envs) * longest


def test_resume_with_more_episodes_raises_the_horizon(capsys, tmp_path):
    run = fake_run(capsys, tmp_path / "run", *TINY, "--episodes", "20", checkpoint=3, episodes_per_update=2)
    before = json.loads((run / "config.json").read_text())["ppo"]["total_steps"]
    printed = printed_config(capsys, "--resume", str(run), "--episodes", "5000")
    ppo, foam = printed["ppo"], printed["foam"]
    longest = math.ceil(foam["max_iterations"] / foam["interval"])
    assert printed["episodes"] == 5000 and ppo["total_steps"] > before
    assert ppo["total_steps"] >= 3 * ppo["steps_per_update"] + math.ceil((5000 - 6) / 2) * longest * 2


def test_anneal_lr_is_refused_in_one_line(capsys, tmp_path):
    config = tmp_path / "anneal.json"
    config.write_text(json.dumps({"ppo": {"anneal_lr": True}}))
    code, _, err = run_cli(capsys, "--config", str(config), "--out", str(tmp_path / "run"), "--print-config")
    assert code == 2 and "anneal_lr is not available in train-foam" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "run").exists()


# ---- 2.7 and 3.3: flags ----------------------------------------------------------------------------
def test_ray_address_on_resume_of_a_local_run_needs_backend_ray(capsys, tmp_path):
    run = fake_run(capsys, tmp_path / "run", *TINY, checkpoint=1)
    code, _, err = run_cli(capsys, "--resume", str(run), "--ray-address", "127.0.0.1:1", "--print-config")
    assert code == 2 and "--ray-address needs --backend ray" in err and len(err.splitlines()) == 1
    printed = printed_config(capsys, "--resume", str(run), "--ray-address", "127.0.0.1:1", "--backend", "ray")
    assert printed["pool"] == 2  # with --backend ray the run may move to a cluster


@pytest.mark.parametrize("argv, message", [
    (["--mesh-scale", "0.3"], "--mesh-scale 0.3 is below 0.4"),
    (["--config", "{work_dir}"], "work_dir is not used by train-foam"),
])
def test_refused_settings_are_one_line_and_exit_2(capsys, tmp_path, argv, message):
    config = tmp_path / "work_dir.json"
    config.write_text(json.dumps({"foam": {"work_dir": str(tmp_path / "cases")}}))
    argv = [str(config) if a == "{work_dir}" else a for a in argv]
    code, _, err = run_cli(capsys, *argv, "--out", str(tmp_path / "run"), "--print-config")
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "run").exists() and not (tmp_path / "cases").exists()


def test_steps_per_update_help_states_the_rounding_the_code_does(capsys):
    with pytest.raises(SystemExit):
        main(["train-foam", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert "rounded up to a multiple of num_minibatches x num_envs" in help_text
    assert "stops after the update in which the target is reached" in help_text
    ppo = printed_config(capsys, "--pool", "2", "--steps-per-update", "10", "--num-minibatches", "3")["ppo"]
    assert ppo["steps_per_update"] == 12  # 3 x 2, not 4 x 2


# ---- real runs: 2.9 (killed before the first checkpoint) and 2.3 (--init-from) ------------------------
@pytest.fixture(scope="module")
def source_run(tmp_path_factory) -> Path:
    """A finished tiny run whose input handling and action mapping are not the defaults."""
    root = tmp_path_factory.mktemp("source")
    config = root / "settings.json"
    config.write_text(json.dumps({"ppo": {"obs_clip": 5.0, "obs_std_floor": 0.02}}))
    run = root / "run"
    assert main(["train-foam", *TINY, "--episodes", "2", "--seed", "1", "--action-margin", "0.01",
                 "--config", str(config), "--out", str(run)]) == 0
    return run


@pytest.mark.slow  # source_run: a real train-foam run
@needs_openfoam
def test_a_run_killed_before_its_first_checkpoint_resumes_from_scratch(capsys, tmp_path, source_run):
    run = tmp_path / "killed"
    shutil.copytree(source_run, run)
    shutil.rmtree(run / "checkpoints")  # as a kill -9 between the rows and the first checkpoint leaves it
    assert (run / "metrics.jsonl").read_text() and len(EpisodeLog.load(run / "episodes.csv", 10**9).rows)
    code, _, err = run_cli(capsys, *TINY, "--out", str(run))
    assert code == 2 and f"--resume {run}" in err  # --out points at --resume, which now accepts it
    code, out, err = run_cli(capsys, "--resume", str(run))
    assert code == 0, err
    assert "no checkpoint" in err and "starting it over" in err and "done:" in out
    rows = EpisodeLog.load(run / "episodes.csv", 10**9).rows
    metrics = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert [r["index"] for r in rows] == list(range(len(rows)))  # no duplicate row
    assert [m["update"] for m in metrics] == list(range(1, len(metrics) + 1))
    summary = json.loads((run / "summary.json").read_text())
    assert summary["episodes"] == len(rows) >= 2 and summary["complete"] and summary["num_updates"] is None
    assert summary["updates"] == len(metrics) == max(int(p.name) for p in (run / "checkpoints").iterdir())
    if len(rows) > 2:  # whole updates: the closing line says why there are more than the target
        assert "target 2; the" in out
    # the same run again: the solver is deterministic, so it is the source's episodes, once each
    source = EpisodeLog.load(source_run / "episodes.csv", 10**9).rows
    assert [(r["env"], r["iterations"]) for r in rows] == [(r["env"], r["iterations"]) for r in source]


@pytest.mark.slow  # source_run: a real train-foam run
@needs_openfoam
def test_init_from_carries_the_sources_input_handling_and_action_mapping(capsys, tmp_path, source_run):
    printed = printed_config(capsys, *TINY, "--init-from", str(source_run))
    assert (printed["ppo"]["obs_clip"], printed["ppo"]["obs_std_floor"]) == (5.0, 0.02)
    assert printed["ppo"]["action_margin"] == 0.01
    # an action mapping this run sets is kept (a plain-tanh policy mapped onto a widened box), and said
    code, out, err = run_cli(capsys, *TINY, "--init-from", str(source_run), "--action-margin", "0",
                             "--print-config")
    assert code == 0 and json.loads(out)["ppo"]["action_margin"] == 0
    assert "action_margin 0.01; this run uses 0" in err
    # input handling set differently is refused: the network expects the source's inputs
    config = tmp_path / "clip.json"
    config.write_text(json.dumps({"ppo": {"obs_clip": 10.0}}))
    code, _, err = run_cli(capsys, *TINY, "--init-from", str(source_run), "--config", str(config),
                           "--out", str(tmp_path / "bad"))
    assert code == 2 and "obs_clip" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "bad").exists()


# ---- 3.3: feedback during an update ------------------------------------------------------------------
class _Metrics:
    wall_time_s = 3600.0


def _episode(iterations: int) -> dict:
    return {"episode": {"actions": [[0.9, 0.9]] * 3, "iterations": iterations, "outcome": "converged",
                        "return": -float(iterations), "wall_time_s": 30.0, "solver_idle_s": 1.0}}


def test_the_bar_counts_episodes_as_they_end_and_keeps_the_count_at_80_columns(tmp_path):
    from jaxsimrl.runs.progress import EpisodeProgress

    log = EpisodeLog(tmp_path / "episodes.csv")
    for i in range(1233):
        log.add(i % 2, 1, _episode(250 + i % 7))
    log.flush()
    stream = io.StringIO()
    with EpisodeProgress(2000, log, 2, _Metrics(), stream=stream, live=True) as bar:
        bar.update(0, 0.0, math.nan, 1, 1)
        bar.episode_ended()  # the host env says: one ended during update 2, before the update's end
        rendered = io.StringIO()
        Console(file=rendered, width=80, color_system=None).print(bar._progress.get_renderable())
        log.add(0, 2, _episode(260))  # it joins the log after the update...
        log.flush()
        bar.update(0, 0.0, math.nan, 2, 2)  # ...and is counted once
        again = io.StringIO()
        Console(file=again, width=80, color_system=None).print(bar._progress.get_renderable())
    text = rendered.getvalue()
    assert "1234/2000 episodes" in text, text
    assert all(len(row) <= 80 for row in text.splitlines())
    assert "1234/2000 episodes" in again.getvalue(), again.getvalue()


def test_the_progress_line_says_when_the_pool_has_lost_workers(tmp_path):
    """A worker lost for good (a Ray node died) shows in every progress line, first, so a narrow
    terminal does not cut it; a full pool says nothing of it."""
    from jaxsimrl.runs.progress import EpisodeProgress

    log = EpisodeLog(tmp_path / "episodes.csv")
    log.add(0, 1, _episode(250))
    workers = [4]
    stream = io.StringIO()
    with EpisodeProgress(100, log, 4, _Metrics(), stream=stream, live=False,
                         workers=lambda: workers[0]) as bar:
        bar.update(0, 0.0, math.nan, 1, 1)
        workers[0] = 3
        bar.update(0, 0.0, math.nan, 2, 2)
    full, smaller = stream.getvalue().splitlines()
    assert "workers" not in full
    assert smaller.startswith("update 2  episodes 1/100  workers 3/4  iterations"), smaller


def test_ctrl_c_during_a_chunk_is_told_at_once_and_the_chunk_is_still_saved(tmp_path):
    """The main thread waits inside a jitted call (as on an update of host envs): the hook hears of each
    Ctrl-C at once, the chunk is saved, then KeyboardInterrupt stops the loop."""
    import jax
    import jax.numpy as jnp
    import numpy as np
    from jax.experimental import io_callback

    from jaxsimrl.runs.checkpoint import Checkpoints
    from jaxsimrl.runs.run_dir import MetricsLog, RunDir
    from jaxsimrl.runs.training import Session, train

    def slow(x):
        time.sleep(2.0)  # a host step: solvers running
        return np.asarray(x)

    step = jax.jit(lambda x: io_callback(slow, jax.ShapeDtypeStruct((), jnp.int32), x, ordered=True))

    class SlowTrainer:
        num_updates = 5

        def run_chunk(self, state):
            update = int(jax.device_get(step(jnp.int32(state["update"] + 1))))
            metrics = {"env_steps": np.array([10 * update]), "episodes": np.array([0])}
            return {"update": np.int32(update)}, metrics

    class Quiet:
        def update(self, *args):
            pass

    told: list[tuple[int, float]] = []
    run = RunDir.create(tmp_path / "run")
    start = time.monotonic()
    for delay in (0.4, 0.8):
        threading.Timer(delay, os.kill, (os.getpid(), signal.SIGINT)).start()
    with Checkpoints(run.checkpoints) as checkpoints:
        session = Session(run, SlowTrainer(), MetricsLog(run), checkpoints, meta={})
        with pytest.raises(KeyboardInterrupt):
            train(session, {"update": np.int32(0)}, 0, Quiet(),
                  on_interrupt=lambda count, signum: told.append((count, time.monotonic() - start)))
    assert [count for count, _ in told] == [1, 2]
    assert told[-1][1] < 1.6  # while the 2 s chunk was still running
    assert run.checkpoint_steps() == [1]


def _train_foam(argv: list[str], tmp: Path) -> tuple[subprocess.Popen, list[str]]:
    """train-foam in a session of its own (Ctrl-C goes to the whole group, trainer and workers, as a
    terminal sends it), its work directories under ``tmp``; stderr lines collected as they come."""
    script = Path(sys.executable).with_name("jaxsimrl")
    process = subprocess.Popen([str(script), "train-foam", *argv], env={**os.environ, "TMPDIR": str(tmp)},
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True)
    lines: list[str] = []
    threading.Thread(target=lambda: lines.extend(iter(process.stderr.readline, "")), daemon=True).start()
    return process, lines


def _stop(process: subprocess.Popen, sig: signal.Signals) -> None:
    """Ctrl-C as a terminal sends it (the whole group); SIGTERM and SIGKILL to the trainer alone."""
    if sig == signal.SIGINT:
        os.killpg(process.pid, sig)
    else:
        process.send_signal(sig)


@pytest.mark.slow  # a real train-foam run stopped and resumed
@needs_openfoam
def test_ctrl_c_stops_now_and_the_run_resumes_from_its_last_checkpoint(tmp_path):
    from foam_bridge._backends.reaper import processes_under

    run, tmp = tmp_path / "run", tmp_path / "tmp"
    tmp.mkdir()
    process, lines = _train_foam([*TINY, "--episodes", "50", "--out", str(run)], tmp)
    try:
        wait_until(lambda: (run / "checkpoints" / "1").is_dir() or process.poll() is not None, 400,
                   "the first checkpoint")
        assert process.poll() is None, lines
        time.sleep(0.5)  # inside update 2 (several seconds of solver steps)
        _stop(process, signal.SIGINT)
        assert process.wait(timeout=10) == 130  # at once, not after the update in flight
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
    assert seconds_until(lambda: not processes_under(tmp), 30.0) < STOP_LIMIT_S
    time.sleep(0.5)  # the reader thread takes the last lines
    assert any("stopped now (Ctrl-C)" in line and f"--resume {run}" in line for line in lines), lines
    assert not any("Traceback" in line for line in lines), lines  # no worker's BrokenPipeError either
    steps = sorted(int(p.name) for p in (run / "checkpoints").iterdir() if p.name.isdigit())
    assert steps and steps[-1] >= 1
    assert main(["train-foam", "--resume", str(run), "--print-config"]) == 0  # resumable


@pytest.mark.slow  # slow_case: steps over a minute
@needs_openfoam
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL])
def test_a_stopped_train_foam_leaves_no_solver_within_5_s_mid_step(tmp_path, sig):
    """Steps that last over a minute (tests/slow_case.py): Ctrl-C, SIGTERM and kill -9 of train-foam,
    sent while both solvers are a few iterations into a step, leave no solver after 5 s. A solver that
    ran on to the end of its step (or of the update) would fail this."""
    from foam_bridge._backends.reaper import processes_under

    case = slow_pitz_daily(tmp_path / "slow")
    run, tmp = tmp_path / "run", tmp_path / "tmp"
    tmp.mkdir()
    process, lines = _train_foam(["--case", str(case), "--pool", "2", "--steps-per-update", "8",
                                  "--max-iterations", "300", "--episodes", "50", "--out", str(run)], tmp)

    try:
        wait_until(lambda: all_into_a_step(tmp, 2) or process.poll() is not None, 300,
                   "both solvers to be 3 iterations into a step")
        assert process.poll() is None, lines
        assert max(episode_progress(tmp)) < 90  # the step has a minute to go
        _stop(process, sig)
        took = seconds_until(lambda: not processes_under(tmp), 30.0)
        code = process.wait(timeout=30)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
    assert took < STOP_LIMIT_S, f"a solver ran on for {took:.1f} s after {sig.name}"
    assert code == {signal.SIGINT: 130, signal.SIGTERM: 143}.get(sig, -signal.SIGKILL)
    if sig != signal.SIGKILL:
        time.sleep(0.5)  # the reader thread takes the last lines
        word = "Ctrl-C" if sig == signal.SIGINT else "SIGTERM"
        assert any(f"stopped now ({word})" in line and "nothing to resume" in line for line in lines), lines
        assert not run.exists()  # stopped before its first update: nothing was saved, nothing is left
