"""foam_bridge._records: one episode record, one codec (info["episode"] JSON and the episodes.csv row).

No solver needed: the real records are those of the committed runs' episodes.csv files (every version of
the file's columns) and of hand-made infos as the env and the batch hand them out.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from foam_bridge._records import COLUMNS, EpisodeRecord, read_rows, rows_to_csv
from jaxsimrl.apps.foam.episodes import EpisodeLog

ROOT = Path(__file__).resolve().parents[1]
COMMITTED = sorted(ROOT.glob("experiments/*/*/episodes.csv"))


def test_committed_runs_read_back_and_each_row_is_one_record():
    assert COMMITTED, "the repository ships runs with an episodes.csv"
    for path in COMMITTED:
        text = path.read_text()
        rows = read_rows(text)
        assert len(rows) == text.count("\n") - 1, path  # no row of a committed run is dropped
        for row in rows:
            back = EpisodeRecord.from_row(row).row(row["env"], row["update"], row["index"])
            assert rows_to_csv([back]) == rows_to_csv([row]), (path, row)


#: Rows as train-foam writes them today (every column; a built-in case's step height and node; a user's
#: case without them, an episode without a seed and with its costs unknown).
CURRENT = (",".join(COLUMNS) + "\n"
           "0,0,1,818220272,51.936893900503904,2,4000,26608.0,32.730000000000004,-4000.0,truncated,,"
           '62.53033826000137,4.373785689991564,"[[0.353728, 0.741917], [0.269199, 0.727407]]",vm,'
           "0.018564893691955832,\n"
           '1,1,1,,,1,100,,,-4000.0,crashed,worker died,2.5,0.0,"[[0.9, 0.5]]",,,pitzDaily-3\n')


def test_a_file_of_the_current_columns_is_rewritten_byte_for_byte():
    rows = read_rows(CURRENT)
    assert [r["seed"] for r in rows] == [818220272, None] and math.isnan(rows[1]["step_height"])
    assert [r["case"] for r in rows] == ["", "pitzDaily-3"]
    assert rows_to_csv(rows) == CURRENT


def test_json_round_trip_keeps_every_field_and_leaves_out_what_is_not_known():
    record = EpisodeRecord(outcome="converged", iterations=412, seed=7, inlet_velocity=44.2,
                           step_height=0.0127, actions=[[0.95, 0.9], [0.9, 0.8]], episode_return=-412.0,
                           linear_iterations=5000, solver_time_s=3.5, wall_time_s=9.0, solver_idle_s=0.5,
                           residuals={"Ux": 1e-4}, env_id=1)
    data = json.loads(json.dumps(record.to_json()))
    assert "node" not in data and "confirmations" not in data
    assert data["steps"] == 2 and data["return"] == -412.0
    assert EpisodeRecord.from_json(data) == record


def test_a_record_the_batch_writes_for_a_dead_worker_reads_as_one_with_the_costs_unknown(tmp_path):
    lost = EpisodeRecord(outcome="crashed", cause="worker died", iterations=100, seed=3, actions=[[0.9, 0.5]],
                         episode_return=-4000.0, wall_time_s=2.0, node="")
    log = EpisodeLog(tmp_path / "episodes.csv")
    log.add(1, 4, {"outcome": "crashed", "episode": lost.to_json()})
    (row,) = log.flush()
    assert (row["index"], row["env"], row["update"], row["steps"]) == (0, 1, 4, 1)
    assert row["cause"] == "worker died" and row["solver_idle_s"] == 0
    assert math.isnan(row["linear_iterations"]) and math.isnan(row["solver_time_s"])
    assert rows_to_csv(EpisodeLog.load(tmp_path / "episodes.csv", 4).rows) == rows_to_csv([row])
    assert EpisodeLog.load(tmp_path / "episodes.csv", 3).rows == []  # rows past a checkpoint are dropped


def test_an_info_without_a_record_still_gives_its_end():
    record = EpisodeRecord.from_info({"outcome": "hung", "cause": "no output", "iterations": 300})
    assert (record.outcome, record.cause, record.iterations, record.steps) == ("hung", "no output", 300, 0)
    assert math.isnan(record.episode_return)


@pytest.mark.parametrize("broken", ["", "0,1", "x,0,1,,44,2,250,,,-250,converged,,1,0,[],,"])
def test_garbled_rows_are_dropped(broken):
    header = ",".join(COLUMNS)
    good = "0,0,1,5,44.2,2,250,,,-250.0,converged,,1.0,0.0,\"[[0.9, 0.5], [0.9, 0.5]]\",host,"
    rows = read_rows(f"{header}\n{good}\n{broken}\n")
    assert [r["iterations"] for r in rows] == [250]



@pytest.mark.parametrize("solver_first", [True, False])
def test_a_solver_record_and_a_lost_worker_record_batch_together_in_either_order(solver_first):
    """CI caught this after a Ray node loss: the solver's record (integer counts) and the host's record
    of the lost episode (NaN costs, no seed) ended in the same step, and gymnasium typed the key's array
    by the first env (``cannot convert float NaN to integer``)."""
    from foam_bridge._batched import _InfoBatcher

    solver = EpisodeRecord(outcome="converged", iterations=300, seed=7, inlet_velocity=40.0,
                           linear_iterations=1234, solver_time_s=2.5, actions=[[0.9, 0.5]]).to_json()
    solver["log"] = {"U": 3}  # an env's own integer extras widen too
    lost = EpisodeRecord(outcome="crashed", cause="node lost: x", iterations=100, seed=None).to_json()
    lost["log"] = {"U": "unknown"}
    order = [(0, solver), (1, lost)] if solver_first else [(1, lost), (0, solver)]
    infos: dict = {}
    batcher = _InfoBatcher(2)
    for env, record in order:
        info = {"final_info": {"episode": record}, "iterations": record["iterations"]}
        infos = batcher.add(infos, info, env)
    episode = infos["final_info"]["episode"]
    assert episode["linear_iterations"][0] == 1234 and math.isnan(episode["linear_iterations"][1])
    assert episode["seed"][0] == 7 and episode["seed"][1] is None
    assert episode["log"]["U"][0] == 3 and episode["log"]["U"][1] == "unknown"
    assert list(infos["iterations"]) == [300, 100] and list(episode["_outcome"]) == [True, True]
    assert isinstance(solver["linear_iterations"], float)  # the record's costs are floats in JSON
