"""The acceptance targets the results pages judge the data against (they live with the
documentation, not in the package).

* :data:`ROBUST_TARGETS` (:func:`robust_targets`): the robust fuzzy policies on the
  mismatch report's robust section (docs/results/mismatch.md);
* :data:`SCALING_TARGETS` (:func:`scaling_targets`): the N-link scaling run
  (docs/results/scaling.md);
* :data:`FUZZY_TARGETS`: the fuzzy designs on the leaderboard
  (docs/results/fuzzy-designs.md).

Writes nothing itself.
"""
from __future__ import annotations


#: What the robust policies should reach in the mismatch report's robust section, judged
#: on its data: (policy, level, mode, measure, comparison, threshold, wording).
ROBUST_TARGETS = (
    ("centralized_robust", "none", "compensated", "rate", ">=", 1.0,
     "centralized_robust, nominal plant: 100 % success"),
    ("centralized_robust", "medium", "compensated", "rate", ">=", 0.98,
     "centralized_robust + compensation, medium: ≥ 98 % success"),
    ("centralized_robust", "medium", "compensated", "worst_plant_rate", ">=", 0.95,
     "centralized_robust + compensation, medium: no plant below 95 %"),
    ("centralized_robust", "medium", "compensated", "median_settle", "<=", 1.5,
     "centralized_robust + compensation, medium: median settle ≤ 1.5 s"),
    ("decentralized_robust", "none", "compensated", "rate", ">=", 0.95,
     "decentralized_robust, nominal plant: ≥ 95 % success"),
    ("decentralized_robust", "medium", "compensated", "rate", ">=", 0.90,
     "decentralized_robust + compensation, medium: ≥ 90 % success"),
)


def robust_targets(section: dict) -> list:
    """Each target of :data:`ROBUST_TARGETS` that ``section`` (the report's robust
    section) measured: ``(wording, value, successes, n, plants, met)``."""
    from twolink.sim.metrics import score_keys

    out = []
    for pol, level, mode, measure, cmp, threshold, text in ROBUST_TARGETS:
        res = section["results"].get(pol, {}).get(level, {}).get(mode)
        if res is None:
            continue
        value = res[measure]
        met = value is not None and (value >= threshold if cmp == ">=" else value <= threshold)
        out.append((text, value, res["successes"], score_keys(res)["n"], res["plants"],
                    bool(met)))
    return out


#: What the scaling table should show: (what, rule, links, check[, scheme]), on the
#: ``decentralized`` row unless a scheme is named. ``check`` is ("success", horizon s,
#: least rate) or ("synthesis", most seconds, most bytes).
SCALING_TARGETS = (
    ("decentralized N = 6 synthesis ≤ 60 s and ≤ 2 GiB (tapered)", "tapered", 6,
     ("synthesis", 60.0, 2 * 2**30)),
    ("decentralized N = 6 synthesis ≤ 60 s and ≤ 2 GiB (copied)", "copied", 6,
     ("synthesis", 60.0, 2 * 2**30)),
    ("tapered N = 3 ≥ 95 % at 8 s", "tapered", 3, ("success", 8.0, 0.95)),
    ("tapered N = 3 ≥ 90 % at 5 s", "tapered", 3, ("success", 5.0, 0.90)),
    ("tapered N = 4 ≥ 95 % at 8 s", "tapered", 4, ("success", 8.0, 0.95)),
    ("copied N = 3 ≥ 95 % at 8 s", "copied", 3, ("success", 8.0, 0.95)),
    ("tapered N = 5 ≥ 95 % at 8 s", "tapered", 5, ("success", 8.0, 0.95)),
    ("tapered N = 6 ≥ 90 % at 8 s", "tapered", 6, ("success", 8.0, 0.90)),
    ("copied N = 4 ≥ 90 % at 8 s", "copied", 4, ("success", 8.0, 0.90)),
    ("tapered N = 5 ≥ 95 % at 8 s (5 levels)", "tapered", 5,
     ("success", 8.0, 0.95), "decentralized_levels"),
    ("tapered N = 6 ≥ 90 % at 8 s (5 levels)", "tapered", 6,
     ("success", 8.0, 0.90), "decentralized_levels"),
    ("copied N = 4 ≥ 90 % at 8 s (5 levels)", "copied", 4,
     ("success", 8.0, 0.90), "decentralized_levels"),
    ("decentralized N = 6 synthesis ≤ 60 s (tapered, 5 levels)", "tapered", 6,
     ("synthesis", 60.0, 2 * 2**30), "decentralized_levels"),
    ("tapered N = 5 ≥ 95 % at 8 s (5 levels, argmax)", "tapered", 5,
     ("success", 8.0, 0.95), "decentralized_argmax"),
    ("tapered N = 6 ≥ 90 % at 8 s (5 levels, argmax)", "tapered", 6,
     ("success", 8.0, 0.90), "decentralized_argmax"),
    ("copied N = 4 ≥ 90 % at 8 s (5 levels, argmax)", "copied", 4,
     ("success", 8.0, 0.90), "decentralized_argmax"),
)


def scaling_targets(report: dict) -> list:
    """Each target of :data:`SCALING_TARGETS` whose row the report holds: ``(target,
    measured, met)``, met on the point estimate (from the evaluation seed nobody tuned
    on)."""
    from twolink.viz.formatting import format_rate

    rows = {(r["scheme"], r["rule"], r["links"]): r for r in report["rows"]
            if r["status"] == "run"}
    out = []
    for what, rule, links, check, *scheme in SCALING_TARGETS:
        row = rows.get((scheme[0] if scheme else "decentralized", rule, links))
        if row is None:
            continue
        if check[0] == "synthesis":
            s = row["synthesis"]
            met = s["wall_seconds"] <= check[1] and s["peak_bytes"] <= check[2]
            shown = (f"{s['wall_seconds']:.1f} s wall ({s['cpu_seconds']:.1f} s CPU), peak "
                     f"{s['peak_bytes'] / 2**20:.0f} MiB ({s['peak_method']})")
        else:
            h = row["evaluation"]["horizons"].get(f"{check[1]:g}")
            if h is None:
                continue
            met = h["rate"] >= check[2]
            shown = f"{format_rate(h['successes'], h['n'])} at {check[1]:g} s"
        out.append((what, shown, bool(met)))
    return out


#: What the fuzzy policies of each kind are held to on the leaderboard: (kind, level,
#: mode, least success rate, least worst-plant successes of 65, most median settle / T*).
#: Acceptance thresholds of a study live here, in the documentation, not in the package.
FUZZY_TARGETS = (
    ("centralized", "none", "plain", 1.0, None, 1.25),
    ("centralized", "medium", "plain", 0.99, None, None),
    ("centralized", "hard", "compensated", 0.95, 52, None),
    ("decentralized", "none", "plain", 1.0, None, 1.6),
    ("decentralized", "medium", "plain", 0.97, None, None),
    ("decentralized", "medium", "compensated", 0.99, None, None),
    ("decentralized", "hard", "compensated", 0.90, 49, None),
)
