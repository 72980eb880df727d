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

from twolink.artifacts import write_text
from twolink.integrate import SUBSTEPS
from twolink.parameters import TABLE_I, TS, ArmParameters

#: The committed model file.
JOINTS = ("shoulder", "elbow")
LINKS = ("link1", "link2")

_LINK_RADIUS = 0.008
_RGBA_LINK1 = (0.85, 0.45, 0.1, 1.0)
_RGBA_LINK2 = (0.15, 0.45, 0.85, 1.0)


def build_spec(p: ArmParameters = TABLE_I) -> mujoco.MjSpec:
    """MjSpec of the arm: link masses, centres of mass and inertias, damping, motors of Table I."""
    spec = mujoco.MjSpec()
    spec.modelname = "twolink"
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
    reach = p.l1 + p.l2
    world.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[reach * 1.6, reach * 1.6, 0.01],
                   pos=[0, 0, -0.03], material="floor", contype=0, conaffinity=0)
    world.add_camera(name="top", pos=[0, 0, reach * 3.0], fovy=45.0)
    world.add_geom(name="base", type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[0.018, 0.02, 0],
                   pos=[0, 0, -0.01], rgba=[0.3, 0.3, 0.3, 1], contype=0, conaffinity=0)

    parent = world
    specs = ((p.l1, p.m1, p.c1, p.I1, p.b1, _RGBA_LINK1, (0.0, 0.0, 0.0)),
             (p.l2, p.m2, p.c2, p.I2, p.b2, _RGBA_LINK2, (p.l1, 0.0, 0.0)))
    for k, (length, mass, com, inertia, damping, rgba, pos) in enumerate(specs):
        body = parent.add_body(name=LINKS[k], pos=list(pos))
        # A slender link along x: only the inertia about z (Table I's I_k) acts on the arm.
        body.mass = mass
        body.ipos = [com, 0.0, 0.0]
        body.inertia = [inertia / 100.0, inertia, inertia]
        body.explicitinertial = True
        body.add_joint(name=JOINTS[k], type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1],
                       damping=damping)
        body.add_geom(name=f"{LINKS[k]}_geom", type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                      fromto=[0, 0, 0, length, 0, 0], size=[_LINK_RADIUS, 0, 0],
                      rgba=list(rgba), contype=0, conaffinity=0, mass=0)
        body.add_site(name=f"{LINKS[k]}_tip", pos=[length, 0, 0], size=[0.004, 0, 0])
        parent = body

    for k, joint in enumerate(JOINTS):
        tmax = p.tau_max[k]
        spec.add_actuator(name=f"tau{k + 1}", target=joint,
                          trntype=mujoco.mjtTrn.mjTRN_JOINT, ctrlrange=[-tmax, tmax],
                          ctrllimited=True, gear=[1, 0, 0, 0, 0, 0])
    return spec


def build_model(p: ArmParameters = TABLE_I) -> mujoco.MjModel:
    """Compiled MjModel of the arm for parameters ``p``."""
    return build_spec(p).compile()


def model_xml(p: ArmParameters = TABLE_I) -> str:
    """The MJCF text for parameters ``p``."""
    spec = build_spec(p)
    spec.compile()
    return spec.to_xml()


def write_model(path: os.PathLike, p: ArmParameters = TABLE_I) -> Path:
    """Write the generated MJCF atomically to ``path``."""
    return write_text(path, model_xml(p))
