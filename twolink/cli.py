"""The ``twolink`` command line: one subcommand per module in ``twolink.commands``.

Only the subcommand named on the command line is imported (with its numpy, mujoco or
matplotlib); ``twolink --help`` lists the summaries of :data:`twolink.commands.SUMMARIES`
without importing any of them.
"""
from __future__ import annotations

import argparse
import importlib
import sys
import zipfile

from twolink.artifacts import VERSION
from twolink.commands import SUMMARIES

#: Subcommand modules, in the order ``--help`` lists them.
COMMANDS = tuple(SUMMARIES)


def build_parser(only: str | None = "all") -> argparse.ArgumentParser:
    """The parser with every subcommand's full parser (``only="all"``), or with the full
    parser of ``only`` and one-line entries for the others (``only=None``: none)."""
    parser = argparse.ArgumentParser(
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
    args, unknown = parser.parse_known_args(argv)
    if unknown:                  # named by the subcommand's parser, with its own usage
        getattr(args, "_parser", parser).error(f"unrecognized arguments: {' '.join(unknown)}")
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
