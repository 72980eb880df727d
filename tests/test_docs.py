"""The documentation: generated pages match their sources, every Python example runs,
the README stays a landing page whose links resolve.

One mechanism runs the examples: every fenced ``python`` block of README.md and of
docs/**/*.md, the blocks of one page in order in one namespace, from a temporary folder.
``<!-- skip-test: why -->`` right before a block skips it (minutes of work);
``<!-- test-requires: module -->`` skips it where that module is missing (an optional
extra). The site itself is built by scripts/build-docs.sh (``mkdocs build --strict``).
"""
from __future__ import annotations

import dataclasses
import importlib.util
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
DOCS = ROOT / "docs"
#: At most this many blocks may be skipped outright (``skip-test``): examples are meant to run.
MAX_SKIPPED = 3


def _generator():
    spec = importlib.util.spec_from_file_location("docs_generate", DOCS / "generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# --------------------------------------------------------------------------- examples
FENCE = re.compile(r"^(?P<indent>[ \t]*)```(?P<lang>[\w+-]*)[^\n]*\n(?P<body>.*?)^(?P=indent)```[ \t]*$",
                   re.M | re.S)
MARK = re.compile(r"<!--\s*(?P<kind>skip-test|test-requires):\s*(?P<what>.*?)\s*-->\s*$")


@dataclasses.dataclass(frozen=True)
class Block:
    page: Path
    line: int                   # line of the page where the code starts (1-based)
    source: str
    skip: str | None = None     # why it is skipped (skip-test)
    requires: str | None = None  # module it needs (test-requires)


def _blocks(page: Path) -> list:
    text = page.read_text()
    out = []
    for m in FENCE.finditer(text):
        if m.group("lang") != "python":
            continue
        before = [ln for ln in text[:m.start()].splitlines() if ln.strip()]
        mark = MARK.search(before[-1]) if before else None
        indent = len(m.group("indent"))
        body = "".join(ln[indent:] + "\n" for ln in m.group("body").splitlines())
        out.append(Block(page, text.count("\n", 0, m.start()) + 2, body,
                         skip=mark.group("what") if mark and mark["kind"] == "skip-test" else None,
                         requires=mark.group("what") if mark and mark["kind"] == "test-requires"
                         else None))
    return out


def _pages() -> list:
    return [README, *sorted(DOCS.rglob("*.md"))]


PAGES = [p for p in _pages() if _blocks(p)]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_python_examples_run(page, tmp_path, monkeypatch):
    """Each page's python blocks, in order, in one namespace, from an empty folder (so
    whatever an example writes lands there). A failure names the page and its line."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("TWOLINK_OUTPUT", str(tmp_path / "renders"))
    monkeypatch.setenv("MPLBACKEND", "Agg")
    namespace = {"__name__": "__docs__"}
    ran = 0
    for block in _blocks(page):
        if block.skip is not None:
            continue
        if block.requires is not None and importlib.util.find_spec(block.requires) is None:
            continue
        code = "\n" * (block.line - 1) + block.source     # tracebacks give the page's lines
        exec(compile(code, str(page.relative_to(ROOT)), "exec"), namespace)
        ran += 1
    if not ran:
        pytest.skip("every python block of this page is marked to skip here")


def test_skips_are_few_and_say_why():
    blocks = [b for p in _pages() for b in _blocks(p)]
    skipped = [b for b in blocks if b.skip is not None]
    assert all(b.skip for b in skipped)
    assert len(skipped) <= MAX_SKIPPED, [f"{b.page.name}:{b.line}" for b in skipped]
    for b in blocks:
        if b.requires is not None:
            assert re.fullmatch(r"[\w.]+", b.requires), (b.page, b.line, b.requires)


def test_the_block_reader_sees_marks_indents_and_other_languages(tmp_path):
    page = tmp_path / "p.md"
    page.write_text("intro\n\n<!-- skip-test: slow -->\n```python\nx = 1\n```\n\n"
                    "```bash\nls\n```\n\n- item\n\n  ```python\n  y = 2\n  ```\n\n"
                    "<!-- test-requires: nosuchmodule -->\n```python\nz = 3\n```\n")
    blocks = _blocks(page)
    assert [(b.line, b.source, b.skip, b.requires) for b in blocks] == [
        (5, "x = 1\n", "slow", None), (15, "y = 2\n", None, None),
        (20, "z = 3\n", None, "nosuchmodule")]


# --------------------------------------------------------------------------- generated
def test_generated_pages_match_their_sources():
    """The CLI and API reference, the results pages and the generated blocks (README,
    mkdocs.yml nav, ...) are what docs/generate.py writes from the code and the data."""
    gen = _generator()
    stale = gen.stale()
    assert not stale, ("out of date (run: python docs/generate.py): " + ", ".join(stale))


def test_every_subcommand_has_its_reference_page():
    from twolink.cli import COMMANDS

    gen = _generator()
    pages = gen.cli_pages()
    for name in COMMANDS:
        page = pages[f"reference/cli/{name}.md"]
        assert page.startswith(gen.STAMP) and f"# `twolink {name}`" in page


def test_the_cli_pages_list_every_option():
    import argparse

    from twolink.cli import build_parser

    gen = _generator()
    pages = gen.cli_pages()
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    for name, parser in sub.choices.items():
        for action in parser._actions:
            if action.option_strings and action.help is not argparse.SUPPRESS \
                    and not isinstance(action, argparse._HelpAction):
                assert f"`{', '.join(action.option_strings)}" in pages[f"reference/cli/{name}.md"]


def test_a_changed_source_makes_its_page_stale(tmp_path, monkeypatch):
    """The check really compares: a page edited by hand is reported."""
    gen = _generator()
    out = gen.outputs()
    rel = "docs/reference/cli/index.md"
    edited = dict(out)
    edited[rel] = out[rel] + "typed by hand\n"
    monkeypatch.setattr(gen.common, "ROOT", tmp_path)
    monkeypatch.setattr(gen.common, "DOCS", tmp_path / "docs")
    for path, text in out.items():
        (tmp_path / path).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / path).write_text(text)
    assert gen.stale(out) == []
    assert gen.stale(edited) == [rel]
    (tmp_path / "docs" / "reference" / "cli" / "gone.md").write_text(gen.STAMP + " -->\n")
    assert gen.stale(out) == ["docs/reference/cli/gone.md"]


def test_a_block_without_markers_is_an_error():
    gen = _generator()
    with pytest.raises(ValueError, match="has no block 'commands'"):
        gen.fill("README.md", "no markers here\n", {"commands": "x"})


# --------------------------------------------------------------------------- results data
#: The results pages written from the development studies' versioned JSON.
STUDY_PAGES = {
    "results/round-off.md": "renders/tie_sensitivity/tie_sensitivity.json",
    "results/finer-grids.md": "renders/grid_study/grid_study.json",
    "results/identification.md": "renders/identification/identification.json",
}


@pytest.mark.parametrize("page", sorted(STUDY_PAGES))
def test_each_study_has_its_results_page(page):
    gen = _generator()
    rel = STUDY_PAGES[page]
    entry = next(e for e in gen.RESULTS if e[0] == page)
    assert entry[2] == rel and isinstance(gen.SCHEMAS[rel], tuple)
    text = gen.result_pages()[page]
    assert text.startswith(gen.STAMP) and "`python docs/generate.py`" in text
    assert (DOCS / page).read_text() == text          # committed, and from this data


@pytest.mark.parametrize("rel", sorted(STUDY_PAGES.values()))
def test_a_file_of_another_schema_or_version_is_refused_in_one_line(rel, tmp_path,
                                                                       monkeypatch, capsys):
    import json

    gen = _generator()
    name, version = gen.SCHEMAS[rel]
    data = json.loads((ROOT / rel).read_text())
    monkeypatch.setattr(gen.common, "ROOT", tmp_path)
    monkeypatch.setattr(gen.common, "DOCS", tmp_path / "docs")
    for wrong in ({**data, "version": version + 1}, {**data, "schema": "twolink.other"},
                  {k: v for k, v in data.items() if k != "schema"}):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(json.dumps(wrong))
        with pytest.raises(gen.DataError, match=re.escape(rel)):
            gen.result_pages()
        assert gen.main(["--check"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("docs/generate.py: error: " + rel)
    # nothing was written: the refusal comes before any page
    assert not (tmp_path / "docs").exists()


def test_an_older_report_of_the_wrong_kind_is_refused():
    gen = _generator()
    rel = "renders/scaling/scaling.json"
    with pytest.raises(gen.DataError, match="no key 'command'"):
        gen._check(rel, {"rows": []}, gen.SCHEMAS[rel])
    with pytest.raises(gen.DataError, match="schema 'twolink.grid_study' version 1"):
        gen._check(rel, {"schema": "twolink.grid_study", "version": 1, "command": "",
                         "provenance": {}, "rows": []}, gen.SCHEMAS[rel])


def test_the_robust_targets_are_judged_on_the_report():
    gen = _generator()

    def res(k, n, worst=1.0, settle=1.0):
        return {"successes": k, "n": n, "rate": k / n, "plants": n // 65,
                "worst_plant_rate": worst, "median_settle": settle}
    section = {"results": {"centralized_robust": {
        "none": {"compensated": res(65, 65)},
        "medium": {"compensated": res(2060, 2080, worst=0.94, settle=1.6)}}}}
    got = {t[0]: t[-1] for t in gen.robust_targets(section)}
    assert got == {"centralized_robust, nominal plant: 100 % success": True,
                   "centralized_robust + compensation, medium: ≥ 98 % success": True,
                   "centralized_robust + compensation, medium: no plant below 95 %": False,
                   "centralized_robust + compensation, medium: median settle ≤ 1.5 s": False}
    page = gen.result_pages()["results/mismatch.md"]
    assert "### Targets" in page and "Targets, measured here" not in page


def test_the_scaling_targets_are_judged_on_the_report():
    gen = _generator()

    def row(scheme, links, k5, k8, n=64):
        return {"scheme": scheme, "rule": "tapered", "links": links, "status": "run",
                "evaluation": {"horizons": {"5": {"successes": k5, "n": n, "rate": k5 / n},
                                            "8": {"successes": k8, "n": n, "rate": k8 / n}}}}
    got = {t[0]: (t[1], t[2]) for t in gen.scaling_targets(
        {"rows": [row("decentralized", 3, 57, 61), row("decentralized_levels", 5, 0, 245, 256),
                  row("decentralized", 5, 0, 230, 256)]})}
    assert got["tapered N = 3 ≥ 95 % at 8 s"][1] is True
    assert got["tapered N = 3 ≥ 90 % at 5 s"] == ("57/64 = 89.1 % [79, 95] at 5 s", False)
    assert got["tapered N = 5 ≥ 95 % at 8 s"][1] is False
    assert got["tapered N = 5 ≥ 95 % at 8 s (5 levels)"][1] is True
    assert "## Targets" in gen.result_pages()["results/scaling.md"]


def test_the_learners_study_duration_is_judged_on_complete_seeds():
    _generator()                             # puts docs/ on the path for the generator
    from generator.results_learners_cost import study_time
    from twolink.studies.learners.plan import plan

    ids = [p.id for p in plan() if p.seed == 0]

    def run(i, wall):
        return {"id": i, "wall_s": wall, "cpu_s": wall, "steps": 1_000_000}

    assert "not yet measured" in study_time({"runs": [run(ids[0], 60.0)]})
    runs = [run(i, 3600.0 / len(ids)) for i in ids]                  # one hour a seed
    line = study_time({"runs": runs})
    assert line.startswith("- met: ") is (len(plan()) // len(ids) <= 8)
    assert "1.0 h (seed 0)" in line and f"the {len(plan())} runs take about" in line
    slow = study_time({"runs": [{**r, "wall_s": r["wall_s"] * 3} for r in runs]})
    assert slow.startswith("- **missed**: ") and "3.0 h (seed 0)" in slow


def test_no_acceptance_targets_in_the_package():
    """What a study should reach is the documentation's to judge (docs/generate.py)."""
    import twolink.studies.robustness as robustness
    import twolink.studies.scaling.measure as measure

    for module in (robustness, measure):
        assert not hasattr(module, "TARGETS") and not hasattr(module, "targets")


# --------------------------------------------------------------------------- README
def test_readme_is_a_landing_page():
    lines = README.read_text().splitlines()
    assert len(lines) <= 250, len(lines)


def test_readme_links_resolve():
    text = README.read_text()
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"[a-z]+://", target) or target.startswith("#"):
            continue
        path = target.split("#")[0]
        assert (ROOT / path).exists(), target


