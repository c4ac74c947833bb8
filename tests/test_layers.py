"""The layer contract and the absence of import cycles, checked on every CI run.

The contracts themselves are in ``pyproject.toml`` (``[tool.importlinter]``): ``fe`` never imports
``podkrig``; the stages import only downward (cli → study → reports → io/diagnosis/sensors →
online → surrogate → offline → ga/parameters → exceptions); numerics never import the CLI,
reports, study, the file formats (``podkrig.io``) or plotting libraries, nor h5py, openpyxl or
pint directly (the snapshot store excepted).
"""

import pathlib

import grimp
import pytest
from importlinter import cli as importlinter_cli

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_import_contracts_are_kept(monkeypatch):
    monkeypatch.chdir(ROOT)
    monkeypatch.syspath_prepend(str(ROOT))
    exit_code = importlinter_cli.lint_imports(config_filename=str(ROOT / "pyproject.toml"), no_cache=True,
                                              no_logo=True)
    assert exit_code == 0, "an import contract is broken: run `lint-imports` for the chain"


def _cycles(graph):
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    modules = sorted(graph.modules)
    edges = {m: sorted(b for b in graph.find_modules_directly_imported_by(m) if b in graph.modules)
             for m in modules}
    index, low, stack, on_stack, found, counter = {}, {}, [], set(), [], 0
    for root in modules:
        if root in index:
            continue
        work = [(root, iter(edges[root]))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        x = stack.pop()
                        on_stack.discard(x)
                        comp.append(x)
                        if x == v:
                            break
                    if len(comp) > 1:
                        found.append(sorted(comp))
            elif w not in index:
                index[w] = low[w] = counter
                counter += 1
                stack.append(w)
                on_stack.add(w)
                work.append((w, iter(edges[w])))
            elif w in on_stack:
                low[v] = min(low[v], index[w])
    return found


def test_no_import_cycles(monkeypatch):
    monkeypatch.syspath_prepend(str(ROOT))
    cycles = _cycles(grimp.build_graph("podkrig", "fe"))
    assert cycles == [], f"import cycles: {cycles}"


@pytest.mark.parametrize("graph_edges, expected", [
    ({"a": ["b"], "b": ["a"], "c": []}, [["a", "b"]]),
    ({"a": ["b"], "b": ["c"], "c": []}, []),
])
def test_cycle_finder_finds_cycles(graph_edges, expected):
    class Graph:
        modules = set(graph_edges)

        @staticmethod
        def find_modules_directly_imported_by(m):
            return set(graph_edges[m])

    assert _cycles(Graph) == expected


def test_public_api_resolves_every_name():
    """Every name ``podkrig`` advertises exists where it says, and ``import podkrig`` stays light."""
    import subprocess
    import sys as _sys

    import podkrig

    for name in podkrig.__all__:
        assert getattr(podkrig, name) is not None, name
    code = "import sys, podkrig; assert 'numba' not in sys.modules and 'podkrig.online' not in sys.modules"
    subprocess.run([_sys.executable, "-c", code], check=True, cwd=ROOT)
