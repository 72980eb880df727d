"""The controller catalogue (twolink.control.catalogue, `twolink controllers`): one entry
per named controller, user catalogue files checked whole, names suggested."""
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from twolink.cli import main
from twolink.control.baselines import BASELINES
from twolink.control.catalogue import (
    BENCHMARK,
    ENV_VAR,
    CatalogueError,
    catalogue,
    entries,
    lookup,
    read_catalogue_file,
    shipped_entries,
)
from twolink.control.handover import HANDOVERS
from twolink.control.learned import LEARNED, LEARNED_AGENTS
from twolink.control.catalogue import links_pd_name
from twolink.control.links_pd import TUNED
from twolink.policy.registry import SHIPPED

TWOLINK = str(Path(sys.executable).parent / "twolink")


def _write(path, controllers, **doc):
    path.write_text(json.dumps({"format": "twolink-catalogue", "version": 1,
                                "controllers": controllers, **doc}))
    return path


def test_the_shipped_entries_are_every_registry_once():
    names = [e.name for e in shipped_entries()]
    assert len(names) == len(set(names))
    links_pd = {links_pd_name(n, rule) for n, rule in TUNED}     # the N-link PD entries
    assert set(names) == (set(SHIPPED) | set(BASELINES) | links_pd | set(LEARNED_AGENTS)
                          | set(HANDOVERS))
    bench = [e.name for e in entries(tag="benchmark")]
    assert sorted(bench) == sorted(BENCHMARK) and len(bench) <= 12
    assert {e.name for e in entries(tag="paper")} == {n for n, p in SHIPPED.items() if p.paper}
    assert {e.name for e in entries(tag="n-link")} == {n for n, p in SHIPPED.items()
                                                       if p.links > 2} | links_pd | {
        n for n, a in LEARNED.items() if a.links > 2}
    assert lookup("lqr").kind == "centralized" and lookup("pd").kind == "decentralized"
    assert [e.name for e in entries(links=3)] == ["decentralized_3link", "pd_3link_copied",
                                                   "pd_3link_tapered"]


@pytest.mark.parametrize("name", ["centralized", "decentralized_locked_gain", "lqr",
                                  "bang_bang", "decentralized_3link"])
def test_an_entry_loads_its_controller(name):
    entry = lookup(name)
    ctrl = entry.load()
    x = np.zeros((3, 2 * entry.links))
    x[:, 0] = 0.5
    u = np.asarray(ctrl(x), dtype=float)
    assert u.shape == (3, entry.links) and np.all(np.isfinite(u))
    assert np.any(u[:, 0] != 0)                   # 0.5 rad off the goal: it pushes


def test_a_user_catalogue_file_adds_entries(tmp_path, monkeypatch):
    (tmp_path / "mine.py").write_text(
        "import numpy as np\n"
        "def make(gain=1.0):\n"
        "    def f(x):\n"
        "        return -gain * np.clip(x[:, :2], -0.1, 0.1)\n"
        "    f.name = 'my_p'\n"
        "    return f\n")
    cat = _write(tmp_path / "cat.json", [
        {"name": "my_p", "entry": f"{tmp_path / 'mine.py'}:make", "data": {"gain": 0.5},
         "tags": ["mine"], "kind": "decentralized", "description": "a P law"}])
    got = catalogue([cat])
    assert got["my_p"].tags == ("user", "mine") and got["my_p"].source == str(cat)
    u = got["my_p"].load()(np.array([[1.0, -1.0, 0.0, 0.0]]))
    assert np.allclose(u, [[-0.05, 0.05]])
    monkeypatch.setenv(ENV_VAR, str(cat))
    assert [e.name for e in entries(tag="mine")] == ["my_p"]


@pytest.mark.parametrize("controllers, doc, message", [
    ([{"name": "a", "entry": "m:f"}, {"name": "a", "entry": "m:g"}], {},
     "the name 'a' is given twice"),
    ([{"name": "lqr", "entry": "m:f"}], {}, "the name 'lqr' is already taken by twolink"),
    ([{"name": "a", "entry": "m:f", "gains": 1}], {}, "unknown field(s) gains"),
    ([{"name": "a", "entry": "no colon"}], {}, "'entry' must be 'module:callable'"),
    ([{"name": "a", "entry": "m:f", "links": 99}], {}, "'links' must be an integer in [2, 12]"),
    ([{"name": "a", "entry": "m:f", "kind": "both"}], {}, "'kind' must be one of"),
    ([{"name": "a b", "entry": "m:f"}], {}, "'name' must be a non-empty word"),
    ([], {"version": 7}, "has version 7"),
    ([], {"format": "other"}, "is not a twolink catalogue"),
])
def test_a_bad_catalogue_file_is_one_line_naming_it(tmp_path, controllers, doc, message):
    cat = _write(tmp_path / "cat.json", controllers, **doc)
    with pytest.raises(CatalogueError) as exc:
        catalogue([cat])
    assert message in str(exc.value) and str(cat) in str(exc.value)
    assert "\n" not in str(exc.value)