def test_the_docs_extra_pins_what_the_build_needs():
    import tomllib

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"]
    pins = {re.split(r"[\[=]", r)[0]: r for r in extras["docs"]}
    for name in ("mkdocs", "mkdocs-material", "mkdocstrings", "mkdocstrings-python"):
        assert name in pins and "==" in pins[name], name
    build = (ROOT / "scripts" / "build-docs.sh").read_text()
    assert "--strict" in build and "build/site" in build
    assert "scripts/build-docs.sh" in (ROOT / ".ci" / "run").read_text()


if __name__ == "__main__":          # python tests/test_docs.py: the stale pages, if any
    sys.exit(_generator().main(["--check"]))


def test_the_reproduction_page_refuses_sweep_counts_of_another_version(tmp_path, monkeypatch,
                                                                        capsys):
    """renders/iteration_norms/iteration_norms.json, read by the reproduction page beside
    docs/data/reproduce.json, is schema-checked like the studies' own pages' data."""
    import json

    gen = _generator()
    rel, report = "renders/iteration_norms/iteration_norms.json", "docs/data/reproduce.json"
    name, version = gen.SCHEMAS[rel]
    data = json.loads((ROOT / rel).read_text())
    assert "iteration_norms.py" in (DOCS / "results/reproduction.md").read_text()
    monkeypatch.setattr(gen.common, "ROOT", tmp_path)
    monkeypatch.setattr(gen.common, "DOCS", tmp_path / "docs")
    for path, text in ((report, (ROOT / report).read_text()),
                       (rel, json.dumps({**data, "version": version + 1}))):
        (tmp_path / path).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / path).write_text(text)
    with pytest.raises(gen.DataError, match=re.escape(rel)):
        gen.result_pages()
    assert gen.main(["--check"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("docs/generate.py: error: " + rel)


def test_the_site_serves_the_committed_figures_wherever_the_checkout_lies(tmp_path,
                                                                         monkeypatch):
    # A checkout under a folder named like a scratch one (/tmp/...): only folders inside
    # renders/ may mark figures as scratch.
    pytest.importorskip("mkdocs")
    from mkdocs.structure.files import Files
    spec = importlib.util.spec_from_file_location("docs_hooks", DOCS / "hooks.py")
    hooks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hooks)
    root = tmp_path / "tmp" / "checkout"
    for rel in ("renders/fig3.png", "renders/mismatch/robust.png",
                "renders/mismatch-quick/robust.png", "renders/tmp/x.png", "renders/a.json"):
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_bytes(b"x")
    monkeypatch.setattr(hooks, "ROOT", root)
    files = hooks.on_files(Files([]), {"site_dir": str(tmp_path / "site"),
                                       "use_directory_urls": True})
    assert sorted(f.src_uri for f in files) == ["renders/fig3.png",
                                                "renders/mismatch/robust.png"]


def test_the_scaling_page_shows_the_reach_study_beside_the_table(tmp_path, monkeypatch):
    """The physical ceiling section: the study's counts with intervals beside the table's
    rates at 8 s, and a verdict that follows the counts."""
    import json

    gen = _generator()
    from generator import results_scaling as rs

    report = json.loads((ROOT / "renders/scaling/scaling.json").read_text())
    monkeypatch.setattr(gen.common, "ROOT", tmp_path)
    assert rs._reach_block(report) == ""                    # no study data: no section
    answers = [{"reachable": True, "seconds": 20.0}] * 15 + [{"reachable": False, "seconds": 40.0}]
    run = {"links": 6, "rule": "tapered", "poses": 16, "reachable": 15, "hold": 2,
           "deadline_s": 7.0, "answers": answers}
    path = tmp_path / rs.REACH
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"schema": "twolink.links_reach", "version": 1, "runs": [run]}))
    text = rs._reach_block(report)
    row = next(line for line in text.splitlines() if line.startswith("| 6 | tapered |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[2].startswith("15/16 = 93.8 %")
    pd = next(r for r in report["rows"] if (r["scheme"], r["rule"], r["links"]) ==
              ("pd", "tapered", 6))["evaluation"]["horizons"]["8"]
    assert cells[5].startswith(f"{pd['successes']}/{pd['n']} = ")
    assert cells[6] == "21 s a pose (at most 40 s)"
    assert "no controller is known to settle it" in text and "Every pose" not in text
    run.update(reachable=16, answers=[{"reachable": True, "seconds": 20.0}] * 16)
    path.write_text(json.dumps({"schema": "twolink.links_reach", "version": 1, "runs": [run]}))
    assert "Every pose tried was reachable" in rs._reach_block(report)


def test_the_scaling_page_counts_successes_by_own_motor_time(tmp_path, monkeypatch):
    """The own-motor section: per class of own-motor time the poses and each controller's
    successes with intervals (a learned agent's column "—" on an arm it was not run on),
    the poses over the deadline named with their joint and the reach study's answers for
    them, whether the table's controllers' totals equal its rows, and the successes at
    the longer horizons on all poses and on those over the deadline."""
    import json

    gen = _generator()
    from generator import results_own_motor as ro

    report = json.loads((ROOT / "renders/scaling/scaling.json").read_text())
    monkeypatch.setattr(gen.common, "ROOT", tmp_path)
    assert ro.own_motor_block(report) == ""                 # no study data: no section
    own = [1.0, 2.0, 4.0, 6.0, 8.0, 9.0]
    run = {"links": 6, "rule": "tapered", "poses": 6, "own_motor_s": own,
           "slowest_joint": [1, 2, 6, 6, 6, 6], "learned": ["agent_6"],
           "success": {"decentralized": [1, 1, 0, 1, 0, 0],
                       "decentralized_levels": [1, 1, 1, 1, 1, 0], "pd": [1, 0, 0, 0, 0, 0],
                       "agent_6": [1, 1, 1, 1, 0, 0]},
           "later": {"12": {"decentralized": [1, 1, 1, 1, 0, 0],
                            "decentralized_levels": [1, 1, 1, 1, 1, 0],
                            "pd": [1, 1, 1, 1, 0, 0], "agent_6": [1, 1, 1, 1, 1, 0]},
                     "16": {"decentralized": [1, 1, 1, 1, 0, 0],
                            "decentralized_levels": [1, 1, 1, 1, 1, 1],
                            "pd": [1, 1, 1, 1, 1, 1], "agent_6": [1, 1, 1, 1, 1, 1]}}}
    other = {"links": 5, "rule": "tapered", "poses": 2, "own_motor_s": [1.0, 2.0],
             "slowest_joint": [1, 5], "learned": [], "later": {},
             "success": {k: [1, 0] for k in ("decentralized", "decentralized_levels", "pd")}}
    path = tmp_path / ro.OWN_MOTOR
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"schema": "twolink.links_own_motor", "version": 2,
                                "runs": [other, run]}))
    reach = {"links": 6, "rule": "tapered", "poses": 5, "reachable": 5, "hold": 2,
             "deadline_s": 7.0, "answers": [{"reachable": True, "seconds": 1.0}] * 5}
    (tmp_path / "renders/links_reach/reach.json").write_text(json.dumps(
        {"schema": "twolink.links_reach", "version": 1, "runs": [reach]}))
    text = ro.own_motor_block(report)
    first = text.split("### Failed, or settled late?")[0]
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in first.splitlines()
            if line.startswith("| 6 | tapered |")]
    assert [r[2:4] for r in rows] == [["≤ 3 s", "2"], ["3–5 s", "1"], ["5–7 s", "1"],
                                      ["> 7 s", "2"]]
    assert rows[0][4].startswith("2/2 = 100.0 %") and rows[0][6].startswith("1/2 = 50.0 %")
    assert rows[3][5].startswith("1/2 = 50.0 %") and rows[3][7] == "0/2 = 0.0 % [0, 66]"
    five = [line for line in text.splitlines() if line.startswith("| 5 | tapered | ≤ 3 s")]
    assert five[0].rstrip(" |").endswith("| —")             # agent_6 not run at N = 5
    assert ("tapered N = 6: 2 of 6 poses are over 7 s (set by joint 6); the controllers "
            "settle 0, 1, 0, 0 of them (decentralized, 5 levels, per-joint PD, `agent_6`)") in text
    assert "of the first 5, which the reach study solved, 1 are over 7 s and 1 of those " \
           "are reachable" in text
    assert "(the table's controllers' totals differ from its rows)" in text
    assert "at N = 6 joint 6 turns at most 0.312 rad/s" in text
    later = {r[2]: r[3:] for r in ([c.strip() for c in line.strip("|").split("|")]
                                   for line in text.split("### Failed, or settled late?")[1]
                                   .splitlines() if line.startswith("| 6 | tapered |"))}
    assert later["`agent_6`"][:3] == ["4/6 = 66.7 % [30, 90]", "5/6 = 83.3 % [44, 97]",
                                      "6/6 = 100.0 % [61, 100]"]
    assert later["`agent_6`"][3:] == ["0/2", "1/2", "2/2"]
    assert later["per-joint PD"][3:] == ["0/2", "0/2", "2/2"]
    assert not any(line.startswith("| 5 | tapered | decentralized |")
                   for line in text.splitlines())            # no later data at N = 5
    assert ("`agent_6` (tapered N = 6) settles 4 of the 4 poses whose own-motor time is at "
            "most 7 s by 8 s, and 0 of the 2 beyond it; by 16 s it settles 6 of 6. What it "
            "misses at 8 s it settles later") in text


