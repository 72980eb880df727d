"""The shipped learned agents as catalogue entries: kind, links and rule from
``twolink.control.learned.LEARNED``, each loadable by name, an N-link agent scored by
``twolink evaluate NAME --links N`` and refused on another arm."""
import json

import pytest

from twolink.cli import main
from twolink.control.catalogue import catalogue
from twolink.control.learned import LEARNED

pytest.importorskip("stable_baselines3")


def test_every_learned_entry_is_in_the_catalogue_as_registered():
    entries = catalogue()
    for name, a in LEARNED.items():
        e = entries[name]
        assert (e.kind, e.links, e.rule) == (a.kind, a.links, a.rule)
        assert "learned" in e.tags and ("n-link" in e.tags) == (a.links > 2)


def test_the_six_link_agent_is_scored_by_name_and_refused_on_two_links(capsys):
    assert main(["evaluate", "ppo_pd_6link_tapered", "--links", "6", "--poses", "4",
                 "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert (got["controller"], got["links"], got["rule"], got["n"]) == (
        "ppo_pd_6link_tapered", 6, "tapered", 4)
    assert main(["evaluate", "ppo_pd_6link_tapered", "--links", "2"]) == 2
    assert "controls an arm of 6 links" in capsys.readouterr().err


def test_the_multi_agent_entry_loads_with_its_history():
    from twolink.control.learned import learned_agent

    agent = learned_agent("mappo_medium")
    assert agent.name == "mappo_medium"
    assert (agent.meta["algo"], agent.meta["observe"], agent.meta["history"],
            agent.meta["challenge"]) == ("mappo", "global", 3, "medium")
