"""The ``twolink`` command line: one subcommand per module in ``twolink.commands``."""
from __future__ import annotations

import argparse
import importlib
import sys
import zipfile

from twolink import __version__

#: Subcommand modules, in the order ``--help`` lists them. Each defines
#: ``add_parser(subparsers)`` (returning its parser) and ``run(args) -> int``.
COMMANDS = ("reproduce", "synthesize", "mjcf", "rollout", "render", "mismatch", "learn",
            "identify", "scaling")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="twolink",
        description="Centralized vs decentralized fuzzy Q-iteration control of a two-link "
                    "arm (Busoniu, De Schutter & Babuska, ICARCV 2006) on MuJoCo.")
    parser.add_argument("--version", action="version", version=f"twolink {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMANDS:
        module = importlib.import_module(f"twolink.commands.{name}")
        p = module.add_parser(sub)
        p.set_defaults(_run=module.run)
    return parser


def main(argv=None) -> int:
    try:
        parser = build_parser()
    except ImportError as exc:   # a broken installation: one line, not a traceback
        print(f"twolink: error: cannot load the commands ({exc})", file=sys.stderr)
        return 2
    args = parser.parse_args(argv)
    from twolink.artifacts import Terminated, sigterm_raises

    try:
        with sigterm_raises():       # SIGTERM unwinds like Ctrl-C: temporary files go
            return int(args._run(args) or 0)
    except Terminated:
        print("twolink: terminated", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print("twolink: interrupted", file=sys.stderr)
        return 130
    except (ValueError, OSError, RuntimeError, zipfile.BadZipFile) as exc:
        print(f"twolink {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
