"""SynthesisSettings (twolink.synthesis.settings): one spelling from the command line to
the file header. The CLI's settings are the Python API's; the settings survive
as_dict/from_dict and a synthesised file's header; every shipped file's header reads back
as its registry entry's settings with the header fields it has always had; bad fields are
one line; synthesize(settings) is the keyword form's policy."""
import json

import numpy as np
import pytest

from twolink.arm import parameter_file
from twolink.arm.parameters import DELTA, GAMMA, TABLE_I
from twolink.cli import build_parser
from twolink.commands.synthesize import _jobs
from twolink.policy.fuzzy_policy import Policy, same_tables
from twolink.policy.readout import Readout
from twolink.policy.registry import ROBUST_SEED, SHIPPED
from twolink.synthesis.settings import SynthesisSettings
from twolink.synthesis.synthesize import synthesize


def _cli_settings(tmp_path, *argv) -> list:
    args = build_parser("synthesize").parse_args(["synthesize", *argv])
    return [s for s, _ in _jobs(args)]


@pytest.mark.parametrize("argv, made", [
    (["centralized"], SynthesisSettings("centralized")),
    (["decentralized", "--sweeps", "serial", "--refine", "2", "--gamma", "0.9", "--delta",
      "0.01"],
     SynthesisSettings("decentralized", context="frozen", sweeps="serial", refine=2,
                       gamma=0.9, delta=0.01)),
    (["decentralized", "--model", "full", "--context", "propagated", "--levels", "7",
      "--bins", "edge", "--agent2-link1", "locked", "--speed-dead-zone", "0.06",
      "--argmax-beyond-deg", "30", "--near-gain", "0.2", "--near-deg", "90"],
     SynthesisSettings("decentralized", model="full", context="propagated", levels=7,
                       bins="edge", agent2_link1="locked",
                       readout=Readout(speed_dead_zone=0.06, argmax_beyond_deg=30.0,
                                       near_gain=0.2, near_deg=90.0))),
    (["centralized", "--model", "full", "--robust", "worst"],
     SynthesisSettings("centralized", model="full", robust="worst", draws=8, spread=0.2,
                       seed=0)),
    (["decentralized", "--links", "3"],
     SynthesisSettings("decentralized", links=3, context="propagated", model="full")),
])
def test_the_clis_settings_are_the_python_apis(tmp_path, argv, made):
    got = _cli_settings(tmp_path, *argv, "-o", str(tmp_path / "p.npz"))
    assert got == [made]
    assert got[0].as_dict() == made.as_dict()


def test_ship_synthesises_the_registry_entrys_settings(tmp_path):
    got = _cli_settings(tmp_path, "--ship", "centralized_robust_tuned",
                        "--ship", "decentralized_3link")
    # a read-out entry ships as the Q-tables of its table entry (centralized_robust)
    assert got == [SynthesisSettings("centralized", model="full", robust="worst", draws=8,
                                     spread=0.2, seed=ROBUST_SEED),
                   SynthesisSettings("decentralized", links=3, context="propagated")]
    assert SynthesisSettings.shipped("centralized_robust_tuned").readout == \
        Readout(speed_dead_zone=0.04, argmax_beyond_deg=30.0)


def test_an_identified_model_takes_its_parameters_and_source_from_the_file(tmp_path):
    arm = TABLE_I.scaled(m2=1.1)
    parameter_file.save(tmp_path / "arm.json", arm, provenance={"by": "test"})
    [s] = _cli_settings(tmp_path, "decentralized", "--model", "identified", "--params",
                        str(tmp_path / "arm.json"), "-o", str(tmp_path / "p.npz"))
    assert s.parameters == arm and s.model == "identified"
    assert s.source["path"] == str(tmp_path / "arm.json")
    assert s.source["provenance"]["by"] == "test" and len(s.source["sha256"]) == 64
    assert s.header()["dynamics"] == "full" and s.header()["parameters_source"] == s.source


@pytest.mark.parametrize("name", list(SHIPPED))
def test_settings_round_trip_through_as_dict_and_json(name):
    s = SynthesisSettings.shipped(name)
    data = json.loads(json.dumps(s.as_dict()))
    assert SynthesisSettings.from_dict(data) == s
    base = SynthesisSettings(s.kind).as_dict()          # fields left out: the defaults
    assert SynthesisSettings.from_dict({k: v for k, v in data.items()
                                        if k == "kind" or v != base[k]}) == s
    assert data["gamma"] == GAMMA and data["delta"] == DELTA


@pytest.mark.parametrize("name", [n for n, e in SHIPPED.items() if e.table_owner == n])
def test_every_shipped_header_reads_back_as_its_registry_settings(name):
    """The header fields come from the settings with the names and values the shipped
    files have: every one of header()'s fields is in the committed file, equal (the
    paper's decentralized files predate ``sweeps`` and ``refine``, which then read as
    their defaults)."""
    policy = Policy.load(SHIPPED[name].file)
    s = SynthesisSettings.from_header(policy.kind, policy.meta)
    assert s == SynthesisSettings.shipped(name)
    header = s.header()
    missing = {k: v for k, v in header.items() if k not in policy.meta}
    assert missing in ({}, {"sweeps": "synchronous", "refine": 1}), missing
    assert {k: policy.meta[k] for k in header if k in policy.meta} == \
        {k: v for k, v in header.items() if k in policy.meta}


