"""The package's shape: the layer contract, no import cycles, no private names imported
across modules, a shallow top level and small modules; and the scripts beside it (the
benchmarks, the development studies, the docs generator) small too, the benchmarks and
studies using only the package's public modules and names."""
import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "twolink"
#: The scripts outside the package that the size rule covers too.
SCRIPT_DIRS = ("benchmarks", "docs/studies", "docs/generator")
#: The scripts that may import only the package's public modules and names.
PUBLIC_USERS = ("benchmarks", "docs/studies", "docs/generator")
MAX_LINES = 500
pytest.importorskip("importlinter")


def _modules() -> dict:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def _imports(name: str, path: Path, modules: dict) -> list:
    """(imported module, imported name or None) for every twolink import in ``path``."""
    tree = ast.parse(path.read_text())
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(a.name, None) for a in node.names if a.name.startswith("twolink")]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package.split(".")[:len(package.split(".")) - node.level + 1]
                                + ([node.module] if node.module else []))
            if base.split(".")[0] != "twolink":
                continue
            for a in node.names:
                sub = f"{base}.{a.name}"
                found.append((sub, None) if sub in modules else (base, a.name))
    return found


def test_the_layer_contract_holds():
    """import-linter's layers contract of pyproject.toml: lower never imports higher."""
    run = subprocess.run([sys.executable, "-c", "from importlinter.cli import lint_imports_command;"
                          "lint_imports_command()"], cwd=PACKAGE.parent, capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]
    assert "1 kept, 0 broken" in run.stdout


def test_no_import_cycles():
    modules = _modules()
    graph = {m: {t for t, _ in _imports(m, p, modules) if t in modules and t != m
                 and not m.startswith(t + ".") and t != "twolink"}
             for m, p in modules.items()}
    cycles, state = [], {}

    def visit(m, stack):
        state[m] = "open"
        stack.append(m)
        for t in sorted(graph[m]):
            if state.get(t) == "open":
                cycles.append(stack[stack.index(t):] + [t])
            elif t not in state:
                visit(t, stack)
        stack.pop()
        state[m] = "done"

    for m in sorted(graph):
        if m not in state:
            visit(m, [])
    assert cycles == []


def test_no_private_name_is_imported_across_modules():
    """A private name (``_x``) is used only in its module; a package's private submodules
    (its compiled kernels) only by that package's modules."""
    modules = _modules()
    bad = []
    for m, p in modules.items():
        for target, name in _imports(m, p, modules):
            if name is not None and name.startswith("_") and not name.startswith("__"):
                bad.append(f"{m} imports {target}.{name}")
            leaf = target.rpartition(".")[2]
            if name is None and leaf.startswith("_") and not leaf.startswith("__"):
                owner = target.rpartition(".")[0]
                if not (m == owner or m.startswith(owner + ".")):
                    bad.append(f"{m} imports the private module {target}")
    assert bad == []


def test_the_package_is_shallow_and_its_modules_small():
    top = sorted(p.name for p in PACKAGE.glob("*.py"))
    assert len(top) <= 8, top
    kernels = {p for p in PACKAGE.rglob("_*kernel.py")}
    long = {str(p.relative_to(PACKAGE)): n for p in PACKAGE.rglob("*.py") if p not in kernels
            for n in [len(p.read_text().splitlines())] if n > MAX_LINES}
    assert long == {}


def _scripts(folders) -> list:
    root = PACKAGE.parent
    return sorted(p for d in folders for p in (root / d).rglob("*.py"))


def test_the_scripts_are_small_too():
    """The size rule of the package holds for the benchmarks, the development studies
    and the docs generator: their reusable parts live in the package (e.g.
    :mod:`twolink.studies.fuzzy_design`) or in modules of one concept each."""
    scripts = _scripts(SCRIPT_DIRS)
    assert len(scripts) > 30 and any(p.name == "synthesis.py" for p in scripts)
    long = {str(p.relative_to(PACKAGE.parent)): n for p in scripts
            for n in [len(p.read_text().splitlines())] if n > MAX_LINES}
    assert long == {}


def _private_uses(name: str, path: Path, modules: dict) -> list:
    """The twolink imports of a script that reach past the public API: a private module
    (a ``_x`` anywhere in its dotted path) or a private name (``from m import _x``)."""
    bad = []
    for target, imported in _imports(name, path, modules):
        full = target if imported is None else f"{target}.{imported}"
        if any(p.startswith("_") and not p.startswith("__") for p in full.split(".")):
            bad.append(f"{name} imports {full}")
    return bad


def test_the_benchmarks_and_studies_use_only_the_public_package():
    """benchmarks/, docs/studies/ and docs/generator/ are users of the package: no private module
    (``twolink.fqi._kernel``) and no private name (``from twolink.x import _y``)."""
    modules = _modules()
    scripts = _scripts(PUBLIC_USERS)
    root = PACKAGE.parent
    names = {p: ".".join(p.relative_to(root).with_suffix("").parts) for p in scripts}
    assert sum(len(_imports(n, p, modules)) for p, n in names.items()) > 100
    bad = [b for p, n in names.items() for b in _private_uses(n, p, modules)]
    assert bad == []


def test_the_script_contract_catches_a_private_import(tmp_path):
    """The check of the scripts' imports finds each way of reaching a private part."""
    script = tmp_path / "study.py"
    script.write_text("import twolink.fqi._kernel\n"
                      "from twolink.fqi import _factored_kernel\n"
                      "from twolink.synthesis.learning import Learner, _hidden\n"
                      "from twolink.commands._options import seed_option\n"
                      "from twolink.policy.fuzzy_policy import greedy_indices\n")
    assert _private_uses("study", script, _modules()) == [
        "study imports twolink.fqi._kernel", "study imports twolink.fqi._factored_kernel",
        "study imports twolink.synthesis.learning._hidden",
        "study imports twolink.commands._options.seed_option"]


def test_every_subpackage_is_installed():
    """pyproject.toml lists its packages explicitly: a new subpackage must be listed, or a
    wheel would lack it."""
    import tomllib

    listed = set(tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text())
                 ["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(PACKAGE.parent).parts)
             for p in PACKAGE.rglob("__init__.py")}
    assert found - listed == set()