def test_the_fuzzy_designs_page_shows_the_near_goal_gain_choices_and_parts(tmp_path,
                                                                          monkeypatch):
    """The near-goal gain section: a design's plain read-out, each criterion's choice with
    its cells and the registry name that ships it, and which part of hard the gain answers
    most, all from the study's data."""
    import json

    gen = _generator()
    from generator import results_leaderboard as rl

    monkeypatch.setattr(gen.common, "ROOT", tmp_path)
    assert rl._near_gain_block() == ""                      # no study data: no section
    cells = {"none": 48, "medium": 240, "medium compensated": 250, "hard": 100,
             "hard compensated": 240}
    run = {"policy": "decentralized_locked", "base": dict(cells, hard=70),
           "rows": [{"angle_deg": 60.0, "gain": 0.3, "cells": cells},
                    {"angle_deg": 20.0, "gain": 0.1, "cells": dict(cells, none=47)}],
           "chosen": {"challenge sum": {"angle_deg": 60.0, "gain": 0.3},
                      "hard compensated": None},
           "parts": {"gain": 0.3, "angle_deg": 60.0, "runs": {
               "delays": {"plain read-out": 200, "with the gain": 250, "pd_deadzone": 256},
               "noise": {"plain read-out": 100, "with the gain": 240, "pd_deadzone": 216}}}}
    path = tmp_path / rl.NEAR_GAIN
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"schema": "twolink.near_gain", "version": 1, "runs": [run],
                                "grid": {"angles_deg": [20.0, 60.0], "gains": [0.1, 0.3]}}))
    text = rl._near_gain_block()
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in text.splitlines()
            if line.startswith("|") and "---" not in line]
    assert rows[1][:9] == ["`decentralized_locked`", "—", "48", "240", "250", "70", "240",
                           "800", ""]
    assert rows[2][1] == "challenge sum: A 60°, g 0.3" and rows[2][7] == "830"
    assert rows[2][-1] == "`decentralized_locked_gain`"       # the registry ships it
    assert rows[3][1] == "hard compensated: none keeps every nominal pose"
    assert "`decentralized_locked` most under its noise (+140 of 256)" in text
    assert ["`decentralized_locked`", "delays alone", "200/256", "250/256",
            "256/256"] in rows


