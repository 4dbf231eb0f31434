"""Fair baselines (issue 18, section 2): the family's best constant chosen from a grid over conditions,
grid-foam over several (step height, inlet velocity) conditions, and the per-case oracle's choice.

The selection is checked on hand-made grids; one real 2-condition x 2-triple grid-foam runs simpleFoam
on the coarsest usable mesh (0.4) with the train criterion and a 300-iteration cap. eval-foam's
case_oracle on a real case is in test_eval_foam.py (it needs that module's saved run).
"""

from __future__ import annotations

import csv
import json
import math

import pytest
from foam_marks import needs_openfoam

from foam_bridge._config import FoamEnvConfig
from foam_bridge._grid import (
    GRID_COLUMNS_3D,
    GridCell,
    best_cell,
    read_grid_csv,
    write_grid_csv,
)
from jaxsimrl.apps.foam.evaluation.family import family_best, family_best_json, grid_cap
from jaxsimrl.cli.main import main

H, H2 = 0.0127, 0.0254


def grid(table: dict[tuple[float, float], list[tuple[int, str]]], cap: int | None = 1000) -> list[GridCell]:
    """Cells of a 2-condition grid (h and 2h at 50 m/s): factors -> [(iterations, outcome) on h, on 2h]."""
    return [GridCell(u, p, its, outcome, 1.0, step_height=height, inlet_velocity=50.0, max_iterations=cap)
            for i, height in enumerate((H, H2)) for (u, p), runs in table.items()
            for its, outcome in [runs[i]]]


def test_a_failure_counts_at_the_cap_not_where_it_stopped():
    # (0.9, 0.9) is fastest on h and crashes early on 2h: counted where it stopped (50 iterations) it
    # would win; at the cap (1000) it costs 1000 / 400 = 2.5x there
    cells = grid({(0.9, 0.9): [(200, "converged"), (50, "crashed")],
                  (0.8, 0.8): [(300, "converged"), (400, "converged")]})
    best = family_best(cells, 1000)
    assert best.factors == (0.8, 0.8)
    assert best.ratios == (((H, 50.0), 1.5), ((H2, 50.0), 1.0))
    assert best.mean_ratio == pytest.approx(math.sqrt(1.5)) and best.worst_ratio == 1.5
    assert (best.solver_runs, best.simple_iterations, best.max_iterations) == (4, 950, 1000)
    # a cap at 500 makes the crash cost 1.25x only: then (0.9, 0.9) wins (sqrt(1 * 1.25) < sqrt(1.5))
    assert family_best(cells, 500).factors == (0.9, 0.9)


def test_a_cell_best_on_no_condition_wins_when_it_is_best_on_average():
    cells = grid({(0.9, 0.5): [(100, "converged"), (300, "converged")],
                  (0.9, 0.9): [(300, "converged"), (100, "converged")],
                  (0.95, 0.7): [(110, "converged"), (120, "converged")]})
    best = family_best(cells, 1000)
    assert best.factors == (0.95, 0.7)  # neither condition's best cell (both are 3x on the other)
    assert best.mean_ratio == pytest.approx(math.sqrt(1.1 * 1.2)) and best.worst_ratio == pytest.approx(1.2)
    assert [best_cell([c for c in cells if c.step_height == h]).factors for h in (H, H2)] == [(0.9, 0.5),
                                                                                              (0.9, 0.9)]


def test_a_condition_where_nothing_converged_is_left_out_and_named():
    cells = grid({(0.9, 0.9): [(200, "converged"), (1000, "truncated")],
                  (0.8, 0.8): [(250, "converged"), (70, "diverged")]})
    best = family_best(cells, 1000)
    assert best.factors == (0.9, 0.9) and best.left_out == ((H2, 50.0),) and best.mean_ratio == 1.0
    report = family_best_json(best, cells, 1000, "test")
    assert report["best"]["left_out"] == [{"step_height": H2, "inlet_velocity": 50.0}]
    assert report["cost"]["solver_runs"] == 4 and report["cost"]["simple_iterations"] == 1520
    nothing = grid({(0.9, 0.9): [(1000, "truncated"), (1000, "truncated")]})
    assert family_best(nothing, 1000) is None and family_best_json(None, nothing, 1000, "t")["best"] is None


def test_a_grid_missing_a_cell_on_a_condition_is_rejected():
    cells = grid({(0.9, 0.9): [(200, "converged"), (300, "converged")],
                  (0.8, 0.8): [(250, "converged"), (260, "converged")]})
    with pytest.raises(ValueError, match="every factor cell once on every condition"):
        family_best(cells[:-1], 1000)


