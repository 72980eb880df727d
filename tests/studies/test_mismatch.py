"""Model-mismatch robustness: what the measurements establish, and the report's honesty."""
import json
import random

import numpy as np
import pytest

from twolink.arm.parameters import TABLE_I
from twolink.cli import main
from twolink.policy.fuzzy_policy import load_policy
from twolink.policy.registry import SHIPPED
from twolink.sim.cell_store import CellFile, load_results
from twolink.sim.cells import states_of
from twolink.sim.challenges import LEVELS
from twolink.sim.evaluation import evaluate
from twolink.sim.metrics import evaluation_set, settle_time, success, wilson_interval
from twolink.sim.plants import MujocoPlant, make_plant
from twolink.sim.rollout import rollout
from twolink.studies.mismatch.measure import (
    THRESHOLD,
    counts,
    margin,
    margins,
    robustness,
)
from twolink.studies.mismatch.plan import (
    CURVES,
    FAMILIES,
    PLANS,
    SWEEP_SEED,
    axis,
    family_challenge,
    plan,
    report_order,
)
from twolink.studies.mismatch.report import robustness_tables
from twolink.studies.robustness import MODES, summarize
from twolink.viz.formatting import format_rate

pytestmark = pytest.mark.robustness


@pytest.fixture(scope="module")
def mujoco_plant():
    plant = MujocoPlant(TABLE_I, nthread=2)
    yield plant
    plant.close()


def _success(name, plant):
    return success(rollout(load_policy(name), plant, evaluation_set()))


def test_policy_synthesised_on_full_model_succeeds_on_mujoco_everywhere(mujoco_plant):
    ok = _success("centralized_full", mujoco_plant)
    assert ok.all(), np.flatnonzero(~ok)


def test_paper_policies_lose_most_of_their_success_on_mujoco(mujoco_plant):
    for name in ("centralized", "decentralized"):
        on_model = _success(name, make_plant("simplified")).mean()
        on_mujoco = _success(name, mujoco_plant).mean()
        assert on_model > 0.45 and on_mujoco < 0.15 and on_model - on_mujoco > 0.35, name


def test_decentralized_adaptation_to_full_model_closes_most_of_the_gap(mujoco_plant):
    paper = _success("decentralized", mujoco_plant).mean()
    adapted = _success("decentralized_full", mujoco_plant).mean()
    central = _success("centralized_full", mujoco_plant).mean()
    assert adapted > 0.9 > paper + 0.8
    assert adapted < central          # agent 2's blind spot (link 1 at rest) costs something
    tr = rollout(load_policy("decentralized_full"), mujoco_plant, evaluation_set())
    assert np.isfinite(settle_time(tr)).all()      # it does settle from every state, later


def test_margin_definition():
    assert margin({0.0: 1.0, -0.1: 1.0, 0.1: 0.96, 0.3: 0.5, -0.3: 1.0}) == 0.1
    assert margin({0.0: 0.9, 0.1: 1.0}) is None
    assert margin({0.0: 1.0, -0.2: 0.5, 0.2: 1.0, 0.5: 1.0}) == 0.0
    m = margins({"p": {"nominal": 1.0, "parameter:m1": {0.0: 1.0, 0.5: 1.0},
                       "parameter:m2": {0.0: 1.0, 0.5: 0.2}, "noise": {0.0: 1.0, 1.0: 1.0}}})
    assert m["p"]["every_parameter_alone"] == 0.0 and m["p"]["noise"] == 1.0
    assert "joint_lower_bound" not in m["p"]