def test_the_learners_page_lists_the_lever_runs(tmp_path, monkeypatch):
    """The levers section: per curve under renders/learners/levers/ its train command,
    its final curve point, its fresh score where a .fresh.json sits beside it, its CPU
    per step; a curve that is not one is refused in one line naming the file."""
    import json

    gen = _generator()
    from generator import results_learners as rl

    monkeypatch.setattr(gen.common, "ROOT", tmp_path)
    assert rl.levers_block() == ""                            # no lever runs: no section
    folder = tmp_path / rl.LEVERS
    folder.mkdir(parents=True)
    config = {"algo": "ppo", "base": "pd", "gamma": 0.995, "history": 1, "action_rate": 0.0,
              "links": 6, "rule": "tapered", "steps": 2000000, "seed": 0}
    curve = {"config": config, "cpu_s": 700.0, "steps": 2000000, "done": True,
             "curve": [{"successes": 12, "n": 64, "steps": 0},
                       {"successes": 50, "n": 64, "steps": 2000000}]}
    (folder / "ppo-pd-g0.995_6t_seed0.json").write_text(json.dumps(curve))
    (folder / "other_6t_seed0.json").write_text(json.dumps(dict(curve, config=dict(
        config, algo="mappo", observe="local", gamma=None))))
    (folder / "ppo-pd-g0.995_6t_seed0.fresh.json").write_text(json.dumps(
        {"successes": 200, "n": 256}))
    (folder / "ppo-pd-g0.995_6t_seed0.fresh16.json").write_text(json.dumps(
        {"successes": 256, "n": 256}))
    rows = {r[0]: r for r in ([c.strip() for c in line.strip("|").split("|")]
                              for line in rl.levers_block().splitlines()
                              if line.startswith("| `"))}
    assert rows["`ppo-pd-g0.995_6t_seed0`"][1:] == [
        "`twolink train --links 6 --rule tapered --algo ppo --base pd --gamma 0.995 "
        "--steps 2000000 --seed 0`", "50/64 = 78.1 % [67, 86] at 2.00 M steps",
        "200/256 = 78.1 % [73, 83]", "256/256 = 100.0 % [99, 100]", "350 µs"]
    assert rows["`other_6t_seed0`"][1].endswith("--algo mappo --observe local --base pd "
                                                 "--steps 2000000 --seed 0`")
    assert rows["`other_6t_seed0`"][3:5] == ["—", "—"]
    (folder / "cloned_6t_seed0.fresh.json").write_text(json.dumps({"successes": 7, "n": 8}))
    assert not any(line.startswith("| `ppo-pd-g0` ") for line in rl.levers_block().splitlines())
    rows = {r[0]: r for r in ([c.strip() for c in line.strip("|").split("|")]
                              for line in rl.levers_block().splitlines()
                              if line.startswith("| `"))}
    assert rows["`cloned_6t_seed0`"][1:] == ["—", "—", "7/8 = 87.5 % [53, 98]", "—", "—"]
    # a run stopped early: its last point, the steps it asked for, its CPU so far; the
    # recipe options in its command
    (folder / "stopped_6t_seed0.json").write_text(json.dumps({
        "config": dict(config, gamma=None, envs=64, batch_size=8192, net=[64, 64]),
        "done": False, "steps_requested": 2000000,
        "curve": [{"successes": 0, "n": 64, "steps": 0, "cpu_s": 0.0},
                  {"successes": 1, "n": 64, "steps": 1000000, "cpu_s": 200.0}]}))
    rows = {r[0]: r for r in ([c.strip() for c in line.strip("|").split("|")]
                              for line in rl.levers_block().splitlines()
                              if line.startswith("| `"))}
    assert rows["`stopped_6t_seed0`"][1:] == [
        "`twolink train --links 6 --rule tapered --algo ppo --base pd --envs 64 "
        "--batch-size 8192 --net 64,64 --steps 2000000 --seed 0`",
        "1/64 = 1.6 % [0, 8] at 1.00 M steps (stopped there; 2.00 M asked)", "—", "—",
        "200 µs"]
    (folder / "broken.json").write_text("{}")
    with pytest.raises(ValueError, match=r"broken.json: not a twolink train curve"):
        rl.levers_block()


