"""The package's structure: imports run one way, down the pipeline, and nothing hides it.

Every module of ``dftl_warp/`` and ``kernels/`` (installed as ``dftl_warp.kernels``) is parsed;
every import is counted, those inside functions included. A module may import from its own layer
or from a layer listed before it in :data:`LAYERS`, never from a later one, and the module graph
has no cycle.
"""

from __future__ import annotations

import ast
import graphlib
import re
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

#: the layers, first to last; a package prefix belongs to the layer of its longest listed prefix
LAYERS = [
    ("foundation", ["dftl_warp.errors", "dftl_warp.version", "dftl_warp.options", "dftl_warp.durable",
                    "dftl_warp.checks", "dftl_warp.kernels"]),
    ("usd", ["dftl_warp.usd", "dftl_warp.importers"]),
    ("core", ["dftl_warp.core", "dftl_warp.kernels.core"]),
    ("features", ["dftl_warp.features", "dftl_warp.kernels.features"]),
    ("solvers", ["dftl_warp.solvers", "dftl_warp.kernels.solvers"]),
    ("output", ["dftl_warp.output", "dftl_warp.kernels.output"]),
    ("simulation", ["dftl_warp.simulation", "dftl_warp.kernels.simulation", "dftl_warp.guides",
                    "dftl_warp.kernels.guides"]),
    ("study, render", ["dftl_warp.study", "dftl_warp.render", "dftl_warp.kernels.render"]),
    ("batch", ["dftl_warp.batch"]),
    ("commands", ["dftl_warp.commands"]),
    ("entry points", ["dftl_warp.cli", "dftl_warp.__main__", "dftl_warp"]),
]


def module_files() -> dict[str, Path]:
    files = {}
    for base, prefix in ((ROOT / "dftl_warp", "dftl_warp"), (ROOT / "kernels", "dftl_warp.kernels")):
        for path in base.rglob("*.py"):
            parts = list(path.relative_to(base).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            files[".".join([prefix] + parts)] = path
    return files


def layer_of(module: str) -> int:
    best, found = -1, None
    for index, (_, prefixes) in enumerate(LAYERS):
        for p in prefixes:
            if (module == p or module.startswith(p + ".")) and len(p) > best:
                best, found = len(p), index
    if found is None:
        raise AssertionError(f"{module} belongs to no layer: add it to LAYERS")
    return found


def imports_of(module: str, path: Path, known: set[str]) -> set[str]:
    """The package modules ``module`` imports, anywhere in its body."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            # "from package import module" imports the module
            names = [target] + [f"{target}.{a.name}" for a in node.names]
        else:
            continue
        for name in names:
            while name and name not in known:
                name = name.rpartition(".")[0]
            if name and name != module:
                found.add(name)
    return found


@pytest.fixture(scope="module")
def graph():
    files = module_files()
    known = set(files)
    return {m: imports_of(m, p, known) for m, p in files.items()}


def test_every_module_has_a_layer(graph):
    for module in graph:
        layer_of(module)


def test_imports_run_down_the_pipeline(graph):
    upward = []
    for module, targets in sorted(graph.items()):
        for target in sorted(targets):
            # a package's __init__ may re-export what its own modules define
            if target.startswith(module + "."):
                continue
            if layer_of(target) > layer_of(module):
                upward.append(f"{module} ({LAYERS[layer_of(module)][0]}) imports {target} "
                              f"({LAYERS[layer_of(target)][0]})")
    assert not upward, "imports against the pipeline:\n" + "\n".join(upward)


def test_no_import_cycle(graph):
    # a package's __init__ importing its own modules is not a cycle of design: leave those edges out
    edges = {m: {t for t in targets if not t.startswith(m + ".")} for m, targets in graph.items()}
    try:
        tuple(graphlib.TopologicalSorter(edges).static_order())
    except graphlib.CycleError as exc:
        pytest.fail(f"import cycle: {' -> '.join(exc.args[1])}")


def test_core_and_solvers_do_not_import_the_usd_reader(graph):
    """The Model, the State and the solvers work on arrays, not stages: the float-precision check
    they share with the USD reader (``check_lengths``) lives in the foundation (dftl_warp.checks),
    not in dftl_warp.usd.curves, which the core and the solvers imported for it."""
    from dftl_warp.checks import check_lengths

    assert layer_of(check_lengths.__module__) == 0
    usd = [i for i, (name, _) in enumerate(LAYERS) if name == "usd"][0]
    lower = {"core", "solvers"}
    found = [f"{m} imports {t}" for m, targets in sorted(graph.items()) if LAYERS[layer_of(m)][0] in lower
             for t in sorted(targets) if layer_of(t) == usd]
    assert not found, "\n".join(found)


def test_no_module_is_over_600_lines():
    long = [f"{p.relative_to(ROOT)}: {n}" for p in module_files().values()
            if (n := len(p.read_text().splitlines())) > 600]
    assert not long, long


def test_no_path_manipulation():
    offenders = []
    for path in list(module_files().values()) + list((ROOT / "scripts").glob("*.py")):
        text = path.read_text()
        if re.search(r"__path__\s*(\.|\+?=)", text) or re.search(r"sys\.path\.(insert|append)\(\s*0?,?\s*str\(ROOT\)", text):
            offenders.append(str(path.relative_to(ROOT)))
    assert not offenders, offenders


def test_every_package_is_installed():
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    on_disk = {m for m, p in module_files().items() if p.name == "__init__.py"}
    assert listed == on_disk
