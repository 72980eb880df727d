"""The time-optimal limit T*(x) (twolink.limits): the CasADi step against
the numpy step, the paper's x0 on both models, the upper bound's replay, the shipped
table (read without CasADi, its torques replayed; a few cheap rows recomputed), bad
input and the command line."""
import json
import math
import sys

import numpy as np
import pytest

from twolink.arm import dynamics
from twolink.arm.integrate import SUBSTEPS, rk4, sample_step
from twolink.arm.parameters import PAPER_X0, TABLE_I, TS
from twolink.arm.task import in_goal_band
from twolink.cli import main
from twolink import limits as to
from twolink.limits.search import replay, wrap_state
from twolink.sim.metrics import evaluation_set

try:
    import casadi
except ImportError:                  # the shipped table's tests run without it
    casadi = None
#: The tests that solve NLPs need CasADi (the `test` extra installs it).
needs_casadi = pytest.mark.skipif(casadi is None, reason="CasADi is not installed "
                                  "(pip install 'twolink[limits]')")

P = TABLE_I


def _numpy_replay(model, x0, torques, seconds=5.0):
    """States (..., K+1, 4) of the numpy plant (wrap, clip, saturation) from x0 (..., 4)
    under torques (..., k, 2), then zero torque, over ``seconds``."""
    accel = dynamics.MODELS[model]
    steps = int(round(seconds / TS))
    torques = np.asarray(torques, float)
    u = np.zeros(torques.shape[:-2] + (steps, 2))
    u[..., :torques.shape[-2], :] = torques
    xs = [np.asarray(x0, float)]
    for k in range(steps):
        xs.append(sample_step(accel, P, xs[-1], u[..., k, :]))
    return np.stack(xs, -2)


# --------------------------------------------------------------------------- the step
@needs_casadi
@pytest.mark.parametrize("model", to.MODELS)
def test_casadi_step_equals_the_numpy_step(model):
    rng = np.random.default_rng(7)
    x = np.c_[rng.uniform(-math.pi, math.pi, (200, 2)), rng.uniform(-2 * math.pi, 2 * math.pi,
                                                                     (200, 2))]
    u = rng.uniform(-1, 1, (200, 2)) * P.tau_max
    step = to.step_function(model)
    ours = np.asarray(step.map(len(x))(x.T, u.T)).T
    theirs = rk4(dynamics.MODELS[model], P, x, u, TS, SUBSTEPS)     # the step before the wrap
    assert np.abs(ours - theirs).max() <= 1e-12
    # and, wrapped and saturated, the plants' sample step
    from twolink.arm.integrate import finish_sample
    assert np.abs(finish_sample(P, ours) - sample_step(dynamics.MODELS[model], P, x, u)
                  ).max() <= 1e-12


# --------------------------------------------------------------------------- the paper's x0
# From the paper's x0 the band is reached fastest with link 2 turning on to -2 pi (3.28 rad
# away, not 3): 18 samples on (6)-(8), 17 on (11). With the band around 0 of the wrapped
# angles only (windings="nearest") the search finds 20 and 18, the figures of the
# independent run that tried no winding.
@needs_casadi
@pytest.mark.slow
@pytest.mark.parametrize("model, samples, nearest", [("full", 18, 20), ("simplified", 17, 18)])
def test_the_paper_x0(model, samples, nearest):
    r = to.limit(PAPER_X0, model)
    assert (r.lower, r.upper, r.samples) == (samples, samples, samples)
    assert r.exact and r.seconds == pytest.approx(samples * TS)
    assert r.winding == (0, -1)
    assert r.lower <= r.upper
    # The upper bound's torques, admissible, replayed on the numpy model: in the band at
    # sample N and at every sample after it to 5 s, and not before N.
    assert np.all(np.abs(r.torques) <= P.tau_max)
    xs = _numpy_replay(model, PAPER_X0, r.torques)
    inside = in_goal_band(xs)
    assert inside[samples:].all() and not inside[:samples].any()
    assert np.abs(xs[:, 2:]).max() <= 2 * math.pi
    n = to.limit(PAPER_X0, model, windings="nearest")
    assert (n.lower, n.upper, n.winding) == (nearest, nearest, (0, 0))


