"""`--links N` through the commands (rollout, render, synthesize, mismatch), the renderer
and the trajectory files: N-link outputs, and bad input refused in one line with nothing
written."""
import json

import mujoco
import numpy as np
import pytest

from twolink.arm import mjcf, parameter_file
from twolink.arm.parameters import TABLE_I, links_parameters
from twolink.cli import main
from twolink.fqi.fuzzy import Axis, Grid
from twolink.policy.fuzzy_policy import Agent, Policy
from twolink.policy.registry import SHIPPED, TWO_LINK
from twolink.sim.metrics import random_poses, success
from twolink.sim.plants import make_plant
from twolink.sim.rollout import Trajectory, rollout
from twolink.sim.trajectory_file import csv_columns, load_npz, to_csv_text
from twolink.studies.mismatch.plan import LINKS_SEED, plan
from twolink.viz.render import goal_tip_radius, tip_positions

COMMANDS = ("rollout", "render", "synthesize", "mismatch")


def _joint_agent(k: int, gain: float) -> Agent:
    """Agent k: bang-zero-bang on the sign of theta_k + dtheta_k (a hand-made controller)."""
    grid = Grid((Axis(f"theta{k}", (-1.0, 0.0, 1.0)), Axis(f"dtheta{k}", (-1.0, 0.0, 1.0))))
    actions = np.array([[-gain], [0.0], [gain]])
    want = -np.sign(grid.centers().sum(-1))
    q = -np.abs(actions[:, 0][None, :] / gain - want[:, None])
    return Agent(f"agent{k}", grid, actions, q, (f"tau{k}",))


@pytest.fixture(scope="module")
def three_link(tmp_path_factory):
    """A 3-link policy file (one hand-made agent per joint)."""
    policy = Policy("decentralized", [_joint_agent(k, g) for k, g in
                                      ((3, 0.05), (2, 0.1), (1, 0.2))], {"links": 3})
    path = tmp_path_factory.mktemp("policies") / "hand3.npz"
    policy.save(path)
    return path


def _run(capsys, *argv):
    code = main([*map(str, argv)])
    out = capsys.readouterr()
    return code, out.out, out.err


