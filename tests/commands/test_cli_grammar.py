"""One command-line grammar (twolink.commands.grammar): every command spells an option
with one meaning, and every old spelling still parses, with one warning line, into what
the new spelling gives."""
import argparse

import pytest

from twolink.cli import COMMANDS, build_parser
from twolink.commands.grammar import DEPRECATED


def _subparsers():
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {name: action.choices[name] for name in COMMANDS}


def _visible(sub):
    return [a for a in sub._actions if a.help != argparse.SUPPRESS]


def test_every_output_option_is_spelt_o_out():
    subs = _subparsers()
    for name, sub in subs.items():
        for a in _visible(sub):
            strings = set(a.option_strings)
            assert "--output" not in strings and "--write" not in strings, name
            if "-o" in strings or "--out" in strings:
                assert strings == {"-o", "--out"}, (name, a.option_strings)


def test_quick_modes_units_and_controllers_have_one_spelling():
    for name, sub in _subparsers().items():
        options = {s for a in _visible(sub) for s in a.option_strings}
        assert not {"--plan", "--states", "--controllers", "--angle-noise",
                    "--argmax-beyond"} & options, name
        for a in _visible(sub):
            text = (a.help or "").lower()
            if a.nargs == 0:            # a flag (--degrees: --x0 is given in degrees)
                continue
            if a.metavar == "DEG" or " in degrees" in text.split(";")[0]:
                assert any(s.endswith("-deg") for s in a.option_strings), (name, a.option_strings)
            if "--controller" in a.option_strings:
                assert isinstance(a, argparse._AppendAction), name


@pytest.mark.parametrize("argv, new", [
    (["synthesize", "centralized", "--output", "x.npz"], ["synthesize", "centralized", "-o", "x.npz"]),
    (["render", "--angle-noise", "0.5"], ["render", "--angle-noise-deg", "0.5"]),
    (["evaluate", "lqr", "--states", "quick"], ["evaluate", "lqr", "--quick"]),
    (["mismatch", "--plan", "quick"], ["mismatch", "--quick"]),
    (["leaderboard", "--controllers", "lqr", "pd"],
     ["leaderboard", "--only", "--controller", "lqr", "--controller", "pd"]),
    (["limits", "--write", "t.json"], ["limits", "-o", "t.json"]),
    (["synthesize", "centralized", "--argmax-beyond", "30"],
     ["synthesize", "centralized", "--argmax-beyond-deg", "30"]),
])
def test_an_old_spelling_parses_as_the_new_one_with_a_warning(argv, new, capsys):
    old_args = build_parser(argv[0]).parse_args(argv)
    err = capsys.readouterr().err
    new_args = build_parser(new[0]).parse_args(new)
    assert capsys.readouterr().err == ""
    assert err.count("\n") == 1 and "is deprecated and goes in the next release; use" in err
    if argv[0] == "leaderboard":      # --controllers names run alone, as --only gives them
        assert old_args.controllers == ["lqr", "pd"] and new_args.controllers == []
        assert new_args.controller == ["lqr", "pd"]
        return
    ignore = {"_run", "_parser"}
    assert {k: v for k, v in vars(old_args).items() if k not in ignore} == \
        {k: v for k, v in vars(new_args).items() if k not in ignore}


def test_the_old_leaderboard_spelling_runs_the_same_controllers():
    from twolink.commands.leaderboard import chosen_specs

    old = build_parser("leaderboard").parse_args(["leaderboard", "--controllers", "lqr"])
    new = build_parser("leaderboard").parse_args(["leaderboard", "--only", "--controller",
                                                  "lqr"])
    assert chosen_specs(old.controllers, old.controller) == \
        chosen_specs(new.controllers, new.controller) == ["lqr"]


def test_every_deprecated_spelling_is_listed_once():
    _subparsers()
    assert len(DEPRECATED) == len(set(DEPRECATED)) >= 10


def test_rollout_o_prefix_still_writes_a_prefix_with_a_warning(tmp_path, capsys):
    from twolink.cli import main

    assert main(["rollout", "--duration", "0.2", "-o", str(tmp_path / "run")]) == 0
    err = capsys.readouterr().err
    assert "-o " + str(tmp_path / "run") + " (a file prefix) is deprecated" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv", "run.npz",
                                                         "run_fig3.png"]
    assert main(["rollout", "--duration", "0.2", "-o", f"{tmp_path / 'out'}/"]) == 0
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "rollout.csv", "rollout.npz", "rollout_fig3.png"]
    assert main(["rollout", "--duration", "0.2", "--prefix", str(tmp_path / "p")]) == 0
    assert (tmp_path / "p.npz").is_file() and "deprecated" not in capsys.readouterr().err
