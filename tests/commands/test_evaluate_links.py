"""`twolink evaluate NAME --links N`: the scaling table's protocol through the command,
scored by the very function the table uses, and bad input refused in one line."""
import json

import numpy as np
import pytest

from twolink.arm.parameters import links_parameters
from twolink.cli import main
from twolink.commands import evaluate as evaluate_cmd
from twolink.control import catalogue
from twolink.control.links_pd import TUNED
from twolink.sim.metrics import random_poses, score, settle_time, success
from twolink.sim.plants import make_plant
from twolink.sim.rollout import rollout
from twolink.studies.scaling import measure as scaling


def _json(capsys, *argv):
    assert main(["evaluate", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_defaults_are_the_scaling_tables():
    assert evaluate_cmd.DEFAULT_POSES == scaling.DEFAULT_POSES
    assert evaluate_cmd.POSE_SEED == scaling.EVAL_SEED


def test_pd_entry_scores_as_the_scaling_tables_pd_row(capsys):
    row = scaling.measure(3, "copied", "pd", poses=6, seed=11)
    want = row.evaluation.horizons["8"]
    got = _json(capsys, "pd_3link_copied", "--links", "3", "--poses", "6", "--seed", "11")
    assert (got["links"], got["rule"], got["horizon"], got["poses_seed"]) == \
        (3, "copied", 8.0, 11 + 3)
    for key in ("successes", "n", "wilson_95", "median_settle"):
        assert got[key] == want[key], key


def test_fuzzy_agents_match_a_rollout_scored_by_hand(capsys):
    got = _json(capsys, "decentralized_3link", "--links", "3", "--poses", "5", "--seed", "3")
    policy = catalogue.load("decentralized_3link")
    with make_plant("mujoco", links_parameters(3, "tapered")) as plant:
        traj = rollout(policy, plant, random_poses(3, 5, 3 + 3), duration=8.0)
    want = score(success(traj), settle_time(traj)).as_dict()
    assert got["controller"] == "decentralized_3link"
    assert (got["successes"], got["n"], got["median_settle"]) == \
        (want["successes"], 5, want["median_settle"])


def test_text_line_has_the_count_interval_and_settle(capsys):
    assert main(["evaluate", "pd_4link_tapered", "--links", "4", "--poses", "3"]) == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith("pd_4link_tapered on 4 links, tapered (3 random poses at rest, "
                           "seed 20061122 + 4, 8 s): ")
    assert "/3 = " in line and "[" in line and "median settle" in line


def test_a_callable_file_for_n_links(tmp_path, capsys):
    f = tmp_path / "still.py"
    f.write_text("import numpy as np\n"
                 "def hold(x):\n    return np.zeros(x.shape[:-1] + (3,))\n")
    got = _json(capsys, f"{f}:hold", "--links", "3", "--poses", "4")
    assert (got["successes"], got["n"], got["median_settle"]) == (0, 4, None)


def test_pd_entries_carry_the_tuned_gains():
    for (n, rule), t in TUNED.items():
        e = catalogue.lookup(f"pd_{n}link_{rule}")
        assert (e.links, e.rule, e.kind) == (n, rule, "decentralized")
        assert set(e.tags) == {"baseline", "n-link"}
        pd = e.load()
        assert pd.name == e.name and pd.links == n
        x = np.zeros((1, 2 * n))
        x[0, 0] = 0.01            # inside every saturation: tau_1 = -kp_1 * 0.01
        kp1 = links_parameters(n, rule).tau_max[0] / np.radians(t["sat_deg"])
        assert pd(x)[0, 0] == pytest.approx(-kp1 * 0.01)
    assert len(catalogue.entries(tag="n-link", links=5)) >= 2


@pytest.mark.parametrize("argv, words", [
    (["pd_3link_tapered", "--links", "9"], "--links must be a whole number from 2 to 6"),
    (["pd_3link_tapered", "--links", "1"], "--links must be a whole number from 2 to 6"),
    (["pd_3link_tapered", "--links", "3", "--poses", "0"], "--poses must be"),
    (["pd_3link_tapered", "--links", "3", "--poses", "100001"], "--poses must be"),
    (["pd_3link_tapered", "--links", "3", "--seed", "-1"], "--seed must be"),
    (["pd_3link_tapered", "--links", "3", "--challenge", "hard"], "--challenge is a two-link"),
    (["pd_3link_tapered", "--links", "3", "--compensate", "--quick"],
     "--compensate, --quick are two-link"),
    (["pd_3link_tapered", "--links", "3", "--rule", "copied"], "give --rule tapered"),
    (["pd_3link_tapered", "--links", "4"], "controls an arm of 3 links; give --links 3"),
    (["lqr", "--links", "3"], "controls an arm of 2 links"),
    (["pd", "--links", "2", "--rule", "copied"], "--rule makes links beyond the second"),
    (["pd", "--poses", "8"], "--poses needs --links N"),
    (["pd", "--poses", "8", "--plant", "model"], "--poses, --plant need --links N"),
    (["pd_9link_tapered", "--links", "3"], "unknown controller 'pd_9link_tapered'"),
    (["pd_3link_tapered", "--links", "3", "--horizon", "1"], "--horizon must be from 2 to 60"),
    (["pd_3link_tapered", "--links", "3", "--horizon", "nan"], "--horizon must be from 2 to 60"),
    (["pd_3link_tapered", "--links", "3", "--horizon", "8.01"], "whole samples of 0.05 s"),
    (["pd", "--horizon", "12"], "--horizon needs --links N"),
])
def test_bad_input_is_one_line_exit_2(argv, words, capsys):
    assert main(["evaluate", *argv]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], lines


def test_plant_model_scores_the_same_poses_on_the_rigid_body_model(capsys):
    """--plant model runs the poses on the model (6): the same draw, another plant, so a
    controller's two scores differ only by the plant (here the trajectories' settle
    times differ, the draw and count do not)."""
    mj = _json(capsys, "pd_3link_tapered", "--links", "3", "--poses", "6")
    model = _json(capsys, "pd_3link_tapered", "--links", "3", "--poses", "6", "--plant", "model")
    assert (mj["plant"], model["plant"]) == ("mujoco", "model")
    assert (model["poses_seed"], model["n"]) == (mj["poses_seed"], 6)
    from twolink.arm.parameters import horizon
    from twolink.control.controllers import resolve_controller
    from twolink.envs.core import arm
    from twolink.sim.plants import ModelPlant
    from twolink.sim.pose_scoring import poses_for
    from twolink.sim.rollout import rollout
    from twolink.sim.metrics import success

    params = arm(links=3, rule="tapered")
    with ModelPlant("full", params) as plant:
        traj = rollout(resolve_controller("pd_3link_tapered", links=3), plant,
                       poses_for(3, 6, 20061122), duration=horizon(3))
    assert int(success(traj).sum()) == model["successes"]


def test_two_links_on_the_protocol_and_the_two_link_evaluate_unchanged(capsys):
    got = _json(capsys, "pd", "--links", "2", "--poses", "4")
    assert (got["links"], got["rule"], got["horizon"], got["n"]) == (2, "Table I", 5.0, 4)
    plain = _json(capsys, "pd", "--quick")
    assert (plain["challenge"], plain["states"], plain["seed"], plain["plants"]) == \
        ("none", 5, 2026, 1)


def test_a_longer_horizon_scores_the_same_poses_run_on(capsys):
    """--horizon 16 runs the same draw for 16 s: success there is the 16 s rollout's (as
    the own-motor study cuts it), and the per-joint PD of six tapered links, which settles
    few poses by 8 s, settles more by 16 s."""
    from twolink.envs.core import arm
    from twolink.sim.pose_scoring import poses_for

    at8 = _json(capsys, "pd_6link_tapered", "--links", "6", "--poses", "6", "--seed", "5")
    at16 = _json(capsys, "pd_6link_tapered", "--links", "6", "--poses", "6", "--seed", "5",
                 "--horizon", "16")
    assert (at8["horizon"], at16["horizon"]) == (8.0, 16.0)
    assert at16["poses_seed"] == at8["poses_seed"] and at16["n"] == 6
    with make_plant("mujoco", arm(links=6, rule="tapered")) as plant:
        traj = rollout(catalogue.load("pd_6link_tapered"), plant, poses_for(6, 6, 5),
                       duration=16.0)
    assert at16["successes"] == int(success(traj).sum())
    assert at16["successes"] > at8["successes"]
