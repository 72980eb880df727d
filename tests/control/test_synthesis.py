"""`twolink synthesize`: where policy files go, and re-synthesising the shipped ones."""
import json

import numpy as np
import pytest

from twolink.cli import main
from twolink.commands import synthesize as synthesize_command
from twolink.commands.synthesize import default_file_name
from twolink.synthesis.problems import table_sizes
from twolink.policy.fuzzy_policy import Policy
from twolink.policy.registry import SHIPPED


def test_default_names_are_the_registry_names():
    for name, entry in SHIPPED.items():
        if entry.robust is None and entry.links == 2 and not entry.tuned:
            assert default_file_name(entry.kind, entry.model, entry.context or "frozen") \
                == f"{name}.npz"
    # a tuned design's file name says its levels and bins (its registry name is its own)
    assert default_file_name("centralized", "full", levels=5, bins="goal") \
        == "centralized_full_5levels_goalbins.npz"
    assert default_file_name("decentralized", "full", "propagated") \
        == "decentralized_full_propagated.npz"
    # robust files say so (the shipped robust ones keep their short registry names)
    assert default_file_name("centralized", "full", robust="worst") == "centralized_full_robust.npz"
    assert default_file_name("decentralized", robust="mean") == "decentralized_mean.npz"


def test_default_output_is_a_new_file_in_the_cwd_and_shipped_files_stay(tmp_path, monkeypatch,
                                                                        capsys):
    shipped = {n: e.file.read_bytes() for n, e in SHIPPED.items()}
    monkeypatch.chdir(tmp_path)
    assert main(["synthesize", "decentralized", "--context", "propagated", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["path"] == "decentralized_propagated.npz"
    pol = Policy.load(tmp_path / "decentralized_propagated.npz")
    assert pol.meta["context"] == "propagated"
    assert {n: e.file.read_bytes() for n, e in SHIPPED.items()} == shipped


def test_an_existing_file_is_kept_unless_forced(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "centralized.npz").write_bytes(b"mine")
    assert main(["synthesize", "centralized"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("twolink synthesize: error: centralized.npz exists; give --force to "
                   "overwrite it or -o another file")
    assert (tmp_path / "centralized.npz").read_bytes() == b"mine"
    assert main(["synthesize", "centralized", "--force"]) == 0
    assert Policy.load(tmp_path / "centralized.npz").kind == "centralized"


def test_ship_rewrites_a_registry_policy_into_the_checkout(tmp_path, monkeypatch, capsys):
    import twolink.resources
    monkeypatch.setattr(twolink.resources, "shipped_policy_dir", lambda: tmp_path)
    monkeypatch.setattr(synthesize_command, "source_checkout", lambda: tmp_path)
    assert main(["synthesize", "--ship", "decentralized_full", "--json"]) == 0
    written = Policy.load(tmp_path / "decentralized_full_frozen.npz")
    original = Policy.load(_real_file("decentralized_full"))
    assert written.meta["model"] == "full" and written.meta["context"] == "frozen"
    for a, b in zip(written.agents, original.agents):
        np.testing.assert_array_equal(a.q, b.q)
    assert json.loads(capsys.readouterr().out)[0]["path"].endswith(
        "decentralized_full_frozen.npz")
    assert [p.name for p in tmp_path.iterdir()] == ["decentralized_full_frozen.npz"]


def _checkout_copy(tmp_path, monkeypatch, files: dict):
    """A policies/ folder in tmp_path standing for the checkout's: ``{file name: shipped
    entry whose file it copies}``."""
    import shutil

    import twolink.resources
    folder = tmp_path / "policies"
    folder.mkdir()
    for name, source in files.items():
        shutil.copyfile(_real_file(source), folder / name)
    monkeypatch.setattr(twolink.resources, "shipped_policy_dir", lambda: folder)
    monkeypatch.setattr(synthesize_command, "source_checkout", lambda: tmp_path)
    return folder


def test_a_reship_of_an_unchanged_policy_keeps_the_file_byte_for_byte(tmp_path, monkeypatch,
                                                                      capsys):
    """The fresh synthesis equals the committed Q-tables bit for bit, so the file (its
    timings and provenance included) is left as it is: git status stays clean."""
    file = "decentralized_simplified_frozen.npz"
    folder = _checkout_copy(tmp_path, monkeypatch, {file: "decentralized"})
    before = (folder / file).read_bytes()
    stat = (folder / file).stat()
    assert main(["synthesize", "--ship", "decentralized"]) == 0
    assert (folder / file).read_bytes() == before
    assert (folder / file).stat().st_mtime_ns == stat.st_mtime_ns
    assert "kept " in capsys.readouterr().out


def test_a_reship_of_changed_q_tables_rewrites_the_file(tmp_path, monkeypatch, capsys):
    """(The synthesis is stubbed by another shipped policy: its Q-tables differ.)"""
    from twolink.policy.fuzzy_policy import same_tables

    other = Policy.load(_real_file("decentralized_propagated"))
    file = "decentralized_simplified_frozen.npz"
    folder = _checkout_copy(tmp_path, monkeypatch, {file: "decentralized"})
    monkeypatch.setattr(synthesize_command, "synthesize", lambda kind, **k: other)
    assert main(["synthesize", "--ship", "decentralized", "--json"]) == 0
    assert same_tables(Policy.load(folder / file), other)
    assert not same_tables(Policy.load(_real_file("decentralized")), other)
    assert "unchanged" not in json.loads(capsys.readouterr().out)[0]


def test_a_reship_of_a_read_out_entry_keeps_its_stored_table(tmp_path, monkeypatch, capsys):
    """decentralized_locked_gain is decentralized_locked's Q-tables read through a gain:
    --ship of it re-synthesises the table (read-out and all of decentralized_locked) and
    writes no file of its own."""
    file = "decentralized_full_propagated_levels7_link1-locked.npz"
    folder = _checkout_copy(tmp_path, monkeypatch, {file: "decentralized_locked"})
    before = (folder / file).read_bytes()
    assert main(["synthesize", "--ship", "decentralized_locked_gain", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [o["path"] for o in out] == [str(folder / file)]
    assert out[0]["unchanged"] is True
    assert sorted(p.name for p in folder.iterdir()) == [file]
    assert (folder / file).read_bytes() == before


def test_no_two_shipped_files_hold_the_same_tables():
    """A Q-table is stored once, in the file its synthesis settings name: every read-out
    variant names its table instead, and the table loads by that name without a read-out."""
    from twolink.policy.fuzzy_policy import load_policy
    from twolink.policy.readout import Readout
    from twolink.policy.registry import table_stem
    from twolink.resources import shipped_policy_dir

    files = sorted(shipped_policy_dir().glob("*.npz"))
    assert {p.stem for p in files} == {e.table for e in SHIPPED.values()}
    digests = {}
    for path in files:
        pol = Policy.load(path)
        key = tuple(np.ascontiguousarray(a.q, dtype="<f8").tobytes() for a in pol.agents)
        assert key not in digests, (path.stem, digests.get(key))
        digests[key] = path.stem
        assert table_stem({"kind": pol.kind, **_table_settings(pol.meta)}) == path.stem
        bare = load_policy(path.stem)       # centralized_full: the entry of that name
        assert bare.readout == Readout() and bare.meta.get("table", path.stem) == path.stem
        assert all(np.array_equal(a.q, b.q) for a, b in zip(bare.agents, pol.agents))
    for name, entry in SHIPPED.items():
        pol = load_policy(name)
        assert pol.readout == entry.readout()
        owner = entry.table_owner == name
        assert pol.meta.get("table") == (None if owner else entry.table)


def _table_settings(meta: dict) -> dict:
    """The table settings a policy file's header records (read back independently of the
    registry: what the file holds, named as :func:`table_stem` names them)."""
    robust = meta.get("robust")
    out = {"model": meta["model"], "links": meta.get("links", 2),
           "sweeps": meta.get("sweeps", "synchronous"),
           **({"context": meta["context"]} if "context" in meta else {}),
           **({"rule": meta["rule"]} if "rule" in meta else {}),
           **{k: meta[k] for k in ("levels", "bins", "agent2_link1") if k in meta}}
    if robust:
        out.update(robust=robust["mode"], draws=robust["draws"], spread=robust["spread"],
                   seed=robust["seed"])
    return out


def _real_file(name):
    """The committed file of the shipped entry ``name`` (whatever shipped_policy_dir is
    patched to)."""
    from twolink.resources import _package_dir
    return _package_dir("twolink._policies") / SHIPPED[name].file.name


@pytest.mark.parametrize("argv, message", [
    (["--ship", "centralized", "centralized"], "--ship takes everything from the registry"),
    (["--ship", "centralized", "--model", "full"], "--ship takes everything from the registry"),
    (["--ship", "nonsense"], "unknown shipped policy 'nonsense'"),
    ([], "give a policy kind"),
    (["centralized", "--context", "propagated"], "--context applies to the decentralized"),
])
def test_bad_combinations_are_one_line_errors(tmp_path, monkeypatch, capsys, argv, message):
    monkeypatch.chdir(tmp_path)
    assert main(["synthesize", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("twolink synthesize: error:") and message in err
    assert len(err.splitlines()) == 1 and list(tmp_path.iterdir()) == []


def test_ship_refuses_outside_a_source_checkout(monkeypatch, capsys):
    shipped = SHIPPED["centralized"].file.read_bytes()
    monkeypatch.setattr(synthesize_command, "source_checkout", lambda: None)
    assert main(["synthesize", "--ship", "centralized"]) == 2
    assert "installed package" in capsys.readouterr().err
    assert SHIPPED["centralized"].file.read_bytes() == shipped


def test_synthesize_and_mjcf_check_their_output_before_any_work(tmp_path, capsys):
    from twolink.cli import main
    assert main(["synthesize", "centralized", "-o", str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err
    assert main(["mjcf", "-o", str(tmp_path / "missing" / "a.xml")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_refine_writes_a_finer_policy_and_records_it(tmp_path, monkeypatch, capsys):
    """--refine 2: every state axis of the paper's grid gets a centre between neighbours
    (12 -> 24 angle bins, 7 -> 13 speed bins); agent 1's tau2 axis stays three torques."""
    monkeypatch.chdir(tmp_path)
    assert main(["synthesize", "decentralized", "--refine", "2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["path"] == "decentralized_refine2.npz"
    pol = Policy.load(tmp_path / "decentralized_refine2.npz")
    assert pol.meta["refine"] == 2 and pol.meta["sweeps"] == "synchronous"
    a2, a1 = pol.agents
    assert a2.grid.shape == (24, 13) and a1.grid.shape == (24, 13, 24, 3)
    assert out["agents"]["agent1"]["q_size"] == 24 * 13 * 24 * 3 * 3
    assert table_sizes("decentralized", 2) == {a: out["agents"][a]["q_size"]
                                               for a in ("agent2", "agent1")}
    assert table_sizes("centralized", 3) == {"centralized": 36 * 36 * 19 * 19 * 9}
    paper = Policy.load(SHIPPED["decentralized"].file)
    # the paper's centres are among the refined ones, every other centre is new
    for fine, coarse in zip(a1.grid.axes[:3], paper.agents[1].grid.axes[:3]):
        np.testing.assert_allclose(fine.centers[::2], coarse.centers, atol=1e-15)


def test_grid_study_measures_the_papers_grid_as_reproduce_does(capsys, monkeypatch):
    """docs/studies/grid_study.py at refine 1 on (11): the evaluation-set outcomes of the
    paper's policies on the simplified plant are those `twolink reproduce` reports."""
    import importlib.util
    from pathlib import Path

    from twolink.policy.fuzzy_policy import load_policy
    from twolink.sim.metrics import evaluation_set, stalled_at_band_edge, success
    from twolink.sim.plants import make_plant
    from twolink.sim.rollout import rollout

    path = Path(__file__).resolve().parents[2] / "docs" / "studies" / "grid_study.py"
    spec = importlib.util.spec_from_file_location("grid_study", path)
    study = importlib.util.module_from_spec(spec)
    import sys
    monkeypatch.setitem(sys.modules, "grid_study", study)     # dataclasses look it up
    spec.loader.exec_module(study)
    rows = study.measure([1], states=4, seed=3, noise_deg=1.0, models=["simplified"])
    assert [(r.kind, r.refine) for r in rows] == [("decentralized", 1), ("centralized", 1)]
    with make_plant("simplified") as plant:
        for r in rows:
            ev = rollout(load_policy(r.kind), plant, evaluation_set())
            got = r.closed_loop["simplified"]["evaluation"]
            assert (got["successes"], got["states"], got["edge_stalls"]) == (
                int(success(ev).sum()), 65, int(stalled_at_band_edge(ev).sum()))
            assert r.q_size == {"centralized": 63504, "decentralized": 9072 + 252}[r.kind]
            assert r.closed_loop["mujoco"]["random"]["states"] == 4
            assert r.peak_traced_mib > 0 and r.nnz > 0
    with pytest.raises(SystemExit):
        study.main(["--refine", "0"])
    assert "--refine factors must be positive" in capsys.readouterr().err


@pytest.mark.parametrize("args, message", [
    (["--states", "1000000000"], "--states must be from 1 to 100000"),
    (["--refine", "9"], "--refine 9: a Q-table of 317552400 values is over the 64 MiB"),
    (["--json", "/nonexistent/r.json"], "directory /nonexistent does not exist"),
])
def test_grid_study_refuses_unbounded_work_before_starting(args, message):
    import subprocess
    import sys
    from pathlib import Path
    script = Path(__file__).resolve().parents[2] / "docs" / "studies" / "grid_study.py"
    res = subprocess.run([sys.executable, str(script), *args], capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 2 and message in res.stderr.strip().splitlines()[-1]
