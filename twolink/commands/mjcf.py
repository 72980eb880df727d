"""``twolink mjcf``: write the MJCF model generated from Table I."""
from __future__ import annotations

from twolink.arm import mjcf
from twolink.artifacts import check_outputs, make_folders, output_file
from twolink.commands import SUMMARIES
from twolink.resources import MODEL_FILE, model_file, source_checkout


def add_parser(sub):
    p = sub.add_parser("mjcf", help=SUMMARIES["mjcf"],
                       description="Generate the MJCF model of the arm from Table I (MjSpec) "
                                   f"and write it (default: ./{MODEL_FILE}; --ship replaces "
                                   "the committed models/twolink.xml of a source checkout).")
    where = p.add_mutually_exclusive_group()
    where.add_argument("-o", "--output", default=None,
                       help=f"file to write (default ./{MODEL_FILE}; DIR/ writes "
                            f"DIR/{MODEL_FILE}, making DIR)")
    where.add_argument("--ship", action="store_true",
                       help="overwrite the committed models/twolink.xml (source checkouts only)")
    return p


def run(args) -> int:
    if args.ship:
        if source_checkout() is None:
            raise OSError("--ship writes models/twolink.xml of a source checkout, but twolink "
                          "runs from an installed package; use -o FILE")
        out, folders = model_file(), []
    else:
        out, folders = output_file(args.output, MODEL_FILE)
    check_outputs({"-o": out}, creatable=folders, ship=args.ship)
    make_folders(folders)
    print(f"wrote {mjcf.write_model(out)}")
    return 0
