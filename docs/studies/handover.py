"""The handover (a fast design into the goal band, a robust one holding it) measured on the
tuning seeds: which hold design and which regions.

``python docs/studies/handover.py [--json FILE]`` builds, for every hold design of
:data:`HOLDS` and every region of :data:`REGIONS`, the handover from
``centralized_9levels`` (:class:`twolink.control.handover.Handover`) and measures it as the
tuning table does (``docs/studies/fading_gain.py``'s ``measure``: 48 poses nominal, the
settle / T* of the tuning grid, 32 poses on 8 plants under ``medium`` without compensation
and ``hard`` with it; all from the tuning seeds, never the leaderboard's). The pick is the
handover that meets the recommended centralized design's targets on these cells (48/48,
settle / T* <= 1.25, ``medium`` plain >= 99 %) with the most ``hard`` compensated
successes (then ``medium``, then speed). Then every rescue of :data:`RESCUES` (none, and
a limit cycle near the goal handed to the hold design) is added to that pick and run on
the same cells and on a larger tuning-side set: the 65 evaluation states on 32 plants of
the tuning plant seed, ``medium`` plain and ``hard`` compensated. The final pick meets
the targets on the cells with the most successes on the larger set (``medium`` plus
``hard``); ``centralized_9levels`` alone is run there too. The catalogue's
``centralized_handover`` (:data:`twolink.control.handover.HANDOVERS`) is the final pick.
About 4 min on this machine; writes ``renders/fuzzy_design/handover.json``.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    sys.path.insert(0, str(Path(__file__).resolve().parent))

from fading_gain import TARGETS, measure  # noqa: E402

from twolink.artifacts import provenance, write_json  # noqa: E402
from twolink.control.controllers import resolve_controller  # noqa: E402
from twolink.control.handover import Handover, Regions  # noqa: E402
from twolink.sim.evaluation import evaluate  # noqa: E402
from twolink.sim.metrics import evaluation_set  # noqa: E402
from twolink.studies.fuzzy_design.tuning_set import PLANT_SEED  # noqa: E402

SCHEMA, VERSION = "twolink.handover", 2
APPROACH = "centralized_9levels"
#: The hold designs tried: the robust centralized designs.
HOLDS = ("centralized_robust_edge_gain_medium", "centralized_robust_edge_gain",
         "centralized_robust_edge", "centralized_robust_tuned", "centralized_robust")
#: The regions tried: the goal band in (the default), and earlier handovers.
REGIONS = (Regions(), Regions(3.0, 0.2, 10.0, 0.8), Regions(4.0, 0.2, 10.0, 0.8),
           Regions(10.0, 0.3, 20.0, 1.0))
#: The rescues tried on the pick: (rescue_deg, rescue_s); None: no rescue.
RESCUES = (None, (10.0, 1.0), (15.0, 1.0), (15.0, 2.0), (20.0, 1.5))
DEFAULT_JSON = Path("renders/fuzzy_design/handover.json")


def meets(cells: dict) -> bool:
    """Whether tuning cells meet the centralized targets that this study can read
    (nominal, speed, ``medium`` plain)."""
    ratio_max, medium_min, _ = TARGETS["centralized"]
    return (cells["none"] == cells["n_none"] and cells["ratio_median"] is not None
            and cells["ratio_median"] <= ratio_max
            and cells["medium"] >= medium_min * cells["n_challenge"])


def wide(controller) -> dict:
    """``medium`` plain and ``hard`` compensated successes of the 65 evaluation states on
    32 plants of the tuning plant seed."""
    out = {"plants": 32, "seed": PLANT_SEED}
    for level, compensate, key in (("medium", False, "medium"),
                                   ("hard", True, "hard compensated")):
        s = evaluate(controller, x0=evaluation_set(), challenge=level, seed=PLANT_SEED,
                     count=32, compensate=compensate).score
        out[key], out["n"] = int(s.successes), int(s.n)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path, default=DEFAULT_JSON, help=f"default {DEFAULT_JSON}")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    fast = resolve_controller(APPROACH)
    rows = []
    for hold in HOLDS:
        slow = resolve_controller(hold)
        for regions in REGIONS:
            cells = measure(Handover(fast, slow, regions))
            rows.append({"hold": hold, "regions": regions.as_dict(), "cells": cells,
                         "meets": meets(cells)})
            print(f"{hold} {regions.as_dict()}: {cells}", flush=True)
    ok = [r for r in rows if r["meets"]]
    pick = max(ok, key=lambda r: (r["cells"]["hard compensated"], r["cells"]["medium"],
                                  -r["cells"]["ratio_median"])) if ok else None
    out = {"schema": SCHEMA, "version": VERSION, "approach": APPROACH,
           "approach_alone": measure(fast), "rows": rows, "pick": pick,
           "tuning_seeds": PLANT_SEED, "rescues": []}
    if pick is not None:
        slow = resolve_controller(pick["hold"])
        for rescue in RESCUES:
            extra = {} if rescue is None else dict(zip(("rescue_deg", "rescue_s"), rescue))
            regions = Regions(**{**pick["regions"], **extra})
            chosen = Handover(fast, slow, regions)
            cells = measure(chosen)
            row = {"hold": pick["hold"], "regions": regions.as_dict(), "cells": cells,
                   "meets": meets(cells), "wide": wide(chosen)}
            out["rescues"].append(row)
            print(f"rescue {rescue}: {cells}; wide {row['wide']}", flush=True)
        ok = [r for r in out["rescues"] if r["meets"]]
        if ok:
            out["final"] = max(ok, key=lambda r: (r["wide"]["medium"]
                                                  + r["wide"]["hard compensated"]))
            out["wide_approach_alone"] = wide(fast)
            print(f"final: {out['final']['regions']}", flush=True)
    out["seconds"] = round(time.perf_counter() - t0, 1)
    out["provenance"] = provenance()
    args.json.parent.mkdir(parents=True, exist_ok=True)
    write_json(args.json, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
