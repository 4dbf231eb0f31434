"""foam_bridge stands alone: the solver plugin imports neither the trainer (jaxsimrl) nor JAX."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

MODULES = ["foam_bridge", "foam_bridge.batched", "foam_bridge.env", "foam_bridge.grid",
           "foam_bridge.gym_envs", "foam_bridge.backends.local", "foam_bridge.backends.ray_backend"]


@pytest.mark.parametrize("module", MODULES)
def test_import_pulls_in_neither_jax_nor_jaxsimrl(module):
    code = (f"import sys, {module}\n"
            "heavy = sorted(m for m in sys.modules if m.split('.')[0] in ('jax', 'jaxlib', 'jaxsimrl'))\n"
            "print(heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_no_foam_bridge_source_mentions_a_jaxsimrl_import():
    package = Path(__file__).parent.parent / "foam_bridge"
    offenders = [str(path) for path in package.rglob("*.py")
                 if any(line.lstrip().startswith(("import jaxsimrl", "from jaxsimrl"))
                        for line in path.read_text().splitlines())]
    assert offenders == []
