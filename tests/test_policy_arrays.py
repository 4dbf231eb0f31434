"""A run's acting arrays (jaxsimrl.policy.arrays): the orbax checkpoint's policy, never a stale one."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from jaxsimrl.apps.foam.solve import DEFAULT_CONTROLLER
from jaxsimrl.policy import load_policy, loading
from jaxsimrl.policy.arrays import ACTING_FILE, export_acting_arrays, read_acting_arrays
from jaxsimrl.runs.run_dir import RunDir


def test_the_shipped_controller_acts_alike_from_its_arrays_and_its_checkpoint(tmp_path: Path,
                                                                             monkeypatch) -> None:
    run = Path(shutil.copytree(DEFAULT_CONTROLLER, tmp_path / "controller"))
    assert read_acting_arrays(RunDir.existing(run), None) is not None  # the shipped file is up to date
    fast = load_policy(run)
    monkeypatch.setattr(loading, "read_acting_arrays", lambda run, checkpoint: None)
    restored = load_policy(run)
    observations = np.random.default_rng(0).uniform(0.0, 3.0, (8, fast.obs_dim)).astype(np.float32)
    assert np.array_equal(fast.act(observations)[0], restored.act(observations)[0])
    assert (fast.update, fast.env_steps, fast.checkpoint) == (restored.update, restored.env_steps,
                                                             restored.checkpoint)


def test_arrays_of_another_checkpoint_are_ignored(tmp_path: Path) -> None:
    run = Path(shutil.copytree(DEFAULT_CONTROLLER, tmp_path / "controller"))
    (run / ACTING_FILE).unlink()
    assert read_acting_arrays(RunDir.existing(run), None) is None  # none: orbax restores
    export_acting_arrays(run)
    step = RunDir.existing(run).checkpoint_steps()[-1]
    assert read_acting_arrays(RunDir.existing(run), step)[0] == step
    assert read_acting_arrays(RunDir.existing(run), step + 1) is None  # asked for another checkpoint
    shutil.copytree(run / "checkpoints" / str(step), run / "checkpoints" / str(step + 1))
    assert read_acting_arrays(RunDir.existing(run), None) is None  # the run trained on: a newer one
    shutil.rmtree(run / "checkpoints" / str(step + 1))
    some_file = next(p for p in sorted((run / "checkpoints" / str(step)).rglob("*")) if p.is_file())
    some_file.write_bytes(some_file.read_bytes() + b" ")
    assert read_acting_arrays(RunDir.existing(run), None) is None  # the checkpoint was replaced