def test_the_cap_of_a_grid_is_its_record_else_inferred():
    cells = grid({(0.9, 0.9): [(200, "converged"), (300, "converged")]})
    assert grid_cap(cells) == (1000, "recorded")
    old = [GridCell(0.9, 0.9, 200, "converged", 1.0), GridCell(0.8, 0.8, 700, "truncated", 1.0)]
    assert grid_cap(old) == (700, "the runs that reached it")
    assert grid_cap(old[:1])[0] == 200  # no record, nothing reached the cap: a lower bound


def test_conditions_round_trip_through_grid_csv_and_old_files_still_load(tmp_path):
    cells = grid({(0.9, 0.9): [(200, "converged"), (300, "converged")]})
    cells = [GridCell(c.alpha_u, c.alpha_p, c.iterations, c.outcome, c.wall_time_s, alpha_t=0.95,
                      step_height=c.step_height, inlet_velocity=c.inlet_velocity, max_iterations=1000)
             for c in cells]
    write_grid_csv(cells, tmp_path / "grid.csv")
    with open(tmp_path / "grid.csv", newline="") as handle:
        header = tuple(next(csv.reader(handle)))
    assert header == ("step_height", "inlet_velocity", *GRID_COLUMNS_3D, "max_iterations")
    assert read_grid_csv(tmp_path / "grid.csv") == cells
    (tmp_path / "old.csv").write_text("alpha_u,alpha_p,iterations,outcome,wall_time_s\n"
                                      "0.9,0.8,412,converged,3.5\n")
    (old,) = read_grid_csv(tmp_path / "old.csv")
    assert old == GridCell(0.9, 0.8, 412, "converged", 3.5)
    assert (old.condition, old.max_iterations) == ((None, None), None)


def test_eval_foams_baseline_of_a_family_grid_is_the_family_best(tmp_path):
    from jaxsimrl.apps.foam.evaluation.baseline import baseline_from_csv

    cells = grid({(0.9, 0.5): [(100, "converged"), (300, "converged")],
                  (0.9, 0.9): [(300, "converged"), (100, "converged")],
                  (0.95, 0.7): [(110, "converged"), (120, "converged")]})
    write_grid_csv(cells, tmp_path / "family.csv")
    baseline = baseline_from_csv(tmp_path / "family.csv")
    assert baseline.factors == (0.95, 0.7) and baseline.grid_iterations is None
    assert baseline.family["best"]["worst_ratio"] == pytest.approx(1.2)
    assert baseline.family["cost"] == {"solver_runs": 6, "simple_iterations": 1030, "wall_time_s": 6.0}
    assert "2 conditions" in baseline.source
    write_grid_csv([c for c in cells if c.step_height == H], tmp_path / "one.csv")  # one condition: as before
    one = baseline_from_csv(tmp_path / "one.csv")
    assert one.factors == (0.9, 0.5) and one.grid_iterations == 100 and one.family is None


def test_the_oracle_keeps_each_cases_best_run_and_the_grids_cost():
    from jaxsimrl.apps.foam.evaluation.oracle import ORACLE, ORACLE_GRID, choose

    cells = [(0.9, 0.8), (0.95, 0.9), (0.95, 0.95)]

    def row(velocity, sample, iterations, outcome, controller=ORACLE):
        return {"controller": controller, "geometry": "h", "step_height": H, "velocity": velocity,
                "sample": sample, "iterations": iterations, "outcome": outcome, "wall_time_s": 2.0,
                "cpu_time_s": 1.5}

    rows = [row(50.0, 0, 90, "crashed"), row(50.0, 1, 300, "converged"), row(50.0, 2, 250, "converged"),
            row(50.0, 0, 400, "converged", "tutorial_defaults"),
            row(75.0, 0, 500, "truncated"), row(75.0, 1, 500, "truncated"), row(75.0, 2, 40, "diverged")]
    relabelled, summary = choose(rows, cells, 500)
    assert [r["controller"] for r in relabelled] == [ORACLE_GRID, ORACLE_GRID, ORACLE, "tutorial_defaults",
                                                     ORACLE, ORACLE_GRID, ORACLE_GRID]
    at50 = summary["h"]["50"]
    assert at50["factors"] == [0.95, 0.95] and at50["solver_runs"] == 3
    assert (at50["simple_iterations"], at50["wall_time_s"], at50["cpu_time_s"]) == (640, 6.0, 4.5)
    assert [g["outcome"] for g in at50["grid"]] == ["crashed", "converged", "converged"]
    assert summary["h"]["75"]["factors"] == [0.9, 0.8]  # nothing converged: the first cell, at the cap


