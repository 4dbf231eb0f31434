"""``jaxsimrl train-foam``: CLI errors, and real simpleFoam training stepped through io_callback,
killed with SIGKILL and resumed (no orphaned solver, no torn or duplicate record)."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import jax
import numpy as np
import pytest
from foam_marks import needs_openfoam

from foam_bridge._backends.reaper import processes_under
from jaxsimrl.apps.foam.episodes import EpisodeLog
from jaxsimrl.apps.foam.plan import foam_ppo_defaults
from jaxsimrl.cli.main import main

# The smallest usable mesh; 4 steps per env per update, so updates come every few seconds. Episodes end
# within 5 steps (most converge in 300-450 iterations here, the others are truncated): one or two per update.
TINY = ["--mesh-scale", "0.4", "--pool", "2", "--steps-per-update", "8", "--max-iterations", "500"]


def run_cli(capsys, *argv: str) -> tuple[int, str]:
    try:
        code = main(["train-foam", *argv])
    except SystemExit as exit_:
        code = exit_.code
    return code, capsys.readouterr().err


@pytest.mark.parametrize("argv, message", [
    (["--episodes", "0"], "expected a positive integer"),
    (["--num-envs", "2", "--pool", "3"], "pool must be an integer in [1, num_envs=2]"),
    (["--mesh-scale", "-1"], "expected a positive number"),
    (["--gamma", "2"], "gamma must be a number in [0, 1]"),
    (["--action-margin", "0.7"], "action_margin must be a number in [0, 0.5]"),
    (["--ray-address", "auto"], "--ray-address needs --backend ray"),
    (["--case", "no/such/case"], "does not exist"),
])
def test_bad_input_is_one_line_and_exit_2(capsys, tmp_path, argv, message):
    code, err = run_cli(capsys, *argv, "--out", str(tmp_path / "run"))
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "run").exists()  # nothing is left behind by a refused run


def test_config_file_and_resume_errors(capsys, tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"ppo": {"lr": 1e-3}, "solver": {}}))
    code, err = run_cli(capsys, "--config", str(bad))
    assert code == 2 and '"ppo" and/or "foam"' in err
    bad.write_text(json.dumps({"foam": {"no_such_field": 1}}))
    code, err = run_cli(capsys, "--config", str(bad), "--out", str(tmp_path / "r"))
    assert code == 2 and "no_such_field" in err
    code, err = run_cli(capsys, "--resume", str(tmp_path / "absent"))
    assert code == 2 and "does not exist" in err
    lorenz = tmp_path / "lorenz"
    lorenz.mkdir()
    (lorenz / "config.json").write_text(json.dumps({"env": "lorenz", "seed": 0, "ppo": {}}))
    code, err = run_cli(capsys, "--resume", str(lorenz))
    assert code == 2 and "not a train-foam run" in err
    code, err = run_cli(capsys, "--resume", str(lorenz), "--mesh-scale", "0.5")
    assert code == 2 and "--mesh-scale cannot be used with --resume" in err


def test_defaults_are_the_papers_and_batches_fit_the_pool(capsys):
    assert main(["train-foam", "--print-config", "--pool", "4"]) == 0
    printed = json.loads(capsys.readouterr().out)
    ppo, foam = printed["ppo"], printed["foam"]
    assert (ppo["network"], ppo["hidden_sizes"], ppo["activation"]) == ("mlp", [64, 64], "tanh")
    assert (ppo["lr"], ppo["gamma"], ppo["num_envs"]) == (2.5e-4, 1.0, 4)
    assert (foam["simple_variant"], foam["relax_k_omega"], foam["interval"]) == ("SIMPLEC", 0.8, 100)
    assert foam["inlet_velocity"] == [35.0, 65.0] and foam["action_low"] == [0.2, 0.2]
    assert foam["action_high"] == [0.95, 0.95] and printed["episodes"] == 2000
    for pool in (1, 2, 3, 4, 8, 16):
        sizes = foam_ppo_defaults(pool)
        assert sizes["steps_per_update"] % (pool * sizes["num_minibatches"]) == 0
        assert 128 <= sizes["steps_per_update"] <= 192


def _train_process(run: Path, tmp: Path, *argv: str) -> subprocess.Popen:
    script = Path(sys.executable).with_name("jaxsimrl")
    env = {**os.environ, "TMPDIR": str(tmp)}  # every case directory lands under tmp
    return subprocess.Popen([str(script), "train-foam", *argv], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_for(condition, process: subprocess.Popen, timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline or process.poll() is not None:
            process.kill()
            pytest.fail(f"{what} did not happen: {process.communicate()}")
        time.sleep(0.2)


def _no_solver_left(tmp: Path, timeout_s: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while processes_under(tmp):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.2)
    return True


def _check_records(run: Path) -> tuple[list[dict], list[dict]]:
    """episodes.csv and metrics.jsonl are whole, in order and without duplicates."""
    rows = EpisodeLog.load(run / "episodes.csv", 10**9).rows
    assert [r["index"] for r in rows] == list(range(len(rows)))
    assert [r["update"] for r in rows] == sorted(r["update"] for r in rows)
    metrics = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert [m["update"] for m in metrics] == list(range(1, len(metrics) + 1))
    for r in rows:
        assert r["outcome"] in ("converged", "truncated", "crashed", "diverged", "hung")
        assert r["steps"] == len(r["actions"])
        assert all(0.2 <= a <= 0.95 for pair in r["actions"] for a in pair)
        if r["outcome"] == "converged":  # K iterations take ceil(K / 100) steps, and the return is -K
            assert r["return"] == -r["iterations"] and r["linear_iterations"] > r["iterations"]
            assert 100 * (r["steps"] - 1) < r["iterations"] <= 100 * r["steps"]
    return rows, metrics


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory) -> Path:
    """A TINY run of 8 episodes with seed 3, never interrupted (its own process, as a user runs it): what
    the killed and resumed run below must equal, and the source network of the --init-from test."""
    root = tmp_path_factory.mktemp("uninterrupted")
    run, tmp = root / "run", root / "tmp"
    tmp.mkdir()
    process = _train_process(run, tmp, *TINY, "--out", str(run), "--episodes", "8", "--seed", "3")
    out, err = process.communicate(timeout=600)
    assert process.returncode == 0, err
    return run


@pytest.mark.slow  # uninterrupted: a real train-foam run; SIGKILL and resume
@needs_openfoam
def test_sigkill_then_resume_leaves_no_solver_and_no_duplicate(tmp_path, uninterrupted):
    run, tmp = tmp_path / "run", tmp_path / "tmp"
    tmp.mkdir()
    # 6 episodes are not all over by the kill in update 3: in 8 steps an env ends at most 2 (3+ steps each)
    process = _train_process(run, tmp, *TINY, "--out", str(run), "--episodes", "6", "--seed", "3")
    checkpoints = run / "checkpoints"
    _wait_for(lambda: checkpoints.is_dir() and any(p.name == "2" for p in checkpoints.iterdir()), process,
              400, "a second checkpoint")
    os.kill(process.pid, signal.SIGKILL)  # mid-update: solvers are running or paused between steps
    process.wait()
    assert _no_solver_left(tmp), f"solvers outlived the killed trainer: {processes_under(tmp)}"
    before, _ = _check_records(run)

    resumed = _train_process(run, tmp, "--resume", str(run), "--episodes", "8", "--pool", "2")
    out, err = resumed.communicate(timeout=600)
    assert resumed.returncode == 0, err
    assert "Traceback" not in err and "mean iterations over the last 100 episodes" in out
    assert "episodes in flight replayed" in err, err
    rows, metrics = _check_records(run)
    saved = json.loads((run / "config.json").read_text())
    assert saved["episodes_target"] == 8 and len(saved["resumed_utc"]) == 1
    last_checkpoint = max(int(p.name) for p in checkpoints.iterdir() if p.name.isdigit())
    assert metrics[-1]["update"] == last_checkpoint
    # rows that the killed run wrote for updates its checkpoints did not keep were redone, not duplicated
    kept = [r for r in before if r["update"] <= 2]
    assert [(r["env"], r["iterations"], r["actions"]) for r in rows[:len(kept)]] == [
        (r["env"], r["iterations"], r["actions"]) for r in kept]
    summary = json.loads((run / "summary.json").read_text())
    assert summary["episodes"] == len(rows) >= 8 and summary["complete"]
    assert summary["final_mean_iterations"] == pytest.approx(sum(r["iterations"] for r in rows) / len(rows))
    linear = sum(r["linear_iterations"] for r in rows) / len(rows)
    assert summary["final_mean_linear_iterations"] == pytest.approx(linear)
    assert linear > 5 * summary["final_mean_iterations"]
    assert summary["final_mean_solver_time_s"] > 0
    assert 0 < summary["pool_utilisation"] <= 1 and summary["episodes_per_hour"] > 0
    assert _no_solver_left(tmp)
    # the episodes in flight were replayed, so killed + resumed is the run that was never interrupted
    same = ("env", "seed", "steps", "iterations", "outcome", "actions")
    assert [[r[k] for k in same] for r in rows] == [
        [r[k] for k in same] for r in EpisodeLog.load(uninterrupted / "episodes.csv", 10**9).rows]


def test_reward_kind_sets_its_scale_and_is_fixed_on_resume(capsys, tmp_path):
    scales = {}
    for kind in ("iterations", "linear-iterations", "solver-time"):
        assert main(["train-foam", "--print-config", "--reward", kind]) == 0
        printed = json.loads(capsys.readouterr().out)
        assert printed["foam"]["reward"] == kind
        scales[kind] = printed["ppo"]["reward_scale"]
    assert scales == {"iterations": 1e-3, "linear-iterations": 1e-4, "solver-time": 0.1}
    assert main(["train-foam", "--print-config", "--reward", "linear-iterations",
                 "--reward-scale", "2e-4"]) == 0
    assert json.loads(capsys.readouterr().out)["ppo"]["reward_scale"] == 2e-4  # a flag beats the default
    code, err = run_cli(capsys, "--resume", str(tmp_path), "--reward", "solver-time")
    assert code == 2 and "--reward cannot be used with --resume" in err


def test_the_convergence_check_is_a_flag_of_the_config_and_fixed_on_resume(capsys, tmp_path):
    assert main(["train-foam", "--print-config"]) == 0
    assert json.loads(capsys.readouterr().out)["foam"]["confirm_alpha_u"] is None  # the paper's test
    assert main(["train-foam", "--print-config", "--confirm-alpha-u", "0.9"]) == 0
    assert json.loads(capsys.readouterr().out)["foam"]["confirm_alpha_u"] == 0.9
    code, err = run_cli(capsys, "--resume", str(tmp_path), "--confirm-alpha-u", "0.9")
    assert code == 2 and "--confirm-alpha-u cannot be used with --resume" in err


def test_episodes_csv_of_an_older_version_loads_without_the_cost_columns(tmp_path):
    old = tmp_path / "episodes.csv"
    old.write_text("index,env,update,seed,inlet_velocity,steps,iterations,return,outcome,cause,wall_time_s,"
                   "solver_idle_s,actions\n0,0,1,5,40.0,3,250,-250.0,converged,,4.5,0.1,\"[[0.9, 0.9]]\"\n"
                   "1,1,1,6,41.0,3,260,-260.0,converged,,4.5\n")  # the second row is short: dropped
    log = EpisodeLog.load(old, 10)
    assert [r["iterations"] for r in log.rows] == [250]
    assert math.isnan(log.rows[0]["linear_iterations"]) and math.isnan(log.moving_mean("solver_time_s"))
    log.flush()  # rewritten with the new columns, empty for the old rows
    assert EpisodeLog.load(old, 10).rows[0]["return"] == -250.0
    assert "linear_iterations,solver_time_s" in old.read_text().splitlines()[0]


@pytest.mark.slow  # uninterrupted: a real train-foam run
@needs_openfoam
def test_init_from_starts_with_the_other_runs_network_and_refuses_a_mismatch(capsys, tmp_path, uninterrupted):
    from jaxsimrl.introspect import load_policy

    source, tuned = uninterrupted, tmp_path / "tuned"  # a finished TINY run, seed 3 (this run's is 2)
    # a learning rate of ~0 keeps the network where it started: it must be the source's, not a new one
    assert main(["train-foam", *TINY, "--episodes", "2", "--seed", "2", "--lr", "1e-12", "--init-from",
                 str(source), "--out", str(tuned)]) == 0
    capsys.readouterr()
    before, after = load_policy(source), load_policy(tuned)
    leaves = zip(jax.tree.leaves(before.params.params), jax.tree.leaves(after.params.params), strict=True)
    assert all(np.allclose(a, b, atol=1e-6) for a, b in leaves)
    # the observation statistics carry on from the source's
    assert float(after.params.normalizer.count) > float(before.params.normalizer.count) > 0
    assert json.loads((tuned / "config.json").read_text())["init_from"]["update"] == before.update
    code, err = run_cli(capsys, *TINY, "--init-from", str(source), "--out", str(tmp_path / "bad"),
                        "--config", _write(tmp_path / "wide.json", {"foam": {"action_high": [0.99, 0.99]}}))
    assert code == 2 and "acts in the box" in err and not (tmp_path / "bad").exists()


def _write(path: Path, content: dict) -> str:
    path.write_text(json.dumps(content))
    return str(path)