def test_joint_margin_by_wilson_lower_bound_tells_neighbouring_sizes_apart():
    """At 96.5 % success, 4 plants x 65 states cannot show the size clears 95 %;
    32 plants x 65 states can. The rate rule says 0.2 either way."""
    rates = {0.0: 1.0, 0.1: 0.985, 0.2: 0.965, 0.3: 0.9}

    def margins_for(n):
        kn = {s: [round(r * n), n] for s, r in rates.items()}
        kn[0.0] = [65, 65]                   # the nominal plant: 65 states, judged by rate
        curves = {"p": {"nominal": 1.0, "joint": {s: k / n for s, (k, n) in kn.items()}}}
        return margins(curves, counted={"p": {"joint": kn}})["p"]

    few, many = margins_for(4 * 65), margins_for(32 * 65)
    assert few["joint"] == many["joint"] == 0.2
    assert wilson_interval(251, 260)[0] < THRESHOLD < wilson_interval(2007, 2080)[0]
    assert few["joint_lower_bound"] == 0.1 and many["joint_lower_bound"] == 0.2


@pytest.mark.slow
def test_quick_report_numbers_are_recomputed(tmp_path, capsys, mujoco_plant):
    out = tmp_path / "report"
    rc = main(["mismatch", "--quick", "--json", "--out", str(out), "--executor", "serial",
               "--policies", "centralized_full", "centralized"])       # out of order
    assert rc == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["plan"] == "quick" and list(printed["success_rate"]) == \
        ["centralized", "centralized_full"]                          # registry order
    # success rates recomputed from fresh rollouts, not stored
    for name in ("centralized", "centralized_full"):
        assert printed["success_rate"][name]["mujoco"] == _success(name, mujoco_plant).mean()
        assert printed["success_rate"][name]["simplified"] == \
            _success(name, make_plant("simplified")).mean()
    ol = printed["open_loop"]
    assert max(v["max"] for v in ol["full"].values()) < 1e-12
    assert ol["simplified"]["dtheta2"]["max"] > 1.0
    report = json.loads((out / "report.json").read_text())
    # the robustness analysis is the sweep file's records, analysed again
    records = load_results(out / "sweep.jsonl")
    assert len(records) == report["robustness"]["cells"] == len(PLANS["quick"].cells(
        ["centralized", "centralized_full"]))
    assert report["robustness"]["reused_cells"] == 0          # a fresh folder: all computed
    curves = robustness(records, ["centralized", "centralized_full"])
    counted = counts(records, ["centralized", "centralized_full"])
    assert report["robustness"]["curves"] == json.loads(json.dumps(curves))
    assert printed["margins"] == json.loads(json.dumps(margins(curves, counted=counted)))
    joint = counted["centralized_full"]["joint"]
    assert joint[0.2][1] == PLANS["quick"].joint_draws * PLANS["quick"].sweep_states()
    assert joint[0.2][0] / joint[0.2][1] == curves["centralized_full"]["joint"][0.2]
    for pol, m in printed["margins"].items():
        nominal = curves[pol]["nominal"]
        assert (m["joint"] is None) == (nominal < THRESHOLD), pol
    # throughput: the steps are what was asked for, the rates are the steps over the times
    tp = printed["throughput"]
    quick = PLANS["quick"]
    assert (tp["rows"], tp["samples"], tp["nstep"]) == \
        (quick.throughput_rows, quick.throughput_samples, mujoco_plant.nstep)
    assert tp["mujoco_steps"] == tp["rows"] * tp["samples"] * tp["nstep"]
    assert tp["closed_loop_steps_per_s"] == tp["mujoco_steps"] / tp["closed_loop_seconds"]
    assert tp["ratio_closed_to_open"] == tp["open_loop_seconds"] / tp["closed_loop_seconds"]
    assert tp["policy_seconds"] > 0             # timed apart from the loop: no order between them
    assert tp["policy_share"] == tp["policy_seconds"] / tp["closed_loop_seconds"]
    md = (out / "report.md").read_text()
    for fig in report["figures"].values():
        assert (out / fig).stat().st_size > 10_000 and f"]({fig})" in md
    g = report["gap_closure"]["centralized"]
    cl = report["closed_loop"]
    assert g["success_mujoco"] == cl["centralized"]["mujoco"]["success_rate"]
    assert g["success_mujoco_full_model_policy"] == cl["centralized_full"]["mujoco"]["success_rate"]
    k = cl["centralized"]["mujoco"]["successes"]
    lo, hi = wilson_interval(k, 65)
    assert f"| {k}/65 = {100 * g['success_mujoco']:.1f} % [{100 * lo:.0f}, {100 * hi:.0f}] |" in md
    worst = report["robustness"]["joint_worst_plant"]["centralized_full"]
    for size, w in worst.items():         # the worst plant is no better than the cell's mean
        assert 0 <= w["successes"] <= w["states"] and w["plants"] >= 1
        assert w["successes"] / w["states"] <= \
            report["robustness"]["curves"]["centralized_full"]["joint"][size] + 1e-12
        assert w["worst_return"] <= w["mean_return"] + 1e-12
    assert f"{100 * g['success_mujoco_full_model_policy']:.1f} %" in md
    # every table lists the policies in registry order
    tables = [t for t in md.split("\n\n") if t.startswith(("| policy", "| paper policy"))]
    assert len(tables) == 6   # closed loop, gap closure, two margins, joint sizes, robust
    # the robust section: every policy x level x mode, each one evaluate() call
    rs = report["robust"]
    assert sorted(rs["results"]) == ["centralized", "centralized_full"]   # json sorts keys
    for pol, modes in (("centralized", ["plain"]), ("centralized_full", sorted(MODES))):
        d = rs["results"][pol]        # the paper's policies run only as they are
        assert sorted(d) == sorted(LEVELS) and all(sorted(m) == modes for m in d.values())
    direct = evaluate("centralized_full", x0=states_of("quick"), seed=quick.robust_seed,
                      count=quick.robust_plants, challenge="medium", compensate=True)
    mine = rs["results"]["centralized_full"]["medium"]["compensated"]
    assert mine == json.loads(json.dumps(summarize(direct)))
    assert (mine["successes"], mine["n"]) == (direct.count, 4 * 5)
    assert printed["robust"]["centralized_full"]["medium"]["compensated"] == [direct.count, 20]
    plain = evaluate("centralized_full", x0=states_of("quick"), seed=quick.robust_seed,
                     count=quick.robust_plants, challenge="medium", compensate=False)
    assert rs["results"]["centralized_full"]["medium"]["plain"]["successes"] == plain.count
    assert plain.count < direct.count          # one sample of delay undone by the predictor
    assert rs["results"]["centralized"]["none"]["plain"]["plants"] == 1   # deterministic
    assert f"| centralized_full | medium | compensated | {format_rate(direct.count, 20)} |" in md
    for table in tables:
        names = [line.split("|")[1].strip() for line in table.splitlines()[2:]]
        ranks = [list(SHIPPED).index(n) for n in names]
        assert ranks == sorted(ranks), names


