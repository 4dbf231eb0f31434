"""Every notebook in experiments/notebooks/ is committed without outputs and runs top to bottom
(nbclient, a fresh python3 kernel, in a temporary directory; JAXSIMRL_NOTEBOOK_QUICK=1 shrinks the
training budget to a smoke run). A foam notebook runs the real simpleFoam: it carries the openfoam
marks."""

from __future__ import annotations

from pathlib import Path

import nbformat
import pytest
from foam_marks import OPENFOAM
from nbclient import NotebookClient

NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "experiments" / "notebooks").glob("*.ipynb"))
CASES = [pytest.param(path, id=path.stem, marks=OPENFOAM if "foam" in path.stem else ())
         for path in NOTEBOOKS]


def test_there_are_notebooks():
    assert {"lorenz_policy.ipynb", "foam_policy.ipynb"} <= {path.name for path in NOTEBOOKS}


@pytest.mark.slow  # a fresh kernel compiles the paper's LSTM trainer: about a minute
@pytest.mark.parametrize("path", CASES)
def test_notebook_is_clean_and_runs(path, tmp_path, monkeypatch):
    notebook = nbformat.read(path, as_version=4)
    code = [cell for cell in notebook.cells if cell.cell_type == "code"]
    assert code and all(not cell.outputs and cell.execution_count is None for cell in code), \
        f"{path.name} is committed with outputs: clear them"
    monkeypatch.setenv("JAXSIMRL_NOTEBOOK_QUICK", "1")
    client = NotebookClient(notebook, timeout=300, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}})
    client.execute()  # raises CellExecutionError with the failing cell's traceback
    errors = [out for cell in code for out in cell.outputs if out.output_type == "error"]
    images = [out for cell in code for out in cell.outputs if "image/png" in out.get("data", {})]
    assert not errors and len(images) >= 4  # Lorenz: trajectory, slice, sensitivity, two PCA plots;
    # foam: training episodes, policy profile, factor history, value
