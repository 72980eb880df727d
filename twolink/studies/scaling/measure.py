"""Table II extended to N = 2..6 links: what each scheme costs and how well it controls.

For every arm of N links (:func:`twolink.arm.parameters.links_parameters`, each link rule) and both
schemes, the centralized policy (16) and one decentralized agent per joint (18):

* the sizes: Q-values and non-zeros of T (Alg. 1's transition table (12)-(13));
* the synthesis: wall and CPU seconds, sweeps per agent and the peak memory, measured
  per synthesis (:mod:`twolink.studies.scaling.synthesis`);
* the control: success (settled one second before the end, docs/conventions.md) and median settle
  time on MuJoCo over :func:`twolink.sim.metrics.random_poses` at rest, drawn from
  :data:`EVAL_SEED` + N, at the horizon of :func:`horizon` (and at the paper's 5 s
  beside it for N >= 3).

For N >= 3 three more rows stand beside them (:data:`LINKS_SCHEMES`): the decentralized
agents with :data:`LEVER_LEVELS` torque levels per joint, the same agents read through
the argmax of Q beyond :data:`LEVER_ARGMAX_DEG` degrees, and the per-joint saturated PD
of :mod:`twolink.control.links_pd` with the gains it was tuned to on its own seeds (the
control only: a PD has no synthesis).

The centralized problem is estimated for every N before any work
(:func:`twolink.synthesis.links_centralized.estimate`) and synthesised only where its estimated peak
fits under the memory cap; otherwise its row is a refusal carrying the estimate. For
N = 2 the rows are the registry's ``centralized_full`` and ``decentralized_full``
(synthesised on the full model (6)); the paper's own Table II figures for (11) are in
``twolink reproduce``.

Measurement only: :func:`scaling` returns a :class:`Scaling`, whose :meth:`Scaling.report`
is the JSON that :mod:`twolink.studies.scaling.report` presents.
"""
from __future__ import annotations

import dataclasses
import math
import os
from typing import Optional

import numpy as np

from twolink._imports import renamed
from twolink.arm.parameters import (
    HORIZON,
    LINK_RULES,
    LINKS_HORIZON,
    MAX_LINKS,
    MIN_LINKS,
    TABLE_I,
    as_links,
    check_links,
    horizon,  # noqa: F401 (the docstring's horizon)
    links_parameters,
)
from twolink.artifacts import provenance
from twolink.sim.metrics import Score, random_poses  # noqa: F401 (documented above)
from twolink.sim.pose_scoring import horizons, score_on_poses, truncated  # noqa: F401
from twolink.sim.progress import progress_bar
from twolink.studies.scaling.synthesis import (
    LEVER_ARGMAX_DEG,
    LEVER_LEVELS,
    ProcessDied,
    Synthesis,
    cell_policy,
    check_peak_method,
    in_fresh_process,
    synthesize_measured,
)

#: Seed of the evaluation poses (N links draw from EVAL_SEED + N). Fixed before any
#: measurement; nothing is tuned on it.
EVAL_SEED = 20061122
#: The two schemes of the paper, in table order.
SCHEMES = ("centralized", "decentralized")
#: Rows measured beside them for N >= 3, in table order: the decentralized agents with
#: :data:`LEVER_LEVELS` torque levels per joint (plain, and read through the argmax of Q
#: beyond :data:`LEVER_ARGMAX_DEG` degrees), and the per-joint saturated PD
#: (:mod:`twolink.control.links_pd`, gains tuned off the evaluation seeds).
LINKS_SCHEMES = ("decentralized_levels", "decentralized_argmax", "pd")
#: Every row kind of the table.
ALL_SCHEMES = SCHEMES + LINKS_SCHEMES
#: Horizon for N >= 3 links (:data:`twolink.arm.parameters.LINKS_HORIZON`).
LONG_HORIZON = LINKS_HORIZON
#: Random poses per arm by default (about +-5 points of 95 % interval at 95 % success).
DEFAULT_POSES = 64
#: Poses and the largest N of ``quick=True``.
QUICK_POSES = 16
QUICK_MAX_LINKS = 4
#: Most poses a run accepts (the rollouts of one arm stay well under a second per pose).
MAX_POSES = 4096
#: Row statuses: synthesised and evaluated, refused over the cap, skipped by quick, failed.
STATUSES = ("run", "refused", "not run (quick)", "failed")