def test_robustness_tables_do_not_follow_completion_order():
    """Records arriving in any order give the same curves, margins and Markdown tables."""
    policies = ["decentralized_full", "centralized"]
    cells = PLANS["quick"].cells(policies)
    rng = np.random.default_rng(0)
    records = {c.key: {"cell": c.as_dict(), "success_rate": float(rng.uniform(0.9, 1))}
               for c in cells}
    keys = list(records)
    shuffled = [dict(zip(ks, (records[k] for k in ks)))
                for ks in (keys[::-1], random.Random(3).sample(keys, len(keys)))]
    first = robustness(records, policies)
    assert list(first) == ["centralized", "decentralized_full"]
    assert list(first["centralized"]) == list(CURVES) + ["nominal"]
    assert all(list(pts) == sorted(pts) for pts in first["centralized"].values()
               if isinstance(pts, dict))
    for recs in shuffled:
        again = robustness(recs, policies)
        assert json.dumps(again) == json.dumps(first)
        assert json.dumps(margins(again)) == json.dumps(margins(first))
        report = {"robustness": {"margins": margins(again), "curves": again}}
        assert _tables(report) == _tables({"robustness": {"margins": margins(first),
                                                          "curves": first}})


def _tables(report):
    """The robustness tables of the Markdown for a report holding only robustness."""
    return robustness_tables(report["robustness"])


