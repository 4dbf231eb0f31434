"""The core names no application (issue 34): no module of jaxsimrl outside jaxsimrl.apps imports
foam_bridge or an application, nor holds the string "foam" in its code; an application plugs in through
jaxsimrl.plugin's contract alone, as the OpenFOAM one does and as a new one would."""

from __future__ import annotations

import ast
import re
import sys
import textwrap
from importlib.metadata import EntryPoint
from pathlib import Path

import pytest

import foam_bridge
import jaxsimrl.plugin as plugin
from foam_bridge._env import FAILURES
from foam_bridge._standin import Profile, StandIn
from jaxsimrl.cli.main import build_parser
from jaxsimrl.envs.protocol import AsyncHostBatch, HostBatch
from jaxsimrl.policy.spec import env_spec

ROOT = Path(__file__).resolve().parents[1] / "jaxsimrl"


def _core_files() -> list[Path]:
    return [path for path in sorted(ROOT.rglob("*.py")) if path.relative_to(ROOT).parts[0] != "apps"]


def _docstrings(tree: ast.AST) -> set[int]:
    bodies = [node.body for node in ast.walk(tree)
              if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef)]
    return {id(body[0].value) for body in bodies
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)}


def _application_names(path: Path) -> list[str]:
    """What in ``path``'s code names an application: its imports of one, and its strings with "foam"."""
    tree = ast.parse(path.read_text(), str(path))
    docs, found = _docstrings(tree), []
    for node in ast.walk(tree):
        names = ([alias.name for alias in node.names] if isinstance(node, ast.Import)
                 else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
        found += [f"imports {name}" for name in names
                  if name.split(".")[0] == "foam_bridge" or name.startswith(plugin.APPS_PACKAGE + ".")]
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docs:
            found += [f"string {node.value!r}"] if "foam" in node.value.lower() else []
    return found


def test_the_scan_sees_an_import_and_a_branch() -> None:
    """The scan itself can fail: a file that imports foam_bridge and branches on "foam" is caught."""
    assert len(_core_files()) > 50
    assert _application_names(ROOT / "apps" / "foam" / "spec.py")  # the application's own imports
    source = ROOT.parent / "tests" / "_branching_core_example.py"
    source.write_text('import foam_bridge._env\nif env == "foam":\n    pass\n')
    try:
        assert _application_names(source) == ["imports foam_bridge._env", "string 'foam'"]
    finally:
        source.unlink()


def test_no_core_module_names_an_application() -> None:
    named = {str(path.relative_to(ROOT.parent)): found for path in _core_files()
             if (found := _application_names(path))}
    assert named == {}


def test_jaxsimrl_uses_foam_bridge_s_public_face_alone() -> None:
    """Every import of foam_bridge in jaxsimrl (its OpenFOAM application) is ``import foam_bridge`` or
    ``from foam_bridge import NAME`` with NAME in its ``__all__``: never a module behind the face."""
    deep, unknown = [], []
    for path in sorted(ROOT.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            where = f"{path.relative_to(ROOT.parent)}:{getattr(node, 'lineno', 0)}"
            if isinstance(node, ast.Import):
                deep += [where for alias in node.names if alias.name.startswith("foam_bridge.")]
            elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("foam_bridge."):
                deep.append(where)
            elif isinstance(node, ast.ImportFrom) and node.module == "foam_bridge":
                unknown += [f"{where} {a.name}" for a in node.names if a.name not in foam_bridge.__all__]
    assert deep == [] and unknown == []


def _step_requests(tree: ast.AST, methods: tuple[str, ...] = ("step",)) -> list[int]:
    """Lines that build a step request to a solver worker (``Request(env, "step", ...)``, or through a
    name ``request`` that stands for it); ``methods``: the requests to look for."""
    return [node.lineno for node in ast.walk(tree) if isinstance(node, ast.Call)
            and str(getattr(node.func, "id", getattr(node.func, "attr", ""))).lower() == "request"
            and len(node.args) > 1 and getattr(node.args[1], "value", None) in methods]


def test_jaxsimrl_drives_no_solver_itself() -> None:
    """solve, eval, grid and rollouts step solvers through foam_bridge's loops (solve: its episode pool),
    never with a loop of their own: no module of jaxsimrl builds a step request."""
    assert _step_requests(ast.parse('backend.run([Request(0, "step", {"action": a})])')) == [1]
    found = {str(path.relative_to(ROOT.parent)): lines for path in sorted(ROOT.rglob("*.py"))
             if (lines := _step_requests(ast.parse(path.read_text(), str(path))))}
    assert found == {}


def test_foam_bridge_drives_its_solvers_from_one_place() -> None:
    """The episode pool, the lock-step and asynchronous training batches and their replay all reset and
    step solvers through FoamBatchCore: one method builds each request, nothing else in foam_bridge does."""
    package = Path(foam_bridge.__file__).parent
    found = {str(path.relative_to(package)): lines for path in sorted(package.rglob("*.py"))
             if (lines := _step_requests(ast.parse(path.read_text(), str(path)), ("step", "reset")))}
    assert list(found) == ["_batched.py"] and len(found["_batched.py"]) == 2


def test_foam_bridge_s_internals_are_private_and_its_face_complete() -> None:
    """foamlib's layout: the package's names are its face, every module behind them is ``_name`` (but the
    public module ``foamdict``), and every name of ``__all__`` loads."""
    package = Path(foam_bridge.__file__).parent
    modules = [path for path in package.iterdir() if path.suffix == ".py" or (path / "__init__.py").exists()]
    public = {path.stem for path in modules if not path.stem.startswith("_")}
    assert public == set(foam_bridge._MODULES)
    missing = [name for name in foam_bridge.__all__ if getattr(foam_bridge, name, None) is None]
    assert missing == [] and set(foam_bridge._EXPORTS) <= set(foam_bridge.__all__)


def test_the_docs_show_foam_bridge_s_public_face_alone() -> None:
    """What a user copies (README, docs pages) imports no private module of foam_bridge."""
    pages = [ROOT.parent / "README.md", *sorted((ROOT.parent / "docs").rglob("*.md"))]
    deep = re.compile(r"(?:from|import)\s+foam_bridge\._")
    found = [f"{page.name}:{number}" for page in pages
             for number, line in enumerate(page.read_text().splitlines(), 1) if deep.search(line)]
    assert len(pages) > 5 and found == []


def test_the_foam_application_plugs_in_through_the_contract() -> None:
    (app,) = [app for app in plugin.applications() if app.env == "foam"]
    assert app.failed_outcomes == frozenset(FAILURES)  # spelled out there, so that finding it stays light
    commands = build_parser()._subparsers._group_actions[0].choices
    expected = {"train-lorenz", "plot", "train-foam", "eval-foam", "grid-foam", "solve", "family"}
    assert expected <= set(commands)
    assert plugin.load(app.env_spec).__module__ == "jaxsimrl.apps.foam.spec"


def test_a_new_application_plugs_in_through_an_entry_point(tmp_path: Path, monkeypatch) -> None:
    """A toy application in another distribution: its command and its runs' env, no edit of the core."""
    (tmp_path / "toyapp.py").write_text(textwrap.dedent('''
        from jaxsimrl.plugin import App
        from jaxsimrl.policy.spec import lorenz_spec

        APP = App(env="toy", commands=("toyapp",), env_spec="toyapp:spec")


        def spec(record):
            return lorenz_spec(record)


        def register(subparsers):
            subparsers.add_parser("toy-run").set_defaults(func=lambda args: 7)
    '''))
    monkeypatch.syspath_prepend(str(tmp_path))
    point = EntryPoint(name="toy", value="toyapp", group=plugin.ENTRY_POINT_GROUP)
    monkeypatch.setattr(plugin, "entry_points", lambda group: [point] if group == point.group else [])
    plugin.applications.cache_clear()
    try:
        assert plugin.application("toy").env_spec == "toyapp:spec"
        assert build_parser().parse_args(["toy-run"]).func(None) == 7
        assert env_spec({"env": "toy"}).obs_names[0] == "x"  # the Lorenz spec it hands on
        with pytest.raises(ValueError, match="known: foam, lorenz, toy"):
            env_spec({"env": "cfd"})
    finally:
        plugin.applications.cache_clear()
        sys.modules.pop("toyapp", None)


def test_the_foam_batches_implement_the_core_s_host_contracts() -> None:
    """The trainer's two host adapters drive an application's batch through jaxsimrl.envs.protocol's
    HostBatch and AsyncHostBatch: the OpenFOAM batches have every member (on the stand-in solver)."""
    fast = StandIn(Profile(iterations=(150,), seconds_per_iteration=(1e-4,), reset_s=0.001))
    lock_step = foam_bridge.BatchedFoamEnv(foam_bridge.FoamEnvConfig(mesh_scale=0.5), num_envs=2, pool=1,
                                           seed=0, make_env=fast)
    asynchronous = foam_bridge.AsyncFoamEnv(foam_bridge.FoamEnvConfig(mesh_scale=0.5), num_envs=2,
                                            batch_size=1, pool=1, seed=0, make_env=fast)
    try:
        assert isinstance(lock_step, HostBatch) and not isinstance(lock_step, AsyncHostBatch)
        assert isinstance(asynchronous, AsyncHostBatch)
    finally:
        lock_step.close()
        asynchronous.close()
