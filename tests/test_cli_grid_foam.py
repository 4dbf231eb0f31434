"""``jaxsimrl grid-foam`` and foam_bridge._grid: CLI errors, CSV/heatmap output, and a real 2x2 grid.

The end-to-end test runs real simpleFoam on the smallest usable mesh (0.4) and checks one cell against
FoamCaseEnv driven directly with the same constant factors.
"""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
from pathlib import Path

import matplotlib.text
import numpy as np
import pytest
from foam_marks import needs_openfoam
from slow_case import STOP_LIMIT_S, all_into_a_step, episode_progress, seconds_until, wait_until

from foam_bridge._config import MESH_SCALE_USABLE_MIN, FoamEnvConfig
from foam_bridge._grid import (
    GRID_COLUMNS,
    GridCell,
    best_cell,
    cell_label,
    check_factors,
    grid_config,
    heatmap_figure,
    plot_grid,
    read_grid_csv,
    write_grid_csv,
)
from jaxsimrl.cli.main import main

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    """Exit code, stderr and stdout of ``jaxsimrl grid-foam ...`` (argparse exits are caught as codes)."""
    try:
        code = main(["grid-foam", *argv])
    except SystemExit as exit_:
        code = exit_.code
    captured = capsys.readouterr()
    return code, captured.err, captured.out


GOOD = ("--alpha-u", "0.7", "--alpha-p", "0.5")


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (("--alpha-u", "1.5", "--alpha-p", "0.5"), "(0, 1]"),
        (("--alpha-u", "0", "--alpha-p", "0.5"), "(0, 1]"),
        (("--alpha-u", "--alpha-p", "0.5"), "--alpha-u"),
        ((*GOOD, "--mesh-scale", "-1"), "positive"),
        ((*GOOD, "--mesh-scale", "nan"), "positive"),
        ((*GOOD, "--pool", "0"), "positive integer"),
        ((*GOOD, "--max-iterations", "50"), "max_iterations"),
        ((*GOOD, "--criterion", "strict"), "invalid choice"),
        ((*GOOD, "--relax-k-omega", "1.2"), "(0, 1]"),
        ((*GOOD, "--relax-k-omega", "alpha_p"), "(0, 1]"),
    ],
)
def test_bad_arguments_are_one_line_exit_2(capsys, tmp_path, argv, needle):
    code, err, _ = run_cli(capsys, *argv, "--out", str(tmp_path / "out"))
    assert code == 2
    assert err.count("\n") == 1 and needle in err
    assert not (tmp_path / "out").exists()


def test_help_names_the_usable_mesh_scale_minimum(capsys):
    code, _, out = run_cli(capsys, "--help")
    assert code == 0
    assert f">= {MESH_SCALE_USABLE_MIN:g}" in " ".join(out.split())


def test_out_dir_that_is_a_file_is_rejected(capsys, tmp_path):
    target = tmp_path / "taken"
    target.write_text("not a directory")
    code, err, _ = run_cli(capsys, *GOOD, "--out", str(target))
    assert code == 2 and err.count("\n") == 1 and "not a directory" in err
    assert target.read_text() == "not a directory"