def test_plans_are_one_table_of_named_plans():
    assert list(PLANS) == ["full", "quick"]
    with pytest.raises(ValueError, match="unknown plan 'huge'; choose one of full, quick"):
        plan("huge")
    for p in PLANS.values():
        cells = p.cells(["centralized"])
        assert len(set(cells)) == len(cells)
        on = [axis(c.as_dict()) for c in cells]
        assert {k.split(":")[0] for k, _ in on} == {"nominal", *FAMILIES}
        assert all(c.states == p.states and c.seed == SWEEP_SEED for c in cells)
        assert all(s != 0 for k, s in on if k != "nominal")
        assert all(c.plants == (p.joint_draws if k == "joint" else 1)
                   for c, (k, _) in zip(cells, on))
        assert sorted(p.sizes) == sorted(FAMILIES)
        for (k, size), c in zip(on, cells):             # each point is one Challenge
            fam, _, name = k.partition(":")
            assert c.challenge == family_challenge(fam, size, name) and c.challenge.name == k
    assert len(PLANS["quick"].cells(["centralized"])) == 1 + 11 * 2 + 4
    assert report_order(["centralized_full", "x.npz", "centralized", "centralized"]) == \
        ("centralized", "centralized_full", "x.npz")


def test_family_points_are_challenges_with_one_line_refusals():
    assert family_challenge("parameter", -0.5, "m2").offsets == (("m2", -0.5),)
    assert family_challenge("noise", 5.0).speed_noise == pytest.approx(0.1)
    assert family_challenge("delay", 2.0).action_delay == 2
    assert family_challenge("joint", 0.3).spread == 0.3
    assert family_challenge("torque_limit", -0.2).torque_limit == -0.2
    assert axis({"challenge": {"name": "medium"}}) is None
    for args, match in ((("wind", 1.0), "unknown perturbation family 'wind'"),
                        (("nominal", 1.0), "the nominal family has size 0"),
                        (("parameter", 0.1, "zz"), "unknown parameter 'zz' in offsets"),
                        (("delay", 0.5), "action_delay must be a whole number")):
        with pytest.raises(ValueError, match=match):
            family_challenge(*args)


def _not_measured(*args, **kwargs):
    raise AssertionError("a cell was measured")


