"""The N-link rule (twolink.arm.parameters.links_parameters) and the N-link MJCF built from it."""
import dataclasses
import math

import mujoco
import numpy as np
import pytest

from twolink.arm import mjcf
from twolink.arm.parameters import (
    LINK_RULES,
    MAX_LINKS,
    MIN_LINKS,
    TABLE_I,
    TAPER,
    ArmParameters,
    LinksParameters,
    as_links,
    check_links,
    links_parameters,
    state_names,
)
from twolink.resources import model_file


@pytest.mark.parametrize("rule", LINK_RULES)
def test_two_links_are_table_i_exactly(rule):
    c = links_parameters(2, rule)
    assert c.as_arm() == TABLE_I
    assert as_links(TABLE_I) == dataclasses.replace(c, rule="tapered")
    assert c.lengths == (0.1, 0.1) and c.masses == (1.25, 1.0)
    assert c.inertias == (0.004, 0.003) and c.dampings == (0.1, 0.02)
    np.testing.assert_array_equal(c.tau_max, TABLE_I.tau_max)
    np.testing.assert_array_equal(c.speed_max, TABLE_I.speed_max)


def test_round_trips():
    scaled = TABLE_I.scaled(m2=1.3, l1=0.8)
    assert as_links(scaled).as_arm() == scaled
    for n in range(MIN_LINKS, MAX_LINKS + 1):
        for rule in LINK_RULES:
            c = links_parameters(n, rule)
            assert LinksParameters.from_dict(c.as_dict()) == c
            assert c.as_dict()["links"] == n


def test_tapered_rule_halves_mass_inertia_and_torque():
    c = links_parameters(4, "tapered")
    assert TAPER == 0.5
    assert c.masses == (1.25, 1.0, 0.5, 0.25)
    assert c.inertias == (0.004, 0.003, 0.0015, 0.00075)
    assert c.torque_limits == (0.2, 0.1, 0.05, 0.025)
    assert c.lengths == (0.1,) * 4 and c.coms == (0.05,) * 4
    assert c.dampings == (0.1, 0.02, 0.02, 0.02)
    assert c.speed_limits == (2 * math.pi,) * 4


def test_copied_rule_repeats_link_two():
    c = links_parameters(5, "copied")
    assert c.masses == (1.25,) + (1.0,) * 4
    assert c.inertias == (0.004,) + (0.003,) * 4
    assert c.torque_limits == (0.2,) + (0.1,) * 4
    assert c.dampings == (0.1,) + (0.02,) * 4


def test_state_names():
    assert state_names(2) == ("theta1", "theta2", "dtheta1", "dtheta2")
    assert state_names(3) == ("theta1", "theta2", "theta3", "dtheta1", "dtheta2", "dtheta3")


@pytest.mark.parametrize("bad", [1, 7, 0, -2, 2.5, 3.0, True, "3", None])
def test_check_links_refuses(bad):
    with pytest.raises(ValueError, match="links must be a whole number from 2 to 6"):
        check_links(bad)


def test_links_refusals():
    with pytest.raises(ValueError, match="unknown link rule 'bent'"):
        links_parameters(3, "bent")
    with pytest.raises(ValueError, match="links must be a whole number"):
        links_parameters(7)
    with pytest.raises(ValueError, match="masses of link 2 must be positive and finite"):
        dataclasses.replace(links_parameters(3), masses=(1.0, float("nan"), 1.0))
    with pytest.raises(ValueError, match="inertias needs 3 values"):
        dataclasses.replace(links_parameters(3), inertias=(1.0, 1.0))
    with pytest.raises(ValueError, match="a 3-link arm has no two-link ArmParameters"):
        links_parameters(3).as_arm()
    with pytest.raises(ValueError, match="links says 4 but the parameters describe 3"):
        LinksParameters.from_dict(dict(links_parameters(3).as_dict(), links=4))
    assert isinstance(links_parameters(2).as_arm(), ArmParameters)


def test_two_links_give_the_committed_model():
    assert mjcf.model_xml(links_parameters(2)) == model_file().read_text()
    assert mjcf.model_xml(links_parameters(2, "copied")) == mjcf.model_xml(TABLE_I)


@pytest.mark.parametrize("rule", LINK_RULES)
@pytest.mark.parametrize("n", range(MIN_LINKS, MAX_LINKS + 1))
def test_n_link_model(n, rule):
    c = links_parameters(n, rule)
    m = mjcf.build_model(c)
    assert (m.nq, m.nv, m.nu, m.nbody) == (n, n, n, n + 1)
    assert tuple(m.joint(k).name for k in range(n)) == mjcf.joint_names(n)
    assert mjcf.joint_names(n)[:2] == ("shoulder", "elbow")
    assert tuple(m.body(k + 1).name for k in range(n)) == mjcf.link_names(n)
    assert tuple(m.actuator(k).name for k in range(n)) == tuple(f"tau{k}" for k in range(1, n + 1))
    np.testing.assert_array_equal(m.actuator_ctrlrange, np.stack([-c.tau_max, c.tau_max], 1))
    np.testing.assert_array_equal(m.body_mass[1:], c.masses)
    np.testing.assert_array_equal(m.body_inertia[1:, 2], c.inertias)
    np.testing.assert_array_equal(m.body_ipos[1:, 0], c.coms)
    np.testing.assert_array_equal(m.body_pos[2:, 0], c.lengths[:-1])
    np.testing.assert_array_equal(m.dof_damping, c.dampings)
    assert np.all(m.jnt_axis == [0, 0, 1])
    # Each link's tip site sits at its length along the link.
    np.testing.assert_array_equal(
        [m.site(f"link{k + 1}_tip").pos[0] for k in range(n)], c.lengths)
    # Horizontal arm: gravity exerts no joint torque at rest.
    d = mujoco.MjData(m)
    d.qpos[:] = np.linspace(-2.0, 2.5, n)
    mujoco.mj_forward(m, d)
    np.testing.assert_allclose(d.qfrc_bias, 0.0, atol=1e-15)
