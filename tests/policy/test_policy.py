"""Policies (14), (16), (18): synthesis, files, provenance, ties, and bad files."""
import json
import zipfile
from pathlib import Path

import numpy as np
import pytest

from twolink.arm.parameters import TABLE_I
from twolink.synthesis.synthesize import synthesize
from twolink.policy.fuzzy_policy import (
    FORMAT_VERSION,
    TIE_TOLERANCE,
    Agent,
    Policy,
    PolicyFileError,
    _content_hash,
    greedy_indices,
    load_policy,
)
from twolink.policy.registry import SHIPPED
from twolink.studies.reproduce import paper


@pytest.mark.parametrize("name", list(SHIPPED))
def test_resynthesis_reproduces_shipped_policy_exactly(name):
    entry = SHIPPED[name]
    shipped = Policy.load(entry.file)
    fresh = synthesize(entry.kind, TABLE_I, **entry.synthesis_options())
    assert [a.name for a in fresh.agents] == [a.name for a in shipped.agents]
    for a, b in zip(fresh.agents, shipped.agents):
        if entry.links == 2:
            np.testing.assert_array_equal(a.q, b.q)
        else:       # N-link agents: Q within 1e-12 (re-synthesis moved it by up to 1.1e-14
            #         on some machines; on the one that shipped it, bit for bit)
            np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(a.greedy_actions, b.greedy_actions)
        assert a.info["iterations"] == b.info["iterations"]
        assert b.tie_tolerance == TIE_TOLERANCE
    assert fresh.meta["model"] == shipped.meta["model"] == entry.model
    assert shipped.meta.get("context") == entry.context


def test_q_table_sizes_of_table_ii(centralized, decentralized):
    assert centralized.q_sizes == {"centralized": paper.Q_SIZES["centralized"]}
    assert decentralized.q_sizes == {"agent2": paper.Q_SIZES["agent2"],
                                     "agent1": paper.Q_SIZES["agent1"]}


def test_provenance_is_recorded(decentralized):
    meta = decentralized.meta
    assert meta["gamma"] == 0.98 and meta["delta"] == 0.01 and meta["model"] == "simplified"
    assert meta["parameters"]["m1"] == 1.25 and meta["context"] == "frozen"
    assert "twolink_version" in meta
    assert decentralized.agents[1].info["iterations"] > 0
    assert decentralized.agents[0].grid.names == ("theta2", "dtheta2")
    assert decentralized.agents[1].grid.names == ("theta1", "dtheta1", "theta2", "tau2")


def test_round_trip_is_bit_for_bit(tmp_path, centralized, rng):
    path = centralized.save(tmp_path / "c.npz")
    again = Policy.load(path)
    np.testing.assert_array_equal(again.agents[0].q, centralized.agents[0].q)
    x = rng.uniform(-3, 3, (100, 4))
    np.testing.assert_array_equal(again(x), centralized(x))
    assert again.meta == centralized.meta


def test_policy_at_bin_centres_is_the_greedy_action(centralized):
    agent = centralized.agents[0]
    c = agent.grid.centers()
    greedy = agent.actions[greedy_indices(agent.q)]
    np.testing.assert_allclose(centralized(c), greedy, atol=1e-12)


def test_policy_interpolates_between_centres(centralized):
    """(14): between two centres the command is the membership-weighted average."""
    agent = centralized.agents[0]
    c = agent.grid.centers()
    a, b = c[0], c[1]                        # neighbours along the last (dtheta2) axis
    mid = 0.25 * a + 0.75 * b
    expected = 0.25 * agent.greedy_actions[0] + 0.75 * agent.greedy_actions[1]
    np.testing.assert_allclose(centralized(mid), expected, atol=1e-12)


def test_ties_break_to_the_first_action(centralized):
    agent = centralized.agents[0]
    tied = agent.__class__(agent.name, agent.grid, agent.actions, np.zeros_like(agent.q),
                           agent.outputs)
    np.testing.assert_array_equal(tied.greedy_actions, np.tile(agent.actions[0], (agent.q.shape[0], 1)))


def test_near_ties_within_the_tolerance_go_to_the_first_action():
    """docs/conventions.md: round-off must never decide an action."""
    q = np.array([[-3.0, -3.0 + 1e-14, -4.0],      # round-off apart: tied, first wins
                  [-3.0 - 1e-14, -3.0, -3.0],      # all three tied
                  [-2.0, -1.0, -1.0 - 1e-15],      # 1 and 2 tied, 0 genuinely worse
                  [-1.0, -1.0 + 1e-5, -2.0]])      # a genuine difference wins
    np.testing.assert_array_equal(greedy_indices(q), [0, 0, 1, 1])
    np.testing.assert_array_equal(greedy_indices(q, 0.0), [1, 1, 1, 1])
    assert 1e-13 < TIE_TOLERANCE < 1e-6