def test_full_model_x0_settles_on_mujoco_at_the_limit():
    """The full model's sequence from the shipped table, open loop on MuJoCo: it settles
    at the same sample (MuJoCo's arm is (6)-(8))."""
    row = to.shipped_limits("full")[0]
    idx, settle = to.replay_on("mujoco", [row])
    assert idx == [0] and settle[0] == pytest.approx(row.seconds)


# --------------------------------------------------------------------------- cheap states
@needs_casadi
def test_a_state_in_the_band_needs_no_sample():
    r = to.limit([0.01, -0.02, 0.05, 0.0])
    assert (r.lower, r.upper, r.seconds, r.solves) == (0, 0, 0.0, 0)


@needs_casadi
def test_a_cheap_state_lower_le_upper_and_its_replay():
    x0 = [0.3, -0.2, 0.5, 0.0]
    for model in to.MODELS:
        r = to.limit(x0, model, mujoco=True)
        assert r.lower <= r.upper <= 10
        states, ok = replay(model, P, np.asarray(x0), r.torques, r.upper)
        assert ok
        inside = in_goal_band(_numpy_replay(model, x0, r.torques))
        assert inside[r.upper:].all()
        assert r.mujoco_settle is not None


@needs_casadi
def test_angles_are_wrapped_and_a_mirror_state_reuses_its_image():
    x = np.array([[0.2 + 2 * math.pi, -0.1, 0.0, 0.0], [-0.2, 0.1, 0.0, 0.0]])
    t = to.limit_table(x, "simplified", workers=1, mujoco=False)
    a, b = t.rows
    assert a.x0[0] == pytest.approx(0.2) and a.mirror_of is None
    assert b.mirror_of == 0 and (b.lower, b.upper) == (a.lower, a.upper)
    assert np.array_equal(b.torques, -a.torques)
    assert t.provenance["casadi_version"] == casadi.__version__
    assert t.provenance["substeps"] == SUBSTEPS and t.provenance["ts"] == TS


# --------------------------------------------------------------------------- the shipped table
@pytest.fixture(scope="module")
def shipped():
    return to.shipped_tables()


def test_the_shipped_table_covers_the_evaluation_set(shipped):
    assert set(shipped) == set(to.MODELS)
    for model, table in shipped.items():
        assert len(table) == 65
        assert np.array_equal(table.states, evaluation_set())
        assert table.mismatches() == []                     # lower == upper everywhere
        assert (table.lower <= table.samples).all()
        prov = table.provenance
        assert prov["model"] == model and prov["substeps"] == SUBSTEPS and prov["ts"] == TS
        assert prov["parameters"] == TABLE_I.as_dict()
        assert prov["casadi_version"] and prov["time_s"] > 0
    assert shipped["full"].median_seconds() == pytest.approx(0.9)
    assert shipped["full"][0].samples == 18 and shipped["simplified"][0].samples == 17


@pytest.mark.parametrize("model", to.MODELS)
def test_the_shipped_torques_replay_into_the_band(shipped, model):
    """Every shipped upper bound on the numpy model over the 5 s horizon: in the band at
    sample N and at every sample after it, never before N."""
    table = shipped[model]
    longest = max(len(r.torques) for r in table)
    u = np.zeros((len(table), longest, 2))
    for i, r in enumerate(table):
        u[i, :len(r.torques)] = r.torques
        assert np.all(np.abs(r.torques) <= P.tau_max)
    inside = in_goal_band(_numpy_replay(model, table.states, u))      # (65, 101)
    for i, r in enumerate(table):
        assert inside[i, r.upper:].all() and not inside[i, :r.upper].any(), r.x0


@needs_casadi
def test_recomputing_cheap_shipped_states_gives_the_shipped_numbers(shipped):
    for model in to.MODELS:
        table = shipped[model]
        cheap = [i for i in np.argsort(table.samples, kind="stable") if table.rows[i].mirror_of
                 is None][:2]
        for i in cheap:
            row = table.rows[i]
            r = to.limit(row.x0, model)
            assert (r.lower, r.upper, r.winding) == (row.lower, row.upper, row.winding)
            assert r.reach_slack == pytest.approx(row.reach_slack, abs=1e-6)


