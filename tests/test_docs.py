"""The documentation site builds strictly, and what the docs say matches the code and the repository.

- ``mkdocs build --strict`` into a temporary directory: a broken link or anchor, or a page missing from
  the nav, fails it (mkdocs.yml's ``validation``). Built without ``-q``: with it, mkdocs 1.6 drops the
  warnings that strict mode counts and returns 0 over a broken link; any WARNING line fails too.
- The CLI reference is generated from the parsers at build time (docs/hooks/cli_reference.py): every
  subcommand and every argument of ``jaxsimrl`` is on the built page.
- Every ``jaxsimrl ...`` command in a shell block of README.md, docs/*.md and experiments/README.md
  parses with the real parser (the blocks that are not run, e.g. long trainings, cannot drift either).
- Every repository path those pages cite (a number's source, a script, a test) exists.
"""

from __future__ import annotations

import contextlib
import glob
import html
import importlib.util
import io
import re
import shlex
import shutil
import subprocess
import sys
from itertools import product
from pathlib import Path
from types import ModuleType, SimpleNamespace

import pytest

from jaxsimrl.cli.main import build_parser

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), ROOT / "experiments" / "README.md"]
#: Top-level folders of the repository: a cited path starting with one of them must exist.
TOP = ("benchmarks/", "docs/", "experiments/", "foam_bridge/", "jaxsimrl/", "scripts/", "tests/")
SHELL_BLOCK = re.compile(r"^```(?:shell|bash)\n(.*?)^```", re.MULTILINE | re.DOTALL)


def _load_hook() -> ModuleType:
    """docs/hooks/cli_reference.py, the mkdocs hook that writes the CLI page (not a package module)."""
    path = ROOT / "docs" / "hooks" / "cli_reference.py"
    spec = importlib.util.spec_from_file_location("cli_reference", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


HOOK = _load_hook()


def build_site(config: Path, out: Path) -> list[str]:
    """Build the site of ``config`` strictly into ``out``; the problems it reports (empty: a clean build).

    Not ``-q``: with it mkdocs 1.6 silences the warnings that ``--strict`` counts, and a broken link
    builds with exit status 0. Every WARNING or ERROR line is a problem, and so is a non-zero exit.
    """
    result = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(config),
                             "-d", str(out)], cwd=config.parent, capture_output=True, text=True,
                            timeout=300, check=False)
    output = result.stdout + result.stderr
    problems = [line for line in output.splitlines() if line.startswith(("WARNING", "ERROR"))]
    if result.returncode != 0:
        problems.append(f"exit status {result.returncode}: {output[-3000:]}")
    return problems


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("site")
    problems = build_site(ROOT / "mkdocs.yml", out)
    assert not problems, "\n".join(problems)
    return out


def test_the_site_builds_strictly_with_every_page(site: Path) -> None:
    for page in sorted((ROOT / "docs").glob("*.md")):
        built = site / "index.html" if page.stem == "index" else site / page.stem / "index.html"
        assert built.is_file(), f"{page.name} was not built"
        # read offline (a cluster's login node): no script or stylesheet from elsewhere
        assert not re.search(r'<(script|link)[^>]*(src|href)="https?://', built.read_text()), page.name


def test_the_strict_build_fails_on_a_broken_link(tmp_path: Path) -> None:
    """A scratch copy of the docs with a link to a missing page and one outside the docs tree fails."""
    shutil.copytree(ROOT / "docs", tmp_path / "docs")
    shutil.copy(ROOT / "mkdocs.yml", tmp_path / "mkdocs.yml")
    with (tmp_path / "docs" / "index.md").open("a") as page:
        page.write("\n[missing](no-such-page.md) and [outside](../benchmarks/RESULTS.md)\n")
    problems = build_site(tmp_path / "mkdocs.yml", tmp_path / "site")
    assert any("no-such-page.md" in line for line in problems), problems
    assert any("../benchmarks/RESULTS.md" in line for line in problems), problems


def test_the_cli_page_has_every_command_and_argument(site: Path) -> None:
    page = html.unescape((site / "cli" / "index.html").read_text())
    commands = HOOK.subcommands(build_parser())
    assert len(commands) >= 6  # train-lorenz, eval-lorenz, grid-foam, train-foam, eval-foam, plot
    for name, parser in commands.items():
        assert f'id="{HOOK.slug(name)}"' in page, name
        for action in parser._actions:
            positional = action.metavar if isinstance(action.metavar, str) else action.dest
            for shown in action.option_strings or [positional]:
                if shown not in ("-h", "--help"):
                    assert shown in page, f"jaxsimrl {name}: {shown} is not on the CLI page"


