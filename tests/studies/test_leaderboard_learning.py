"""What a learned row cost to learn: ``twolink.control.learned.learning_cost`` read from
the shipped curves, the leaderboard report's ``learning`` section (Markdown, checked on
--merge/--from-json, kept and replaced by ``merged``)."""
import json
from pathlib import Path

import pytest

from twolink.control import learned
from twolink.control.learned import LEARNED, Learned, learning_cost
from twolink.sim.controller import ControllerError
from twolink.studies.leaderboard.merge import merged, saved_report
from twolink.studies.leaderboard.report import markdown

ROOT = Path(__file__).resolve().parents[2]


def _curve(seed, steps, cpu, k, n=520):
    return {"config": {"seed": seed}, "steps": steps, "cpu_s": cpu, "wall_s": cpu + 1,
            "curve": [{"successes": 0, "n": n}, {"successes": k, "n": n}]}


@pytest.fixture
def fake(tmp_path, monkeypatch):
    """A checkout at tmp_path with one entry ``toy`` of two curves (no agent file)."""
    import twolink.resources

    for seed, cpu, k in ((1, 100.0, 500), (2, 50.0, 20)):
        (tmp_path / f"toy_seed{seed}.json").write_text(json.dumps(_curve(seed, 1000, cpu, k)))
    monkeypatch.setattr(twolink.resources, "source_checkout", lambda: tmp_path)
    monkeypatch.setitem(learned.LEARNED, "toy", Learned(
        "toy.zip", curves=("toy_seed1.json", "toy_seed2.json")))
    monkeypatch.setitem(learned.LEARNED_AGENTS, "toy", "toy.zip")
    return tmp_path


def test_the_cost_sums_every_seed_trained(fake):
    c = learning_cost("toy")
    assert (c["steps"], c["cpu_s"], c["wall_s"]) == (2000, 150.0, 152.0)
    assert [(s["seed"], s["successes"], s["n"]) for s in c["seeds"]] == [(1, 500, 520),
                                                                      (2, 20, 520)]
    assert c["chosen_seed"] is None                     # no agent file to read it from


def test_no_curves_or_a_missing_one_is_no_cost(fake):
    assert learning_cost("ppo_seed0") is None
    (fake / "toy_seed2.json").unlink()
    assert learning_cost("toy") is None


def test_a_foreign_curve_is_one_line(fake):
    (fake / "toy_seed2.json").write_text(json.dumps({"curve": []}))
    with pytest.raises(ControllerError, match=r"^learned agent toy: toy_seed2.json is not a "
                                              r"twolink train curve"):
        learning_cost("toy")


def test_the_shipped_challenge_agents_name_their_chosen_seed():
    import importlib.util

    multi = ("mappo_medium", "ippo_medium", "mappo_local_medium") \
        if importlib.util.find_spec("torch") else ()
    for name in ("ppo_medium", "ppo_hard", "sac_medium", "sac_hard", *multi):
        c = learning_cost(name)                          # (the multi-agent ones: .marl.pt)
        files = [json.loads((ROOT / p).read_text()) for p in LEARNED[name].curves]
        assert len(c["seeds"]) == 3
        assert c["steps"] == sum(f["steps"] for f in files) >= 900_000
        best = max(c["seeds"], key=lambda s: s["successes"])
        assert c["chosen_seed"] == best["seed"]           # the selection rule, on its data
    # a seed's candidate is its best agent where the run kept one
    ippo = [json.loads((ROOT / p).read_text()) for p in LEARNED["ippo_medium"].curves]
    if multi:
        assert [s["successes"] for s in learning_cost("ippo_medium")["seeds"]] == \
            [f["best"]["successes"] for f in ippo]


REPORT = {"command": "twolink leaderboard", "states": 65, "plants": 32, "seed": 2026,
          "horizon": 5.0, "limits": "data/limits.json", "levels": ["none"],
          "rows": [{"controller": "toy", "level": "none", "mode": "plain", "successes": 65,
                    "n": 65, "rate": 1.0, "wilson_95": [0.94, 1.0], "worst_plant": None,
                    "worst_plant_successes": None, "median_settle": 1.5,
                    "settle_ratio_median": 1.7, "settle_ratio_worst": 3.0,
                    "mean_abs_torque": 0.1, "seconds": 1.0}]}


def test_the_report_shows_the_cost(fake):
    report = {**REPORT, "learning": {"toy": {**learning_cost("toy"), "chosen_seed": 1}}}
    text = markdown(report)
    assert "## Cost of learning" in text
    assert ("| toy | 1 (500/520, chosen), 2 (20/520) | 0.00 M | 2.5 min | 2.5 min | "
            "75000 µs |") in text
    assert "Cost of learning" not in markdown(REPORT)


def test_a_saved_report_with_a_broken_cost_is_refused(tmp_path, fake):
    good = {**REPORT, "learning": {"toy": learning_cost("toy")}}
    (tmp_path / "ok.json").write_text(json.dumps(good))
    assert saved_report(tmp_path / "ok.json")["learning"]["toy"]["steps"] == 2000
    bad = {**REPORT, "learning": {"toy": {"seeds": [], "steps": 1, "wall_s": 1}}}
    (tmp_path / "bad.json").write_text(json.dumps(bad))
    with pytest.raises(ValueError, match="learning of toy lacks seeds, steps, cpu_s or wall_s"):
        saved_report(tmp_path / "bad.json")


def test_merge_replaces_the_cost_of_the_rows_it_replaces(fake):
    cost = learning_cost("toy")
    saved = {**REPORT, "learning": {"toy": cost, "gone": cost}}
    new = {**REPORT, "rows": REPORT["rows"], "learning": {"toy": {**cost, "steps": 7}}}
    out = merged(saved, new)
    assert out["learning"]["toy"]["steps"] == 7 and out["learning"]["gone"] == cost
    plain = merged({**REPORT, "learning": {"toy": cost}}, {**REPORT})
    assert "learning" not in plain                      # its row was measured again, without