def test_missing_openfoam_is_one_line_exit_2(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    code, err, _ = run_cli(capsys, *GOOD, "--out", str(tmp_path / "out"))
    assert code == 2 and err.count("\n") == 1
    assert "openfoam" in err.lower() and "install" in err.lower()


def test_check_factors_and_grid_config_cover_the_grid():
    assert check_factors([0.5, 1.0], "alpha_u") == (0.5, 1.0)
    with pytest.raises(ValueError, match="alpha_p"):
        check_factors([], "alpha_p")
    with pytest.raises(ValueError, match=r"\(0, 1\]"):
        check_factors([0.5, 1.01], "alpha_u")
    cfg = grid_config(FoamEnvConfig(), [0.1, 0.9], [0.5, 1.0])
    assert cfg.action_low == (0.1, 0.2) and cfg.action_high == (0.95, 1.0)



@pytest.mark.parametrize(("extra", "height"), [((), 0.0127), (("--step-height", "0.0254"), 0.0254)])
def test_step_height_reaches_the_grids_config(extra, height):
    from jaxsimrl.apps.foam.cli.grid_foam import _config
    from jaxsimrl.cli.main import build_parser

    args = build_parser().parse_args(["grid-foam", *GOOD, *extra, "--out", "x"])
    assert _config(args).step_height == height


def test_bad_step_height_is_one_line_and_exit_2(capsys, tmp_path):
    code, err, _ = run_cli(capsys, *GOOD, "--step-height", "-1", "--out", str(tmp_path / "out"))
    assert code == 2 and err.count("\n") == 1 and "--step-height" in err


CELLS = [
    GridCell(0.5, 0.5, 834, "converged", 1.0),
    GridCell(0.5, 0.9, 1053, "converged", 1.5),
    GridCell(0.9, 0.5, 3000, "truncated", 2.0),
    GridCell(0.9, 0.9, 1269, "crashed", 0.5),
]


def test_csv_round_trip_and_best_cell(tmp_path):
    path = tmp_path / "grid.csv"
    write_grid_csv(CELLS, path)
    with open(path, newline="") as handle:
        assert tuple(next(csv.reader(handle))) == GRID_COLUMNS
    assert read_grid_csv(path) == CELLS
    assert best_cell(CELLS) == CELLS[0]
    assert best_cell(CELLS[2:]) is None
    assert [cell_label(c) for c in CELLS] == ["834", "1053", ">3000", "crashed\n@1269"]
    assert [p.name for p in tmp_path.iterdir()] == ["grid.csv"]  # no temporary file left behind


def test_a_grid_stopped_part_way_keeps_its_finished_cells(capsys, tmp_path, monkeypatch):
    """grid.csv after every cell: a Ctrl-C after two of four cells leaves those two on disk, and each
    finished cell is a line in a log (no live bar off a terminal)."""
    import jaxsimrl.apps.foam.cli.grid_foam

    def two_cells_then_interrupted(*args, on_cell, **kwargs):
        on_cell(CELLS[1])
        on_cell(CELLS[0])
        raise KeyboardInterrupt

    monkeypatch.setattr(jaxsimrl.apps.foam.cli.grid_foam, "_check_openfoam", lambda: None)
    monkeypatch.setattr(jaxsimrl.apps.foam.cli.grid_foam, "run_grid", two_cells_then_interrupted)
    out = tmp_path / "out"
    argv = ("--alpha-u", "0.5", "0.9", "--alpha-p", "0.5", "0.9", "--out", str(out))
    code, err, stdout = run_cli(capsys, *argv)
    assert code != 0 and "interrupted" in err
    assert read_grid_csv(out / "grid.csv") == [CELLS[1], CELLS[0]]
    lines = stdout.splitlines()
    assert [line.split()[0] for line in lines] == ["[1/4]", "[2/4]", "stopped:"]
    assert "(0.5, 0.9) converged @ 1053" in lines[0]
    assert lines[2] == f"stopped: 2 of 4 cells finished ({out / 'grid.csv'} holds them)"


def test_heatmap_is_a_png_of_the_grid(tmp_path):
    import matplotlib.image

    path = tmp_path / "grid.png"
    plot_grid(CELLS, path, "test grid")
    assert path.read_bytes()[:8] == PNG_MAGIC
    image = matplotlib.image.imread(path)
    assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100
    assert image[..., :3].std() > 0.05  # drawn, not blank


@pytest.mark.parametrize("shape", [(1, 1), (1, 2), (2, 1), (4, 4)])
def test_heatmap_text_fits_inside_the_figure_whatever_the_grid(shape):
    us, ps = [0.5 + 0.1 * i for i in range(shape[0])], [0.5 + 0.1 * j for j in range(shape[1])]
    cells = [GridCell(u, p, 400 + i, "converged" if i else "crashed", 1.0)
             for i, (u, p) in enumerate((u, p) for u in us for p in ps)]
    title = ("SIMPLE iterations to convergence, constant factors\nSIMPLEC, k/omega 0.8, train criterion, "
             "mesh scale 1, V = 44.2 m/s")
    fig = heatmap_figure(cells, title)
    renderer = fig.canvas.get_renderer()
    fig.draw(renderer)
    width, height = fig.bbox.width, fig.bbox.height
    texts = [t for t in fig.findobj(matplotlib.text.Text) if t.get_visible() and t.get_text().strip()]
    assert any("SIMPLEC" in t.get_text() for t in texts)  # the title is among the texts checked
    for text in texts:
        box = text.get_window_extent(renderer)
        assert box.x0 >= 0 and box.x1 <= width and box.y0 >= 0 and box.y1 <= height, text.get_text()


@needs_openfoam
def test_default_grid_cell_runs_the_papers_simplec_with_k_omega_at_0_8(capsys, tmp_path):
    from foam_bridge._env import FoamCaseEnv

    cells = {}
    plain = ("--simple-variant", "SIMPLE", "--relax-k-omega", "alpha_u")
    for name, extra in (("default", ()), ("plain", plain)):
        argv = ("--alpha-u", "0.95", "--alpha-p", "0.95", "--mesh-scale", "0.4", "--max-iterations", "400",
                *extra, "--out", str(tmp_path / name))
        code, err, _ = run_cli(capsys, *argv)
        assert code == 0, err
        (cells[name],) = read_grid_csv(tmp_path / name / "grid.csv")
    explicit = FoamEnvConfig(mesh_scale=0.4, simple_variant="SIMPLEC", relax_k_omega=0.8,
                             inlet_velocity=44.2, max_iterations=400)
    with FoamCaseEnv(explicit, work_dir=tmp_path / "direct") as env:
        env.reset(seed=0)
        while True:
            _, _, terminated, truncated, info = env.step([0.95, 0.95])
            if terminated or truncated:
                break
    assert (cells["default"].outcome, cells["default"].iterations) == ("converged", info["iterations"])
    assert (cells["plain"].outcome, cells["plain"].iterations) != ("converged", info["iterations"])


@pytest.mark.slow  # a grid of whole runs
@needs_openfoam
def test_grid_end_to_end_matches_the_env(capsys, tmp_path):
    from foam_bridge._env import FoamCaseEnv

    out = tmp_path / "out"
    # Mesh 0.4 (the usable minimum): the alpha_u 0.95 cells converge within the cap (237 and 181
    # iterations), the 0.7 ones do not.
    argv = ("--alpha-u", "0.7", "0.95", "--alpha-p", "0.5", "0.95", "--mesh-scale", "0.4", "--pool", "2",
            "--max-iterations", "300", "--simple-variant", "SIMPLEC", "--out", str(out))
    code, err, stdout = run_cli(capsys, *argv)
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["grid.csv", "grid.png"]
    cells = read_grid_csv(out / "grid.csv")
    assert [(c.alpha_u, c.alpha_p) for c in cells] == [(0.7, 0.5), (0.7, 0.95), (0.95, 0.5), (0.95, 0.95)]
    for cell in cells:
        assert cell.outcome in ("converged", "truncated", "crashed", "diverged", "hung")
        assert 0 < cell.iterations <= 300 and cell.wall_time_s > 0
        assert (cell.outcome == "truncated") == (cell.iterations == 300)
    assert (out / "grid.png").read_bytes()[:8] == PNG_MAGIC
    best = best_cell(cells)
    assert best is not None and f"alpha_u={best.alpha_u:g} alpha_p={best.alpha_p:g}" in stdout

    # The best cell again, with FoamCaseEnv driven directly: same iterations and outcome.
    cell = best
    base = FoamEnvConfig(mesh_scale=0.4, simple_variant="SIMPLEC", inlet_velocity=44.2, max_iterations=300)
    cfg = grid_config(base, [0.7, 0.95], [0.5, 0.95])
    env = FoamCaseEnv(cfg, work_dir=tmp_path / "direct", env_id=0)
    try:
        env.reset(seed=0)
        done = False
        while not done:
            _, _, terminated, truncated, info = env.step(np.array([cell.alpha_u, cell.alpha_p]))
            done = terminated or truncated
    finally:
        env.close()
    assert (info["iterations"], info["outcome"]) == (cell.iterations, cell.outcome)


class _ScriptedPool:
    """A stand-in backend: every episode converges on its first step after 100 iterations."""

    def __init__(self) -> None:
        self.resets: list[int] = []
        self.stranded: dict[int, str] = {}  # envs whose worker died beside them: none here

    def node_of(self, env_id: int) -> str:
        return ""

    def run(self, requests):
        from foam_bridge._backends import Reply

        replies = []
        for request in requests:
            if request.method == "reset":
                self.resets.append(request.env_id)
                replies.append(Reply(request.env_id, True, (np.zeros(1), {})))
            else:
                info = {"iterations": 100, "outcome": "converged", "cause": "",
                        "episode": {"wall_time_s": 1.0}}
                replies.append(Reply(request.env_id, True, (np.zeros(1), -100.0, True, False, info)))
        return replies


    def close(self) -> None:
        pass


def test_two_slots_freed_in_one_step_with_one_cell_left_start_only_that_cell(monkeypatch, tmp_path):
    from foam_bridge import _batched as batched
    from foam_bridge._grid import run_grid

    pool = _ScriptedPool()
    monkeypatch.setattr(batched, "make_backend", lambda *args, **kwargs: pool)
    # three cells on two slots: raised IndexError when both slots ended at once
    cells = run_grid(FoamEnvConfig(), [0.9, 0.8, 0.7], [0.9], pool=2, work_dir=tmp_path)
    assert [(c.alpha_u, c.iterations, c.outcome, c.wall_time_s) for c in cells] == [
        (0.9, 100, "converged", 1.0), (0.8, 100, "converged", 1.0), (0.7, 100, "converged", 1.0)]
    assert pool.resets == [0, 1, 0]


@pytest.mark.slow  # slow_case: steps over a minute
@needs_openfoam
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_stopped_grid_on_a_refined_mesh_leaves_no_solver_within_5_s(tmp_path, sig):
    """The built-in step refined 2.5x (128k cells, about half a second an iteration here, so a step of
    100 lasts close to a minute): Ctrl-C (to the whole group, as a terminal sends it) or SIGTERM, sent
    while both solvers are a few iterations into a step, leaves no solver after 5 s and says what
    OUT holds."""
    from foam_bridge._backends.reaper import processes_under

    tmp = tmp_path / "tmp"
    tmp.mkdir()
    process = subprocess.Popen(
        [str(Path(sys.executable).with_name("jaxsimrl")), "grid-foam", "--mesh-scale", "2.5", "--alpha-u",
         "0.95", "--alpha-p", "0.9", "0.95", "--pool", "2", "--out", str(tmp_path / "out")],
        env={**os.environ, "TMPDIR": str(tmp)}, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True)

    try:
        wait_until(lambda: all_into_a_step(tmp, 2) or process.poll() is not None, 300,
                   "both solvers to be 3 iterations into a step")
        assert process.poll() is None, process.communicate()
        assert max(episode_progress(tmp)) < 70  # the step has most of it to go
        if sig == signal.SIGINT:
            os.killpg(process.pid, sig)
        else:
            process.send_signal(sig)
        took = seconds_until(lambda: not processes_under(tmp), 30.0)
        output, _ = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
    assert took < STOP_LIMIT_S, f"a solver ran on for {took:.1f} s after {sig.name}"
    assert process.returncode == 128 + sig
    assert "stopped: 0 of 2 cells finished (nothing was written)" in output, output
