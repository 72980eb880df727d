"""One command-line grammar for every subcommand, and the old spellings it replaced.

The rules (the CLI reference states them, from :data:`RULES`):

* ``-o/--out`` names what a command writes: a file where it writes one file, a folder
  where it writes a set of files.
* ``--quick`` is the one spelling of a command's quick mode.
* An option in degrees ends in ``-deg``; every other quantity is in SI units (rad, rad/s,
  s, N m) and its name carries no unit.
* ``--controller NAME`` is repeatable wherever a command takes controllers.
* ``--json`` prints the result as JSON; ``--seed`` is a non-negative whole number.

An old spelling still parses for one release: :func:`deprecated` adds it hidden from
``--help``; using it prints one warning line on stderr naming the new spelling and then
acts exactly as the new spelling would (:data:`DEPRECATED` lists them all).
"""
from __future__ import annotations

import argparse
import sys

#: The grammar, one rule a line (the CLI reference prints them).
RULES = (
    "`-o/--out` names what a command writes: a file where it writes one file, a folder "
    "where it writes a set of files.",
    "`--quick` is the one spelling of a quick mode.",
    "An option in degrees ends in `-deg`; every other quantity is in SI units (rad, rad/s, "
    "s, N m) and its name carries no unit.",
    "`--controller NAME` is repeatable wherever a command takes controllers.",
    "`--json` prints the result as JSON; `--seed` takes a non-negative whole number.",
)
#: Every old spelling: (command, old, new). Each parses, with a warning, for one release.
DEPRECATED = []


class _Deprecated(argparse.Action):
    """An old spelling: warns on stderr, then stores ``value`` (or ``const``) in ``dest``."""

    def __init__(self, option_strings, dest, *, new: str, command: str, value=None,
                 **kwargs):
        self.new, self.command, self.value = new, command, value
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"twolink {self.command}: warning: {option_string} is deprecated and goes in "
              f"the next release; use {self.new}", file=sys.stderr)
        if self.value is not None:
            values = self.value(values) if callable(self.value) else self.value
        elif self.nargs == 0:
            values = self.const
        setattr(namespace, self.dest, values)


def deprecated(p, command: str, old: str, new: str, *, dest: str, nargs=None, const=None,
               type=None, choices=None, value=None) -> None:
    """Add the old spelling ``old`` of ``new`` to ``p`` (hidden from --help), storing into
    ``dest``; ``value`` (a constant or a function of the parsed value) replaces what is
    stored, as the new spelling would store it."""
    kwargs = {"nargs": 0, "const": const} if nargs == 0 else {"nargs": nargs}
    if type is not None:
        kwargs["type"] = type
    if choices is not None:
        kwargs["choices"] = choices
    p.add_argument(old, dest=dest, action=_Deprecated, new=new, command=command,
                   value=value, help=argparse.SUPPRESS, **kwargs)
    if (command, old, new) not in DEPRECATED:
        DEPRECATED.append((command, old, new))


def add_out(p, command: str, *, dest: str = "output", old: str | None = "--output",
            **kwargs) -> None:
    """``-o/--out`` into ``dest`` (a file or a folder, as ``help`` says), and its old
    spelling ``old`` (``--output``; None: none)."""
    p.add_argument("-o", "--out", dest=dest, **kwargs)
    if old:
        deprecated(p, command, old, "-o/--out", dest=dest, type=kwargs.get("type"))