def test_every_lever_command_gives_back_its_run():
    """Each committed lever run's command in the levers table, read by `twolink train`'s
    own parser, gives every option of the run's config that is not the default, and the
    command list covers every field of both config types."""
    import dataclasses
    import json
    import shlex

    from twolink.cli import build_parser
    from twolink.commands.train import given_options
    from twolink.training.config import TrainConfig
    from twolink.training.marl import MARL_ALGOS, MarlConfig

    _generator()
    from generator import results_learners as rl

    for cls in (TrainConfig, MarlConfig):
        fields = {f.name for f in dataclasses.fields(cls)} - {"links", "rule"}
        assert fields <= set(rl.LEVER_OPTIONS), sorted(fields - set(rl.LEVER_OPTIONS))
    parser = build_parser()
    curves = [p for p in sorted((ROOT / rl.LEVERS).glob("*.json")) if ".fresh" not in p.name]
    assert curves
    for path in curves:
        config = json.loads(path.read_text())["config"]
        words = shlex.split(rl._lever_command(config))[1:]
        given = given_options(parser.parse_args(words))
        cls = MarlConfig if config["algo"] in MARL_ALGOS else TrainConfig
        for f in dataclasses.fields(cls):
            value = config.get(f.name)
            value = tuple(value) if isinstance(value, list) else value
            if f.name in given:
                mine = given[f.name]
                assert (tuple(mine) if isinstance(mine, list) else mine) == value, \
                    (path.name, f.name)
            else:
                assert value == f.default or value is None, (path.name, f.name)


