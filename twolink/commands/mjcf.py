"""``twolink mjcf``: regenerate models/twolink.xml from Table I."""
from __future__ import annotations

from pathlib import Path

from twolink import mjcf


def add_parser(sub):
    p = sub.add_parser("mjcf", help="write the MJCF model generated from Table I",
                       description="Generate the MJCF model of the arm from Table I (MjSpec) "
                                   "and write it (default: models/twolink.xml).")
    p.add_argument("-o", "--output", type=Path, default=mjcf.MODEL_PATH)
    return p


def run(args) -> int:
    print(f"wrote {mjcf.write_model(args.output)}")
    return 0
