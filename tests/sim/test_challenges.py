"""Challenge levels: the table, the plant draws (held against their own loop), bad input."""
import dataclasses
import json
import math

import numpy as np
import pytest

from twolink.arm.parameters import TABLE_I
from twolink.sim import challenges
from twolink.sim.challenges import (
    LEVELS,
    PLANT_STREAM,
    Challenge,
    challenge,
    draw_plants,
)
from twolink.sim.perturbations import PHYSICAL, random_perturbation, torque_limited

_NUMBERS = [f.name for f in dataclasses.fields(Challenge)
            if f.name not in ("name", "description", "offsets")]


def test_medium_is_exactly_the_combined_challenge_of_the_issue():
    m = LEVELS["medium"]
    assert (m.spread, m.action_delay, m.angle_noise_deg, m.speed_noise) == (0.2, 1, 1.0, 0.02)
    assert (m.torque_limit, m.observation_delay, m.dropout, m.stuck) == (0, 0, 0, 0)
    assert all(getattr(LEVELS["none"], k) == 0 for k in _NUMBERS)
    assert all(c.offsets == () for c in LEVELS.values())


def test_levels_grow_harder_field_by_field():
    order = list(LEVELS)
    assert order == ["none", "easy", "medium", "hard"]
    for mild, harsh in zip(order, order[1:]):
        for k in _NUMBERS:
            a, b = getattr(LEVELS[mild], k), getattr(LEVELS[harsh], k)
            assert (abs(b) >= abs(a)), (mild, harsh, k)
    assert all(LEVELS[n].description for n in order)


def test_challenge_by_name_and_unknown_names():
    assert challenge("hard") is LEVELS["hard"]
    assert challenge(None) is LEVELS["none"]
    custom = Challenge("mine", spread=0.05)
    assert challenge(custom) is custom
    with pytest.raises(ValueError, match="unknown challenge 'brutal'; choose one of none, easy, "
                                         "medium, hard"):
        challenge("brutal")
    with pytest.raises(ValueError, match="challenge name must be a non-empty string"):
        Challenge("")


def _reference_plant(spread, seed, i):
    """Plant i by hand: the i-th spawned child of SeedSequence([seed, PLANT_STREAM]) draws
    one relative change per PHYSICAL name, in order."""
    child = np.random.SeedSequence([seed, PLANT_STREAM]).spawn(i + 1)[i]
    changes = np.random.default_rng(child).uniform(-spread, spread, len(PHYSICAL))
    return TABLE_I.scaled(**{n: 1.0 + c for n, c in zip(PHYSICAL, changes)})


def test_draw_plants_equals_a_hand_loop_and_keeps_its_prefix():
    plants = draw_plants(0.2, 6, seed=31)
    assert plants == [_reference_plant(0.2, 31, i) for i in range(6)]
    assert draw_plants(0.2, 3, seed=31) == plants[:3]          # plant i whatever the count
    assert draw_plants(0.2, 6, seed=32) != plants
    assert len(set(plants)) == 6
    for p in plants:
        for name in PHYSICAL:
            assert abs(getattr(p, name) / getattr(TABLE_I, name) - 1) <= 0.2 + 1e-12
        for name in ("g", "tau1_max", "tau2_max", "dtheta1_max", "dtheta2_max"):
            assert getattr(p, name) == getattr(TABLE_I, name)
    # all ten drawn jointly: some parameter of some plant changed by more than 15 %
    worst = max(abs(getattr(p, n) / getattr(TABLE_I, n) - 1) for p in plants for n in PHYSICAL)
    assert 0.15 < worst <= 0.2


def test_challenge_plants_add_the_torque_limit():
    hard = LEVELS["hard"]
    plants = hard.plants(4, seed=2)
    for p, q in zip(plants, draw_plants(hard.spread, 4, seed=2)):
        assert p.tau1_max == pytest.approx(0.8 * TABLE_I.tau1_max)
        assert p.tau2_max == pytest.approx(0.8 * TABLE_I.tau2_max)
        assert dataclasses.replace(p, tau1_max=q.tau1_max, tau2_max=q.tau2_max) == q
    assert LEVELS["none"].plants(2, seed=0) == [TABLE_I, TABLE_I]
    rng = np.random.default_rng(0)
    state = rng.bit_generator.state
    assert LEVELS["none"].plant(rng) == TABLE_I and rng.bit_generator.state == state


