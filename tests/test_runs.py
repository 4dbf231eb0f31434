"""Run-directory building blocks without training: atomic writes, metrics files, summary, checkpoints,
Ctrl-C deferral and the plain-text progress lines."""

from __future__ import annotations

import io
import json
import math
import os
import shutil
import signal
import stat

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxsimrl.runs import atomic
from jaxsimrl.runs.checkpoint import Checkpoints
from jaxsimrl.runs.progress import TrainingProgress
from jaxsimrl.runs.run_dir import MetricsLog, RunDir, summarise
from jaxsimrl.runs.training import chunk_rows, interrupts_deferred


# ---- atomic writes ---------------------------------------------------------------------------------
def test_atomic_write_replaces_content_with_normal_permissions(tmp_path):
    target = tmp_path / "a.json"
    previous = os.umask(0o027)  # the umask in force at the write decides, as for a plain open()
    try:
        atomic.atomic_write_json(target, {"x": 1})
        atomic.atomic_write_json(target, {"x": 2})
    finally:
        os.umask(previous)
    assert json.loads(target.read_text()) == {"x": 2}
    assert stat.S_IMODE(target.stat().st_mode) == 0o640
    assert os.listdir(tmp_path) == ["a.json"]


def test_failed_write_leaves_old_file_and_no_temp_file(tmp_path, monkeypatch):
    target = tmp_path / "summary.json"
    target.write_text("old")

    def broken_fsync(fd):
        raise OSError("disk full")

    # Fail after the data went into the temp file but before the rename.
    monkeypatch.setattr(atomic.os, "fsync", broken_fsync)
    with pytest.raises(OSError, match="disk full"):
        atomic.atomic_write_text(target, "new content " * 1000)
    assert target.read_text() == "old"
    assert os.listdir(tmp_path) == ["summary.json"]


def test_unserialisable_json_writes_nothing(tmp_path):
    target = tmp_path / "eval.json"
    with pytest.raises(TypeError):
        atomic.atomic_write_json(target, {"bad": object()})
    assert not target.exists() and os.listdir(tmp_path) == []


# ---- run directory and metrics -----------------------------------------------------------------------
def _rows(updates, episodes=1):
    return [{"update": u, "env_steps": 64 * u, "wall_time_s": 0.5 * u, "steps_per_s": 128.0,
             "mean_episode_return": float(u) if episodes else math.nan, "episodes": episodes}
            for u in updates]


def test_metrics_files_hold_the_same_rows_and_nan_as_null(tmp_path):
    run = RunDir.create(tmp_path / "run")
    log = MetricsLog(run)
    log.extend(_rows([1, 2], episodes=0))
    log.extend(_rows([3]))
    lines = [json.loads(line) for line in run.metrics_jsonl.read_text().splitlines()]
    assert [row["update"] for row in lines] == [1, 2, 3]
    assert lines[0]["mean_episode_return"] is None and lines[2]["mean_episode_return"] == 3.0
    csv_lines = run.metrics_csv.read_text().splitlines()
    assert csv_lines[0].split(",") == list(lines[0])
    assert len(csv_lines) == 4 and csv_lines[1].split(",")[4] == ""


def test_load_drops_rows_past_the_checkpoint_and_a_torn_line(tmp_path):
    run = RunDir.create(tmp_path / "run")
    MetricsLog(run).extend(_rows([1, 2, 3, 4]))
    with run.metrics_jsonl.open("a") as handle:
        handle.write('{"update": 5, "env_st')  # a write cut off by a crash
    log = MetricsLog.load(run, up_to_update=2)
    assert [row["update"] for row in log.rows] == [1, 2]
    assert log.env_steps == 128 and log.wall_time_s == 1.0


def test_summary_final_return_is_episode_weighted_over_last_updates_with_episodes():
    rows = _rows(range(1, 9))
    rows[-1].update(episodes=0, mean_episode_return=math.nan)  # update 8: no episode ended
    rows[-2].update(episodes=3)  # update 7 counts three times
    summary = summarise(rows, {"seed": 4})
    assert summary["final_return_updates"] == [3, 4, 5, 6, 7]
    assert summary["final_mean_return"] == pytest.approx((3 + 4 + 5 + 6 + 3 * 7) / 7)
    assert summary["total_steps"] == 512 and summary["steps_per_s"] == pytest.approx(512 / 4.0)
    assert summary["seed"] == 4
    assert math.isnan(summarise(_rows([1, 2], episodes=0))["final_mean_return"])


