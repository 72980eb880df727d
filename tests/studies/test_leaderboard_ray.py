"""`twolink leaderboard --executor ray`: the rows as Ray tasks, with the numbers of a local
run; an address that does not answer is one line and no file."""
import json
import socket

import pytest

from twolink.cli import main

PD = ("import numpy as np\n"
      "def pd(x):\n"
      "    return np.clip(-np.array([1.0, 2.0]) * x[:, :2]"
      " - np.array([0.15, 0.05]) * x[:, 2:], [-1.5, -0.1], [1.5, 0.1])\n")


def _rows(capsys, argv) -> list:
    assert main(argv) == 0
    report = json.loads(capsys.readouterr().out)
    for row in report["rows"]:
        assert row.pop("seconds") > 0              # wall time: the one field that differs
    return report["rows"]


@pytest.mark.slow
def test_ray_rows_equal_local_rows(tmp_path, capsys):
    pytest.importorskip("ray")
    mine = tmp_path / "mine.py"
    mine.write_text(PD)
    argv = ["leaderboard", "--quick", "--only", "--controller", "lqr", "--controller", f"{mine}:pd",
            "--levels", "medium", "--plants", "2", "--json", "--no-save"]
    local = _rows(capsys, argv)
    remote = _rows(capsys, [*argv, "--executor", "ray"])
    assert [(r["controller"], r["mode"]) for r in local] == [
        ("lqr", "plain"), ("lqr", "compensated"), ("pd", "plain")]
    assert remote == local                          # every number, every row, in order
    assert {r["n"] for r in local} == {10} and local[1]["successes"] > local[0]["successes"]


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@pytest.mark.parametrize("argv, match", [
    (["--executor", "ray", "--address", "127.0.0.1:{port}"], "no Ray cluster answers"),
    (["--address", "127.0.0.1:{port}"], "--address needs --executor ray"),
])
def test_a_ray_address_that_does_not_answer_is_one_line_no_file(tmp_path, capsys, argv,
                                                                 match):
    pytest.importorskip("ray")
    out = tmp_path / "lb"
    argv = [a.replace("{port}", str(_free_port())) for a in argv]
    assert main(["leaderboard", "--quick", "--only", "--controller", "lqr", "--out", str(out),
                 *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0] and err[0].startswith("twolink leaderboard: ")
    assert list(tmp_path.iterdir()) == []