def test_a_second_run_on_one_folder_is_refused_at_once(tmp_path, capsys, monkeypatch):
    out = tmp_path / "r"
    out.mkdir()
    monkeypatch.setattr("twolink.sim.cells.run_cells", _not_measured)   # before any measurement
    with CellFile(out / "sweep.jsonl"):
        assert main(["mismatch", "--quick", "--out", str(out), "--executor", "serial"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "sweep.jsonl is in use by another run (pid" in err[0]
    assert err[0].startswith("twolink mismatch: error: ")
    assert sorted(p.name for p in out.iterdir()) == ["sweep.jsonl"]


@pytest.mark.parametrize("argv, match", [
    (["--policies", "nosuch"], "unknown policy"),
    (["--workers", "0"], "workers"),
    (["--address", "ray://x:1"], "--executor ray"),
    (["--challenge", "easy", "nosuch"], "unknown challenge 'nosuch'; choose one of none, easy"),
    (["--no-robust", "--seed", "3"], "drop --no-robust or them"),
    (["--seed", "-1"], "--seed must be a whole number from 0")])
def test_bad_input_is_one_error_line_and_writes_nothing(tmp_path, capsys, argv, match):
    out = tmp_path / "r"
    assert main(["mismatch", "--quick", "--out", str(out)] + argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0]
    assert not out.exists()


def _free_port() -> int:
    """A local TCP port nothing listens on (bound, then released)."""
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@pytest.mark.parametrize("address, match", [
    (None, "no Ray cluster answers there (connection refused)"),
    ("nonsense", "--address must be HOST:PORT, ray://HOST:PORT, auto or local"),
])
def test_a_ray_address_that_does_not_answer_fails_at_once_and_writes_nothing(
        tmp_path, capsys, monkeypatch, address, match):
    out = tmp_path / "r"
    address = address or f"127.0.0.1:{_free_port()}"
    monkeypatch.setattr("twolink.sim.cells.run_cells", _not_measured)
    assert main(["mismatch", "--quick", "--out", str(out), "--executor", "ray",
                 "--address", address]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0] and err[0].startswith("twolink mismatch: error:")
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_a_users_report_is_not_overwritten(tmp_path, capsys):
    out = tmp_path / "r"
    out.mkdir()
    (out / "report.md").write_text("my notes\n")
    assert main(["mismatch", "--quick", "--out", str(out), "--executor", "serial"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "already holds a report.md" in err[0] and "--force" in err[0]
    assert (out / "report.md").read_text() == "my notes\n"
    assert sorted(p.name for p in out.iterdir()) == ["report.md"]
    file = tmp_path / "f"
    file.write_text("x")
    assert main(["mismatch", "--quick", "--out", str(file)]) == 2
    assert "is a file; give a folder" in capsys.readouterr().err


def test_a_policy_keeps_its_colour_whatever_the_order(monkeypatch, tmp_path):
    from matplotlib.colors import to_hex

    from twolink.studies.mismatch import figures as mismatch_figures

    figures = []
    monkeypatch.setattr(mismatch_figures, "_save", lambda fig, path: figures.append(fig))
    curves = {"decentralized_full": {"noise": {0.0: 1.0, 1.0: 0.5}},
              "centralized": {"noise": {0.0: 0.4, 1.0: 0.2}}}
    for order in (curves, dict(reversed(list(curves.items())))):
        mismatch_figures.robustness_figure(
            {"robustness": {"curves": order, "threshold": THRESHOLD}}, ["noise"],
            tmp_path / "x.png", "t")
    colours = [{line.get_label(): to_hex(line.get_color()) for line in fig.axes[0].lines
                if not line.get_label().startswith("_")} for fig in figures]
    assert colours[0] == colours[1]
    assert colours[0]["centralized"] == to_hex(mismatch_figures.policy_color("centralized"))
    assert colours[0]["centralized"] != colours[0]["decentralized_full"]
    assert mismatch_figures.policy_color("centralized_full") == \
        f"C{list(SHIPPED).index('centralized_full')}"


def test_robust_figure_draws_rates_at_the_ends_of_their_intervals(tmp_path):
    """2080/2080 has a Wilson upper bound a hair under 1 (round-off): still drawn."""
    from twolink.studies.mismatch.figures import robust_figure

    def res(k, n):
        return {"rate": k / n, "wilson95": list(wilson_interval(k, n))}
    section = {"levels": {"none": {}, "medium": {}}, "plants": 32, "states": 65, "seed": 1,
               "modes": {"centralized": ["plain"], "centralized_robust": list(MODES)},
               "results": {"centralized": {"none": {"plain": res(7, 65)},
                                           "medium": {"plain": res(0, 2080)}},
                           "centralized_robust": {lv: {m: res(2080, 2080) for m in MODES}
                                                  for lv in ("none", "medium")}}}
    settle = {(p, lv, m): np.r_[np.full(60, 1.2), np.full(5, np.inf)]
              for p, d in section["results"].items() for lv, ms in d.items() for m in ms}
    assert wilson_interval(2080, 2080)[1] < 1.0
    assert robust_figure(section, settle, tmp_path / "r.png") == "r.png"
    assert (tmp_path / "r.png").stat().st_size > 10_000