_GIB = 2.0**30
_MAX_SEED = 2**63 - MAX_LINKS


def machine_bytes() -> int:
    """Physical memory of this machine."""
    return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))


def default_max_bytes() -> int:
    """The centralized memory cap by default: :data:`twolink.synthesis.links_centralized.MAX_BYTES`."""
    from twolink.synthesis.links_centralized import MAX_BYTES
    return int(MAX_BYTES)


# -- input checks ---------------------------------------------------------------------

def check_rules(rules) -> tuple:
    """The link rules, deduplicated in order; a ValueError naming the known ones."""
    rules = tuple(dict.fromkeys(rules))
    if not rules:
        raise ValueError(f"give at least one link rule ({', '.join(LINK_RULES)})")
    for r in rules:
        if r not in LINK_RULES:
            raise ValueError(f"unknown link rule {r!r}; choose from {', '.join(LINK_RULES)}")
    return rules


def check_link_list(links) -> tuple:
    """The arm sizes, each checked by :func:`twolink.arm.parameters.check_links`, sorted."""
    links = tuple(sorted({check_links(n) for n in links}))
    if not links:
        raise ValueError(f"give at least one number of links ({MIN_LINKS} to {MAX_LINKS})")
    return links


def check_poses(poses) -> int:
    """A whole number of evaluation poses, 1 to :data:`MAX_POSES`."""
    if isinstance(poses, bool) or int(poses) != poses or not 1 <= poses <= MAX_POSES:
        raise ValueError(f"poses must be a whole number from 1 to {MAX_POSES}, got {poses}")
    return int(poses)


def check_max_bytes(max_bytes) -> int:
    """A memory cap in bytes: positive and at most this machine's physical memory."""
    total = machine_bytes()
    if not (isinstance(max_bytes, (int, float)) and math.isfinite(max_bytes)
            and 0 < max_bytes <= total):
        shown = f"{max_bytes / _GIB:g} GiB" if isinstance(max_bytes, (int, float)) \
            else repr(max_bytes)
        raise ValueError(f"the memory cap must be more than 0 and at most this machine's "
                         f"{total / _GIB:.1f} GiB, got {shown}")
    return int(max_bytes)


def check_seed(seed) -> int:
    """An evaluation seed: a whole number from 0 (N links draw from seed + N)."""
    if isinstance(seed, bool) or int(seed) != seed or not 0 <= seed < _MAX_SEED:
        raise ValueError(f"seed must be a whole number from 0 to {_MAX_SEED - 1}, got {seed}")
    return int(seed)


# -- what is measured -----------------------------------------------------------------

@dataclasses.dataclass
class Evaluation:
    """Closed-loop success on MuJoCo from ``poses`` random poses at rest (seed ``seed``):
    per horizon (seconds, as a string key) the shared score of the poses,
    :meth:`twolink.sim.metrics.Score.as_dict` (successes, 95 % Wilson interval, median
    settle time, None when half or more never settle). Held as that JSON, the form a row
    takes (:meth:`Row.as_dict`) and crosses the fresh process in; :meth:`scores` reads
    it back."""

    poses: int
    seed: int
    horizons: dict

    def scores(self) -> dict:
        """``{horizon: Score}``."""
        return {h: Score.from_dict(d) for h, d in self.horizons.items()}


@dataclasses.dataclass
class Row:
    """One (N, link rule, scheme) cell of the table. ``estimate`` is the centralized
    problem's size and memory estimate (centralized rows); ``note`` says why a row was not
    run (the refusal with its estimate) or how it failed."""

    links: int
    rule: str
    scheme: str
    status: str
    estimate: Optional[dict] = None
    synthesis: Optional[Synthesis] = None
    evaluation: Optional[Evaluation] = None
    note: str = ""

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


@dataclasses.dataclass
class Scaling:
    """Every row measured, in table order, with the options they were measured under."""

    rows: list
    options: dict

    def report(self) -> dict:
        """JSON-ready: the options, the horizons, every row and the provenance."""
        return {"options": self.options,
                "horizons": {str(n): list(horizons(n)) for n in self.options["links"]},
                "eval_seed": EVAL_SEED,
                "rows": [r.as_dict() for r in self.rows],
                "provenance": provenance()}


