"""Options every command shares a contract for: a bad --seed (or --delta, --gamma) is one
line naming the option, exit 2, before any work or file."""
import pytest

from twolink.cli import COMMANDS, main

#: Each command with a --seed, with what else it needs to reach the seed's check.
SEEDED = {
    "evaluate": ["centralized"],
    "identify": [],
    "leaderboard": ["--quick", "--no-save"],
    "learn": ["--task", "decentralized"],
    "limits": ["--x0", "random"],
    "mismatch": ["--quick"],
    "render": [],
    "rollout": ["--no-save"],
    "scaling": ["--quick"],
    "synthesize": ["decentralized", "--robust", "worst"],
    "train": ["--steps", "1000"],
}
#: Where each command is told to write (so that nothing lands in the working directory).
OUTPUT = {"identify": "-o", "learn": "-o", "mismatch": "--out", "render": "-o",
          "scaling": "-o", "synthesize": "-o", "train": "-o"}


def test_every_command_with_a_seed_is_listed():
    """Read from the command modules' sources (importing every command takes seconds)."""
    import re
    from pathlib import Path

    import twolink.commands

    folder = Path(twolink.commands.__file__).parent
    seeded = {name for name in COMMANDS
              if re.search(r"add_argument\(\s*\"--seed\"", (folder / f"{name}.py").read_text())}
    assert seeded == set(SEEDED)


@pytest.mark.parametrize("command", sorted(SEEDED))
@pytest.mark.parametrize("seed", ["-1"])
def test_a_negative_seed_names_the_option(tmp_path, capsys, command, seed):
    argv = [command, *SEEDED[command], "--seed", seed]
    if command in OUTPUT:
        argv += [OUTPUT[command], str(tmp_path / "out")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"twolink {command}: error: --seed must be" in err, err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv, message", [
    (["--delta", "inf"], "--delta must be a finite positive number, got inf"),
    (["--delta", "nan"], "--delta must be a finite positive number, got nan"),
    (["--delta", "0"], "--delta must be a finite positive number, got 0.0"),
    (["--gamma", "1"], "--gamma must be a number in (0, 1), got 1.0"),
    (["--links", "3", "--delta", "inf"], "--delta must be a finite positive number"),
])
def test_synthesize_names_a_bad_delta_or_gamma_before_any_work(tmp_path, capsys, argv,
                                                                message):
    assert main(["synthesize", "decentralized", *argv, "-o", str(tmp_path / "p.npz")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err
    assert list(tmp_path.iterdir()) == []