@pytest.mark.parametrize("name", list(SHIPPED))
def test_round_off_does_not_move_the_shipped_greedy_actions(name):
    """Perturbing Q by 1e-12 (far above round-off, far below the tolerance) moves no bin."""
    rng = np.random.default_rng(7)
    for agent in load_policy(name).agents:
        for eps in (1e-12, -1e-12):
            noisy = agent.q + eps * rng.choice([-1.0, 1.0], agent.q.shape)
            np.testing.assert_array_equal(greedy_indices(noisy), greedy_indices(agent.q))
        np.testing.assert_array_equal(
            greedy_indices(np.round(agent.q, 11)), greedy_indices(agent.q))


def test_agent1_frozen_greedy_actions_use_the_tolerance(decentralized):
    agent1 = decentralized.agents[1]
    idx = greedy_indices(agent1.q)
    np.testing.assert_array_equal(agent1.greedy_actions, agent1.actions[idx])
    # round-off decided 142 of its bins under a plain argmax
    assert np.count_nonzero(idx != np.argmax(agent1.q, axis=1)) > 100


def test_decentralized_agent1_sees_agent2_torque(decentralized, rng):
    x = rng.uniform(-3, 3, (50, 4))
    a2, a1 = decentralized.agents
    tau2 = a2.act(x[:, [1, 3]])[:, 0]
    tau1 = a1.act(np.stack([x[:, 0], x[:, 2], x[:, 1], tau2], -1))[:, 0]
    np.testing.assert_allclose(decentralized(x), np.stack([tau1, tau2], -1))


def test_foreign_files_are_refused(tmp_path, centralized):
    text = tmp_path / "notes.npz"
    text.write_text("hello")
    with pytest.raises(PolicyFileError, match="not a twolink policy file"):
        Policy.load(text)
    other = tmp_path / "other.npz"
    np.savez(other, weights=np.zeros(3))
    with pytest.raises(PolicyFileError, match="no policy header"):
        Policy.load(other)
    foreign = tmp_path / "foreign.npz"
    np.savez(foreign, header=np.array(json.dumps({"format": "something-else"})))
    with pytest.raises(PolicyFileError, match="not a twolink policy file"):
        Policy.load(foreign)
    with pytest.raises(PolicyFileError, match="does not exist"):
        Policy.load(tmp_path / "missing.npz")


def _write(path, header, rehash=True, **arrays):
    """A policy archive with ``header`` (its sha256 recomputed) and ``arrays`` as given."""
    header = dict(header)
    if rehash:
        header["sha256"] = _content_hash(header, {k[2:]: v for k, v in arrays.items()})
    np.savez(path, header=np.array(json.dumps(header)), **arrays)
    return path


def test_wrong_shapes_are_refused(tmp_path, centralized):
    header = centralized.header()
    bad = tmp_path / "bad.npz"
    with pytest.raises(PolicyFileError, match="Q must have shape"):
        Policy.load(_write(bad, header, q_centralized=np.zeros((10, 9))))
    q = centralized.agents[0].q.copy()
    q[0, 0] = np.nan
    with pytest.raises(PolicyFileError, match="nan.npz: agent centralized: Q contains NaN"):
        Policy.load(_write(tmp_path / "nan.npz", header, rehash=False, q_centralized=q))


@pytest.mark.parametrize("dtype", [np.complex128, np.str_, np.bool_, np.float32, np.int64])
def test_non_real_or_non_float64_q_is_refused(tmp_path, decentralized, dtype):
    header = decentralized.header()
    q1 = decentralized.agents[1].q.astype(dtype)
    path = _write(tmp_path / "odd.npz", header, rehash=False, q_agent2=decentralized.agents[0].q,
                  q_agent1=q1)
    with pytest.raises(PolicyFileError, match=r"odd\.npz: agent agent1.*float64"):
        Policy.load(path)


def test_object_arrays_are_refused(tmp_path, decentralized):
    q1 = np.empty(decentralized.agents[1].q.shape, dtype=object)
    path = tmp_path / "obj.npz"
    np.savez(path, header=np.array(json.dumps(decentralized.header())),
             q_agent2=decentralized.agents[0].q, q_agent1=q1)
    with pytest.raises(PolicyFileError, match="obj.npz"):
        Policy.load(path)