def test_the_cost_target_counts_six_link_lever_runs_that_learnt(tmp_path, monkeypatch):
    """A finished six-link lever run whose agent settles fresh poses meets the cost target
    with its whole run's CPU per step; one that learnt nothing does not count; the
    benchmark's MAPPO rows on the model (6) follow, with their ratio to its physics."""
    import json

    gen = _generator()
    from generator import results_learners as rl

    monkeypatch.setattr(gen.common, "ROOT", tmp_path)
    six = {"links": 6, "rule": "tapered", "algo": "mappo", "learner": "MAPPO (local)",
           "cpu_us_per_step": 600.0, "seeds": [0],
           "fresh": {"successes": 100, "n": 256}, "table": {"successes": 90, "n": 256}}
    folder = tmp_path / rl.LEVERS
    folder.mkdir(parents=True)
    for stem, cpu, successes in (("cheap_6t_seed0", 120.0, 150), ("nothing_6t_seed0", 50.0, 0)):
        (folder / f"{stem}.json").write_text(json.dumps({
            "config": {"links": 6, "rule": "tapered", "algo": "mappo"}, "done": True,
            "cpu_s": cpu, "steps": 1_000_000,
            "curve": [{"steps": 1_000_000, "successes": 1, "n": 64}]}))
        (folder / f"{stem}.fresh.json").write_text(json.dumps({"successes": successes,
                                                               "n": 256}))
    line = rl._targets([six])[-1]
    assert line.startswith("- met: training cost at N = 6 <= 150 µs")
    assert line.endswith("cheapest MAPPO (local) 600 µs; cheapest six-link lever run that "
                         "learnt (below): `cheap_6t_seed0` 120 µs, its fresh poses at 8 s "
                         "150/256 = 58.6 % [52, 64]")
    bench = tmp_path / rl.BENCH
    bench.parent.mkdir(parents=True)
    sec = "training: MAPPO, 6 links, on the model (6) (envs 256, epochs 3)"
    bench.write_text(json.dumps({"command": "x", "machine": {}, "mode": "full", "seconds": {},
                                 "rows": [
        {"section": sec, "name": "training on the model, updates included: CPU per env step",
         "value": 115.0},
        {"section": sec, "name": "the same recipe on MuJoCo: CPU per env step",
         "value": 150.0},
        {"section": sec, "name": "physics alone (the model): CPU per env step",
         "value": 50.0}]}))
    assert rl._targets([six])[-1].endswith(
        "; MAPPO trained on the model (6) (envs 256, epochs 3) 115 µs (meets the target; "
        "2.3 × the model's physics alone, 50 µs), the same recipe on MuJoCo 150 µs")
    (folder / "cheap_6t_seed0.fresh.json").write_text(json.dumps({"successes": 0, "n": 256}))
    assert rl._targets([six])[-1].startswith("- **missed**: training cost")