def test_the_oracles_axes_and_the_defaults_k_omega_factor():
    from types import SimpleNamespace

    from jaxsimrl.apps.foam.evaluation.baseline import as_action
    from jaxsimrl.apps.foam.evaluation.eval_spec import TUTORIAL_DEFAULTS
    from jaxsimrl.apps.foam.evaluation.oracle import oracle_axes, oracle_cells

    three = FoamEnvConfig(relax_k_omega="action", action_low=(0.2, 0.2, 0.2), action_high=(0.95, 0.95, 0.95))
    spec = SimpleNamespace(oracle_alpha_u=None, oracle_alpha_p=(0.5,), oracle_alpha_t=None,
                           grid_alpha_u=(0.8, 0.9), grid_alpha_p=(0.9,), grid_alpha_t=None)
    baseline_grid = grid({(0.95, 0.6): [(1, "converged")] * 2, (0.7, 0.6): [(1, "converged")] * 2})
    # a 2-D baseline grid on a 3-action run: k/omega at 0.8, as its 2-factor constants are run
    assert oracle_axes(spec, three, baseline_grid) == ((0.95, 0.7), (0.5,), (0.8,))
    assert oracle_axes(spec, three, None) == ((0.8, 0.9), (0.5,), (0.8,))  # small grid; k/omega 0.8
    assert oracle_cells([(0.8, 0.9), (0.5,), (0.8,)]) == [(0.8, 0.5, 0.8), (0.9, 0.5, 0.8)]
    assert oracle_axes(spec, FoamEnvConfig(), None) == ((0.8, 0.9), (0.5,))
    with pytest.raises(ValueError, match="oracle_alpha_t"):
        oracle_axes(SimpleNamespace(**{**vars(spec), "oracle_alpha_t": (0.9,)}), FoamEnvConfig(), None)
    # the tutorial's own settings on a 3-action run: U 0.9, p 0.8 and k/omega 0.8 (its ".*" 0.8)
    assert as_action(three, TUTORIAL_DEFAULTS) == (0.9, 0.8, 0.8)


def test_repeated_conditions_are_one_line_exit_2(capsys, tmp_path):
    code = main(["grid-foam", "--alpha-u", "0.9", "--alpha-p", "0.9", "--inlet-velocity", "50", "50.0",
                 "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "--inlet-velocity" in err and "distinct" in err
    assert not (tmp_path / "out").exists()


@pytest.mark.slow  # a grid of whole runs
@needs_openfoam
def test_grid_foam_over_two_conditions(capsys, tmp_path):
    out = tmp_path / "family"
    code = main(["grid-foam", "--alpha-u", "0.95", "--alpha-p", "0.9", "0.95", "--alpha-t", "0.95",
                 "--step-height", str(H), str(H2), "--inlet-velocity", "50", "--mesh-scale", "0.4",
                 "--pool", "2", "--max-iterations", "300", "--out", str(out)])
    stdout = capsys.readouterr().out
    assert code == 0
    assert sorted(p.name for p in out.iterdir()) == ["family_best.json", "grid.csv",
                                                      "grid_2h_V50_alpha_t_0.95.png",
                                                      "grid_h_V50_alpha_t_0.95.png"]
    cells = read_grid_csv(out / "grid.csv")
    assert [(c.step_height, c.alpha_p) for c in cells] == [(H, 0.9), (H, 0.95), (H2, 0.9), (H2, 0.95)]
    assert all((c.inlet_velocity, c.alpha_u, c.alpha_t, c.max_iterations) == (50.0, 0.95, 0.95, 300)
               for c in cells)
    # the step height reached the solver: the taller step's flow takes longer at the same factors
    by_height = {h: sum(c.iterations for c in cells if c.step_height == h) for h in (H, H2)}
    assert by_height[H2] > by_height[H]
    report = json.loads((out / "family_best.json").read_text())
    best = family_best(cells, 300)
    assert report["max_iterations"] == 300 and len(report["conditions"]) == 2
    assert list(report["best"]["factors"].values()) == list(best.factors)
    assert report["best"]["mean_ratio"] == pytest.approx(best.mean_ratio)
    assert report["cost"]["solver_runs"] == 4
    assert report["cost"]["simple_iterations"] == sum(c.iterations for c in cells)
    line = next(line for line in stdout.splitlines() if line.startswith("family best over 2 conditions"))
    assert f"{report['cost']['simple_iterations']:,} SIMPLE iterations" in line
