"""`twolink evaluate --worst-case` (the level's grid of plants) and the --compensate hint."""
import json

import pytest

from twolink.cli import main


def _run(capsys, *argv):
    code = main(["evaluate", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_worst_case_adds_the_grid_beside_the_random_plants(capsys):
    code, out, _ = _run(capsys, "lqr", "--challenge", "easy", "--compensate", "--quick", "--plants", "2", "--worst-case", "--json")
    assert code == 0
    r = json.loads(out)
    g = r["grid"]
    assert g["plants"] == 25 and g["states"] == 5 and g["n"] == 125
    assert sum(g["per_plant"].values()) == g["successes"]
    assert g["worst_plant_successes"] == min(g["per_plant"].values())
    assert r["plants"] == 2 and "hint" not in r            # compensated: no hint


def test_a_plain_run_of_a_model_based_controller_hints_at_compensate(capsys):
    code, out, _ = _run(capsys, "lqr", "--challenge", "medium", "--quick",
                        "--plants", "1")
    assert code == 0
    hint = out.strip().splitlines()[-1]
    assert hint.startswith("hint: lqr names its model (full); --compensate runs it")
    code, out, _ = _run(capsys, "lqr", "--quick")           # level none
    assert code == 0 and "hint" not in out


@pytest.mark.parametrize("argv, message", [
    (["--worst-case", "--links", "3"], "--worst-case is a two-link evaluation option"),
])
def test_worst_case_is_a_two_link_option(capsys, argv, message):
    code, _, err = _run(capsys, "lqr", *argv)
    assert code == 2 and message in err and err.count("\n") == 1