def test_offsets_change_named_parameters_before_the_draws():
    ch = Challenge("o", offsets={"m2": 0.2, "tau1_max": -0.5})
    assert ch.offsets == (("m2", 0.2), ("tau1_max", -0.5))       # PERTURBABLE's order
    assert ch.perturbs_plant() and ch.plants(2, seed=0) == [TABLE_I.scaled(m2=1.2,
                                                                          tau1_max=0.5)] * 2
    joint = Challenge("j", spread=0.2, offsets={"m2": 0.2}, torque_limit=-0.1)
    assert joint.plants(3, seed=4) == [
        dataclasses.replace(q, tau1_max=0.9 * q.tau1_max, tau2_max=0.9 * q.tau2_max)
        for q in draw_plants(0.2, 3, seed=4, base=TABLE_I.scaled(m2=1.2))]
    assert joint.plant(np.random.default_rng(5)) == torque_limited(random_perturbation(
        np.random.default_rng(5), 0.2, TABLE_I.scaled(m2=1.2), PHYSICAL), -0.1)
    d = joint.as_dict()
    assert d["offsets"] == {"m2": 0.2} and Challenge(**d) == joint
    assert json.loads(json.dumps(d)) == d


@pytest.mark.parametrize("offsets, message", [
    ({"zz": 0.1}, "unknown parameter 'zz' in offsets; perturbable: l1, m1,"),
    ({"l2": 0.1}, "unknown parameter 'l2' in offsets"),
    ({"m1": 1.5}, "offset of m1 must be a relative change in (-0.9, 1], got 1.5"),
    ({"m1": -0.9}, "offset of m1 must be a relative change in (-0.9, 1]"),
    ({"m1": math.inf}, "offset of m1 must be a relative change"),
    ({"m1": "x"}, "offset of m1 must be a relative change"),
    ((("m1", 0.1), ("m1", 0.2)), "offsets name a parameter twice: m1, m1"),
    (3, "offsets must map Table I parameter names to relative changes, got 3"),
    ("m1", "offsets must map Table I parameter names"),
    ([("m1", 0.1, 2)], "offsets must map Table I parameter names"),
])
def test_bad_offsets_refused(offsets, message):
    with pytest.raises(ValueError, match=__import__("re").escape(message)):
        Challenge("bad", offsets=offsets)


@pytest.mark.parametrize("kwargs, message", [
    (dict(spread=0.9), "spread must be a relative change in [0, 0.9), got 0.9"),
    (dict(spread=-0.1), "spread must be a relative change in [0, 0.9)"),
    (dict(spread=math.nan), "spread must be a finite number"),
    (dict(torque_limit=-0.95), "torque_limit"),
    (dict(action_delay=1.5), "action_delay must be a whole number of samples"),
    (dict(observation_delay=-1), "observation_delay must be a whole number"),
    (dict(action_delay=10**6), "from 0 to 1000"),
    (dict(angle_noise_deg=-1.0), "angle_noise_deg must be non-negative, got -1.0"),
    (dict(speed_noise=-0.01), "speed_noise must be non-negative"),
    (dict(dropout=1.0), "dropout must be a probability in [0, 1)"),
    (dict(stuck=True), "stuck must be a finite number"),
])
def test_bad_challenges_refused(kwargs, message):
    with pytest.raises(ValueError, match=__import__("re").escape(message)):
        Challenge("bad", **kwargs)


@pytest.mark.parametrize("args, message", [
    ((0.9, 4, 0), "spread must be a relative change in [0, 0.9)"),
    ((0.2, 0, 0), "count must be a whole number of plants from 1 to 10000"),
    ((0.2, 10**9, 0), "count must be a whole number of plants"),
    ((0.2, 4, -1), "seed must be a non-negative whole number"),
    ((0.2, 4, "x"), "seed must be a non-negative whole number"),
])
def test_bad_draws_refused(args, message):
    with pytest.raises(ValueError, match=__import__("re").escape(message)):
        draw_plants(*args)


def test_table_rows_and_markdown():
    rows = challenges.table()
    assert [r["name"] for r in rows] == list(LEVELS)
    assert rows[2]["spread"] == 0.2 and rows[3]["dropout"] == 0.05
    md = challenges.markdown_table().splitlines()
    assert len(md) == 2 + len(LEVELS)
    assert md[4].startswith("| `medium` | 20 % | 0 % | 1 (50 ms) | 0 | 1 deg | 0.02 rad/s")
    assert "| -20 % |" in md[5]
