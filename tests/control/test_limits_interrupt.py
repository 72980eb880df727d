"""Ctrl-C stops ``twolink limits`` within seconds, silently, and writes nothing."""
import os
import signal
import subprocess
import sys
import time

import pytest

pytest.importorskip("casadi")


@pytest.mark.parametrize("workers", [[], ["--workers", "1"]], ids=["pool", "in-process"])
def test_ctrl_c_stops_limits_at_once_and_writes_nothing(tmp_path, workers):
    out = tmp_path / "limits.json"
    proc = subprocess.Popen(
        [sys.executable, "-m", "twolink.cli", "limits", "--evaluation-set", "--model", "full",
         "--no-mujoco", "-o", str(out), *workers],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
        # a terminal's Ctrl-C reaches a foreground command; a pytest-xdist worker runs with
        # SIGINT ignored, which its children would inherit, so give the child the default
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        first = proc.stderr.readline()                  # its first progress line
        assert first.startswith("limits: solving 65 states"), first
        time.sleep(1.5)                                 # well inside the search
        assert proc.poll() is None
        t0 = time.monotonic()
        os.killpg(proc.pid, signal.SIGINT)              # as a terminal's Ctrl-C does
        rest, err = proc.communicate(timeout=30)
        stopped = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, err
    # The target is 2 s (0.1 s measured on an idle machine); the bound leaves room for a
    # CI machine whose two cores run the rest of the suite beside this test.
    assert stopped < 6.0, f"took {stopped:.1f} s to stop"
    assert err.strip().splitlines() == ["twolink: interrupted"], err   # no solver warnings
    assert not rest and list(tmp_path.iterdir()) == []


def test_a_signal_recorded_during_a_solve_stops_the_search_even_if_swallowed():
    """CasADi may swallow the KeyboardInterrupt a Ctrl-C raises inside one of its Python
    callbacks and print its warning where the solve's stderr is not read: a signal that
    sigterm_raises recorded during the solve still stops the search when it returns; one
    recorded before it does not."""
    from twolink import artifacts
    from twolink.limits.nlp import _solver_output

    with artifacts.sigterm_raises():
        artifacts._received.append("SIGINT")            # one handled before the solve
        assert artifacts.signal_count() == 1
        with _solver_output(False):                      # recorded before: no effect
            pass
        with pytest.raises(KeyboardInterrupt):
            with _solver_output(False):
                artifacts._received.append("SIGINT")    # as the handler does, swallowed
        with pytest.raises(artifacts.Terminated):
            with _solver_output(False):
                artifacts._received.append("SIGTERM")


def test_a_signal_swallowed_outside_the_solver_call_still_stops_the_search(monkeypatch):
    """A Ctrl-C whose exception a CasADi call outside the IPOPT solve swallowed (building a
    problem, evaluating its defects) is raised when the cache's solve returns: this was the
    remaining way for ``twolink limits --workers 1`` to finish a run after a Ctrl-C."""
    from twolink import artifacts
    from twolink.limits import nlp

    def swallowed(self, *args, **kw):                  # as CasADi does after the handler
        artifacts._received.append("SIGINT")
        return "solution"

    monkeypatch.setattr(nlp.ShootingProblem, "solve", swallowed)
    monkeypatch.setattr(nlp.ProblemCache, "get",
                        lambda self, model, k: object.__new__(nlp.ShootingProblem))
    cache = nlp.ProblemCache()
    with artifacts.sigterm_raises():
        with pytest.raises(KeyboardInterrupt):
            cache.solve("full", 10, None, None, None, None)
        artifacts._received.clear()
        monkeypatch.setattr(nlp.ShootingProblem, "solve", lambda self, *a, **k: "solution")
        assert cache.solve("full", 10, None, None, None, None) == "solution"
