"""The 0.1 names of the N-link arm that said *chain* still import, for one release, as the
very objects of their *links* names, with a DeprecationWarning
(twolink._imports.renamed); the package itself uses only the new names."""
import ast
import importlib
from pathlib import Path

import pytest

from twolink.studies.mismatch.plan import plan

PACKAGE = Path(__file__).resolve().parents[1] / "twolink"

#: (module, old name, new name): every rename of the "links" release.
RENAMED = [
    ("twolink.arm.parameters", "ChainParameters", "LinksParameters"),
    ("twolink.arm.parameters", "chain", "links_parameters"),
    ("twolink.arm.parameters", "as_chain", "as_links"),
    ("twolink.arm.parameters", "CHAIN_HORIZON", "LINKS_HORIZON"),
    ("twolink.arm.dynamics", "chain_weights", "links_weights"),
    ("twolink.arm.dynamics", "chain_mass_matrix", "links_mass_matrix"),
    ("twolink.arm.dynamics", "chain_bias", "links_bias"),
    ("twolink.arm.dynamics", "chain_acceleration", "links_acceleration"),
    ("twolink.control.links_pd", "ChainPD", "LinksPD"),
    ("twolink.control.links_pd", "chain_pd", "make_links_pd"),
    ("twolink.synthesis.links_decentralized", "synthesize_chain", "synthesize_links"),
    ("twolink.synthesis.links_decentralized", "CHAIN_DEFAULT", "LINKS_DEFAULT"),
    ("twolink.synthesis.links_decentralized", "CHAIN_DEFAULTS", "LINKS_DEFAULTS"),
    ("twolink.commands.synthesize", "chain_file_name", "links_file_name"),
    ("twolink.studies.mismatch.figures", "chain_markdown", "links_markdown"),
    ("twolink.studies.mismatch.plan", "CHAIN_SEED", "LINKS_SEED"),
    ("twolink.studies.scaling.measure", "CHAIN_SCHEMES", "LINKS_SCHEMES"),
]


@pytest.mark.parametrize("module, old, new", RENAMED)
def test_an_old_name_is_the_new_object_with_a_deprecation_warning(module, old, new):
    m = importlib.import_module(module)
    with pytest.warns(DeprecationWarning, match=rf"^{module}\.{old} is now {module}\.{new};"):
        assert getattr(m, old) is getattr(m, new)
    space = {}
    with pytest.warns(DeprecationWarning, match=rf"{module}\.{old} is now"):
        exec(f"from {module} import {old}", space)
    assert space[old] is getattr(m, new)
    assert old not in vars(m)                  # not cached: every use warns


def test_each_module_keeps_exactly_the_listed_old_names():
    by_module = {}
    for module, old, new in RENAMED:
        by_module.setdefault(module, {})[old] = new
    for module, names in by_module.items():
        assert importlib.import_module(module).__getattr__.renamed == names


def test_an_unknown_name_is_still_an_attribute_error():
    m = importlib.import_module("twolink.arm.parameters")
    with pytest.raises(AttributeError, match="^module 'twolink.arm.parameters' has no "
                                             "attribute 'chains'$"):
        m.chains
    with pytest.raises(ImportError, match="cannot import name 'ChainPd'"):
        exec("from twolink.control.links_pd import ChainPd", {})


def test_the_old_plan_field_reads_the_new_one():
    quick = plan("quick")
    with pytest.warns(DeprecationWarning, match="Plan.chain_poses is now Plan.links_poses"):
        assert quick.chain_poses == quick.links_poses == 8


def test_the_package_uses_only_the_new_names():
    old = {o for _, o, _ in RENAMED} | {"chain_poses"}
    found = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            name = (node.id if isinstance(node, ast.Name) else
                    node.attr if isinstance(node, ast.Attribute) else
                    node.name if isinstance(node, (ast.FunctionDef, ast.ClassDef,
                                                   ast.alias)) else None)
            if name in old and not (isinstance(node, ast.FunctionDef)   # the Plan property
                                    and name == "chain_poses"):
                found.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno} {name}")
    assert found == []
