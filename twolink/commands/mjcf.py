"""``twolink mjcf``: write the MJCF model generated from Table I (``--links N``: the N-link
arm that extends it, :func:`twolink.arm.parameters.links_parameters`)."""
from __future__ import annotations

from twolink.arm import mjcf
from twolink.artifacts import check_outputs, make_folders, output_file
from twolink.commands import SUMMARIES
from twolink.commands.grammar import deprecated
from twolink.commands._options import add_arm_options, arm_of
from twolink.resources import MODEL_FILE, model_file, source_checkout


def default_name(links: int = 2, rule: str = "tapered") -> str:
    """``twolink.xml`` for two links, else ``twolink_<N>link[_<rule>].xml`` (the rule when
    not tapered)."""
    if links == 2:
        return MODEL_FILE
    return f"twolink_{links}link" + ("" if rule == "tapered" else f"_{rule}") + ".xml"


def add_parser(sub):
    p = sub.add_parser("mjcf", help=SUMMARIES["mjcf"],
                       description="Generate the MJCF model of the arm from Table I (MjSpec) "
                                   f"and write it (default: ./{MODEL_FILE}, or "
                                   "./twolink_<N>link[_<rule>].xml with --links N; --ship "
                                   "replaces the committed models/twolink.xml of a source "
                                   "checkout).")
    where = p.add_mutually_exclusive_group()
    where.add_argument("-o", "--out", dest="output", default=None, metavar="FILE",
                       help=f"file to write (default ./{MODEL_FILE}, with --links N "
                            f"./twolink_<N>link[_<rule>].xml; DIR/ writes that name in DIR, "
                            f"making DIR)")
    where.add_argument("--ship", action="store_true",
                       help="overwrite the committed models/twolink.xml (source checkouts only)")
    deprecated(p, "mjcf", "--output", "-o/--out", dest="output")
    add_arm_options(p)
    return p


def run(args) -> int:
    links, params = arm_of(args)
    if args.ship:
        if links != 2:
            raise ValueError(f"--ship writes the committed two-link models/twolink.xml; drop "
                             f"--links {links} (or write the {links}-link model with -o)")
        if source_checkout() is None:
            raise OSError("--ship writes models/twolink.xml of a source checkout, but twolink "
                          "runs from an installed package; use -o FILE")
        out, folders = model_file(), []
    else:
        out, folders = output_file(args.output, default_name(links, args.rule))
    check_outputs({"-o": out}, creatable=folders, ship=args.ship)
    make_folders(folders)
    print(f"wrote {mjcf.write_model(out, params)}")
    return 0
