"""The leaderboard as a person reads it: the ranking rule, the default rows (the
catalogue's benchmark tag), the README's compact table, the figure, the ``ranks k of M``
lines of --controller and --merge, --from-json, --timeout, and where outputs go."""
import importlib.util
import json
import os
import re
import subprocess
from pathlib import Path

import pytest

from twolink.cli import main
from twolink.studies.leaderboard import ranking
from twolink.studies.leaderboard.ranking import RULE, ranked

ROOT = Path(__file__).resolve().parents[2]
COMMITTED = ROOT / "renders/leaderboard/leaderboard.json"
PD = ("import numpy as np\n"
      "class DampedPD:\n"
      "    name = 'damped_pd'\n"
      "    def __call__(self, x):\n"
      "        return np.clip(-np.array([1.0, 2.0]) * x[:, :2]"
      " - np.array([0.15, 0.05]) * x[:, 2:], [-1.5, -0.1], [1.5, 0.1])\n"
      "def spin(x):\n"
      "    while True:\n"
      "        pass\n")


def row(name, k, n, settle, level="hard", mode="plain"):
    return {"controller": name, "level": level, "mode": mode, "successes": k, "n": n,
            "rate": k / n, "settle_ratio_median": settle}


# ------------------------------------------------------------------- the ranking rule
def test_overlapping_intervals_tie_and_the_shorter_settle_wins():
    # 2080/2080 [99.8, 100] and 2079/2080 [99.7, 100] overlap: the quicker one is first;
    # 1900/2080 lies far below both and ranks third despite settling quickest.
    rows = [row("slow", 2080, 2080, 2.9), row("quick", 2079, 2080, 1.6),
            row("weak", 1900, 2080, 1.1)]
    assert [r["controller"] for r in ranked(rows)] == ["quick", "slow", "weak"]


def test_intervals_apart_rank_by_rate_and_never_settling_is_last_in_a_tier():
    rows = [row("a", 60, 100, 1.0), row("b", 90, 100, 3.0), row("c", 88, 100, None),
            row("d", 86, 100, 2.0)]
    # b leads; c [80, 93] and d [78, 91] overlap b's [83, 94]: d settles sooner, c never;
    # a [50, 69] is a tier of its own.
    assert [r["controller"] for r in ranked(rows)] == ["d", "b", "c", "a"]


def test_full_ties_go_to_the_higher_rate_then_the_name():
    rows = [row("zeta", 50, 100, 2.0), row("alpha", 50, 100, 2.0), row("mid", 52, 100, 2.0)]
    assert [r["controller"] for r in ranked(rows)] == ["mid", "alpha", "zeta"]


def test_standings_rank_within_a_level_and_mode():
    report = {"levels": ["hard"], "rows": [
        row("x", 90, 100, 2.0), row("y", 50, 100, 1.0),
        row("x", 95, 100, 2.0, mode="compensated")]}
    assert [(lv, m, k, n) for lv, m, k, n, _ in ranking.standings(report, "x")] == [
        ("hard", "plain", 1, 2), ("hard", "compensated", 1, 1)]
    assert [(k, n) for _, _, k, n, _ in ranking.standings(report, "y")] == [(2, 2)]


# ------------------------------------------------------------------- the default rows
def test_the_default_controllers_are_the_benchmark_tag():
    from twolink.commands.leaderboard import chosen_specs
    from twolink.control.catalogue import entries
    from twolink.control.learned import default_learned_agents

    present = set(default_learned_agents())
    benchmark = [e.name for e in entries(tag="benchmark", links=2)
                 if "learned" not in e.tags or e.name in present]
    assert chosen_specs(None, []) == benchmark and len(benchmark) >= 10
    assert chosen_specs(None, ["x.py:f"]) == [*benchmark, "x.py:f"]
    every = chosen_specs(None, [], every=True)
    assert set(benchmark) < set(every) and "centralized_9levels" in every
    assert "decentralized_3link" not in every                  # two-link entries only
    tuned = chosen_specs(None, [], tag="tuned")
    assert tuned and "lqr" not in tuned and "centralized_tuned" in tuned
    assert chosen_specs(["lqr"], []) == ["lqr"]