def test_run_dir_refuses_non_empty_out_and_non_runs(tmp_path):
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "file").write_text("x")
    with pytest.raises(ValueError, match="not empty"):
        RunDir.create(tmp_path / "busy")
    with pytest.raises(ValueError, match="not a run directory"):
        RunDir.existing(tmp_path / "busy")
    with pytest.raises(ValueError, match="does not exist"):
        RunDir.existing(tmp_path / "missing")


def test_chunk_rows_share_the_chunk_time_between_updates():
    metrics = {"env_steps": np.array([192, 256]), "episodes": np.array([0, 2], np.int32),
               "mean_episode_return": np.array([np.nan, -5.0], np.float32)}
    rows = chunk_rows(metrics, first_update=3, count=2, steps_before=128, wall_before=10.0, chunk_time=2.0)
    assert [r["update"] for r in rows] == [3, 4]
    assert [r["wall_time_s"] for r in rows] == [11.0, 12.0]
    assert rows[0]["steps_per_s"] == 64.0 and isinstance(rows[1]["episodes"], int)


# ---- checkpoints ------------------------------------------------------------------------------------
def _tree(scale):
    return {"params": {"w": jnp.arange(6.0).reshape(2, 3) * scale}, "rng": jax.random.PRNGKey(scale),
            "step": jnp.int32(scale)}


def test_checkpoints_keep_last_two_and_restore_exactly(tmp_path):
    with Checkpoints(tmp_path / "checkpoints") as checkpoints:
        for step in (2, 4, 6):
            checkpoints.save(step, _tree(step), {"update": step})
    assert sorted(p.name for p in (tmp_path / "checkpoints").iterdir()) == ["4", "6"]
    with Checkpoints(tmp_path / "checkpoints", writable=False) as checkpoints:
        assert checkpoints.latest_step() == 6 and checkpoints.read_meta() == {"update": 6}
        state, meta = checkpoints.restore(_tree(1))
        older, _ = checkpoints.restore(_tree(1), step=4)
    assert meta == {"update": 6}
    for got, want in zip(jax.tree.leaves(state), jax.tree.leaves(_tree(6)), strict=True):
        np.testing.assert_array_equal(got, want)
    assert int(older["step"]) == 4


def test_checkpoint_restore_into_a_different_layout_is_a_one_line_value_error(tmp_path):
    with Checkpoints(tmp_path / "checkpoints") as checkpoints:
        checkpoints.save(1, _tree(1), {})
        wrong = {**_tree(1), "params": {"w": jnp.zeros((3, 3))}}
        with pytest.raises(ValueError, match=r"shape \(2, 3\), expected \(3, 3\)"):
            checkpoints.restore(wrong)
    with pytest.raises(ValueError, match="no checkpoint"):
        Checkpoints(tmp_path / "nothing", writable=False)


def test_damaged_checkpoint_is_a_one_line_value_error(tmp_path):
    with Checkpoints(tmp_path / "checkpoints") as checkpoints:
        checkpoints.save(1, _tree(1), {"update": 1})
        checkpoints.save(2, _tree(2), {"update": 2})
    shutil.rmtree(tmp_path / "checkpoints" / "2" / "meta")
    (tmp_path / "checkpoints" / "1" / "meta" / "metadata").write_text("{torn")
    with Checkpoints(tmp_path / "checkpoints", writable=False) as checkpoints:
        for read in (checkpoints.read_meta, lambda: checkpoints.restore(_tree(1))):
            with pytest.raises(ValueError, match=r"checkpoint 2 .* is damaged \(no meta item\)"):
                read()
        with pytest.raises(ValueError, match=r"checkpoint 1 .* is damaged \(.+\); remove it") as error:
            checkpoints.read_meta(step=1)
    assert "\n" not in str(error.value)


# ---- Ctrl-C and progress ----------------------------------------------------------------------------
def test_ctrl_c_inside_deferred_block_waits_for_the_block():
    finished = []
    with pytest.raises(KeyboardInterrupt), interrupts_deferred():
        os.kill(os.getpid(), signal.SIGINT)
        finished.append(True)  # still runs: the interrupt is held back
    assert finished == [True]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_progress_prints_plain_lines_off_a_tty():
    stream = io.StringIO()
    with TrainingProgress(total_steps=1000, stream=stream) as progress:
        progress.update(500, 1234.0, math.nan, update=1, num_updates=2)
        progress.update(1000, 2000.0, -12.5, update=2, num_updates=2)
    lines = stream.getvalue().splitlines()
    assert lines == ["update 1/2  env steps 500/1,000  1,234 steps/s  mean return -",
                     "update 2/2  env steps 1,000/1,000  2,000 steps/s  mean return -12.5"]
