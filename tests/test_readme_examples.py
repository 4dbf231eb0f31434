"""Every example of README.md and docs/*.md runs as written, as a script in a fresh working directory.

What runs: every ```python block (``python example.py``) and every ```bash block (``bash example.sh``,
with ``-e`` and ``pipefail``). Blocks fenced ```shell are commands shown, not run (long trainings,
cluster set-up); tests/test_docs.py still checks that each of their ``jaxsimrl`` commands parses.

Each block is its own script with the current directory a new temporary one, so relative paths in the
examples (``work_dir="runs/foam"``) resolve there, and nothing leaks between blocks. A shell block finds
the project's environment as ``.venv`` there (a link to the one running the tests), as it would in the
repository root. A block that appears on two pages (the README's tour is also in docs/getting-started.md)
runs once. Blocks that use foam_bridge or a foam command run the real simpleFoam (on coarse meshes).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from foam_marks import OPENFOAM

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```(python|bash)\n(.*?)^```", re.MULTILINE | re.DOTALL)
#: Generous: the slowest example (a PPO training run) takes about a minute on a quiet 2-core machine.
TIMEOUT_S = 900
#: The interpreter of a block, by its fence's language.
RUNNERS = {"python": [sys.executable], "bash": ["bash", "-eo", "pipefail"]}
IN_A_VENV = (Path(sys.prefix) / "bin" / "activate").is_file()


def _blocks() -> dict[tuple[str, str], str]:
    """(language, code) -> where it first appears (``page:number``), in page order."""
    blocks: dict[tuple[str, str], str] = {}
    for page in PAGES:
        for number, match in enumerate(FENCE.finditer(page.read_text())):
            blocks.setdefault((match.group(1), match.group(2)), f"{page.relative_to(ROOT)}:{number}")
    return blocks


BLOCKS = _blocks()


def _uses_openfoam(code: str) -> bool:
    foam = r"\bjaxsimrl ((grid|train|eval)-foam|generate-cases)\b"
    return "foam_bridge" in code or re.search(foam, code) is not None


def _is_slow(code: str) -> bool:
    """A block that trains (train-lorenz, train-foam, make_train), solves a whole case or runs a grid
    (its comments aside): tens of seconds each, so the quick tier (``-m "not slow"``) leaves it out."""
    commands = re.compile(r"\b(train-lorenz|train-foam|make_train|grid-foam)\b|\bjaxsimrl solve\b")
    return commands.search(re.sub(r"#.*", "", code)) is not None


def _params() -> list:
    params = []
    for (language, code), where in BLOCKS.items():
        first = code.strip().splitlines()[0] if code.strip() else "(empty)"
        marks = []
        if _uses_openfoam(code):
            marks = list(OPENFOAM)
        if _is_slow(code):
            marks.append(pytest.mark.slow)
        if language == "bash":
            marks.append(pytest.mark.skipif(not IN_A_VENV, reason="the tests run outside a virtual env"))
        params.append(pytest.param(language, code, id=f"{where}: {first[:40].rstrip()}", marks=marks))
    return params


def test_the_docs_have_examples() -> None:
    languages = [language for language, _ in BLOCKS]
    # the Lorenz env, load_policy, PPO, FoamCaseEnv, BatchedFoamEnv, gymnasium ids, ...; the tour
    assert languages.count("python") >= 7 and languages.count("bash") >= 1
    readme = FENCE.findall((ROOT / "README.md").read_text())
    assert readme, "the README's five-minute tour should be a block the tests run"


@pytest.mark.parametrize(("language", "code"), _params())
def test_example_runs_as_written(language: str, code: str, tmp_path: Path) -> None:
    script = tmp_path / ("example.py" if language == "python" else "example.sh")
    script.write_text(code)
    if language == "bash":
        (tmp_path / ".venv").symlink_to(sys.prefix)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    result = subprocess.run([*RUNNERS[language], str(script)], cwd=tmp_path, env=env, capture_output=True,
                            text=True, timeout=TIMEOUT_S, check=False)
    assert result.returncode == 0, result.stderr[-3000:]
    leftovers = [p for p in tmp_path.rglob("*") if p.is_dir() and p.name.startswith("env_")]
    assert all(not any(p.iterdir()) for p in leftovers), "an example left case directories behind"