def test_non_real_actions_are_refused(tmp_path, decentralized):
    header = json.loads(json.dumps(decentralized.header()))
    header["agents"][1]["actions"] = [["-3"], ["0"], ["3"]]
    qs = {f"q_{a.name}": a.q for a in decentralized.agents}
    with pytest.raises(PolicyFileError, match="actions must hold real numbers"):
        Policy.load(_write(tmp_path / "s.npz", header, **qs))
    header["agents"][1]["actions"] = [[True], [False], [True]]
    with pytest.raises(PolicyFileError, match="actions must hold real numbers"):
        Policy.load(_write(tmp_path / "b.npz", header, **qs))
    header["agents"][1]["actions"] = [[float("nan")], [0.0], [0.2]]
    np.savez(tmp_path / "n.npz", header=np.array(json.dumps(header)), **qs)
    with pytest.raises(PolicyFileError, match=r"n\.npz: malformed twolink policy"):
        Policy.load(tmp_path / "n.npz")
    with pytest.raises(ValueError, match="Q must hold real numbers"):
        a = decentralized.agents[1]
        Agent(a.name, a.grid, a.actions, a.q.astype(complex), a.outputs)


def test_edited_provenance_or_q_is_refused(tmp_path, decentralized):
    """The sha256 ties the header (gamma, model, iterations) to the Q-tables."""
    path = decentralized.save(tmp_path / "d.npz")
    with np.load(path) as npz:
        files = {k: npz[k] for k in npz.files}
    header = json.loads(str(files["header"]))
    assert len(header["sha256"]) == 64
    edits = [("meta", "gamma", 0.9), ("meta", "model", "full")]
    for section, key, value in edits:
        h = json.loads(json.dumps(header))
        h[section][key] = value
        np.savez(tmp_path / "e.npz", **{**files, "header": np.array(json.dumps(h))})
        with pytest.raises(PolicyFileError, match=r"e\.npz: content does not match"):
            Policy.load(tmp_path / "e.npz")
    h = json.loads(json.dumps(header))
    h["agents"][1]["info"]["iterations"] = 192
    np.savez(tmp_path / "i.npz", **{**files, "header": np.array(json.dumps(h))})
    with pytest.raises(PolicyFileError, match="sha256"):
        Policy.load(tmp_path / "i.npz")
    q = files["q_agent1"].copy()
    q[5, 1] += 1e-12
    np.savez(tmp_path / "q.npz", **{**files, "q_agent1": q})
    with pytest.raises(PolicyFileError, match="sha256"):
        Policy.load(tmp_path / "q.npz")
    assert Policy.load(path).meta == decentralized.meta


def test_old_format_versions_are_refused_with_a_hint(tmp_path, centralized):
    header = centralized.header()
    header["format_version"] = 1
    path = _write(tmp_path / "old.npz", header, q_centralized=centralized.agents[0].q)
    with pytest.raises(PolicyFileError,
                       match=f"old.npz: unsupported policy format version 1, expected "
                             f"{FORMAT_VERSION}.*re-synthesise"):
        Policy.load(path)


def test_oversized_members_are_refused_before_decompressing(tmp_path, centralized, monkeypatch):
    """A small archive with a huge compressed member is refused from the zip directory."""
    header = centralized.header()
    big = np.zeros((centralized.agents[0].q.shape[0] * 40, 9))   # 20 MB of zeros, ~20 kB zipped
    path = tmp_path / "bomb.npz"
    np.savez_compressed(path, header=np.array(json.dumps(header)), q_centralized=big)
    assert path.stat().st_size < 1 << 20
    opened = []
    real_open = zipfile.ZipFile.open
    monkeypatch.setattr(zipfile.ZipFile, "open",
                        lambda self, name, *a, **k: opened.append(name) or real_open(self, name, *a, **k))
    with pytest.raises(PolicyFileError, match=r"bomb\.npz: agent centralized's Q-table .* "
                                              r"refused before decompressing"):
        Policy.load(path)
    assert "q_centralized.npy" not in opened
    # an unexpected member is refused too, and a header that is too large
    np.savez(tmp_path / "extra.npz", header=np.array(json.dumps(header)),
             q_centralized=centralized.agents[0].q, junk=np.zeros(3))
    with pytest.raises(PolicyFileError, match="unexpected members"):
        Policy.load(tmp_path / "extra.npz")
    np.savez_compressed(tmp_path / "hh.npz", header=np.array("x" * (1 << 19)))
    with pytest.raises(PolicyFileError, match="the header .* refused before decompressing"):
        Policy.load(tmp_path / "hh.npz")


