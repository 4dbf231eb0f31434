"""The import graph of jaxsimrl and foam_bridge has no cycle (issue 17): read from the source with ast.

Every import counts, at module level and inside functions (a function-level import that closes a circle
is still a circle: it only defers the failure to the call). An edge goes from a module to the module it
names (``from pkg import name`` names ``pkg.name`` when that is a module, else ``pkg``), not to the
parent packages an import also runs: a package's ``__init__`` re-exporting its own modules is no cycle.
(The lazy exports of ``jaxsimrl.envs`` and ``jaxsimrl.agents.ppo``, by ``importlib``, only name their own
modules, so leaving them out hides no cycle.)
The same graph collapsed to jaxsimrl's subpackages (policy, evaluation, introspect, ...) must be
acyclic too, so the layers stay layers.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("jaxsimrl", "foam_bridge", "atomicfile")


def modules() -> dict[str, Path]:
    """Dotted module name -> file, for every .py file of the packages."""
    found = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def imported(name: str, path: Path, known: dict[str, Path]) -> Iterator[str]:
    """The modules of ``known`` that ``name`` (at ``path``) imports anywhere in its source."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from .x import y
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base
                       for alias in node.names]
        else:
            continue
        yield from (target for target in targets if target in known and target != name)


def graph() -> dict[str, set[str]]:
    known = modules()
    return {name: set(imported(name, path, known)) for name, path in known.items()}


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for nxt in sorted(edges.get(node, ())):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(edges):
        if node not in index:
            visit(node)
    return found


def layer(name: str) -> str:
    """jaxsimrl's subpackage of a module (jaxsimrl.policy.loading -> jaxsimrl.policy), an application
    (jaxsimrl.apps.foam.solve.drive -> jaxsimrl.apps.foam); foam_bridge is one."""
    parts = name.split(".")
    if parts[0] == "foam_bridge":
        return "foam_bridge"
    return ".".join(parts[:3] if parts[1:2] == ["apps"] else parts[:2])


def test_the_graph_is_read_from_the_source():
    edges = graph()
    # a module-level and a function-level import that are known to exist, so an empty graph cannot pass
    assert "jaxsimrl.policy.loading" in edges["jaxsimrl.introspect.loading"]
    assert "jaxsimrl.envs.lorenz" in edges["jaxsimrl.agents.ppo.policy"]  # make_policy's default env
    assert "jaxsimrl.introspect.loading" in edges["jaxsimrl"]  # jaxsimrl.load_policy, on first use
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_module_imports_itself_back():
    assert cycles(graph()) == []


def test_the_subpackages_are_layers():
    collapsed: dict[str, set[str]] = {}
    for name, targets in graph().items():
        collapsed.setdefault(layer(name), set()).update(layer(t) for t in targets if layer(t) != layer(name))
    assert cycles(collapsed) == []


def test_the_trained_policy_sits_below_evaluation_introspection_and_solve():
    edges = graph()
    below = {t for name, targets in edges.items() if layer(name) == "jaxsimrl.policy" for t in targets}
    above = {"jaxsimrl.evaluation", "jaxsimrl.introspect", "jaxsimrl.apps.foam", "jaxsimrl.cli"}
    assert not {layer(t) for t in below} & above


@pytest.mark.slow  # subprocesses that import JAX
def test_loading_and_acting_import_no_plotting(tmp_path):
    """jaxsimrl.load_policy and jaxsimrl.policy.load_policy, then one action of the shipped controller, in a
    fresh interpreter: matplotlib (most of a second, on every `jaxsimrl solve`) stays out."""
    import json
    import subprocess
    import sys

    from jaxsimrl.apps.foam.solve.controller import DEFAULT_CONTROLLER

    script = ("import sys, numpy as np, jaxsimrl, jaxsimrl.policy\n"
              "from jaxsimrl.apps.foam.solve.controller import DEFAULT_CONTROLLER\n"
              "for load in (jaxsimrl.load_policy, jaxsimrl.policy.load_policy):\n"
              "    policy = load(DEFAULT_CONTROLLER)\n"
              "    print(type(policy).__name__, policy.act(np.ones(policy.obs_dim))[0].shape)\n"
              "print(sorted(name for name in sys.modules if name.split('.')[0] == 'matplotlib'))\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300,
                         cwd=tmp_path, check=True).stdout.splitlines()
    actions = len(json.loads((DEFAULT_CONTROLLER / "provenance.json").read_text())["actions"])
    assert out == [f"LoadedPolicy ({actions},)", f"TrainedPolicy ({actions},)", "[]"]


#: The project modules a function may import where it runs instead of at its module's top: each loads JAX,
#: orbax or matplotlib (test_deferred_modules_are_heavy measures it), which `jaxsimrl --help`, a flag
#: error and solve's start must not wait for. Every other import of a project module is at the top.
DEFERRED = {"jaxsimrl.agents.ppo", "jaxsimrl.agents.ppo.batch", "jaxsimrl.apps.foam.evaluation.plots",
            "jaxsimrl.apps.foam.evaluation.policy", "jaxsimrl.apps.foam.vec_env", "jaxsimrl.envs.host",
            "jaxsimrl.envs.host_async", "jaxsimrl.envs.lorenz", "jaxsimrl.evaluation.lorenz_eval",
            "jaxsimrl.evaluation.plots", "jaxsimrl.introspect.loading", "jaxsimrl.policy",
            "jaxsimrl.runs.checkpoint", "jaxsimrl.runs.training"}


def function_level_imports() -> list[tuple[str, str]]:
    """(module, imported project module) for every import of a project module inside a function."""
    known, found = modules(), []
    for name, path in known.items():
        for function in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(function, ast.FunctionDef | ast.AsyncFunctionDef):
                for node in ast.walk(function):
                    if isinstance(node, ast.Import):
                        found += [(name, alias.name) for alias in node.names if alias.name in known]
                    elif isinstance(node, ast.ImportFrom) and node.module in known:
                        targets = (f"{node.module}.{alias.name}" for alias in node.names)
                        found += [(name, target if target in known else node.module) for target in targets]
    return sorted(set(found))


def test_imports_are_at_the_top_but_for_the_heavy_ones():
    found = function_level_imports()
    assert ("jaxsimrl.training.lorenz", "jaxsimrl.runs.training") in found  # the scan sees one that is known
    assert [(name, target) for name, target in found if target not in DEFERRED] == []


@pytest.mark.slow  # a fresh interpreter per module
def test_deferred_modules_are_heavy():
    import subprocess
    import sys

    heavy = {"jax", "orbax", "matplotlib"}
    code = ("import sys, importlib; module = importlib.import_module(sys.argv[1])\n"
            "for name in getattr(module, '__all__', []): getattr(module, name)  # a lazy package's names\n"
            "print(sorted({m.split('.')[0] for m in sys.modules}))")
    for module in sorted(DEFERRED):
        loaded = subprocess.run([sys.executable, "-c", code, module], capture_output=True, text=True,
                                check=True, cwd=ROOT, timeout=120).stdout
        assert heavy & set(ast.literal_eval(loaded)), module
