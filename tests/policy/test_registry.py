"""The shipped-policy registry's stored tables: each Q-table in one file under policies/,
named by its synthesis settings (twolink.policy.registry.table_stem)."""
import itertools

import pytest

from twolink.policy.registry import SHIPPED, table_stem


@pytest.mark.parametrize("options, stem", [
    ({"kind": "centralized", "model": "simplified"}, "centralized_simplified"),
    ({"kind": "decentralized", "model": "simplified", "context": "frozen"},
     "decentralized_simplified_frozen"),
    ({"kind": "centralized", "model": "full", "robust": "worst", "draws": 8, "spread": 0.2,
      "seed": 2006}, "centralized_full_worst8-0.2-seed2006"),
    ({"kind": "decentralized", "model": "full", "context": "propagated", "links": 3,
      "rule": "tapered"}, "decentralized_full_propagated_3tapered"),
    ({"kind": "centralized", "model": "full", "levels": 5, "bins": "goal"},
     "centralized_full_levels5_bins-goal"),
    ({"kind": "decentralized", "model": "full", "context": "propagated", "levels": 7,
      "bins": "edge", "agent2_link1": "locked"},
     "decentralized_full_propagated_levels7_bins-edge_link1-locked"),
    ({"kind": "decentralized", "model": "simplified", "context": "frozen",
      "sweeps": "serial", "robust": "mean", "draws": 4, "spread": 0.05, "seed": 1},
     "decentralized_simplified_frozen_serial_mean4-0.05-seed1"),
    # defaults given explicitly are not named
    ({"kind": "centralized", "model": "simplified", "links": 2, "sweeps": "synchronous",
      "levels": 3, "bins": "paper", "agent2_link1": "free", "robust": None, "draws": 1,
      "spread": 0.0, "seed": 0, "context": None}, "centralized_simplified"),
])
def test_the_stem_is_the_documented_name(options, stem):
    assert table_stem(options) == stem


def test_every_shipped_file_is_named_by_its_settings():
    for name, entry in SHIPPED.items():
        assert entry.table == table_stem(entry.table_options())
        assert entry.file.name == f"{entry.table}.npz" and entry.file.is_file(), name
    files = {p.name for p in next(iter(SHIPPED.values())).file.parent.glob("*.npz")}
    assert files == {e.file.name for e in SHIPPED.values()}


def test_two_entries_share_a_file_iff_their_table_settings_are_equal():
    for a, b in itertools.combinations(SHIPPED.values(), 2):
        assert (a.file == b.file) == (a.table_options() == b.table_options()), (a.name, b.name)


def test_the_owner_of_a_table_is_its_first_entry():
    for name, entry in SHIPPED.items():
        first = next(p.name for p in SHIPPED.values() if p.table == entry.table)
        assert entry.table_owner == first
    # a table named like a catalogue entry is that entry's own
    for name, entry in SHIPPED.items():
        if name in {e.table for e in SHIPPED.values()}:
            assert entry.table == name and entry.table_owner == name


def test_distinct_settings_give_distinct_stems():
    seen = {}
    for kind, model, sweeps, robust, draws, spread, seed, levels, bins, link1 in \
            itertools.product(("centralized", "decentralized"), ("simplified", "full"),
                              ("synchronous", "serial"), (None, "worst", "mean"), (1, 8),
                              (0.0, 0.2, 0.25), (0, 2006), (3, 5), ("paper", "edge"),
                              ("free", "locked")):
        if robust is None and (draws, spread, seed) != (1, 0.0, 0):
            continue
        options = {"kind": kind, "model": model, "sweeps": sweeps, "levels": levels,
                   "bins": bins, "agent2_link1": link1}
        if kind == "decentralized":
            options["context"] = "frozen"
        if robust is not None:
            options.update(robust=robust, draws=draws, spread=spread, seed=seed)
        stem = table_stem(options)
        assert stem not in seen, (options, seen.get(stem))
        seen[stem] = options
    for links, rule in itertools.product((3, 4), ("tapered", "copied")):
        stem = table_stem({"kind": "decentralized", "model": "full", "context": "frozen",
                           "links": links, "rule": rule})
        assert stem not in seen
        seen[stem] = links, rule


@pytest.mark.parametrize("options, message", [
    ({"kind": "centralized"}, "table settings need a model"),
    ({"kind": "centralized", "model": "full", "gamma": 0.9}, "unknown table setting.*gamma"),
    ({"kind": "decentralized", "model": "full"}, "context names the decentralized"),
    ({"kind": "centralized", "model": "full", "context": "frozen"},
     "context names the decentralized"),
    ({"kind": "centralized", "model": "full", "draws": 8}, "robust table only"),
    ({"kind": "centralized", "model": "full", "rule": "copied"}, "two links take none"),
    ({"kind": "centralized", "model": "Full"}, "model must be a word"),
    ({"kind": "centralized", "model": "full", "bins": "my_bins"}, "bins must be a word"),
    ({"kind": "centralized", "model": "full", "bins": None}, "bins must be a word"),
    ({"kind": "centralized", "model": "full", "levels": 2.5}, "levels must be a"),
    ({"kind": "centralized", "model": "full", "robust": "worst", "draws": 8,
      "spread": -0.1, "seed": 1}, "spread"),
    ("centralized", "table settings must be a dict"),
])
def test_bad_table_settings_are_one_line_errors(options, message):
    with pytest.raises(ValueError, match=message) as err:
        table_stem(options)
    assert "\n" not in str(err.value)