def _refused(capsys, tmp_path, *argv) -> str:
    """The one error line of a refused command; asserts exit 2 and an empty folder."""
    out_dir = tmp_path / "out"
    out_dir.mkdir(exist_ok=True)
    code, out, err = _run(capsys, *argv)
    assert code == 2, (out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert list(out_dir.iterdir()) == []
    return lines[0]


def _outputs(command: str, tmp_path) -> list:
    out = tmp_path / "out"
    return {"rollout": ["--prefix", out / "run"], "render": ["-o", out / "v.gif"],
            "synthesize": ["decentralized", "-o", out / "p.npz"],
            "mismatch": ["--out", out / "m"]}[command]


# --------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("links", [1, 7])
def test_links_outside_two_to_six_is_one_line(command, links, tmp_path, capsys):
    line = _refused(capsys, tmp_path, command, "--links", links, *_outputs(command, tmp_path))
    assert line == f"twolink {command}: error: --links must be a whole number from 2 to 6, " \
                   f"got {links}"


@pytest.mark.parametrize("command", ["rollout", "render", "mismatch"])
def test_a_policy_of_another_n_is_refused_naming_both(command, three_link, tmp_path, capsys):
    line = _refused(capsys, tmp_path, command, "--policy" if command != "mismatch"
                    else "--policies", three_link, *_outputs(command, tmp_path))
    assert "hand3 is for a 3-link arm" in line or "hand3.npz is for a 3-link arm" in line
    assert "has 2 links" in line
    line = _refused(capsys, tmp_path, command, "--links", 3, "--policy" if command != "mismatch"
                    else "--policies", "decentralized", *_outputs(command, tmp_path))
    assert "decentralized is for a 2-link arm" in line and "has 3 links" in line


@pytest.mark.parametrize("command", ["rollout", "render"])
def test_x0_of_the_wrong_count_for_n(command, three_link, tmp_path, capsys):
    line = _refused(capsys, tmp_path, command, "--links", 3, "--policy", three_link,
                    "--x0", "1", "2", "0", "0", *_outputs(command, tmp_path))
    assert "--x0 must be 6 numbers for 3 links" in line and "got 4" in line


def test_two_link_options_are_refused_for_more_links(three_link, tmp_path, capsys):
    line = _refused(capsys, tmp_path, "rollout", "--links", 3, "--policy", three_link,
                    "--plant", "simplified", "-o", tmp_path / "out" / "run")
    assert "simplified model (11)" in line and "--links 3" in line
    line = _refused(capsys, tmp_path, "rollout", "--links", 3, "--policy", three_link,
                    "--challenge", "medium", "-o", tmp_path / "out" / "run")
    assert "--challenge applies to the two-link arm only" in line
    for extra in (["--model", "simplified"], ["--robust", "worst"], ["--sweeps", "serial"]):
        line = _refused(capsys, tmp_path, "synthesize", "decentralized", "--links", 3, *extra,
                        "-o", tmp_path / "out" / "p.npz")
        assert "a two-link option" in line, line


def test_a_parameter_file_is_refused_for_more_links(tmp_path, capsys):
    params = parameter_file.save(tmp_path / "arm.json", TABLE_I, provenance={})
    line = _refused(capsys, tmp_path, "synthesize", "decentralized", "--links", 3,
                    "--params", params, "-o", tmp_path / "out" / "p.npz")
    assert "parameter file describes a 2-link arm; --links 3" in line


@pytest.mark.parametrize("links", [3, 4])
def test_centralized_synthesis_is_refused_with_its_estimate(links, tmp_path, capsys):
    line = _refused(capsys, tmp_path, "synthesize", "centralized", "--links", links,
                    "-o", tmp_path / "out" / "p.npz")
    assert "GiB" in line
    if links == 3:       # 592 704 states x 27 actions: over a policy file's 64 MiB
        assert "16,003,008 values" in line and "policy file" in line
    else:                # over the memory cap
        assert "over the cap" in line


# --------------------------------------------------------------------------- N-link outputs
def test_rollout_of_three_links_matches_the_library(three_link, tmp_path, capsys):
    x0 = [0.5, -1.0, 2.0, 0.0, 0.1, -0.2]
    code, out, err = _run(capsys, "rollout", "--links", 3, "--policy", three_link,
                          "--plant", "mujoco", "--plant", "full", "--x0", *x0,
                          "--duration", 0.5, "--json", "-o", tmp_path / "run")
    assert code == 0, err
    rep = json.loads(out)
    assert rep["links"] == 3 and rep["rule"] == "tapered" and rep["duration"] == 0.5
    policy = Policy.load(three_link)
    with make_plant("mujoco", links_parameters(3)) as plant:
        direct = rollout(policy, plant, x0, duration=0.5)
    mj = next(e for e in rep["runs"] if e["plant"] == "mujoco")
    assert mj["final_state"] == direct.x[-1].tolist()
    assert set(mj["gap_to_full"]) == {"angle_rms", "speed_rms"}
    saved = load_npz(tmp_path / "run.npz")[("hand3", "mujoco")]
    np.testing.assert_array_equal(saved.x, direct.x)
    assert saved.u.shape == (10, 3)
    lines = (tmp_path / "run.csv").read_text().splitlines()
    assert lines[0].split(",") == list(csv_columns(3))
    assert len(lines) == 1 + 2 * 11
    assert (tmp_path / "run_fig3.png").read_bytes()[:4] == b"\x89PNG"


def test_csv_columns_and_mixed_arms():
    assert csv_columns(2) == ("policy", "plant", "k", "t", "theta1", "theta2", "dtheta1",
                              "dtheta2", "tau1", "tau2", "r", "r1", "r2")
    assert csv_columns(4)[-5:] == ("r", "r1", "r2", "r3", "r4")

    def traj(n):
        return Trajectory(np.arange(2) * 0.05, np.zeros((2, 2 * n)), np.zeros((1, n)),
                          np.zeros(1), np.zeros((1, n)))
    rows = [line.split(",") for line in to_csv_text({("a", "mujoco"): traj(3)}).splitlines()]
    assert rows[1][-4:] == [""] * 4 and "" not in rows[1][10:13]   # no r on the first sample
    assert rows[2][10:13] == [""] * 3 and "" not in rows[2][-4:]   # no u on the last one
    with pytest.raises(ValueError, match=r"arms with \[2, 3\] links"):
        to_csv_text({("a", "mujoco"): traj(3), ("b", "mujoco"): traj(2)})


def test_render_three_links_writes_a_gif(three_link, tmp_path, capsys):
    out = tmp_path / "v.gif"
    code, stdout, err = _run(capsys, "render", "--links", 3, "--policy", three_link,
                             "--duration", 0.2, "--size", "64x48", "--json", "-o", out)
    assert code == 0, err
    rep = json.loads(stdout)
    assert rep["frames"] == 5 and rep["links"] == 3 and len(rep["x0"]) == 6
    assert out.read_bytes()[:6] == b"GIF89a"


@pytest.mark.parametrize("links", [2, 3, 5])
def test_tip_positions_are_mujocos_sites(links, rng):
    p = TABLE_I if links == 2 else links_parameters(links, "copied")
    model = mjcf.build_model(p)
    data = mujoco.MjData(model)
    x = np.concatenate([rng.uniform(-np.pi, np.pi, links), np.zeros(links)])
    data.qpos[:] = x[:links]
    mujoco.mj_kinematics(model, data)
    sites = np.array([data.site(f"link{k}_tip").xpos[:2] for k in range(1, links + 1)])
    np.testing.assert_allclose(tip_positions(x, p), sites, atol=1e-12)
    assert goal_tip_radius(p) > 0


@pytest.mark.slow
def test_mismatch_section_counts_are_the_plants(three_link, tmp_path, capsys):
    out = tmp_path / "m"
    code, stdout, err = _run(capsys, "mismatch", "--links", 3, "--quick",
                             "--policies", three_link, "--json", "--out", out)
    assert code == 0, err
    rep = json.loads(stdout)
    n = plan("quick").links_poses
    x0 = random_poses(3, n, LINKS_SEED)
    with make_plant("full", links_parameters(3)) as plant:
        tr = rollout(Policy.load(three_link), plant, x0, duration=8.0)
    got = rep["results"]["hand3"]["full"]
    assert (got["successes"], got["n"]) == (int(success(tr).sum()), n)
    assert rep["seed"] == LINKS_SEED and rep["duration"] == 8.0
    md = (out / "report.md").read_text()
    assert "| hand3 |" in md and f"{got['successes']}/{n}" in md
    assert json.loads((out / "report.json").read_text())["results"] == rep["results"]


# --------------------------------------------------------------------------- registry
def test_two_link_reports_ignore_n_link_policies(tmp_path, capsys):
    assert all(SHIPPED[n].links == 2 for n in TWO_LINK)
    three = [n for n, e in SHIPPED.items() if e.links == 3]
    if three:        # the shipped 3-link policy is rollout's and render's default for N = 3
        code, out, err = _run(capsys, "rollout", "--links", 3, "--duration", 0.1,
                              "--no-save", "--json")
        assert code == 0, err
        assert json.loads(out)["runs"][0]["policy"] == three[0]
    else:            # none shipped yet: the default is refused with the way to make one
        line = _refused(capsys, tmp_path, "rollout", "--links", 3, "--no-save")
        assert "twolink synthesize decentralized --links 3" in line


def test_reproduce_takes_two_link_policies_only():
    from twolink.studies.reproduce.measure import reproduce
    with pytest.raises(ValueError, match=r"two-link arm; 'decentralized_3link' is not one"):
        reproduce(1.0, policies=("centralized", "decentralized_3link"))


def test_synthesize_three_links_gives_the_shipped_policy(tmp_path, capsys, monkeypatch):
    from twolink.commands.synthesize import links_file_name
    shipped_file = SHIPPED["decentralized_3link"].file
    assert links_file_name("decentralized", 3, "tapered") == "decentralized_3link.npz"
    assert links_file_name("decentralized", 4, "copied", "frozen") == \
        "decentralized_4link_copied_frozen.npz"
    monkeypatch.chdir(tmp_path)
    code, out, err = _run(capsys, "synthesize", "decentralized", "--links", 3, "--json")
    assert code == 0, err
    rep = json.loads(out)
    assert (rep["path"], rep["links"], rep["rule"]) == ("decentralized_3link.npz", 3, "tapered")
    assert list(rep["agents"]) == ["agent3", "agent2", "agent1"]
    made, shipped = Policy.load(tmp_path / rep["path"]), Policy.load(shipped_file)
    for a, b in zip(made.agents, shipped.agents):   # within 1e-12: see tests/policy
        np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(a.greedy_actions, b.greedy_actions)