def _commands(text: str) -> list[list[str]]:
    """The arguments of each ``jaxsimrl`` command in the shell blocks of ``text``."""
    commands = []
    for block in SHELL_BLOCK.findall(text):
        for line in block.replace("\\\n", " ").splitlines():
            lexer = shlex.shlex(line, posix=True, punctuation_chars=True)
            lexer.whitespace_split, lexer.commentors = True, "#"
            tokens = list(lexer)
            for start, token in enumerate(tokens):
                if Path(token).name == "jaxsimrl":
                    rest = tokens[start + 1:]
                    ends = [i for i, t in enumerate(rest) if set(t) <= set(";&|()<>")]
                    commands.append(rest[:ends[0]] if ends else rest)
    return commands


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_documented_commands_parse(page: Path) -> None:
    for args in _commands(page.read_text()):
        err = io.StringIO()
        try:
            with contextlib.redirect_stderr(err):
                build_parser().parse_args(args)
        except SystemExit:
            pytest.fail(f"{page.name}: `jaxsimrl {' '.join(args)}` does not parse: {err.getvalue().strip()}")


def test_the_command_finder_sees_commands() -> None:
    found = _commands("```shell\nRAY_AUTH_MODE=token .venv/bin/jaxsimrl plot runs/x --out \\\n  a.png && ls\n"
                      "# jaxsimrl not-a-command\n```\n")
    assert found == [["plot", "runs/x", "--out", "a.png"]]
    assert any(_commands(page.read_text()) for page in PAGES)


def _expand(path: str) -> list[str]:
    """``a_{x,y}.csv`` -> both names; ``<v>`` and ``*`` are wildcards."""
    path = re.sub(r"<[^>]*>", "*", path)
    parts = re.split(r"\{([^{}]*)\}", path)
    choices = [[p] if i % 2 == 0 else p.split(",") for i, p in enumerate(parts)]
    return ["".join(c) for c in product(*choices)]


def _exists(cited: str) -> bool:
    file, _, test = cited.partition("::")
    for pattern in _expand(file):
        matches = glob.glob(str(ROOT / pattern)) if "*" in pattern else [str(ROOT / pattern)]
        if not any(Path(m).exists() for m in matches):
            return False
    return not test or "<" in test or f"def {test}(" in (ROOT / file).read_text()


def cited_paths(text: str) -> set[str]:
    """Repository paths in code spans and relative links of a page."""
    cited = set()
    for span in re.findall(r"`([^`\n]+)`", text):
        for token in span.split():
            token = token.strip(".,;:()[]'\"")
            if token.startswith(TOP) and not re.search(r"-v\d+$", token):  # not a gymnasium id
                cited.add(token)
    return cited


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_cited_repository_paths_exist(page: Path) -> None:
    text = page.read_text()
    missing = sorted(p for p in cited_paths(text) if not _exists(p))
    links = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    missing += [link for link in links if "://" not in link and not (page.parent / link).exists()]
    assert not missing, f"{page.relative_to(ROOT)} cites paths that do not exist: {missing}"


def test_the_path_check_can_fail() -> None:
    assert _exists("tests/test_docs.py::test_the_path_check_can_fail")
    assert _exists("experiments/foam/constant_factors/full_test_alpha_p_V{25,50,75}.csv")
    assert _exists("tests/<file>.py::<test>") and not _exists("tests/<file>.rs")
    assert not _exists("tests/test_docs.py::no_such_test")
    assert not _exists("benchmarks/RESULTS_nothing.md")
    spans = "see `python benchmarks/bench_env.py --out F.json`, `runs/x`, `jaxsimrl/Lorenz-v0`"
    assert cited_paths(spans) == {"benchmarks/bench_env.py"}


def test_the_experiments_index_names_every_run() -> None:
    """A run or evaluation directory under experiments/ (config.json or eval.json) is in the index."""
    index = (ROOT / "experiments" / "README.md").read_text()
    runs = {p.parent for name in ("config.json", "eval.json") for p in (ROOT / "experiments").rglob(name)}
    missing = sorted(str(run.relative_to(ROOT)) for run in runs
                     if "checkpoints" not in run.parts and f"{run.name}/" not in index)
    assert len(runs) >= 20
    assert not missing, f"experiments/README.md does not name {missing}"


def test_the_hook_fills_only_the_cli_page_and_needs_its_marker() -> None:
    def page(uri: str) -> SimpleNamespace:
        return SimpleNamespace(file=SimpleNamespace(src_uri=uri))

    assert HOOK.on_page_markdown(f"x {HOOK.MARKER}", page("foam.md"), None, None) == f"x {HOOK.MARKER}"
    filled = HOOK.on_page_markdown(f"# CLI\n\n{HOOK.MARKER}\n", page(HOOK.PAGE), None, None)
    assert "## jaxsimrl train-lorenz" in filled and HOOK.MARKER not in filled
    with pytest.raises(ValueError, match="cli-reference"):
        HOOK.on_page_markdown("# CLI\n", page(HOOK.PAGE), None, None)