@pytest.mark.parametrize("settings", [
    SynthesisSettings("decentralized"),
    SynthesisSettings("decentralized", model="full", context="propagated", robust="worst",
                      draws=2, spread=0.1, seed=3, levels=5,
                      readout=Readout(speed_dead_zone=0.05, argmax_beyond_deg=30.0)),
    SynthesisSettings("decentralized", model="identified", agent2_link1="locked",
                      parameters=TABLE_I.scaled(m2=1.1), source={"path": "arm.json"}),
], ids=["paper", "robust-design", "identified"])
def test_settings_round_trip_through_a_synthesised_files_header(tmp_path, settings):
    policy = synthesize(settings)
    loaded = Policy.load(policy.save(tmp_path / "p.npz"))
    assert SynthesisSettings.from_header(loaded.kind, loaded.meta) == settings
    assert {k: loaded.meta[k] for k in settings.header()} == settings.header()
    assert loaded.readout == (settings.readout or Readout())


def test_the_keyword_form_and_the_settings_form_give_one_policy():
    keywords = synthesize("decentralized", model="full", context="propagated", levels=5,
                          bins="edge", robust="mean", draws=2, spread=0.1, seed=4)
    settings = synthesize(SynthesisSettings("decentralized", model="full",
                                            context="propagated", levels=5, bins="edge",
                                            robust="mean", draws=2, spread=0.1, seed=4))
    assert same_tables(keywords, settings) and keywords.meta == settings.meta
    for a, b in zip(keywords.agents, settings.agents):
        assert np.array_equal(a.q, b.q)
    assert keywords.meta["robust"]["draws"] == 2 and keywords.meta["levels"] == 5


@pytest.mark.parametrize("fields, error, match", [
    (dict(kind="federated"), ValueError, "unknown policy kind 'federated'"),
    (dict(kind="centralized", model="exact"), ValueError, "unknown synthesis model 'exact'"),
    (dict(kind="decentralized", context="magic"), ValueError,
     "unknown agent-1 context 'magic'"),
    (dict(kind="centralized", context="propagated"), ValueError,
     "the centralized policy takes none"),
    (dict(kind="centralized", gamma=1.0), ValueError,
     r"gamma must be a number in \(0, 1\), got 1.0"),
    (dict(kind="centralized", delta=0.0), ValueError, "delta must be a finite positive"),
    (dict(kind="centralized", sweeps="bogus"), ValueError, "unknown sweeps 'bogus'"),
    (dict(kind="centralized", refine=0), ValueError,
     "refine must be a whole number from 1 to 16, got 0"),
    (dict(kind="centralized", draws=3), ValueError, "apply to a robust synthesis only"),
    (dict(kind="centralized", robust="worst", draws=2, spread=0.9), ValueError,
     r"spread must lie in \[0, 0.9\)"),
    (dict(kind="centralized", robust="worst", draws=2, sweeps="serial"), ValueError,
     "robust synthesis runs synchronous sweeps only"),
    (dict(kind="centralized", robust="best", draws=2), ValueError,
     "unknown robust mode 'best'"),
    (dict(kind="centralized", levels=1), ValueError,
     "levels must be a whole number from 2 to 9, got 1"),
    (dict(kind="centralized", bins="fine"), ValueError, "unknown bin layout 'fine'"),
    (dict(kind="centralized", readout={"speed_dead_zone": 0.1}), TypeError,
     "readout must be a twolink.policy.readout.Readout"),
    (dict(kind="decentralized", agent2_link1="locked"), ValueError,
     r"under \(11\) link 2 does not depend on link 1"),
    (dict(kind="centralized", model="full", agent2_link1="locked"), ValueError,
     "agent2_link1 is how the decentralized agent 2 reads link 1"),
    (dict(kind="centralized", rule="copied"), ValueError,
     "rule makes the links beyond the second"),
    (dict(kind="centralized", links=3), ValueError,
     "centralized synthesis of a 3-link arm is twolink.synthesis.links_centralized"),
    (dict(kind="decentralized", links=3, levels=5), ValueError,
     "levels, bins, readout and agent2_link1 are two-link options"),
    (dict(kind="decentralized", links=3, model="simplified"), ValueError,
     "a 3-link arm is synthesised on its full model"),
    (dict(kind="decentralized", links=3, rule="bent"), ValueError, "unknown link rule 'bent'"),
    (dict(kind="decentralized", links=7), ValueError,
     "links must be a whole number from 2 to 6, got 7"),
    (dict(kind="centralized", parameters={"m1": 1.0}), ValueError,
     "parameters must be a twolink.arm.parameters.ArmParameters, got dict"),
])
def test_bad_fields_are_one_line(fields, error, match):
    with pytest.raises(error, match=match) as e:
        SynthesisSettings(**fields)
    assert "\n" not in str(e.value)


def test_from_dict_refuses_unknown_fields_and_needs_a_kind():
    with pytest.raises(ValueError, match=r"^unknown synthesis setting\(s\) colour, size; "
                                         r"known: kind, model, ") as e:
        SynthesisSettings.from_dict({"kind": "centralized", "size": 1, "colour": "red"})
    assert "\n" not in str(e.value)
    with pytest.raises(ValueError, match="synthesis settings need a kind"):
        SynthesisSettings.from_dict({"model": "full"})
    with pytest.raises(ValueError, match="synthesis settings must be a dict, got list"):
        SynthesisSettings.from_dict([])
    with pytest.raises(ValueError, match="a synthesised policy's header records 'model'"):
        SynthesisSettings.from_header("centralized", {"gamma": GAMMA})


def test_settings_are_frozen_and_synthesize_takes_them_alone():
    s = SynthesisSettings("decentralized")
    with pytest.raises(AttributeError):
        s.levels = 5
    assert s.replace(levels=5).levels == 5 and s.levels == 3
    assert SynthesisSettings("decentralized", readout=Readout()) == s   # inactive: none
    with pytest.raises(ValueError, match="synthesize\\(settings\\) takes its settings from "
                                         "them; model, levels given as well"):
        synthesize(s, model="full", levels=5)