def test_unknown_policy_name_and_bad_states(centralized):
    with pytest.raises(PolicyFileError, match="unknown policy 'nonsense'"):
        load_policy("nonsense")
    with pytest.raises(ValueError, match="shape"):
        centralized(np.zeros(3))
    with pytest.raises(ValueError, match="NaN"):
        centralized(np.array([0.0, np.nan, 0.0, 0.0]))


def test_unknown_kind_model_or_context():
    with pytest.raises(ValueError, match="unknown policy kind"):
        synthesize("federated")
    with pytest.raises(ValueError, match="unknown synthesis model"):
        synthesize("centralized", model="exact")
    with pytest.raises(ValueError, match="unknown agent-1 context"):
        synthesize("decentralized", context="magic")


def test_save_leaves_no_partial_file(tmp_path, centralized):
    with pytest.raises(OSError, match="does not exist"):
        centralized.save(tmp_path / "no" / "such" / "dir.npz")
    assert list(tmp_path.iterdir()) == []


def test_refined_problems_for_scaling_studies():
    from twolink.synthesis.problems import agent1_problem, agent2_problem
    a2 = agent2_problem(refine=2)
    assert a2.grid.shape == (24, 13) and a2.next_points.shape == (24 * 13, 3, 2)
    a1 = agent1_problem(None, refine=2)
    assert a1.grid.shape == (24, 13, 24, 3) and a1.rewards.shape == (24 * 13 * 24 * 3, 3)
    with pytest.raises(ValueError, match="needs agent 2"):
        agent1_problem(None, context="propagated")


def test_save_refuses_what_load_would_refuse(tmp_path, monkeypatch):
    from twolink.policy import fuzzy_policy as policy_module
    policy = load_policy("decentralized")
    monkeypatch.setattr(policy_module, "MAX_Q_BYTES", policy.agents[1].q.nbytes - 1)
    with pytest.raises(ValueError, match="agent agent1: a Q-table of 72576 bytes is larger"):
        policy.save(tmp_path / "p.npz")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("where, what", [("dir", "is a directory"),
                                         ("/dev/zero", "is not a regular file"),
                                         ("missing.npz", "does not exist")])
def test_a_policy_path_says_what_it_is(tmp_path, where, what):
    path = tmp_path if where == "dir" else (Path(where) if where.startswith("/")
                                            else tmp_path / where)
    with pytest.raises(PolicyFileError, match=f"policy file {path} {what}"):
        Policy.load(path)


def test_a_member_declaring_a_huge_array_is_refused_before_allocating(tmp_path):
    """A Q member whose own .npy header claims 10^12 values (8 TB) is refused from its
    header; numpy never allocates it."""
    import io
    import zipfile

    src = SHIPPED["decentralized"].file
    forged = tmp_path / "huge.npz"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(forged, "w") as zout:
        for info in zin.infolist():
            data = zin.read(info.filename)
            if info.filename == "q_agent2.npy":
                buf = io.BytesIO()
                np.lib.format.write_array_header_1_0(
                    buf, {"descr": "<f8", "fortran_order": False, "shape": (84, 10**12)})
                data = buf.getvalue() + b"\0" * 64
            zout.writestr(info.filename, data)
    with pytest.raises(PolicyFileError, match=r"q_agent2.npy declares an array of shape "
                                              r"\(84, 1000000000000\)"):
        Policy.load(forged)


def test_a_policy_whose_grid_would_weigh_millions_of_bins_per_state_is_refused(tmp_path):
    """22 two-bin inputs: 4 M bins, a table a file may hold, but 2**22 memberships per
    state; refused from the header, before any Q-table is read."""
    import io
    import json
    import zipfile

    src = SHIPPED["decentralized"].file
    forged = tmp_path / "wide.npz"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(forged, "w") as zout:
        for info in zin.infolist():
            data = zin.read(info.filename)
            if info.filename == "header.npy":
                header = json.loads(str(np.load(io.BytesIO(data))))
                agent = header["agents"][0]
                agent["grid"]["axes"] = [{"name": f"a{i}", "centers": [-1.0, 1.0],
                                          "circular": False} for i in range(22)]
                agent["q_shape"] = [2**22, 1]
                buf = io.BytesIO()
                np.save(buf, np.array(json.dumps(header)))
                data = buf.getvalue()
            zout.writestr(info.filename, data)
    with pytest.raises(PolicyFileError, match="reads 22 inputs, more than the 12"):
        Policy.load(forged)
