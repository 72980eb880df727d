"""The ``twolink`` command line: one subcommand per module in ``twolink.commands``.

Only the subcommand named on the command line is imported (with its numpy, mujoco or
matplotlib); ``twolink --help`` lists the summaries of :data:`twolink.commands.SUMMARIES`
without importing any of them.
"""
from __future__ import annotations

import argparse
import difflib
import importlib
import sys
import zipfile

from twolink.artifacts import VERSION
from twolink.commands import SUMMARIES

#: Subcommand modules, in the order ``--help`` lists them.
COMMANDS = tuple(SUMMARIES)


class UsageError(Exception):
    """A command line argparse refuses: ``parser`` is the (sub)command's parser."""

    def __init__(self, parser: argparse.ArgumentParser, message: str):
        super().__init__(message)
        self.parser = parser


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are raised as :class:`UsageError` instead of
    printing the usage block and exiting; :func:`main` prints them as one line. The
    subcommands' parsers are of this class too (``add_subparsers`` takes the parent's)."""

    def error(self, message: str):
        raise UsageError(self, message)


def unknown_options(parser: argparse.ArgumentParser, words) -> list:
    """The words of ``words`` (a subcommand's arguments) that look like options but
    that ``parser`` does not know, nor abbreviates uniquely; ``--`` ends the options."""
    unknown = []
    for word in words:
        if word == "--":
            break
        if not word.startswith("-") or word == "-" \
                or parser._negative_number_matcher.match(word):
            continue
        name = word.split("=", 1)[0]
        known = parser._option_string_actions
        if name in known or (name.startswith("--") and len(
                {known[o] for o in known if o.startswith(name)}) == 1):
            continue
        unknown.append(name)
    return unknown


def usage_line(parser: argparse.ArgumentParser, message: str, words=()) -> str:
    """The one line of a refused command line: the unknown options among ``words``
    (one with the closest known option as "did you mean"), if any, else argparse's
    ``message``; either points to the command's ``--help``."""
    unknown = unknown_options(parser, words)
    if len(unknown) == 1:
        close = difflib.get_close_matches(unknown[0][2:], [
            o[2:] for o in parser._option_string_actions if o.startswith("--")],
            n=1, cutoff=0.75)
        message = f"unknown option {unknown[0]}" + (
            f" (did you mean --{close[0]}?)" if close else "")
    elif unknown:
        message = f"unknown options {', '.join(unknown)}"
    return f"{parser.prog}: error: {message} (see {parser.prog} --help)"


def build_parser(only: str | None = "all") -> argparse.ArgumentParser:
    """The parser with every subcommand's full parser (``only="all"``), or with the full
    parser of ``only`` and one-line entries for the others (``only=None``: none). Its
    errors raise :class:`UsageError` (:class:`Parser`)."""
    parser = Parser(
        prog="twolink",
        description="Centralized vs decentralized fuzzy Q-iteration control of a two-link "
                    "arm (Busoniu, De Schutter & Babuska, ICARCV 2006) on MuJoCo.")
    parser.add_argument("--version", action="version", version=f"twolink {VERSION}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMANDS:
        if only in ("all", name):
            module = importlib.import_module(f"twolink.commands.{name}")
            p = module.add_parser(sub)
            p.set_defaults(_run=module.run, _parser=p)
        else:
            sub.add_parser(name, help=SUMMARIES[name])
    return parser


def _command(argv) -> str | None:
    """The subcommand ``argv`` names: its first word that is not an option."""
    for word in argv:
        if not word.startswith("-"):
            return word if word in SUMMARIES else None
    return None


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        parser = build_parser(_command(argv))
    except ImportError as exc:   # a broken installation: one line, not a traceback
        print(f"twolink: error: cannot load the commands ({exc})", file=sys.stderr)
        return 2
    try:
        args, unknown = parser.parse_known_args(argv)
        if unknown:              # named by the subcommand's parser
            getattr(args, "_parser", parser).error(
                f"unexpected argument{'s' if len(unknown) > 1 else ''} "
                f"{' '.join(map(repr, unknown))}")
    except UsageError as exc:    # one line, exit 2 (argparse's own status)
        words = argv[argv.index(_command(argv)) + 1:] if exc.parser is not parser else argv
        print(usage_line(exc.parser, str(exc), words), file=sys.stderr)
        raise SystemExit(2) from None
    from twolink.artifacts import Terminated, signal_received, sigterm_raises

    try:
        with sigterm_raises():       # SIGTERM unwinds like Ctrl-C: temporary files go
            return int(args._run(args) or 0)
    except Terminated:
        return _signalled("SIGTERM")
    except KeyboardInterrupt:
        return _signalled("SIGINT")
    except Exception as exc:
        if signal_received():        # a signal's exception, wrapped by a foreign call
            return _signalled(signal_received())
        if not isinstance(exc, (ValueError, OSError, RuntimeError, zipfile.BadZipFile)):
            raise
        print(f"twolink {args.command}: error: {exc}", file=sys.stderr)
        return 2


def _signalled(name: str) -> int:
    """The line and exit status (128 + the signal's number, as a shell reports it) of a
    command ended by SIGTERM or Ctrl-C."""
    if name == "SIGTERM":
        print("twolink: terminated", file=sys.stderr)
        return 143
    print("twolink: interrupted", file=sys.stderr)
    return 130

if __name__ == "__main__":
    sys.exit(main())