def test_an_unknown_tag_is_one_line(capsys, tmp_path):
    assert main(["leaderboard", "--quick", "--tag", "benchmrk",
                 "--out", str(tmp_path / "lb")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown tag 'benchmrk'" in err[0] and "benchmark" in err[0]


# ------------------------------------------------------------------- the README block
def _generator():
    spec = importlib.util.spec_from_file_location("docs_generate", ROOT / "docs/generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_readme_block_is_short_with_one_best_per_level():
    _generator()
    from generator.blocks_guides import leaderboard_headline

    from twolink.control.catalogue import BENCHMARK

    report = json.loads(COMMITTED.read_text())
    text = leaderboard_headline()
    lines = text.splitlines()
    table = [line for line in lines if line.startswith("|")]
    body = [[c.strip() for c in line.strip("|").split("|")] for line in table[2:]]
    header = [c.strip() for c in table[0].strip("|").split("|")]
    assert header[2:-1] == ["none", "easy", "easy + comp.", "medium", "medium + comp.",
                            "hard", "hard + comp."]
    assert {r[0].strip("`") for r in body} == {n for n in BENCHMARK
                                                if any(x["controller"] == n
                                                       for x in report["rows"])}
    # at most 12 rows (the default table) and 14 lines of text around them
    assert len(body) <= 12 and max(map(len, lines)) < 150 and len(lines) <= 14 + 12
    for j in range(2, len(header) - 1):             # one bold (best) cell per column
        assert sum(r[j].startswith("**") for r in body) == 1, header[j]
    cells = [c for r in body for c in r[2:-1]]
    assert all(re.fullmatch(r"\**([<>]?\d+(\.\d)? %|—|·)\**", c) for c in cells), cells
    best = [line for line in lines if line.startswith("- best under ")]
    assert [re.search(r"\*\*(\w+)\*\*", b).group(1) for b in best] == report["levels"]
    # The bold cell of hard (plain) is the controller its best line names.
    hard = header.index("hard")
    bold = next(r[0] for r in body if r[hard].startswith("**"))
    assert best[-1].startswith(f"- best under **hard**: {bold} (")
    if "—" in cells:                                 # every blank cell says why
        assert "— no compensated run: the controller names no model" in text


# ------------------------------------------------------------------- the figure
def test_the_figure_has_a_panel_per_level_and_at_most_twelve_labels():
    from twolink.studies.leaderboard.report import families, figure_of

    report = json.loads(COMMITTED.read_text())
    fig = figure_of(report)
    try:
        panels = [ax for ax in fig.axes if ax.get_visible()]
        assert len(panels) == len(report["levels"])
        assert [ax.get_title().split(":")[0] for ax in panels] == report["levels"]
        legend = fig.legends[0]
        names = {r["controller"] for r in report["rows"]}
        labels = [t.get_text() for t in legend.get_texts()]
        assert 1 <= len([t for t in labels if t in names]) <= 12
        assert "fuzzy" in labels and "baseline" in labels and "learned" in labels
        assert any(t.endswith("other controllers") for t in labels)
        fig.canvas.draw()
        box, canvas = legend.get_window_extent(), fig.bbox
        assert box.x0 >= canvas.x0 and box.y0 >= canvas.y0 and box.x1 <= canvas.x1
        assert box.y1 <= min(ax.get_tightbbox().y0 for ax in panels) + 1
    finally:
        import matplotlib.pyplot as plt
        plt.close(fig)
    fam = families(["lqr", "centralized", "ppo_seed0", "mine.py:f"])
    assert fam == {"lqr": "baseline", "centralized": "fuzzy", "ppo_seed0": "learned",
                   "mine.py:f": "user"}


# ------------------------------------------------------------------- what it prints
def test_merge_prints_where_the_controller_ranks_not_the_table(tmp_path, capsys):
    mine = tmp_path / "mine.py"
    mine.write_text(PD)
    out = tmp_path / "lb"
    common = ["leaderboard", "--quick", "--levels", "none", "--out", str(out)]
    assert main([*common, "--only", "--controller", "lqr", "--controller", "pd"]) == 0
    capsys.readouterr()
    assert main(["leaderboard", "--quick", "--merge", "--controller", f"{mine}:DampedPD",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    lines = text.strip().splitlines()
    assert re.fullmatch(r"damped_pd ranks [123] of 3 under none \(plain\): \d/5 = .*, "
                        r"settle / T\* .+", lines[0]), lines
    assert lines[1] == RULE and "|" not in text
    assert lines[-1].startswith(f"wrote {out / 'leaderboard.md'}")
    saved = json.loads((out / "leaderboard.json").read_text())
    assert sorted({r["controller"] for r in saved["rows"]}) == ["damped_pd", "lqr", "pd"]
    # The whole table on request.
    assert main(["leaderboard", "--from-json", str(out / "leaderboard.json"), "--no-save",
                 "--table"]) == 0
    assert "| damped_pd | plain |" in capsys.readouterr().out


def test_from_json_rerenders_without_measuring(tmp_path, capsys):
    out = tmp_path / "again"
    assert main(["leaderboard", "--from-json", str(COMMITTED), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == ["leaderboard.md", "leaderboard.png"]
    assert (out / "leaderboard.md").read_text() == (COMMITTED.parent / "leaderboard.md").read_text()
    assert "- best under **hard**: " in text and RULE in text
    bad = tmp_path / "bad.json"
    bad.write_text('{"rows": []}')
    assert main(["leaderboard", "--from-json", str(bad), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"leaderboard report {bad}" in err[0]
    assert not (tmp_path / "x").exists()
    assert main(["leaderboard", "--from-json", str(COMMITTED), "--quick", "--no-save"]) == 2
    assert "--from-json measures nothing; give no --quick" in capsys.readouterr().err


def test_a_stuck_controller_ends_at_the_timeout(tmp_path, capsys):
    mine = tmp_path / "mine.py"
    mine.write_text(PD)
    out = tmp_path / "lb"
    assert main(["leaderboard", "--quick", "--levels", "none", "--only", "--controller", "pd",
                 "--controller", f"{mine}:spin", "--timeout", "0.5", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == "twolink leaderboard: error: controller spin took longer than 0.5 s " \
                      "on one call"
    assert [line for line in err if not line.startswith("[")] == err[-1:]   # one line
    assert not out.exists()
    assert main(["leaderboard", "--quick", "--timeout", "0", "--no-save"]) == 2
    assert "--timeout must be a number of seconds" in capsys.readouterr().err


# ------------------------------------------------------------------- where outputs go
def test_the_default_output_folder_is_outside_the_tracked_tree_and_ignored(monkeypatch,
                                                                          tmp_path):
    from twolink.resources import DEFAULT_OUTPUT, OUTPUT_ENV, output_dir

    monkeypatch.delenv(OUTPUT_ENV, raising=False)
    monkeypatch.chdir(ROOT)
    default = output_dir(create=False)
    assert default == Path(DEFAULT_OUTPUT) and default.parts[0] != "renders"
    res = subprocess.run(["git", "check-ignore", "-q", f"{default}/leaderboard/x.json"],
                         cwd=ROOT)
    assert res.returncode == 0
    tracked = subprocess.run(["git", "ls-files", str(default)], cwd=ROOT,
                             capture_output=True, text=True).stdout
    assert tracked == ""
    monkeypatch.setenv(OUTPUT_ENV, str(tmp_path / "mine"))     # the variable still wins
    assert output_dir(create=False) == tmp_path / "mine"


def test_the_leaderboard_writes_into_the_default_folder(monkeypatch, tmp_path, capsys):
    monkeypatch.delenv("TWOLINK_OUTPUT", raising=False)
    monkeypatch.chdir(tmp_path)
    assert main(["leaderboard", "--quick", "--levels", "none", "--only", "--controller", "lqr"]) == 0
    assert sorted(os.listdir(tmp_path / "twolink-results" / "leaderboard-quick")) == [
        "leaderboard.json", "leaderboard.md", "leaderboard.png"]
    assert os.listdir(tmp_path) == ["twolink-results"]
    assert "wrote twolink-results/leaderboard-quick/leaderboard.md" in capsys.readouterr().out


def test_worst_case_rows_carry_the_grid_and_the_table_shows_it(tmp_path, capsys):
    """--worst-case: every row of a perturbing level also runs on the level's grid of
    plants (centre and 24 corners); the saved row holds it and --merge accepts it."""
    import json

    from twolink.cli import main
    from twolink.studies.leaderboard.merge import saved_report

    out = tmp_path / "lb"
    assert main(["leaderboard", "--quick", "--only", "--controller", "lqr", "--levels",
                 "none", "medium", "--plants", "1", "--worst-case", "-o", str(out)]) == 0
    capsys.readouterr()
    rows = json.loads((out / "leaderboard.json").read_text())["rows"]
    medium = [r for r in rows if r["level"] == "medium"]
    assert {r["mode"] for r in medium} == {"plain", "compensated"}
    for r in medium:
        g = r["grid"]
        assert g["plants"] == 25 and g["n"] == 25 * r["n"]
        assert g["worst_plant_successes"] == min(g["per_plant"].values())
    assert all("grid" not in r for r in rows if r["level"] == "none")   # one nominal plant
    assert "grid (worst plant)" in (out / "leaderboard.md").read_text()
    assert saved_report(out / "leaderboard.json")["rows"] == rows         # merge reads it