def test_the_cost_target_names_the_lighter_recipe_of_the_benchmark(tmp_path, monkeypatch):
    """The learners page's cost target: the cheapest study row at six links, then the
    training benchmark's default and lighter PPO recipes (one run) and how the lighter
    recipe's lever run scored; without the benchmark's rows, the study row alone."""
    import json

    gen = _generator()
    from generator import results_learners as rl

    monkeypatch.setattr(gen.common, "ROOT", tmp_path)
    six = {"links": 6, "rule": "tapered", "algo": "mappo", "learner": "MAPPO (local)",
           "cpu_us_per_step": 600.0, "seeds": [0],
           "fresh": {"successes": 100, "n": 256}, "table": {"successes": 90, "n": 256}}
    line = rl._targets([six])[-1]
    assert line == ("- **missed**: training cost at N = 6 <= 150 µs CPU per environment "
                    "step (updates and the curve's evaluations included): cheapest MAPPO "
                    "(local) 600 µs")
    bench = tmp_path / rl.BENCH
    bench.parent.mkdir(parents=True)
    name = "training, updates included: CPU per env step"
    bench.write_text(json.dumps({"command": "x", "machine": {}, "mode": "full", "seconds": {},
                                 "rows": [
        {"section": "training: PPO, 6 links, 16 arms", "name": name, "value": 290.0},
        {"section": "training: PPO, 6 links, 16 arms",
         "name": "physics alone: CPU per env step", "value": 73.0},
        {"section": "training: PPO, 6 links, lighter recipe (batch size 1024, net 64x64)",
         "name": name, "value": 140.4},
        {"section": "training: MAPPO, 6 links, 16 arms", "name": name, "value": 700.0},
        {"section": "training: MAPPO, 6 links, lighter recipe (envs 256)", "name": name,
         "value": 155.2}]}))
    ppo = rl.LIGHT_LEVERS["PPO"]
    lever = tmp_path / rl.LEVERS / f"{ppo}0.fresh.json"
    lever.parent.mkdir(parents=True)
    lever.write_text(json.dumps({"successes": 196, "n": 256}))
    lever.with_name(f"{ppo}1.fresh.json").write_text(json.dumps(
        {"successes": 0, "n": 256}))
    line = rl._targets([six])[-1]
    assert line.endswith("cheapest MAPPO (local) 600 µs. The training benchmark (updates "
                         "included, no evaluations; one run; the physics alone 73 µs): the "
                         "default PPO recipe 290 µs, "
                         "the lighter recipe (batch size 1024, net 64x64) 140 µs (meets the "
                         "target); its runs (below) on the fresh poses: "
                         "`ppo-pd-light_6t_seed0` 196/256 = 76.6 % [71, 81], "
                         "`ppo-pd-light_6t_seed1` 0/256 = 0.0 % [0, 1]; the default MAPPO "
                         "recipe 700 µs, the lighter recipe (envs 256) 155 µs (misses the "
                         "target)")


def test_the_swing_returns_block_counts_the_poses_the_answer_earns_more_on(tmp_path,
                                                                          monkeypatch):
    """The scaling page's "Does their reward pay for the swing?": each cell the mean
    return and on how many poses the time-optimal answer earns more; the finding names the
    learned agents' largest count under the shaped reward and their range under (15)."""
    import json

    gen = _generator()
    from generator import results_swing_returns as sr

    monkeypatch.setattr(gen.common, "ROOT", tmp_path)
    assert sr.swing_returns_block() == ""

    def record(name, shaped, paper, ok8):
        team = {r: [[v, v, v] for v in (shaped if r.startswith("shaped") else paper)]
                for r in ("shaped", "shaped_time", "paper")}
        links = [[[v] * 3 for _ in range(3)] for v in shaped]
        ret = dict(team, links=links)
        return {"controller": name, "n": 2, "success_8s": ok8, "success_16s": [True, True],
                "returns_8s": ret, "returns_16s": ret}

    data = {"schema": "twolink.studies.swing_returns", "version": 1, "links": 3,
            "rule": "tapered", "poses": 2, "demo_seed": 7, "indices": [0, 1],
            "windows_s": [8.0, 16.0], "gammas": [0.98, 0.995, 1.0],
            "team": ["shaped", "shaped_time", "paper"], "records": [
                record("time-optimal answers", [-30.0, -30.0], [-20.0, -20.0], [True] * 2),
                record("pd_3link_tapered", [-40.0, -20.0], [-25.0, -25.0], [False] * 2),
                record("runs/ppo_3t_seed0/a.zip", [-35.0, -20.0], [-25.0, -10.0],
                       [False, True])]}
    path = tmp_path / sr.RETURNS
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps(data))
    block = sr.swing_returns_block()
    assert "| `ppo_3t_seed0` | 1/2 | 2/2 | -27.5; the answer more on 1/2 |" in block
    assert "| time-optimal answers (replayed) | 2/2 | 2/2 | -30.0 | -30.0 |" in block
    assert "| `pd_3link_tapered` | 0/2 | 2/2 | -30.0; the answer more on 1/2 |" in block
    assert ("earns more than the agent's own trajectory on at most 1 of the 2 poses** "
            "(γ 0.98; with no discount over 16 s on at most 1)") in block
    assert "the answer earns more there on 1 poses, the agents leave 1 unsettled" in block
    assert sr.reward_note((3, "copied")) == ""
    assert sr.reward_note((3, "tapered")).startswith(
        ". The shaped reward they learn from pays those answers less than each of 1 learned "
        "agents' own trajectories on all but at most 1 of 2 demonstration poses beyond "
        "that reach (γ 0.98; at most 1 at any discount tried")
    # the inner links of three: two link-poses per pose
    assert "the answer more on 2/4 |" in block


