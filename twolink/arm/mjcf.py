"""The MJCF model of the horizontal arm, generated from Table I with MjSpec.

``models/twolink.xml`` is written by :func:`write_model` (``twolink mjcf``) and a test
checks it equals the generated XML, so the committed file cannot drift from Table I.
Joints turn about the vertical z axis, so gravity (along -z) exerts no joint torque:
G(theta) = 0 as for the paper's horizontal arm.
"""
from __future__ import annotations

import os
from pathlib import Path

import mujoco

from twolink.arm.integrate import SUBSTEPS
from twolink.arm.parameters import TABLE_I, TS, ArmParameters, LinksParameters, as_links
from twolink.artifacts import write_text


def joint_names(links: int = 2) -> tuple:
    """The joints of an arm of ``links`` links: shoulder, elbow, then joint3, joint4, ..."""
    return ("shoulder", "elbow") + tuple(f"joint{k}" for k in range(3, links + 1))


def link_names(links: int = 2) -> tuple:
    """The bodies of an arm of ``links`` links: link1 ... linkN."""
    return tuple(f"link{k}" for k in range(1, links + 1))


#: The joints and links of the paper's two-link arm (the committed model file).
JOINTS = joint_names(2)
LINKS = link_names(2)

_LINK_RADIUS = 0.008
#: Link colours, link 1 first (orange, blue, then green, purple, red, teal).
_RGBA_LINKS = ((0.85, 0.45, 0.1, 1.0), (0.15, 0.45, 0.85, 1.0), (0.2, 0.65, 0.3, 1.0),
               (0.55, 0.3, 0.75, 1.0), (0.8, 0.2, 0.25, 1.0), (0.1, 0.6, 0.6, 1.0))


def build_spec(p: ArmParameters | LinksParameters = TABLE_I) -> mujoco.MjSpec:
    """MjSpec of the arm: link masses, centres of mass and inertias, damping, motors of
    Table I (an :class:`ArmParameters`), or of an arm of N links (a :class:`LinksParameters`,
    :func:`twolink.arm.parameters.links_parameters`). Two links give the same model either way."""
    c = as_links(p)
    n = c.links
    joints, links = joint_names(n), link_names(n)
    spec = mujoco.MjSpec()
    spec.modelname = "twolink" if n == 2 else f"twolink_{n}link"
    spec.compiler.degree = False
    spec.compiler.autolimits = True
    spec.option.timestep = TS / SUBSTEPS
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_RK4
    spec.option.gravity = [0.0, 0.0, -p.g]
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    spec.visual.global_.offwidth = 1280
    spec.visual.global_.offheight = 960

    grid = spec.add_texture(name="grid", type=mujoco.mjtTexture.mjTEXTURE_2D,
                            builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, width=300, height=300,
                            rgb1=[0.92, 0.92, 0.92], rgb2=[0.85, 0.85, 0.85])
    floor_mat = spec.add_material(name="floor", texrepeat=[8, 8], reflectance=0.0)
    floor_mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = grid.name

    world = spec.worldbody
    world.add_light(name="top", pos=[0, 0, 1.0], dir=[0, 0, -1], diffuse=[0.8, 0.8, 0.8])
    reach = sum(c.lengths)
    world.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[reach * 1.6, reach * 1.6, 0.01],
                   pos=[0, 0, -0.03], material="floor", contype=0, conaffinity=0)
    world.add_camera(name="top", pos=[0, 0, reach * 3.0], fovy=45.0)
    world.add_geom(name="base", type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[0.018, 0.02, 0],
                   pos=[0, 0, -0.01], rgba=[0.3, 0.3, 0.3, 1], contype=0, conaffinity=0)

    parent = world
    specs = [(c.lengths[k], c.masses[k], c.coms[k], c.inertias[k], c.dampings[k],
              _RGBA_LINKS[k % len(_RGBA_LINKS)],
              (0.0 if k == 0 else c.lengths[k - 1], 0.0, 0.0)) for k in range(n)]
    for k, (length, mass, com, inertia, damping, rgba, pos) in enumerate(specs):
        body = parent.add_body(name=links[k], pos=list(pos))
        # A slender link along x: only the inertia about z (Table I's I_k) acts on the arm.
        body.mass = mass
        body.ipos = [com, 0.0, 0.0]
        body.inertia = [inertia / 100.0, inertia, inertia]
        body.explicitinertial = True
        body.add_joint(name=joints[k], type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1],
                       damping=damping)
        body.add_geom(name=f"{links[k]}_geom", type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                      fromto=[0, 0, 0, length, 0, 0], size=[_LINK_RADIUS, 0, 0],
                      rgba=list(rgba), contype=0, conaffinity=0, mass=0)
        body.add_site(name=f"{links[k]}_tip", pos=[length, 0, 0], size=[0.004, 0, 0])
        parent = body

    for k, joint in enumerate(joints):
        tmax = c.tau_max[k]
        spec.add_actuator(name=f"tau{k + 1}", target=joint,
                          trntype=mujoco.mjtTrn.mjTRN_JOINT, ctrlrange=[-tmax, tmax],
                          ctrllimited=True, gear=[1, 0, 0, 0, 0, 0])
    return spec


def build_model(p: ArmParameters | LinksParameters = TABLE_I) -> mujoco.MjModel:
    """Compiled MjModel of the arm for parameters ``p`` (two links or more)."""
    return build_spec(p).compile()


def model_xml(p: ArmParameters | LinksParameters = TABLE_I) -> str:
    """The MJCF text for parameters ``p``."""
    spec = build_spec(p)
    spec.compile()
    return spec.to_xml()


def write_model(path: os.PathLike, p: ArmParameters | LinksParameters = TABLE_I) -> Path:
    """Write the generated MJCF atomically to ``path``."""
    return write_text(path, model_xml(p))
