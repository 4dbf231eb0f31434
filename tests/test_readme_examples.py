"""Every ```python block of README.md runs as written, as a script in a fresh working directory.

Each block is its own script (``python example.py``) with the current directory a new temporary one,
so relative paths in the examples (``work_dir="runs/foam"``) resolve there, and nothing leaks between
blocks. Blocks that use foam_bridge run the real simpleFoam (the examples use coarse meshes).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from foam_marks import HAVE_OPENFOAM

ROOT = Path(__file__).resolve().parent.parent
BLOCKS = re.findall(r"^```python\n(.*?)^```", (ROOT / "README.md").read_text(), re.MULTILINE | re.DOTALL)
#: Generous: the slowest example (a PPO training run) takes about a minute on a quiet 2-core machine.
TIMEOUT_S = 900


def _params() -> list:
    params = []
    for number, code in enumerate(BLOCKS):
        first = code.strip().splitlines()[0] if code.strip() else "(empty)"
        marks = []
        if "foam_bridge" in code:
            marks = [pytest.mark.openfoam,
                     pytest.mark.skipif(not HAVE_OPENFOAM, reason="simpleFoam not on PATH")]
        params.append(pytest.param(code, id=f"block{number}: {first[:40]}", marks=marks))
    return params


def test_the_readme_has_python_examples():
    assert len(BLOCKS) >= 4  # the Lorenz env, PPO, FoamCaseEnv, BatchedFoamEnv, gymnasium ids, ...


@pytest.mark.parametrize("code", _params())
def test_readme_example_runs_as_written(code: str, tmp_path: Path) -> None:
    script = tmp_path / "example.py"
    script.write_text(code)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    result = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True,
                            text=True, timeout=TIMEOUT_S, check=False)
    assert result.returncode == 0, result.stderr[-3000:]
    leftovers = [p for p in tmp_path.rglob("*") if p.is_dir() and p.name.startswith("env_")]
    assert all(not any(p.iterdir()) for p in leftovers), "an example left case directories behind"