def estimate(links: int) -> dict:
    """The centralized problem of N links before any work (Q-values, non-zeros of T,
    bytes): :func:`twolink.synthesis.links_centralized.estimate` as a dict."""
    from twolink.synthesis.links_centralized import estimate as _estimate
    e = _estimate(check_links(links))
    return {k: (int(v) if isinstance(v, (int, np.integer)) else v)
            for k, v in dataclasses.asdict(e).items()}


def decentralized_estimate(links: int, rule: str, levels: int = 3) -> dict:
    """The decentralized agents' largest transition memory, known before any work
    (:func:`twolink.synthesis.links_decentralized.transition_bytes` of the default
    construction with ``levels`` torque levels per joint)."""
    from twolink.synthesis.links_decentralized import construction, design, transition_bytes
    p = as_links(params_of(links, rule))
    return {"peak_bytes": int(transition_bytes(p, construction(p.links, p.rule),
                                               design(levels)))}


def refusal(est: dict, max_bytes: int) -> Optional[str]:
    """The refusal line when the estimated peak exceeds ``max_bytes``, else None."""
    need = est["peak_bytes"]
    if need <= max_bytes:
        return None
    return f"refused: needs {_gib(need)} GiB > cap {_gib(max_bytes)} GiB"


def _gib(b: int) -> str:
    g = b / _GIB
    return f"{g:.1f}" if g < 1000 else f"{g:.2g}"


def params_of(links: int, rule: str):
    """The arm: Table I itself for two links (as the shipped policies use it), else
    :func:`twolink.arm.parameters.links_parameters`."""
    return TABLE_I if check_links(links) == 2 else links_parameters(links, rule)


def evaluate(policy, links: int, rule: str, *, poses: int = DEFAULT_POSES,
             seed: int = EVAL_SEED) -> Evaluation:
    """Run ``policy`` on MuJoCo from ``poses`` random poses at rest
    (:func:`random_poses` with ``seed + links``) for :func:`horizon` seconds and score every
    horizon of :func:`horizons` on that run: :func:`twolink.sim.pose_scoring.score_on_poses`,
    the one scorer ``twolink evaluate --links N`` uses too."""
    poses = check_poses(poses)
    drawn, scores = score_on_poses(policy, params_of(links, rule), poses=poses, seed=seed)
    return Evaluation(poses, drawn, {f"{h:g}": s.as_dict() for h, s in scores.items()})


def pd_note(links: int, rule: str) -> str:
    """How the ``pd`` row's controller is made: its gains and where they were tuned."""
    from twolink.control.links_pd import TUNED, TUNING_POSES, TUNING_SEED
    t = TUNED[(links, rule)]
    return (f"per-joint saturated PD (twolink.control.links_pd): sat "
            f"{t['sat_deg']:g} deg, zeta {t['zeta']:g} on every joint, tuned on "
            f"random_poses({links}, {TUNING_POSES}, {TUNING_SEED} + {links})")


def _cell(links: int, rule: str, scheme: str, poses: int, seed: int, max_bytes: int,
          peak: str, warm_up: bool) -> tuple:
    """Synthesis and evaluation of one cell (run in a fresh process by :func:`measure`)."""
    if warm_up:          # load the compiled kernels before the measured synthesis
        cell_policy(2, rule, "decentralized", max_bytes)
    policy, synth = synthesize_measured(links, rule, scheme, max_bytes=max_bytes, peak=peak)
    return synth, evaluate(policy, links, rule, poses=poses, seed=seed)


