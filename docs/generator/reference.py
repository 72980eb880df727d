"""The CLI and API reference pages.

* :func:`cli_pages`: ``docs/reference/cli/index.md`` and one ``docs/reference/cli/NAME.md``
  per subcommand, from the argparse parsers of :func:`twolink.cli.build_parser`;
* :func:`api_pages`: ``docs/reference/api/STEM.md``, one page per layer of
  :data:`API_LAYERS`, the mkdocstrings ``:::`` directives of every public module
  (mkdocstrings renders the docstrings at build time).
"""
from __future__ import annotations

import argparse

from .common import _cell, ROOT, _stamp, _table


def _subparsers(parser) -> dict:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _args(action) -> str:
    """The metavar part of ``action`` as argparse's usage writes it."""
    if action.nargs == 0:
        return ""
    formatter = argparse.HelpFormatter("twolink")
    default = action.dest if not action.option_strings else action.dest.upper()
    return formatter._format_args(action, default)


def _visible(parser):
    return [a for a in parser._actions
            if a.help is not argparse.SUPPRESS and not isinstance(a, argparse._HelpAction)]


def _usage(prog: str, parser) -> str:
    words = [prog]
    for a in _visible(parser):
        if a.option_strings:
            flag = max(a.option_strings, key=len)
            word = f"{flag} {_args(a)}".strip()
            words.append(word if a.required else f"[{word}]")
    words += [_args(a) for a in _visible(parser) if not a.option_strings]
    return " ".join(words)


def _help(action, prog: str) -> str:
    text = action.help or ""
    if "%" in text:
        params = dict(vars(action), prog=prog)
        for name in list(params):
            if params[name] is argparse.SUPPRESS:
                del params[name]
        if params.get("choices") is not None:
            params["choices"] = ", ".join(str(c) for c in params["choices"])
        text = text % params
    return text


def _default(action) -> str:
    d = action.default
    if action.nargs == 0 or d in (None, argparse.SUPPRESS) or d == [] or d is False:
        return ""
    if isinstance(d, (list, tuple)):
        d = " ".join(str(x) for x in d)
    return f"`{d}`"


def _argument_rows(parser, prog: str):
    rows = []
    for a in _visible(parser):
        name = ", ".join(a.option_strings) if a.option_strings else a.metavar or a.dest
        metavar = _args(a) if a.option_strings else ""
        choices = ""
        if a.choices is not None and not isinstance(a.choices, dict):
            choices = " (one of: " + ", ".join(f"`{c}`" for c in a.choices) + ")"
        label = f"`{name}{' ' + metavar if metavar else ''}`"
        rows.append((label, _default(a), _cell(_help(a, prog)) + choices))
    return rows


def _grammar_section(parser) -> str:
    """The grammar every command follows (:data:`twolink.commands.grammar.RULES`) and the
    old spellings that still parse, with a warning, for one release."""
    from twolink.commands.grammar import DEPRECATED, RULES

    rows = [(f"`twolink {c}`", f"`{old}`", new.replace("(", "").replace(")", ""))
            for c, old, new in sorted(DEPRECATED)]
    return "".join(["## One grammar\n\n", "".join(f"- {r}\n" for r in RULES), "\n",
                    "Old spellings still parse for one release: each prints one warning "
                    "line naming its new spelling on stderr and then does what the new "
                    "spelling does.\n\n",
                    _table(("command", "old spelling", "use"), rows), "\n"])


def cli_pages() -> dict:
    from twolink.cli import build_parser
    from twolink.commands import SUMMARIES

    parser = build_parser()
    source = "the argparse parsers of twolink.cli.build_parser()"
    pages = {}
    rows = [(f"[`twolink {name}`]({name}.md)", _cell(SUMMARIES[name])) for name in SUMMARIES]
    pages["reference/cli/index.md"] = "".join([
        _stamp(source), "# Command-line reference\n\n",
        "One page per subcommand of `twolink`, written from its argparse parser, so each "
        "lists exactly the options `twolink COMMAND --help` prints.\n\n",
        "```text\nusage: twolink [--version] COMMAND [options]\n```\n\n",
        _table(("command", "what it does"), rows), "\n\n",
        "Every command has `--help`. Errors are one line (`twolink COMMAND: error: ...`) "
        "with exit status 2, and no output file is left half-written: every file is "
        "written atomically, also on Ctrl-C or SIGTERM.\n\n", _grammar_section(parser)])
    for name, sub in _subparsers(parser).items():
        prog = f"twolink {name}"
        text = [_stamp(source), f"# `twolink {name}`\n\n", SUMMARIES[name][:1].upper(),
                SUMMARIES[name][1:], ".\n\n"]
        if sub.description:
            text += [_cell(sub.description), "\n\n"]
        text += ["```text\n", _usage(prog, sub), "\n```\n\n"]
        text += [_table(("argument", "default", "description"),
                        _argument_rows(sub, prog)), "\n"]
        if sub.epilog:
            text += ["\n", _cell(sub.epilog), "\n"]
        pages[f"reference/cli/{name}.md"] = "".join(text)
    return pages


