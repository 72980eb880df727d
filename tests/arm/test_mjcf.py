"""The MJCF arm against (7)-(8) and Table I."""
import mujoco
import numpy as np
import pytest

from twolink.arm import dynamics, mjcf
from twolink.arm.parameters import TABLE_I, TS
from twolink.resources import model_file


@pytest.fixture(scope="module")
def model():
    return mjcf.build_model()


def test_committed_xml_equals_generated():
    assert model_file().read_text() == mjcf.model_xml(TABLE_I)


def test_committed_xml_loads_with_table_i(model):
    m = mujoco.MjModel.from_xml_path(str(model_file()))
    np.testing.assert_allclose(m.body_mass[1:], [TABLE_I.m1, TABLE_I.m2])
    np.testing.assert_allclose(m.dof_damping, [TABLE_I.b1, TABLE_I.b2])
    np.testing.assert_allclose(m.actuator_ctrlrange, [[-0.2, 0.2], [-0.1, 0.1]])
    np.testing.assert_allclose(m.body_ipos[1:, 0], [TABLE_I.c1, TABLE_I.c2])
    np.testing.assert_allclose(m.body_inertia[1:, 2], [TABLE_I.I1, TABLE_I.I2])
    assert m.opt.timestep * round(TS / m.opt.timestep) == pytest.approx(TS)


@pytest.mark.parametrize("params", [TABLE_I, TABLE_I.scaled(m2=1.3, l1=0.8, I1=1.5)])
def test_mass_matrix_and_bias_forces_match_eqs_7_8(params, rng):
    m = mjcf.build_model(params)
    d = mujoco.MjData(m)
    full = np.zeros((2, 2))
    for x in rng.uniform(-np.pi, np.pi, (200, 4)) * [1, 1, 2, 2]:
        d.qpos[:] = x[:2]
        d.qvel[:] = x[2:]
        mujoco.mj_forward(m, d)
        mujoco.mj_fullM(m, d, full)
        np.testing.assert_allclose(full, dynamics.mass_matrix(params, x[1]), rtol=0, atol=1e-15)
        np.testing.assert_allclose(d.qfrc_bias, dynamics.coriolis_forces(params, x),
                                   rtol=0, atol=1e-14)
        np.testing.assert_allclose(d.qfrc_passive, -np.array([params.b1, params.b2]) * x[2:],
                                   rtol=0, atol=1e-15)


def test_motors_saturate_at_tau_max(model):
    d = mujoco.MjData(model)
    d.ctrl[:] = [5.0, -5.0]
    mujoco.mj_forward(model, d)
    np.testing.assert_allclose(d.actuator_force, [0.2, -0.1])


@pytest.mark.parametrize("links, rule, name", [(3, "tapered", "twolink_3link.xml"),
                                               (5, "copied", "twolink_5link_copied.xml")])
def test_mjcf_command_writes_the_n_link_arm(tmp_path, capsys, links, rule, name):
    import mujoco

    from twolink.arm.parameters import links_parameters
    from twolink.cli import main

    assert main(["mjcf", "--links", str(links), "--rule", rule, "-o", f"{tmp_path}/"]) == 0
    path = tmp_path / name
    assert path.read_text() == mjcf.model_xml(links_parameters(links, rule))
    model = mujoco.MjModel.from_xml_path(str(path))
    assert model.nq == links and model.nu == links
    assert np.allclose(model.body_mass[1:], links_parameters(links, rule).masses)


def test_mjcf_command_refuses_links_it_cannot_build_or_ship(tmp_path, capsys):
    from twolink.cli import main

    for argv, message in ((["--links", "7"], "--links must be a whole number from 2 to 6"),
                          (["--links", "3", "--ship"], "--ship writes the committed two-link")):
        assert main(["mjcf", *argv, *([] if "--ship" in argv else ["-o", f"{tmp_path}/"])]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and message in err
    assert list(tmp_path.iterdir()) == []
