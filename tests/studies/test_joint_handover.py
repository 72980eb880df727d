"""docs/studies/joint_handover.py: the decentralized handover switches each joint on its
own reading only; the target check reads the decentralized targets."""
from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
PATH = ROOT / "docs/studies/joint_handover.py"


def _module():
    sys.path.insert(0, str(PATH.parent))
    try:
        spec = importlib.util.spec_from_file_location("joint_handover", PATH)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(PATH.parent))
    return module


class Const:
    links, meta = 2, {"model": "full"}

    def __init__(self, value):
        self.value = value

    def __call__(self, x):
        return np.full((len(x), 2), float(self.value))


def _x(deg1, deg2, speed=1.0):
    return np.array([[math.radians(deg1), math.radians(deg2), speed, speed]])


def test_each_joint_switches_on_its_own_reading():
    m = _module()
    h = m.JointHandover(Const(1.0), Const(-1.0), rescue_deg=10.0, rescue_s=0.1,
                        exit_deg=30.0, band=False)
    h.reset(1)
    np.testing.assert_array_equal(h(_x(5, 50)), [[1.0, 1.0]])     # joint 1 near once
    np.testing.assert_array_equal(h(_x(5, 50)), [[-1.0, 1.0]])    # twice: joint 1 held
    np.testing.assert_array_equal(h(_x(25, 8)), [[-1.0, 1.0]])    # kept inside 30 deg
    np.testing.assert_array_equal(h(_x(35, 8)), [[1.0, -1.0]])    # 1 released, 2 held
    assert h.meta == {"model": "full"} and h.kind == "decentralized"


def test_with_the_band_a_settled_joint_switches_at_once():
    m = _module()
    h = m.JointHandover(Const(1.0), Const(-1.0), rescue_deg=10.0, rescue_s=5.0,
                        exit_deg=30.0, band=True)
    np.testing.assert_array_equal(h(_x(2, 20, speed=0.05)), [[-1.0, 1.0]])


def test_bad_switches_are_one_line():
    m = _module()
    with pytest.raises(ValueError, match="need 0 < rescue_deg <= exit_deg <= 180"):
        m.JointHandover(Const(1.0), Const(-1.0), rescue_deg=40.0, rescue_s=1.0,
                        exit_deg=30.0, band=False)


def test_meets_reads_every_decentralized_target():
    m = _module()
    good = {"none": 48, "n_none": 48, "ratio_median": 1.55, "medium": 250,
            "n_challenge": 256, "hard compensated": 231}
    assert m.meets(good)
    assert not m.meets({**good, "ratio_median": 1.61})
    assert not m.meets({**good, "medium": 248})          # 248/256 < 97 %
    assert not m.meets({**good, "hard compensated": 230})
    assert not m.meets({**good, "none": 47})


def test_the_pick_follows_the_stated_rule():
    m = _module()
    cells = {"none": 48, "n_none": 48, "ratio_median": 1.55, "medium": 200,
             "n_challenge": 256, "hard compensated": 200}
    base = {"medium": 2030, "hard compensated": 1900, "n": 2080, "plants": 32}

    def row(hold, after_s, ratio=1.55, **wide):
        c = {**cells, "ratio_median": ratio}
        w = {**base, **{k.replace("_", " "): v for k, v in wide.items()}}
        return {"hold": hold, "after_s": after_s, "cells": c, "wide": w,
                "meets": m.fast_enough(c) and m.wide_meets(w)}

    rows = [row("a", 2.0, ratio=1.61, medium=2079),              # most medium, too slow
            row("b", 3.0, medium=2030), row("c", 2.5, medium=2030, hard_compensated=1950),
            row("d", 2.0, ratio=1.5, medium=2030, hard_compensated=1950),
            row("e", 1.5, ratio=1.5, medium=2030, hard_compensated=1950),
            row("f", 1.5, medium=2079, hard_compensated=1871)]      # 1871 < 90 % of 2080
    assert [r["meets"] for r in rows] == [False, True, True, True, True, False]
    assert m.pick(rows)["hold"] == "e"        # wide medium, wide hard, speed, earliest
    assert m.pick(rows[:3])["hold"] == "c"
    assert m.pick(rows[:1]) is None           # too slow
    assert m.pick([rows[5]]) is None          # hard compensated below its target
    close = [row("g", 3.0, medium=2000), row("h", 3.0, medium=1990)]
    assert m.pick(close)["hold"] == "g" and not m.pick(close)["meets"]   # the closest
    assert not m.wide_meets({**base, "medium": 2017})             # 2017/2080 < 97 %
    assert m.wide_meets({**base, "medium": 2018})


def test_a_fade_keeps_the_approach_s_table_and_argmax_rule():
    m = _module()
    from twolink.policy.fuzzy_policy import load_policy

    r = m.fade_readout(0.04, 0.2, 120.0)
    base = load_policy(m.APPROACH).readout
    assert (r.speed_dead_zone, r.near_gain, r.near_deg) == (0.04, 0.2, 120.0)
    assert r.argmax_beyond_deg == base.argmax_beyond_deg == 30.0
    assert len(m.FADES) == 27 and len(set(m.FADES)) == 27
    with pytest.raises(ValueError, match="near_gain"):
        m.fade_readout(0.02, 0.0, 90.0)


def test_the_shipped_decentralized_handover_is_the_committed_pick():
    """The catalogue's decentralized_handover is the study's committed pick: the same
    approach and switch time, and a hold that reads the picked table through the picked
    read-out."""
    import json

    from twolink.control.handover import HANDOVERS
    from twolink.policy.registry import SHIPPED

    data = json.loads((ROOT / "renders/fuzzy_design/joint_handover.json").read_text())
    chosen, shipped = data["pick"], HANDOVERS["decentralized_handover"]
    assert data["version"] == _module().VERSION
    assert shipped.approach == data["approach"] and shipped.after_s == chosen["after_s"]
    hold = SHIPPED[shipped.hold]
    assert hold.table == SHIPPED[chosen["hold"]].table
    expected = chosen.get("readout", SHIPPED[chosen["hold"]].readout().as_dict())
    assert hold.readout().as_dict() == expected
