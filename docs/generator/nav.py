"""The generated parts of the ``nav`` of mkdocs.yml (:func:`nav_blocks`): the results pages,
the CLI reference and the API reference.
"""
from __future__ import annotations

from .reference import API_LAYERS
from .results import RESULTS


def _nav(entries, indent: str) -> str:
    return "\n".join(f"{indent}- {title}: {page}" for title, page in entries)


def nav_blocks(pages: dict) -> dict:
    from twolink.commands import SUMMARIES

    results = [(title, page) for page, title, _, _ in RESULTS if page in pages]
    cli = [("Overview", "reference/cli/index.md")] + [
        (f"twolink {n}", f"reference/cli/{n}.md") for n in SUMMARIES
        if f"reference/cli/{n}.md" in pages]
    api = [(title, f"reference/api/{stem}.md") for stem, title, _, _ in API_LAYERS]
    return {"nav-results": _nav(results, "      "), "nav-cli": _nav(cli, "          "),
            "nav-api": _nav(api, "          ")}
