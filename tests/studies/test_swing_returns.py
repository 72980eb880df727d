"""docs/studies/swing_returns.py: the returns the learners' rewards give the time-optimal
answers and a controller from the same poses; bad input is one line, exit 2, nothing
written."""
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import load_study

from twolink.arm.parameters import REWARD_OTHER
from twolink.studies.guided.demos import DEMOS

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def study(monkeypatch):
    return load_study("swing_returns", monkeypatch)


def test_returns_add_up_the_rewards_on_the_states_reached(study):
    k = 160                                       # 8 s
    home = np.zeros((1, 2 * k + 1, 12))           # 16 s at rest in the band
    away = np.zeros((1, 2 * k + 1, 12))
    away[0, 1:, 5] = 1.0                          # joint 6 one radian off, from x_1 on
    away[0, 0, 5] = -3.0                          # x_0 is never rewarded
    at_home, off = study.returns(home, 8.0), study.returns(away, 8.0)
    assert set(off) == {*study.TEAM, "links"} and off["links"].shape == (1, 3, 6)
    for name in study.TEAM:
        assert np.all(at_home[name] == 0.0)
    gammas = np.array(study.GAMMAS)
    want = REWARD_OTHER * (1 - gammas ** k) / np.where(gammas < 1, 1 - gammas, 1)
    want[gammas == 1] = REWARD_OTHER * k
    np.testing.assert_allclose(off["paper"][0], want, rtol=1e-12)
    # one link of six off: the team's shaped reward is the mean of the links'
    np.testing.assert_allclose(off["shaped"][0], off["links"][0].mean(-1), rtol=1e-12)
    assert np.all(off["links"][0, :, :5] == 0.0) and np.all(off["links"][0, :, 5] < 0)
    np.testing.assert_allclose(off["shaped_time"][0] - off["shaped"][0],
                               want / -REWARD_OTHER, rtol=1e-12)
    assert study.returns(away, 16.0)["paper"][0, -1] == 2 * k * REWARD_OTHER
    with pytest.raises(ValueError, match="trajectories of 320 samples, not 340"):
        study.returns(away, 17.0)


def test_the_answers_settle_where_the_pd_does_not_and_the_shaped_reward_prefers_the_pd(
        study, tmp_path, capsys):
    """Two committed demonstrations: the replayed answers settle by 8 s, the per-joint PD
    by 16 s only; the shaped reward pays the PD more, (15) the answers."""
    for path in sorted((ROOT / DEMOS).glob("pose_*.json"))[:2]:
        shutil.copy(path, tmp_path / path.name)
    out = tmp_path / "returns.json"
    assert study.main(["pd_6link_tapered", "--demos", str(tmp_path), "--json",
                       str(out)]) == 0
    data = json.loads(out.read_text())
    answer, pd = data["records"]
    assert (data["poses"], data["links"], data["rule"]) == (2, 6, "tapered")
    assert answer["success_8s"] == [True, True] and pd["success_8s"] == [False, False]
    assert pd["success_16s"] == [True, True]
    g = data["gammas"].index(0.98)
    for i in range(2):
        assert answer["returns_8s"]["shaped"][i][g] < pd["returns_8s"]["shaped"][i][g]
        assert answer["returns_8s"]["paper"][i][g] > pd["returns_8s"]["paper"][i][g]
        # the answer is home from 7 s on: nothing more to earn or lose after 8 s
        assert answer["returns_16s"]["shaped"][i] == answer["returns_8s"]["shaped"][i]
    assert "2/2 settled by 8 s" in capsys.readouterr().out


@pytest.mark.parametrize("args, message", [
    (["missing.zip"], "missing.zip: no such agent file"),
    (["no_such_controller"], "unknown controller 'no_such_controller'"),
    (["pd_3link_tapered"], "controls an arm of 3 links"),
    (["--demos", "EMPTY"], "no demonstration whose replay succeeded"),
    (["--demos", "NOWHERE"], "no such folder of demonstrations"),
])
def test_bad_input_is_one_line_exit_2_nothing_written(study, tmp_path, capsys, args,
                                                      message):
    (tmp_path / "EMPTY").mkdir()
    path = sorted((ROOT / DEMOS).glob("pose_*.json"))[0]
    (tmp_path / "one").mkdir()
    shutil.copy(path, tmp_path / "one" / path.name)
    out = tmp_path / "returns.json"
    argv = [str(tmp_path / a) if a in ("missing.zip", "EMPTY", "NOWHERE") else a
            for a in args]
    demos = [] if "--demos" in args else ["--demos", str(tmp_path / "one")]
    assert study.main([*argv, *demos, "--json", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err and err.startswith("swing_returns: error")
    assert not out.exists()
