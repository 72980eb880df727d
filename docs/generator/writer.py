"""What docs/generate.py does with it all: :func:`outputs` (every file it writes, blocks
filled in by :func:`fill`), :func:`stale` and :func:`obsolete` (what differs from the
committed files) and :func:`main` (write them, or ``--check``). Pages are written whole:
a temporary file renamed onto each.
"""
from __future__ import annotations

import argparse
import re
import sys

from . import common
from .blocks import blocks
from .common import DataError, STAMP
from .reference import api_pages, cli_pages
from .results import result_pages


def _marker(path: str, kind: str, name: str) -> str:
    if path.endswith((".yml", ".yaml")):
        return f"# {kind} generated: {name} (docs/generate.py)"
    return f"<!-- {kind} generated: {name} (docs/generate.py) -->"


def fill(path: str, text: str, contents: dict) -> str:
    """``text`` with each generated block of ``contents`` replaced; a ValueError when a
    block's markers are missing."""
    for name, body in contents.items():
        begin, end = _marker(path, "BEGIN", name), _marker(path, "END", name)
        pattern = re.compile(rf"(^[ \t]*{re.escape(begin)}\n).*?(^[ \t]*{re.escape(end)}$)",
                             re.S | re.M)
        if not pattern.search(text):
            raise ValueError(f"{path} has no block {name!r} (lines {begin!r} ... {end!r})")
        text = pattern.sub(lambda m: m.group(1) + body + "\n" + m.group(2), text, count=1)
    return text


def outputs() -> dict:
    """``{path relative to the repository: content}`` of every file this script writes."""
    pages = {**cli_pages(), **api_pages(), **result_pages()}
    out = {f"docs/{page}": text for page, text in pages.items()}
    for rel, contents in blocks(pages).items():
        out[rel] = fill(rel, (common.ROOT / rel).read_text(), contents)
    return out


def obsolete(out: dict) -> list:
    """Generated pages on disk that the generator no longer writes (to delete)."""
    root = common.ROOT
    return sorted(str(p.relative_to(root)) for p in common.DOCS.rglob("*.md")
                  if p.read_text().startswith(STAMP) and str(p.relative_to(root)) not in out)


def stale(out: dict | None = None) -> list:
    """The files whose committed content differs from what this script writes."""
    out = outputs() if out is None else out
    root = common.ROOT
    return sorted(rel for rel, text in out.items()
                  if not (root / rel).is_file() or (root / rel).read_text() != text) + obsolete(out)


def main(argv=None, description: str | None = None) -> int:
    """Write the generated files (``--check``: write nothing, exit 1 naming the stale
    ones); exit status 2 on a DataError. ``description`` is the ``--help`` line."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--check", action="store_true",
                   help="write nothing; exit 1 naming the files that are out of date")
    args = p.parse_args(argv)
    try:
        out = outputs()
    except DataError as exc:
        print(f"docs/generate.py: error: {exc}", file=sys.stderr)
        return 2
    bad = stale(out)
    if args.check:
        for rel in bad:
            print(f"out of date: {rel} (run: python docs/generate.py)", file=sys.stderr)
        return 1 if bad else 0
    for rel in obsolete(out):
        (common.ROOT / rel).unlink()
        print(f"removed {rel}")
    for rel, text in out.items():
        path = common.ROOT / rel
        if not path.is_file() or path.read_text() != text:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_name(f".{path.name}.tmp")      # never half a page: rename whole
            tmp.write_text(text)
            tmp.replace(path)
            print(f"wrote {rel}")
    return 0
