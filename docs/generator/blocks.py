"""Every generated block inside a hand-written file: :func:`blocks` maps each file to its
blocks (README.md, docs/index.md, the guides, the agents concept page, the nav of
mkdocs.yml); the command list (:func:`commands_table`) and the challenge table
(:func:`challenges_table`) are written here.
"""
from __future__ import annotations

from .blocks_agents import context_readings, context_sweeps
from .blocks_guides import (baselines_table, centralized_3link_block, compensation_table,
                            leaderboard_headline, link_mismatch_table, policies_table,
                            ranking_rule, sb3_agent_summary, tables_table)
from .blocks_mismatch import mismatch_findings
from .common import _cell, _table
from .nav import nav_blocks
from .results_handover import handovers_fresh_table


def commands_table(link_prefix: str) -> str:
    from twolink.commands import SUMMARIES

    return _table(("command", "what it does"),
                  [(f"[`twolink {n}`]({link_prefix}reference/cli/{n}.md)", _cell(s))
                   for n, s in SUMMARIES.items()])


def challenges_table() -> str:
    from twolink.sim.challenges import markdown_table
    return markdown_table().strip()


def blocks(pages: dict) -> dict:
    """``{file: {block name: content}}`` of the generated blocks in hand-written files."""
    return {
        "README.md": {"commands": commands_table("docs/"),
                      "policies": policies_table(tuned=False),
                      "leaderboard": leaderboard_headline()},
        "docs/index.md": {"commands": commands_table("")},
        "docs/guides/synthesis.md": {"policies": policies_table(), "tables": tables_table(),
                                     "handovers-fresh": handovers_fresh_table()},
        "docs/guides/compensation.md": {"compensation": compensation_table()},
        "docs/guides/controllers.md": {"baselines": baselines_table()},
        "docs/guides/leaderboard.md": {"ranking": ranking_rule()},
        "docs/guides/stable-baselines3.md": {"agent": sb3_agent_summary()},
        "docs/guides/n-links.md": {"centralized-3link": centralized_3link_block(),
                                   "mismatch-3link": link_mismatch_table()},
        "docs/guides/challenges.md": {"challenges": challenges_table()},
        "docs/guides/mismatch.md": {"findings": mismatch_findings()},
        "docs/concepts/agents.md": {"contexts": context_readings(),
                                    "context-sweeps": context_sweeps()},
        "mkdocs.yml": nav_blocks(pages),
    }