def test_a_foreign_or_missing_file_is_one_line(tmp_path):
    (tmp_path / "x.json").write_text("{not json")
    with pytest.raises(CatalogueError, match="x.json is not valid JSON"):
        read_catalogue_file(tmp_path / "x.json")
    with pytest.raises(CatalogueError, match="does not exist"):
        read_catalogue_file(tmp_path / "none.json")


def test_an_entry_point_that_does_not_import_names_the_entry(tmp_path):
    cat = _write(tmp_path / "cat.json", [
        {"name": "broken", "entry": "twolink_no_such_module:f"},
        {"name": "typo", "entry": "twolink.control.baselines:basline", "data": {"name": "x"}}])
    with pytest.raises(CatalogueError, match="catalogue entry 'broken' .*cannot import"):
        catalogue([cat])["broken"].load()
    with pytest.raises(CatalogueError, match="'typo' .*has no attribute 'basline'"):
        catalogue([cat])["typo"].load()


def test_an_unknown_name_or_tag_suggests_the_closest():
    with pytest.raises(CatalogueError, match=r"unknown controller 'lqrr' \(did you mean 'lqr'"):
        lookup("lqrr")
    with pytest.raises(CatalogueError, match=r"unknown tag 'benchmrk' \(did you mean "
                                             r"'benchmark'\?\)"):
        entries(tag="benchmrk")


def test_the_command_lists_the_catalogue(capsys):
    assert main(["controllers", "--tag", "benchmark", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [c["name"] for c in doc["controllers"]] == [e.name for e in entries(tag="benchmark")]
    assert doc["controllers"][0]["entry"] == "twolink.policy.fuzzy_policy:load_policy"
    assert main(["controllers", "--tag", "baseline"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0].split()[:4] == ["name", "kind", "links", "tags"]
    assert f"{len(BASELINES) + len(TUNED)} controllers." in out


def test_the_command_says_an_unknown_tag_in_one_line_within_a_second(tmp_path):
    t0 = time.perf_counter()
    res = subprocess.run([TWOLINK, "controllers", "--tag", "lernd"], capture_output=True,
                         text=True, timeout=60)
    took = time.perf_counter() - t0
    assert res.returncode == 2 and res.stdout == ""
    assert res.stderr.strip().splitlines() == [
        "twolink controllers: error: unknown tag 'lernd' (did you mean 'learned'?); the tags "
        "are baseline, benchmark, fuzzy, learned, n-link, paper, tuned, user"]
    print(f"unknown tag answered in {took:.2f} s")


def test_a_read_out_entry_is_data_over_a_stored_table():
    """decentralized_locked_gain is decentralized_locked's table read through a gain: the
    catalogue names the table by its synthesis settings."""
    e = lookup("decentralized_locked_gain")
    assert e.entry == "twolink.policy.fuzzy_policy:policy_with_readout"
    assert e.data["table"] == "decentralized_full_propagated_levels7_link1-locked"
    assert e.data["readout"]["near_gain"] == 0.3
    gain, base = e.load(), lookup("decentralized_locked").load()
    x = np.array([[0.3, -0.2, 0.0, 0.0], [1.0, -2.0, 0.5, 0.0]])   # 17 deg: inside 60 deg
    assert np.allclose(gain(x)[0, 0], base(x)[0, 0] * (0.3 + 0.7 * 0.3 / np.radians(60)))
    assert all(a.q is b.q or np.array_equal(a.q, b.q) for a, b in zip(gain.agents,
                                                                     base.agents))


def test_a_user_read_out_over_a_table_of_another_arm_is_refused(tmp_path):
    cat = _write(tmp_path / "cat.json", [
        {"name": "my_gain", "entry": "twolink.policy.fuzzy_policy:policy_with_readout",
         "data": {"table": "decentralized_3link", "readout": {"near_gain": 0.5,
                                                              "near_deg": 60.0}},
         "links": 2},
        {"name": "bad_readout", "entry": "twolink.policy.fuzzy_policy:policy_with_readout",
         "data": {"table": "decentralized", "readout": {"gain": 0.5}}}])
    with pytest.raises(CatalogueError, match="'my_gain' .* is for 2 links, and what "
                                             ".* made is for 3"):
        catalogue([cat])["my_gain"].load()
    with pytest.raises(CatalogueError, match="'bad_readout' .*readout must be a dict of"):
        catalogue([cat])["bad_readout"].load()
