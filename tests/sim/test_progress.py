"""Progress in logs: a bar that is not on a terminal prints plain lines, periodically and
at its end, instead of vanishing."""
import io

from twolink.sim import progress


def test_off_a_terminal_the_bar_prints_lines(monkeypatch):
    log = io.StringIO()
    monkeypatch.setattr(progress.sys, "stderr", log)
    now = [0.0]
    monkeypatch.setattr(progress, "_now", lambda: now[0])
    with progress.progress_bar(total=100, desc="work", unit=" steps", leave=False) as bar:
        for k in range(100):                        # one update a second, a postfix each
            now[0] = float(k + 1)
            bar.set_postfix(k=k)
            bar.update()
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue() and all(line.startswith("work:") for line in lines)
    assert lines[0].startswith("work:   0%") and "100/100" in lines[-1]
    # 100 s of updates, a line at most every LOG_INTERVAL (10 s), and the last one
    assert 8 <= len(lines) <= 12, lines


def test_hidden_when_not_enabled_and_drawn_in_place_on_a_terminal(monkeypatch):
    log = io.StringIO()
    monkeypatch.setattr(progress.sys, "stderr", log)
    with progress.progress_bar(range(3), enabled=False, desc="quiet") as bar:
        list(bar)
    assert log.getvalue() == ""

    class Tty(io.StringIO):
        def isatty(self):
            return True

    tty = Tty()
    monkeypatch.setattr(progress.sys, "stderr", tty)
    with progress.progress_bar(total=2, desc="tty") as bar:
        bar.update(2)
    assert "\r" in tty.getvalue()


def test_a_command_logs_its_progress_when_stderr_is_a_file(tmp_path, monkeypatch):
    """`twolink synthesize --links 3` with stderr to a file prints its bar as lines (each
    agent's solve stubbed by the shipped agent: the bar, not the synthesis, is at stake)."""
    from twolink.cli import main
    from twolink.synthesis import links_decentralized
    from twolink.policy.fuzzy_policy import load_policy

    shipped = iter(load_policy("decentralized_3link").agents)
    monkeypatch.setattr(links_decentralized, "agent_problem", lambda *a: None)
    monkeypatch.setattr(links_decentralized, "solve", lambda *a, **k: next(shipped))
    log = tmp_path / "log.txt"
    with open(log, "w") as fh:
        monkeypatch.setattr("sys.stderr", fh)
        assert main(["synthesize", "decentralized", "--links", "3",
                     "-o", str(tmp_path / "p.npz")]) == 0
    lines = log.read_text().splitlines()
    assert lines[0].startswith("3-link agents:   0%") and "0/3" in lines[0], lines
    assert any(line.startswith("3-link agents: 100%") and "3/3" in line for line in lines)


def test_two_link_synthesis_logs_its_q_iterations_when_stderr_is_a_file(tmp_path,
                                                                        monkeypatch):
    """`twolink synthesize decentralized -o X` (the real two-link synthesis, about 1 s)
    with stderr to a file prints each agent's Q-iteration bar as lines."""
    from twolink.cli import main

    log = tmp_path / "log.txt"
    with open(log, "w") as fh:
        monkeypatch.setattr("sys.stderr", fh)
        assert main(["synthesize", "decentralized", "-o", str(tmp_path / "d.npz")]) == 0
    lines = log.read_text().splitlines()
    for agent in ("agent1", "agent2"):
        mine = [line for line in lines if line.startswith(f"Q-iteration {agent}: ")]
        assert mine and mine[-1].split(": ")[1].split()[0].isdigit(), lines
        assert int(mine[-1].split(": ")[1].split()[0]) > 0, lines     # sweeps counted
    assert (tmp_path / "d.npz").exists()
