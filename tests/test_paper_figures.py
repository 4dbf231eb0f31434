"""experiments/paper/fig_foam_pools.py on the small committed train-foam run (no solver needed)."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
RUN = ROOT / "experiments" / "notebooks" / "foam_small_run"


def _script(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "experiments" / "paper" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_pool_figure_places_episodes_at_their_updates_wall_time(tmp_path: Path) -> None:
    script = _script("fig_foam_pools")
    assert script.main([str(RUN), "--episodes", "5", "--out", str(tmp_path)]) == 0
    written = json.loads((tmp_path / "fig_foam_pools.json").read_text())
    (row,) = written["runs"]
    episodes = [json.loads(line) for line in (RUN / "metrics.jsonl").read_text().splitlines()]
    csv_rows = (RUN / "episodes.csv").read_text().splitlines()[1:6]
    iterations = np.array([int(line.split(",")[6]) for line in csv_rows])
    last_update = int(csv_rows[-1].split(",")[2])
    wall = next(m["wall_time_s"] for m in episodes if m["update"] == last_update)
    assert (row["pool"], row["num_envs"], row["episodes"]) == (2, 2, 5)
    assert row["wall_time_s"] == pytest.approx(wall, abs=0.05)
    assert row["episodes_per_hour"] == pytest.approx(5 / wall * 3600, rel=1e-3)
    assert row["final_moving_mean_iterations"] == pytest.approx(iterations.mean(), abs=0.05)
    assert (tmp_path / "fig_foam_pools.png").stat().st_size > 10_000
    with pytest.raises(SystemExit):  # not a run directory: argparse's one-line error, exit 2
        script.main([str(tmp_path / "absent"), "--out", str(tmp_path)])
