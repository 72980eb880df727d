"""`twolink evaluate` on controllers that try to cheat or take the process down: each run
ends in one line naming the controller and exit status 2, `--json` stays valid JSON, and a
stuck controller ends at `--timeout`; a real Ctrl-C still exits 130."""
import json
import os
import signal
import subprocess
import sys
import time

import pytest

CHEATS = '''import sys
import numpy as np


def zero_the_state(x):
    x[...] = 0
    return np.zeros((len(x), 2))


def strings(x):
    return np.full((len(x), 2), "0.1")


def complex_torques(x):
    return np.zeros((len(x), 2)) + 0.1j


def leave(x):
    sys.exit(0)


def stop(x):
    raise KeyboardInterrupt


def spin(x):
    while True:
        pass


class Chatty:
    def __init__(self):
        print("making Chatty")

    def __call__(self, x):
        print("called")
        return np.zeros((len(x), 2))
'''


@pytest.fixture
def cheats(tmp_path):
    path = tmp_path / "cheats.py"
    path.write_text(CHEATS)
    return path


def _evaluate(spec, *extra, timeout=60, **kw):
    return subprocess.run([sys.executable, "-m", "twolink.cli", "evaluate", str(spec), "--json",
                           "--quick", *extra], capture_output=True, text=True,
                          timeout=timeout, check=False, **kw)


@pytest.mark.parametrize("name, line", [
    ("zero_the_state", "controller zero_the_state raised ValueError: assignment destination "
                       "is read-only (the states a controller gets are read-only: copy them "
                       "to change them)"),
    ("strings", "controller strings returned ndarray of dtype <U3, not an array of real "
                "torques of shape (5, 2)"),
    ("complex_torques", "controller complex_torques returned ndarray of dtype complex128, not "
                        "an array of real torques of shape (5, 2)"),
    ("leave", "controller leave called sys.exit(0); a controller must return torques, not "
              "end the program"),
    ("stop", "controller stop raised KeyboardInterrupt (no Ctrl-C was pressed)"),
])
def test_a_cheating_or_exiting_controller_is_one_line_and_exit_2(cheats, name, line):
    r = _evaluate(f"{cheats}:{name}")
    assert r.returncode == 2
    assert r.stdout == ""
    assert r.stderr == f"twolink evaluate: error: {line}\n"


def test_what_a_controller_prints_leaves_the_json_intact(cheats, tmp_path):
    chatty = tmp_path / "chatty.py"
    chatty.write_text('print("importing chatty")\nfrom cheats import Chatty\n')
    r = _evaluate(f"{chatty}:Chatty", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["controller"] == "Chatty" and out["n"] == 5
    assert r.stderr.startswith("importing chatty\nmaking Chatty\ncalled\ncalled\n")


def test_a_stuck_controller_ends_at_the_timeout(cheats):
    t0 = time.monotonic()
    r = _evaluate(f"{cheats}:spin", "--timeout", "0.5", timeout=30)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr == ("twolink evaluate: error: controller spin took longer than 0.5 s "
                        "on one call\n")
    assert time.monotonic() - t0 < 20


@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf", "1e9"])
def test_a_bad_timeout_is_one_line(value):
    r = _evaluate("pd", "--timeout", value, timeout=30)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.startswith("twolink evaluate: error: --timeout must be a number of "
                               "seconds from 0.001 to 3600, got ")
    assert r.stderr.count("\n") == 1


def test_a_real_ctrl_c_still_interrupts(cheats):
    p = subprocess.Popen([sys.executable, "-m", "twolink.cli", "evaluate", f"{cheats}:spin",
                          "--json", "--quick"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        time.sleep(3.0)                   # well inside the endless call
        os.kill(p.pid, signal.SIGINT)
        out, err = p.communicate(timeout=30)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 130
    assert out == "" and err.strip().endswith("twolink: interrupted")
