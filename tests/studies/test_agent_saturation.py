"""docs/studies/agent_saturation.py: per joint, how much of the last 2 s a controller holds
the torque at its limit and the joint's final speed; bad input is one line, exit 2,
nothing written."""
import json
import sys

import pytest
from conftest import load_study

from twolink.arm.parameters import links_parameters


SATURATED = """
import numpy as np
TAU = np.array({tau})
def joint2_pushed(x):
    u = np.zeros((len(x), 3))
    u[:, 1] = TAU[1]                  # joint 2 held at its limit: it turns on and on
    return u
"""


@pytest.fixture
def study(monkeypatch):
    return load_study("agent_saturation", monkeypatch)


def test_a_joint_held_at_its_limit_is_named_and_a_pd_is_not(study, tmp_path, capsys):
    tau = list(links_parameters(3, "tapered").torque_limits)
    user = tmp_path / "user.py"
    user.write_text(SATURATED.format(tau=tau))
    out = tmp_path / "sat.json"
    assert study.main([f"{user}:joint2_pushed", "pd_3link_tapered", "--links", "3",
                       "--poses", "4", "--json", str(out)]) == 0
    pushed, pd = json.loads(out.read_text())["records"]
    assert pushed["at_limit"] == [0.0, 1.0, 0.0]
    assert pushed["successes"] == 0 and pushed["n"] == 4
    assert pushed["speed"][1] > 1.0 > 0.1 > pd["speed"][1]
    assert max(pd["at_limit"]) < 0.05
    assert all(0.0 <= a <= 3.1416 for a in pushed["angle"]) and max(pd["angle"]) < 0.09
    assert pd["successes"] == 4
    printed = capsys.readouterr().out
    assert "0/4 settled" in printed and "4/4 settled" in printed


@pytest.mark.parametrize("args, message", [
    (["missing.zip"], "missing.zip: no such agent file"),
    (["no_such_controller"], "unknown controller 'no_such_controller'"),
    (["pd_3link_tapered", "--poses", "0"], "--poses must be"),
    (["pd_3link_tapered"], "controls an arm of 3 links"),
])
def test_bad_input_is_one_line_exit_2_nothing_written(study, tmp_path, capsys, args,
                                                      message):
    out = tmp_path / "sat.json"
    argv = [a.replace("missing.zip", str(tmp_path / "missing.zip")) for a in args]
    links = ["--links", "3"] if "--poses" in args else []
    assert study.main([*argv, *links, "--json", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err and err.startswith("agent_saturation: error")
    assert not out.exists()
