"""The design options of the N-link decentralized agents: torque levels and bin layouts."""
import numpy as np
import pytest

from twolink.arm.parameters import links_parameters
from twolink.synthesis.links_decentralized import (
    LINKS_DEFAULT,
    PAPER_DESIGN,
    Design,
    agent_grid,
    agent_problem,
    design,
    synthesize_links,
    transition_bytes,
)


def test_levels_set_the_actions_and_the_neighbours_torque_axis():
    p = links_parameters(4)
    five = design(5)
    assert design() == PAPER_DESIGN == Design(3, "paper")
    # agent 3 reads tau4 on the neighbour's five levels; agent 4 acts on its own five
    axis = agent_grid(3, p, LINKS_DEFAULT, five).axes[-1]
    assert axis.name == "tau4"
    np.testing.assert_allclose(axis.centers, p.tau_max[3] * np.array([-1, -0.5, 0, 0.5, 1]))
    assert agent_grid(3, p, LINKS_DEFAULT).axes[-1].size == 3
    outer = agent_problem(4, p, LINKS_DEFAULT, design=five)
    np.testing.assert_allclose(outer.actions[:, 0],
                               p.tau_max[3] * np.array([-1, -0.5, 0, 0.5, 1]))
    assert outer.next_points.shape[:2] == (12 * 7, 5)
    # the memory estimate grows with the rows: 5/3 more actions, 5/3 more context bins
    assert transition_bytes(p, LINKS_DEFAULT, five) > 2.5 * transition_bytes(p, LINKS_DEFAULT)


def test_goal_bins_on_the_own_axes_only():
    g = agent_grid(2, links_parameters(3), LINKS_DEFAULT, design(bins="goal"))
    assert [a.size for a in g.axes] == [16, 13, 12, 9, 3]
    # the goal layout has bins at +-5 deg/s already: no extra +-6 deg/s bins on it
    assert not np.any(np.isclose(np.abs(np.rad2deg(g.axes[1].centers)), 6.0))


@pytest.mark.parametrize("options, message", [
    ({"levels": 1}, "levels must be a whole number from 2 to 9, got 1"),
    ({"levels": 12}, "levels must be a whole number from 2 to 9, got 12"),
    ({"levels": 2.5}, "levels must be a whole number"),
    ({"bins": "fine"}, "unknown bin layout 'fine'; choose one of paper, goal"),
])
def test_bad_design_options_are_refused_before_any_work(options, message):
    with pytest.raises(ValueError, match=message):
        synthesize_links(links_parameters(6), max_bytes=1, **options)   # the cap would refuse next


def test_the_default_design_leaves_the_meta_as_it_was():
    pol = synthesize_links(links_parameters(2).as_arm())
    assert "design" not in pol.meta
    pol = synthesize_links(links_parameters(2).as_arm(), levels=5)
    assert pol.meta["design"] == {"levels": 5, "bins": "paper"}
    assert [a.actions.shape[0] for a in pol.agents] == [5, 5]