def test_shipped_limits_reads_without_casadi(monkeypatch):
    monkeypatch.setitem(sys.modules, "casadi", None)
    table = to.shipped_limits("simplified")
    assert len(table) == 65 and table.model == "simplified"


# --------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("call, match", [
    (lambda: to.limit([0, 0, 0]), r"shape \(4,\) or \(n, 4\)"),
    (lambda: to.limit([[0.5, 0, 0, 0]] * 2), "one state of shape"),
    (lambda: to.limit([np.nan, 0, 0, 0]), "NaN or infinite"),
    (lambda: to.limit([0.5, 0, 7.0, 0]), "beyond the speed limit"),
    (lambda: to.limit([5e3, 0, 0, 0]), "angle of magnitude"),
    (lambda: to.limit(["a", 0, 0, 0]), "must be numbers"),
    (lambda: to.limit(PAPER_X0, "mujoco"), "unknown model 'mujoco'"),
    (lambda: to.limit(PAPER_X0, max_samples=0), "max_samples must be a whole number"),
    (lambda: to.limit(PAPER_X0, max_samples=10_000), "from 1 to 100"),
    (lambda: to.limit(PAPER_X0, max_samples=True), "max_samples"),
    (lambda: to.limit(PAPER_X0, starts=0), "starts must be"),
    (lambda: to.limit(PAPER_X0, hold=1.5), "hold must be"),
    (lambda: to.limit(PAPER_X0, windings="some"), "windings must be"),
    (lambda: to.limit_table(np.zeros((0, 4))), "shape"),
    (lambda: to.limit_table([PAPER_X0], workers=0), "workers"),
    (lambda: to.shipped_limits("vertical"), "unknown model"),
])
def test_bad_input_is_one_clear_line(call, match):
    with pytest.raises(ValueError, match=match) as info:
        call()
    assert "\n" not in str(info.value)


def test_a_missing_casadi_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "casadi", None)
    with pytest.raises(to.CasadiMissing, match=r"pip install 'twolink\[limits\]'") as info:
        to.limit(PAPER_X0)
    assert isinstance(info.value, ImportError) and "\n" not in str(info.value)
    assert main(["limits", "--x0", "0.3", "0", "0", "0"]) == 2   # one line, no traceback


@needs_casadi
def test_a_state_beyond_max_samples_has_no_upper_bound():
    r = to.limit([math.radians(150), math.radians(150), 0, 0], "simplified", max_samples=3)
    assert r.upper is None and r.samples is None and r.seconds is None
    assert r.lower == 4 and not r.exact


# --------------------------------------------------------------------------- the command
def test_the_command_prints_the_shipped_table(capsys):
    assert main(["limits"]) == 0
    out = capsys.readouterr().out
    assert "shipped" in out and "full: 65 states, median 0.90 s" in out
    assert len([line for line in out.splitlines() if line.count("|") == 2]) == 66


def test_the_command_json(capsys):
    assert main(["limits", "--model", "full", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    rows = data["models"]["full"]["rows"]
    assert len(rows) == 65 and rows[0]["upper"] == 18 and "torques" not in rows[0]
    assert list(data["models"]) == ["full"]


@needs_casadi
def test_the_command_computes_and_writes(capsys, tmp_path):
    out = tmp_path / "limits.json"
    assert main(["limits", "--model", "simplified", "--x0", "0.3", "-0.2", "0", "0",
                 "--no-mujoco", "--workers", "1", "-o", str(out), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    row = data["models"]["simplified"]["rows"][0]
    assert row["lower"] == row["upper"] and row["x0"] == [0.3, -0.2, 0.0, 0.0]
    tables = to.tables_from_json(out.read_text())
    assert tables["simplified"][0].upper == row["upper"]
    assert tables["simplified"].provenance["command"].startswith("twolink limits")


def test_the_command_refuses_write_without_states(capsys):
    assert main(["limits", "-o", "x.json"]) == 2
    assert "-o/--out saves computed tables" in capsys.readouterr().err


def test_wrap_state_keeps_angles_in_range_bit_for_bit():
    x = evaluation_set()
    assert np.array_equal(wrap_state(x), x)
    assert wrap_state([math.pi, 0, 0, 0])[0] == pytest.approx(-math.pi)