def test_the_study_time_target_states_its_cpu_cause():
    """The learners page's duration target: nothing to judge before a seed is complete;
    a complete seed's walls added up; when missed, the CPU its runs used against two
    cores' four CPU hours and the CPU per step that would fit, from the records."""
    _generator()
    from generator import results_learners_cost as rc
    from twolink.studies.learners.plan import plan

    assert rc.study_time({"runs": []}).startswith("- not yet measured: the full study")
    seed0 = [p for p in plan() if p.seed == 0]
    steps = sum(p.steps for p in seed0)
    # every run costs 400 µs a step of CPU and takes 1.5 times its CPU in wall time
    runs = [{"id": p.id, "steps": p.steps, "cpu_s": 400e-6 * p.steps,
             "wall_s": 600e-6 * p.steps} for p in seed0]
    line = rc.study_time({"runs": runs})
    cpu_h = 400e-6 * steps / 3600
    assert line.startswith("- **missed**: the full study <= 8 h on this 2-core machine, "
                           f"one seed <= 2 h: a complete seed's runs took "
                           f"{1.5 * cpu_h:.1f} h (seed 0)")
    assert f"Seed 0's training used {cpu_h:.1f} CPU hours" in line
    assert f"at least {cpu_h / 2:.1f} h" in line
    assert f"asks for {3600e6 * 4 / steps:.0f} µs, less than the cheapest run" in line
    assert len(seed0) == 60 and "the issue's 35 runs" in line
    fast = [dict(r, cpu_s=r["cpu_s"] / 100, wall_s=r["wall_s"] / 100) for r in runs]
    assert rc.study_time({"runs": fast}).startswith("- met: the full study")
    assert "Cause" not in rc.study_time({"runs": fast})


def test_a_learning_target_picks_on_the_table_poses_and_judges_on_the_fresh(tmp_path,
                                                                            monkeypatch):
    """The learners page's copied N = 4 target: the study row and the lever run are each
    picked by their table score (the lever by its final curve point), and the target is
    met only by the fresh score of what was picked."""
    import json

    gen = _generator()
    from generator import results_learners as rl

    monkeypatch.setattr(gen.common, "ROOT", tmp_path)

    def row(learner, table, fresh):
        return {"links": 4, "rule": "copied", "algo": "mappo", "learner": learner,
                "seeds": [0], "cpu_us_per_step": 400.0,
                "table": {"successes": table, "n": 256}, "fresh": {"successes": fresh, "n": 256}}

    rows = [row("MAPPO (local)", 200, 150), row("MAPPO (neighbours)", 100, 220)]
    line = rl._targets(rows)[1]
    assert line.startswith("- **missed**: copied N = 4") and "MAPPO (local) 150/256" in line
    folder = tmp_path / rl.LEVERS
    folder.mkdir(parents=True)
    config = {"links": 4, "rule": "copied", "algo": "mappo"}
    for stem, last, fresh in (("a_4c_seed0", 50, 240), ("b_4c_seed0", 60, 200)):
        (folder / f"{stem}.json").write_text(json.dumps(
            {"config": config, "curve": [{"successes": last, "n": 64}]}))
        (folder / f"{stem}.fresh.json").write_text(json.dumps({"successes": fresh, "n": 256}))
    line = rl._targets(rows)[1]
    assert line.startswith("- **missed**") and "best of 2 lever run(s)" in line
    assert "`b_4c_seed0` 200/256" in line                  # picked by its curve, not 240
    assert "(its only seed)" in line
    (folder / "b_4c_seed1.json").write_text(json.dumps(
        {"config": config, "curve": [{"successes": 40, "n": 64}]}))
    (folder / "b_4c_seed1.fresh.json").write_text(json.dumps({"successes": 90, "n": 256}))
    assert "(the same recipe's other seeds: `b_4c_seed1` 90/256" in rl._targets(rows)[1]
    (folder / "b_4c_seed0.fresh.json").write_text(json.dumps({"successes": 232, "n": 256}))
    assert rl._targets(rows)[1].startswith("- met: copied N = 4")


def test_every_development_study_is_listed_with_its_help():
    """docs/studies/README.md names every script of docs/studies with its --help line."""
    text = (ROOT / "docs" / "studies" / "README.md").read_text()
    for path in sorted((ROOT / "docs" / "studies").glob("*.py")):
        assert f"| `{path.name}` |" in text, path.name
        assert f"`.venv/bin/python docs/studies/{path.name} --help`" in text, path.name
