"""A run stopped after a chunk and resumed ends exactly where an uninterrupted run ends; a real Ctrl-C
leaves whole files and a resume hint."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import jax
import numpy as np
import pytest
from test_cli_lorenz import TINY_FLAGS

from jaxsimrl.cli.lorenz import INTERRUPTED, run_train
from jaxsimrl.cli.main import build_parser, main
from jaxsimrl.runs.checkpoint import Checkpoints

pytestmark = pytest.mark.slow  # trainings run twice, and a real process stopped with Ctrl-C

# 5 updates of 64 steps in chunks of 2: checkpoints after updates 2, 4, 5.
TINY = [*TINY_FLAGS, "--seed", "3"]
TIMING = ("wall_time_s", "steps_per_s")


def train(argv, on_chunk=None):
    return run_train(build_parser().parse_args(["train-lorenz", *argv]), on_chunk=on_chunk)


def metrics(run: Path) -> list[dict]:
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    return [{k: v for k, v in row.items() if k not in TIMING} for row in rows]


def final_state(run: Path):
    with Checkpoints(run / "checkpoints", writable=False) as checkpoints:
        return checkpoints.restore(None)


def stop_after(update: int):
    def hook(done: int) -> None:
        if done >= update:
            raise KeyboardInterrupt  # what Ctrl-C does between chunks

    return hook


def test_resumed_run_matches_uninterrupted_run(tmp_path, capsys):
    whole, split = tmp_path / "whole", tmp_path / "split"
    assert train([*TINY, "--out", str(whole)]) == 0
    assert train([*TINY, "--out", str(split)], on_chunk=stop_after(2)) == INTERRUPTED
    assert f"--resume {split}" in capsys.readouterr().err
    assert len(metrics(split)) == 2
    # A crash after a chunk's metrics were written but before its checkpoint landed, cut mid-line.
    with (split / "metrics.jsonl").open("a") as handle:
        handle.write(json.dumps({"update": 3, "env_steps": 192, "policy_loss": 123.0}) + "\n")
        handle.write('{"update": 4, "env_ste')

    assert main(["train-lorenz", "--resume", str(split)]) == 0
    assert metrics(split) == metrics(whole)
    assert [row["update"] for row in metrics(split)] == list(range(1, 6))
    assert len((split / "metrics.csv").read_text().splitlines()) == 6
    (state_a, meta_a), (state_b, meta_b) = final_state(whole), final_state(split)
    assert meta_a["update"] == meta_b["update"] == 5
    leaves_a, leaves_b = jax.tree.leaves(state_a), jax.tree.leaves(state_b)
    assert len(leaves_a) == len(leaves_b) > 5
    for a, b in zip(leaves_a, leaves_b, strict=True):
        np.testing.assert_array_equal(a, b)
    summary_a, summary_b = (json.loads((run / "summary.json").read_text()) for run in (whole, split))
    assert summary_a["total_steps"] == summary_b["total_steps"] == 320
    assert summary_b["wall_time_s"] > 0 and summary_b["complete"]

    # --total-steps may be raised on resume: the run continues to the new end.
    assert main(["train-lorenz", "--resume", str(split), "--total-steps", "448"]) == 0
    assert [row["update"] for row in metrics(split)] == list(range(1, 8))
    assert metrics(split)[:5] == metrics(whole)
    assert json.loads((split / "config.json").read_text())["ppo"]["total_steps"] == 448
    assert sorted(int(p.name) for p in (split / "checkpoints").iterdir()) == [5, 7]


def test_ctrl_c_in_a_real_process_exits_130_with_whole_files(tmp_path):
    run = tmp_path / "run"
    script = Path(sys.executable).with_name("jaxsimrl")
    argv = [*TINY, "--total-steps", str(64 * 400), "--out", str(run)]
    process = subprocess.Popen([str(script), "train-lorenz", *argv], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 240
    while not (run / "summary.json").exists():
        if time.monotonic() > deadline or process.poll() is not None:
            process.kill()
            pytest.fail(f"training did not reach its first checkpoint: {process.communicate()}")
        time.sleep(0.2)
    os.kill(process.pid, signal.SIGINT)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 130
    assert f"jaxsimrl train-lorenz --resume {run}" in err and "Traceback" not in err
    saved = final_state(run)[1]["update"]
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert [row["update"] for row in rows] == list(range(1, saved + 1))
    assert json.loads((run / "summary.json").read_text())["updates"] == saved
    assert not [p for p in run.rglob("*") if p.name.endswith(".tmp") or "orbax-checkpoint-tmp" in p.name]