#: The API pages: (file stem, title, what the layer holds, its module prefixes).
API_LAYERS = (
    ("index", "twolink", "The top-level package: its shallow public API loads each module on "
     "first use.", None),
    ("arm", "twolink.arm", "Table I and the N-link rule, the dynamics (6)-(11), integration, "
     "the MJCF model, parameter files, the task.", "twolink.arm"),
    ("fqi", "twolink.fqi", "The fuzzy partition (12)-(13) and Alg. 1 (fixed-width and "
     "factored tables).", "twolink.fqi"),
    ("policy", "twolink.policy", "Policy (14), its file format and the shipped-policy "
     "registry.", "twolink.policy"),
    ("sim", "twolink.sim", "Plants, perturbations and challenges, the controller protocol, "
     "estimation, identification, rollouts, metrics and the one evaluation call.",
     "twolink.sim"),
    ("synthesis", "twolink.synthesis", "The makers of fuzzy policies: the two-link problems, "
     "N-link agents, synthesize(), online fuzzy Q-learning.", "twolink.synthesis"),
    ("limits", "twolink.limits", "The time-optimal limit T*(x) and the reach of N-link "
     "arms (CasADi/IPOPT), and the shipped table of T*.", "twolink.limits"),
    ("control", "twolink.control", "What acts: the controller resolver and catalogue, "
     "classical baselines, the N-link PD, the time-optimal MPC, learned agents.",
     "twolink.control"),
    ("envs", "twolink.envs", "The arm as dm_env, Gymnasium, PettingZoo (and "
     "Stable-Baselines3) environments.", "twolink.envs"),
    ("viz", "twolink.viz", "Rendering, videos, plots and formatting.", "twolink.viz"),
    ("studies", "twolink.studies", "The studies behind the reports: each measures (returns "
     "data) beside the module that presents it.", "twolink.studies"),
    ("training", "twolink.training", "Deep RL on the arm (`twolink train`): the run's "
     "config, training with evaluation and the learning curve, checkpoints that resume "
     "exactly.", "twolink.training"),
    ("base", "base modules", "What every layer uses: atomic writes and provenance, where "
     "files live, the GL backend, value checks.", ""),
)


def public_modules() -> list:
    """Every module of twolink whose dotted path has no part starting with ``_``, except
    the subcommands (the CLI reference documents those)."""
    out = []
    for path in sorted((ROOT / "twolink").rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        if any(p.startswith("_") for p in parts) or "commands" in parts or parts == ("twolink", "cli"):
            continue
        out.append(".".join(parts))
    return out


def _layer_of(module: str) -> str:
    for stem, _, _, prefix in API_LAYERS[1:-1]:
        if module == prefix or module.startswith(prefix + "."):
            return stem
    return "index" if module == "twolink" else "base"


def api_pages() -> dict:
    source = "the module list of the twolink package"
    modules = public_modules()
    pages = {}
    for stem, title, about, _ in API_LAYERS:
        mine = [m for m in modules if _layer_of(m) == stem]
        text = [_stamp(source), f"# {title}\n\n", about, "\n\n"]
        if stem == "index":
            text += ["The layers, highest first, are `commands` (the CLI), `studies` and `training`, "
                     "`envs`, `viz` and `control`, `synthesis` and `limits`, `sim`, `policy`, `fqi`, "
                     "`arm` and the base "
                     "modules; a module imports only from its own layer or those below it "
                     "(see [Contributing](../../contributing.md#the-import-layer-contract)).\n\n"]
            text += ["| layer | |\n|---|---|\n"] + [
                f"| [{t}]({s}.md) | {a} |\n" for s, t, a, _ in API_LAYERS[1:]] + ["\n"]
        for m in mine:
            text += [f"::: {m}\n\n"]
        pages[f"reference/api/{stem}.md"] = "".join(text)
    return pages
