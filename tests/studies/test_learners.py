"""The learners' study: its plan, its report's numbers, its command's errors, and the
smoke run end to end (a few thousand steps; learning quality is not judged)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from twolink.studies.learners import plan as P
from twolink.studies.learners import report

ROOT = Path(__file__).resolve().parents[2]


def test_plan_is_seed_major_small_arms_first_and_ids_unique():
    runs = P.plan()
    over_pd = sum(b == "pd" for _, _, b, _ in P.LEARNERS)      # not on the two-link arm
    assert len(runs) == (len(P.ARMS) * len(P.LEARNERS) - over_pd) * len(P.SEEDS)
    assert not [r for r in runs if r.links == 2 and r.base == "pd"]
    assert len({r.id for r in runs}) == len(runs)
    seeds = [r.seed for r in runs]
    assert seeds == sorted(seeds)                        # seed 0 whole first
    first = runs[:len(runs) // len(P.SEEDS)]
    assert [r.links for r in first] == sorted(r.links for r in first)
    assert runs[0].id == "ppo_2t_seed0" and runs[0].steps == P.STEPS[2]
    (run,) = P.plan(arms=((4, "copied"),), learners=(("ippo", "local", "pd", "mujoco"),),
                    seeds=(2,), steps=4096)
    assert run.id == "ippo-local-pd_4c_seed2"
    assert run.train_args() == [
        "--algo", "ippo", "--links", "4", "--rule", "copied", "--steps", "4096",
        "--seed", "2", "--eval-every", "4096", "--observe", "local", "--base", "pd"]
    (model,) = P.plan(arms=((3, "tapered"),), learners=(("ppo", "global", "none", "model"),),
                      seeds=(0,))
    assert model.id == "ppo-model_3t_seed0" and model.train_args()[-2:] == ["--plant", "model"]
    with pytest.raises(ValueError, match="plant"):         # skrl's learners step MuJoCo only
        P.plan(learners=(("ippo", "local", "none", "model"),))


def test_fresh_poses_seed_is_used_by_nothing_else():
    from twolink.control.links_pd import TUNING_SEED
    from twolink.training.config import EVALUATION_SEEDS

    fresh = {P.FRESH_SEED + n for n in range(2, 7)}
    other = {P.TABLE_SEED + n for n in range(2, 7)} | {TUNING_SEED + n for n in range(2, 7)}
    other |= set(EVALUATION_SEEDS) | set(range(500, 600))
    assert not fresh & other


@pytest.mark.parametrize("text, message", [
    ("7", "links"), ("2c", "no copied rule"), ("x", "unknown arm")])
def test_bad_arm_is_one_line(text, message):
    with pytest.raises(ValueError, match=message):
        P.parse_arm(text)


def test_arms_and_learners_parse():
    assert P.parse_arm("4c") == (4, "copied") and P.parse_arm("6") == (6, "tapered")
    assert P.parse_learner("mappo-neighbours") == ("mappo", "neighbours", "none", "mujoco")
    assert P.parse_learner("ippo-local-pd") == ("ippo", "local", "pd", "mujoco")
    assert P.parse_learner("ppo-model") == ("ppo", "global", "none", "model")
    with pytest.raises(ValueError, match="unknown learner 'ippo-local-model'"):
        P.parse_learner("ippo-local-model")
    with pytest.raises(ValueError, match="unknown learner 'sac'.*ippo-local"):
        P.parse_learner("sac")


def _record(links, algo, observe, seed, rate, curve_rates, n=10):
    k = int(round(rate * n))
    steps = [0, 100, 200]
    return {"id": f"{algo}_{links}_{seed}", "run": {"links": links, "rule": "tapered",
            "algo": algo, "observe": observe, "seed": seed},
            "curve": [{"steps": s, "rate": r} for s, r in zip(steps, curve_rates)],
            "steps": 200, "wall_s": 10.0, "cpu_s": 8.0, "peak_rss_bytes": 2**20 * 300,
            "parameters": 1234,
            "fresh": {"successes": k, "n": n, "rate": k / n, "median_settle": 3.0},
            "table": {"successes": k, "n": n, "rate": k / n, "median_settle": 3.0}}


def test_rows_pool_seeds_iqm_and_steps_to_the_ceiling():
    data = {"runs": [_record(3, "ippo", "local", s, r, c) for s, r, c in [
        (0, 0.5, [0, 0.4, 0.5]), (1, 0.8, [0, 0.9, 0.8]), (2, 1.0, [0, 1.0, 1.0])]]}
    (row,) = report.rows(data, {(3, "tapered"): 1.0})
    assert row["fresh"]["successes"] == 23 and row["fresh"]["n"] == 30
    assert row["fresh"]["iqm"] == pytest.approx((0.5 + 0.8 + 1.0) / 3)
    lo, hi = row["fresh"]["iqm_95"]
    assert 0.5 <= lo < row["fresh"]["iqm"] < hi <= 1.0
    assert row["steps_to_90pct_ceiling"] == [None, 100, 100]
    assert row["cpu_us_per_step"] == pytest.approx(8.0 / 200 * 1e6)
    assert "| 3 | tapered | IPPO (local) | 3 | 23/30 = 76.7 %" in report.table([row])
    assert row["fresh_late"] is None                     # no seed scored at 16 s
    cells = [c.strip() for c in report.table([row]).splitlines()[2].split("|")]
    assert cells[7] == "—"
    data["runs"][0]["fresh_late"] = {"successes": 10, "n": 10}
    data["runs"][2]["fresh_late"] = {"successes": 9, "n": 10}
    (row,) = report.rows(data, {(3, "tapered"): 1.0})
    assert row["fresh_late"]["successes"] == 19 and row["fresh_late"]["seeds"] == 2
    cells = [c.strip() for c in report.table([row]).splitlines()[2].split("|")]
    assert cells[7].startswith("19/20 = 95.0 %")


def test_iqm_trims_the_outer_quarters():
    point, lo, hi = report.iqm([0.0, 0.5, 0.6, 1.0])
    assert point == pytest.approx(0.55)
    assert report.iqm([0.3]) == (0.3, 0.3, 0.3)


def test_figure_draws_a_panel_per_arm(tmp_path):
    data = {"runs": [_record(2, "ppo", "global", 0, 1.0, [0, 1, 1]),
                     _record(3, "ippo", "local", 0, 0.5, [0, 0.2, 0.5])]}
    path = report.figure(data, tmp_path / "c.png", {(3, "tapered"): 1.0})
    import matplotlib.image as mpimg

    img = mpimg.imread(path)
    assert img.shape[1] > img.shape[0] and np.std(img) > 0


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "twolink.cli", "learners", *args],
                          capture_output=True, text=True, cwd=cwd, timeout=600)


@pytest.mark.parametrize("args, message", [
    (["--arms", "9"], "links must be"),
    (["--learners", "dqn"], "unknown learner 'dqn'"),
    (["--steps", "0"], "--steps must be a whole number"),
    (["--smoke", "--arms", "3"], "--smoke is its own plan"),
    (["--address", "x:1"], "--address is the ray executor's"),
    (["-o", "study.csv"], "is a .json file"),
])
def test_bad_input_is_one_line_exit_2_nothing_written(tmp_path, args, message):
    r = _cli(*args, cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert message in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not list(tmp_path.rglob("*.json"))


def test_list_names_every_run_and_its_state(tmp_path):
    r = _cli("--list", "--arms", "3c", "--learners", "ppo", "mappo-local-pd", "--seeds", "1",
             cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert [ln.split()[0] for ln in lines] == ["ppo_3c_seed1", "mappo-local-pd_3c_seed1"]
    assert all(ln.endswith("new") for ln in lines)


def test_smoke_runs_end_to_end_and_a_second_call_keeps_it(tmp_path):
    pytest.importorskip("stable_baselines3")
    pytest.importorskip("skrl")
    r = _cli("--smoke", "--json", cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    rows = json.loads(r.stdout)
    assert [(x["links"], x["algo"], x["base"], x["plant"]) for x in rows] == [
        (2, "ppo", "none", "mujoco"), (2, "ippo", "none", "mujoco"),
        (2, "ppo", "none", "model"), (3, "ppo", "none", "mujoco"),
        (3, "ippo", "none", "mujoco"), (3, "ippo", "pd", "mujoco"), (3, "ppo", "none", "model")]
    for x in rows:
        assert x["fresh"]["n"] == P.SMOKE["poses"] and x["steps"] == P.SMOKE["steps"]
        assert x["parameters"] > 1000 and x["cpu_us_per_step"] > 0
        assert x["fresh_model"]["n"] == P.SMOKE["poses"]     # the same poses on the model
        assert x["fresh_late"]["n"] == P.SMOKE["poses"]      # and run for 16 s
    data = json.loads((tmp_path / "twolink-results/learners-smoke/learners.json").read_text())
    assert data["schema"] == P.SCHEMA and len(data["runs"]) == 7
    assert data["runs"][0]["fresh"]["poses_seed"] in {P.FRESH_SEED + 2, P.FRESH_SEED + 3}
    model_run = next(r for r in data["runs"] if r["id"] == "ppo-model_2t_seed0")
    curve = json.loads((tmp_path / "twolink-results/learners-smoke/runs/ppo-model_2t_seed0/"
                        "curve.json").read_text())
    assert curve["config"]["plant"] == "model"             # trained on the model (6)
    assert model_run["fresh_model"]["poses_seed"] == model_run["fresh"]["poses_seed"]
    assert model_run["fresh_late"]["poses_seed"] == model_run["fresh"]["poses_seed"]
    again = _cli("--smoke", cwd=tmp_path)
    assert again.returncode == 0 and "7 of 7 runs" in again.stderr
    assert "training" not in again.stderr
    # docs/studies/learners_late.py: a record without the 16 s score gets the same one back
    # from its agent; a run whose agent is gone is listed and left as it is.
    path = tmp_path / "twolink-results/learners-smoke/learners.json"
    work = tmp_path / "twolink-results/learners-smoke/runs"
    before = {r["id"]: r["fresh_late"] for r in data["runs"]}
    for r in data["runs"][:2]:
        del r["fresh_late"]
    path.write_text(json.dumps(data))
    (work / data["runs"][1]["id"] / "curve.json").unlink()
    late = subprocess.run([sys.executable, str(ROOT / "docs/studies/learners_late.py"),
                           "--json", str(path), "--work", str(work)],
                          capture_output=True, text=True, cwd=tmp_path)
    assert late.returncode == 0, late.stderr[-2000:]
    summary = json.loads(late.stdout.strip().splitlines()[-1])
    assert summary == {"scored": 1, "agent_gone": [data["runs"][1]["id"]]}
    after = {r["id"]: r.get("fresh_late") for r in json.loads(path.read_text())["runs"]}
    assert after[data["runs"][0]["id"]] == before[data["runs"][0]["id"]]
    assert after[data["runs"][1]["id"]] is None


def _fake_train(monkeypatch, scripts: dict):
    """``twolink train`` of run seed S replaced by the Python one-liner scripts[S]."""
    from twolink.studies.learners import measure

    started = []

    def fake(*args):
        args = list(map(str, args))
        seed = int(args[args.index("--seed") + 1])
        started.append(seed)
        return [sys.executable, "-c", scripts[seed]]

    monkeypatch.setattr(measure, "_twolink", fake)
    return started


KILLED = "import os, signal; os.kill(os.getpid(), signal.SIGTERM)"


def test_a_run_ended_by_a_signal_stops_the_study(tmp_path, monkeypatch):
    from twolink.studies.learners import measure

    started = _fake_train(monkeypatch, {0: KILLED, 1: "pass", 2: "pass"})
    runs = [P.Run("ppo", "global", 2, "tapered", s, 1000, 500) for s in range(3)]
    with pytest.raises(measure.RunInterrupted, match="ppo_2t_seed0 was interrupted.*resume"):
        measure.study(runs, tmp_path / "s.json", tmp_path / "runs", log=lambda t: None)
    assert started == [0]                      # the later runs never started
    assert not (tmp_path / "s.json").exists()


def test_an_interrupted_study_ends_its_other_live_runs(tmp_path, monkeypatch):
    from twolink.studies.learners import measure

    mark = tmp_path / "slept"
    sleeper = f"import time, pathlib; time.sleep(20); pathlib.Path({str(mark)!r}).touch()"
    killed_later = "import os, signal, time; time.sleep(1); os.kill(os.getpid(), 15)"
    _fake_train(monkeypatch, {0: sleeper, 1: killed_later, 2: "pass"})
    runs = [P.Run("ppo", "global", 2, "tapered", s, 1000, 500) for s in range(3)]
    with pytest.raises(measure.RunInterrupted, match="ppo_2t_seed1"):
        measure.study(runs, tmp_path / "s.json", tmp_path / "runs", workers=2,
                      log=lambda t: None)
    assert not measure._children               # every child ended and reaped
    assert not mark.exists()                   # the sleeper was terminated, not awaited


def test_sigterm_to_a_parallel_study_ends_its_runs_and_starts_no_other(tmp_path):
    """The study's process, SIGTERMed while two runs train, ends both and starts none of
    the queued ones (it used to wait for the live runs and then start the rest)."""
    import signal
    import time

    script = tmp_path / "study.py"
    script.write_text(f"""