def measure(links: int, rule: str, scheme: str, *, poses: int = DEFAULT_POSES,
            seed: int = EVAL_SEED, max_bytes: Optional[int] = None,
            peak: str = "process", quick: bool = False) -> Row:
    """One row: the estimate (centralized), then synthesis and evaluation unless refused
    (estimated peak over ``max_bytes``) or skipped (``quick`` and centralized N >= 3).
    ``peak="process"`` runs the synthesis in a fresh process
    (:data:`~twolink.studies.scaling.synthesis.PEAK_METHODS`)."""
    links = check_links(links)
    check_rules([rule])
    if scheme not in ALL_SCHEMES:
        raise ValueError(f"unknown scheme {scheme!r}; choose from {', '.join(ALL_SCHEMES)}")
    if scheme in LINKS_SCHEMES and links == 2:
        raise ValueError(f"the {scheme} rows are for three links and more, got 2")
    max_bytes = check_max_bytes(default_max_bytes() if max_bytes is None else max_bytes)
    check_peak_method(peak)
    row = Row(links, rule if links > 2 else "Table I", scheme, "run")
    if scheme == "pd":
        from twolink.control.links_pd import tuned
        row.note = pd_note(links, rule)
        row.evaluation = evaluate(tuned(links_parameters(links, rule)), links, rule, poses=poses,
                                  seed=seed)
        return row
    if scheme in ("decentralized_levels", "decentralized_argmax"):
        row.estimate = decentralized_estimate(links, rule, LEVER_LEVELS)
    elif scheme == "decentralized":
        row.estimate = decentralized_estimate(links, rule)
    else:
        row.estimate = estimate(links)
        refused = refusal(row.estimate, max_bytes)
        if refused:
            row.status, row.note = "refused", refused
            return row
        if quick and links > 2:
            row.status = "not run (quick)"
            row.note = (f"not run (quick): estimated {row.estimate['peak_bytes'] / _GIB:.1f} "
                        f"GiB fits the {max_bytes / _GIB:.1f} GiB cap")
            return row
    args = (links, rule, scheme, poses, seed, max_bytes, peak, peak == "process")
    try:
        cell = in_fresh_process(_cell, args) if peak == "process" else _cell(*args)
        row.synthesis, row.evaluation = cell
    except (ProcessDied, MemoryError) as exc:
        row.status = "failed"
        row.note = f"failed: {type(exc).__name__.lstrip('_')}: {exc}"
    return row


def plan(links=tuple(range(MIN_LINKS, MAX_LINKS + 1)), rules=LINK_RULES, *,
         quick: bool = False) -> list:
    """The cells (links, rule, scheme) in table order. Two links are Table I whatever the
    rule, so they are measured once, in the two schemes; from three links on every row
    kind of :data:`ALL_SCHEMES`."""
    links, rules = check_link_list(links), check_rules(rules)
    if quick and links[-1] > QUICK_MAX_LINKS:
        raise ValueError(f"quick runs go up to {QUICK_MAX_LINKS} links, got "
                         f"{links[-1]}; drop the quick option for more")
    cells = [(2, rules[0], s) for s in SCHEMES] if 2 in links else []
    return cells + [(n, r, s) for r in rules for n in links if n > 2 for s in ALL_SCHEMES]


def scaling(links=None, rules=LINK_RULES, *, quick: bool = False,
            poses: Optional[int] = None, seed: int = EVAL_SEED,
            max_bytes: Optional[int] = None, peak: str = "process",
            progress: bool = False) -> Scaling:
    """Measure every cell of :func:`plan`: N = 2..6 (2..4 when ``quick``), ``rules``,
    both schemes; ``poses`` evaluation poses per arm (default 64, 16 when ``quick``)."""
    if links is None:
        links = range(MIN_LINKS, (QUICK_MAX_LINKS if quick else MAX_LINKS) + 1)
    cells = plan(links, rules, quick=quick)
    poses = check_poses((QUICK_POSES if quick else DEFAULT_POSES) if poses is None else poses)
    seed = check_seed(seed)
    max_bytes = check_max_bytes(default_max_bytes() if max_bytes is None else max_bytes)
    check_peak_method(peak)
    load_before = os.getloadavg()
    rows = []
    with progress_bar(cells, desc="scaling", unit=" rows", enabled=progress) as bar:
        for n, rule, scheme in bar:
            bar.set_postfix_str(f"N={n} {rule} {scheme}")
            rows.append(measure(n, rule, scheme, poses=poses, seed=int(seed),
                                max_bytes=max_bytes, peak=peak, quick=quick))
    options = {"links": sorted({c[0] for c in cells}), "rules": list(check_rules(rules)),
               "quick": quick, "poses": poses, "seed": int(seed), "max_bytes": max_bytes,
               "machine_bytes": machine_bytes(), "peak_method": peak,
               "horizon_short": HORIZON, "horizon_long": LONG_HORIZON,
               "load_average": {"before": list(load_before), "after": list(os.getloadavg())}}
    return Scaling(rows, options)


#: The names of 0.1 that said *chain*, kept until the next release (with a
#: DeprecationWarning; twolink._imports.renamed).
__getattr__ = renamed(__name__, {
    "CHAIN_SCHEMES": "LINKS_SCHEMES"
})