import pathlib, sys
from twolink.artifacts import sigterm_raises
from twolink.studies.learners import measure, plan as P
tmp = pathlib.Path({str(tmp_path)!r})
def fake(*args):
    seed = list(map(str, args))[list(map(str, args)).index("--seed") + 1]
    (tmp / f"started{{seed}}").touch()
    return [sys.executable, "-c",
            f"import time, pathlib; time.sleep(20); pathlib.Path({{str(tmp)!r}}, 'slept{{seed}}').touch()"]
measure._twolink = fake
runs = [P.Run("ppo", "global", 2, "tapered", s, 1000, 500) for s in range(4)]
try:
    with sigterm_raises():
        measure.study(runs, tmp / "s.json", tmp / "runs", workers=2, log=lambda t: None)
except KeyboardInterrupt:
    print("stopped", flush=True)
""")
    proc = subprocess.Popen([sys.executable, str(script)], cwd=ROOT, stdout=subprocess.PIPE,
                            text=True)
    for _ in range(300):                       # both runs' children started
        if (tmp_path / "started0").exists() and (tmp_path / "started1").exists():
            break
        time.sleep(0.05)
    time.sleep(0.5)
    proc.send_signal(signal.SIGTERM)
    out, _ = proc.communicate(timeout=60)
    assert out.strip() == "stopped"
    assert sorted(p.name for p in tmp_path.glob("started*")) == ["started0", "started1"]
    assert not list(tmp_path.glob("slept*"))   # terminated, not awaited
