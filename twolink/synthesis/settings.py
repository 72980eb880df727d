"""The settings of one fuzzy synthesis (Alg. 1): what
:func:`twolink.synthesis.synthesize.synthesize` builds, in one frozen, checked value.

One spelling runs from the command line to the file: ``twolink synthesize`` reads its
options into a :class:`SynthesisSettings`, ``synthesize(settings)`` solves it, and the
policy file's header records :meth:`SynthesisSettings.header` (the same fields and
values the header has always had, so every shipped file reads back as the settings of its
registry entry: :meth:`SynthesisSettings.from_header`). :meth:`as_dict` and
:meth:`from_dict` write and read the settings as JSON data.

The defaults are the paper's: gamma and delta of Alg. 1 (:data:`twolink.arm.parameters.GAMMA`,
:data:`~twolink.arm.parameters.DELTA`), synchronous sweeps over the paper's bins (refine 1),
three torque levels per joint (:data:`twolink.arm.task.PAPER_LEVELS`), Table I's arm on the
simplified model (11), agent 1 with a frozen context, agent 2 reading link 1 free, no
read-out and no robust draws.
"""
from __future__ import annotations

import copy
import dataclasses
import json
from typing import Optional

from twolink.arm.integrate import check_sampling
from twolink.arm.parameters import (
    DELTA,
    GAMMA,
    TABLE_I,
    ArmParameters,
    check_links,
    links_parameters,
)
from twolink.arm.task import PAPER_LEVELS, check_levels
from twolink.fqi import fuzzy
from twolink.policy.readout import Readout
from twolink.policy.registry import shipped
from twolink.sim.perturbations import PHYSICAL
from twolink.synthesis.problems import (
    CONTEXTS,
    IDENTIFIED_MODELS,
    KINDS,
    check_link1,
    check_refine,
    check_robust,
    check_robust_size,
    check_size,
    check_sweeps,
    dynamics_of,
    parameter_draws,
)
from twolink.validate import real

#: The design options of the two-link synthesis (refused for a longer arm).
_TWO_LINK_DESIGN = ("levels", "bins", "readout", "agent2_link1")


@dataclasses.dataclass(frozen=True)
class SynthesisSettings:
    """Everything one synthesis depends on, checked when made (a one-line ValueError
    naming the field; a TypeError for a read-out that is not a
    :class:`~twolink.policy.readout.Readout`).

    ``kind``: the centralized policy (16) or the decentralized agents (18);
    ``model``: the model of the transitions (:data:`twolink.synthesis.problems.SYNTHESIS_MODELS`,
    or ``identified``: the full model (6) with ``parameters`` read from a file whose
    provenance is ``source``; None: ``simplified``, or ``full`` beyond two links);
    ``context``: agent 1's reading of link 2 (decentralized only; None: ``frozen``, or the
    N-link construction's default); ``gamma``, ``delta``: Alg. 1's discount and stopping
    threshold; ``sweeps``: synchronous or serial; ``refine``: subdivisions of every bin;
    ``robust``/``draws``/``spread``/``seed``: the worst case or mean over K parameter draws
    (:func:`twolink.synthesis.problems.parameter_draws`); ``links``/``rule``: an N-link arm
    (:func:`twolink.arm.parameters.links_parameters`); ``levels``, ``bins``, ``readout``,
    ``agent2_link1``: the two-link design (torque levels per joint, bin layout, read-out,
    agent 2's reading of link 1); ``parameters``: the arm (the centre of the draws).

    Fields left at None are resolved when made, and an inactive read-out is None, so two
    settings that synthesise the same policy compare equal.
    """

    kind: str
    model: Optional[str] = None
    context: Optional[str] = None
    gamma: float = GAMMA
    delta: float = DELTA
    sweeps: str = "synchronous"
    refine: int = 1
    robust: Optional[str] = None
    draws: int = 1
    spread: float = 0.0
    seed: int = 0
    links: int = 2
    rule: str = "tapered"
    levels: int = PAPER_LEVELS
    bins: str = "paper"
    readout: Optional[Readout] = None
    agent2_link1: str = "free"
    parameters: ArmParameters = TABLE_I
    source: Optional[dict] = None

    def __post_init__(self):
        def put(name, value):
            object.__setattr__(self, name, value)

        if self.kind not in KINDS:
            raise ValueError(f"unknown policy kind {self.kind!r}; choose one of "
                             f"{', '.join(KINDS)}")
        if not isinstance(self.parameters, ArmParameters):
            raise ValueError(f"parameters must be a twolink.arm.parameters.ArmParameters, "
                             f"got {type(self.parameters).__name__}")
        put("gamma", real(self.gamma, "gamma", 0.0, 1.0, open_low=True, open_high=True))
        put("delta", real(self.delta, "delta", 0.0, open_low=True))
        put("levels", check_levels(self.levels))
        put("bins", fuzzy.check_bins(self.bins))
        if self.readout is not None and not isinstance(self.readout, Readout):
            raise TypeError(f"readout must be a twolink.policy.readout.Readout, got "
                            f"{type(self.readout).__name__}")
        if self.readout is not None and not self.readout.active:
            put("readout", None)
        if self.agent2_link1 != "free":
            if self.kind != "decentralized":
                raise ValueError(f"agent2_link1 is how the decentralized agent 2 reads "
                                 f"link 1; the {self.kind} policy takes none")
            check_link1(self.agent2_link1)
        if self.source is not None:
            if not isinstance(self.source, dict):
                raise ValueError(f"source must be a dict (a parameter file's provenance), "
                                 f"got {type(self.source).__name__}")
            put("source", json.loads(json.dumps(self.source)))      # a copy, JSON data
        check_sweeps(self.sweeps)
        if check_links(self.links) > 2:
            self._check_links(put)
        else:
            self._check_two_link(put)

    def _check_links(self, put) -> None:
        """The checks of an N-link arm (N > 2): its decentralized agents on its full model,
        synchronous or serial sweeps, the paper's grid and design."""
        from twolink.synthesis.links_decentralized import construction

        n = self.links
        paper = {f.name: f.default for f in dataclasses.fields(self)}
        if any(getattr(self, f) != paper[f] for f in _TWO_LINK_DESIGN):
            raise ValueError(f"levels, bins, readout and agent2_link1 are two-link options; "
                             f"a {n}-link arm takes none of them")
        if self.kind != "decentralized":
            raise ValueError(f"the centralized synthesis of a {n}-link arm is "
                             f"twolink.synthesis.links_centralized; synthesize builds its "
                             f"decentralized agents")
        if self.model not in (None, "full"):
            raise ValueError(f"a {n}-link arm is synthesised on its full model, not "
                             f"{self.model!r} (model (11) is the paper's two-link "
                             f"simplification)")
        if (self.robust, self.draws, self.spread, self.seed) != (None, 1, 0.0, 0) \
                or self.refine != 1 or self.source is not None:
            raise ValueError(f"robust synthesis, refine and parameter files are two-link "
                             f"options; a {n}-link arm takes none of them")
        put("model", "full")
        put("context", construction(n, self.rule, context=self.context).context)

    def _check_two_link(self, put) -> None:
        """The checks of the two-link synthesis, in the order synthesize() has made them."""
        if self.rule != "tapered":
            raise ValueError(f"rule makes the links beyond the second; a {self.links}-link "
                             f"arm takes none (got {self.rule!r})")
        put("model", "simplified" if self.model is None else self.model)
        put("refine", check_refine(self.refine))
        dynamics_of(self.model)
        if self.kind == "decentralized":
            put("context", "frozen" if self.context is None else self.context)
            if self.context not in CONTEXTS:
                raise ValueError(f"unknown agent-1 context {self.context!r}; choose one of "
                                 f"{', '.join(CONTEXTS)}")
        elif self.context is not None:
            raise ValueError(f"context is agent 1's reading of link 2; the centralized "
                             f"policy takes none (got {self.context!r})")
        check_link1(self.agent2_link1, self.model)
        if dynamics_of(self.model) == "full":
            check_sampling(self.parameters)
        check_size(self.kind, self.refine, self.levels, self.bins)
        if self.robust is None:
            if (self.draws, self.spread, self.seed) != (1, 0.0, 0):
                raise ValueError("draws, spread and seed apply to a robust synthesis only: "
                                 "give robust='worst' or 'mean'")
            return
        robust, draws, spread, seed = check_robust(self.robust, self.draws, self.spread,
                                                   self.seed)
        put("draws", draws)
        put("spread", spread)
        put("seed", seed)
        if self.sweeps != "synchronous":
            raise ValueError("robust synthesis runs synchronous sweeps only")
        check_robust_size(self.kind, self.refine, self.draws, self.levels, self.bins)

    @classmethod
    def shipped(cls, name: str) -> "SynthesisSettings":
        """The settings that rebuild the shipped policy ``name``'s Q-tables and read-out
        (:data:`twolink.policy.registry.SHIPPED`, on Table I): what ``twolink synthesize
        --ship NAME`` runs."""
        entry = shipped(name)
        return cls(entry.kind, **entry.synthesis_options())

    def replace(self, **changes) -> "SynthesisSettings":
        """A copy with ``changes``, checked again."""
        return dataclasses.replace(self, **changes)

    def draw_models(self) -> list:
        """The K models a robust synthesis solves over (:func:`parameter_draws`: draw 0
        is :attr:`parameters`); ``[parameters]`` when it is not robust."""
        if self.robust is None:
            return [self.parameters]
        return parameter_draws(self.parameters, self.draws, self.spread, self.seed)

    def header(self) -> dict:
        """The fields these settings contribute to a policy file's header (``meta``), with
        the names and values the header has always had: the parameters, model, gamma and
        delta; agent 1's context (decentralized); the sweeps and refine; the design when it
        is not the paper's (levels, bins, readout, agent2_link1); ``dynamics`` of an
        identified model and ``parameters_source``; ``robust`` (mode, draws, spread, seed,
        the perturbed parameters and every model). Beyond two links: the links, rule,
        :class:`~twolink.arm.parameters.LinksParameters`, full model, resolved context,
        gamma, delta and sweeps that
        :func:`twolink.synthesis.links_decentralized.synthesize_links` records."""
        if self.links > 2:
            return {"links": self.links, "rule": self.rule,
                    "parameters": links_parameters(self.links, self.rule,
                                                   base=self.parameters).as_dict(),
                    "model": "full", "context": self.context, "gamma": self.gamma,
                    "delta": self.delta, "sweeps": self.sweeps}
        out = {"parameters": self.parameters.as_dict(), "model": self.model,
               "gamma": self.gamma, "delta": self.delta}
        if self.kind == "decentralized":
            out["context"] = self.context
        out.update(sweeps=self.sweeps, refine=self.refine)
        if self.levels != PAPER_LEVELS:
            out["levels"] = self.levels
        if self.bins != "paper":
            out["bins"] = self.bins
        if self.readout is not None:
            out["readout"] = self.readout.as_dict()
        if self.agent2_link1 != "free":
            out["agent2_link1"] = self.agent2_link1
        if self.model in IDENTIFIED_MODELS:
            out["dynamics"] = dynamics_of(self.model)
        if self.source is not None:
            out["parameters_source"] = copy.deepcopy(self.source)
        if self.robust is not None:
            out["robust"] = {"mode": self.robust, "draws": self.draws, "spread": self.spread,
                             "seed": self.seed, "draw_0": "centre", "perturbed": list(PHYSICAL),
                             "models": [m.as_dict() for m in self.draw_models()]}
        return out

    @classmethod
    def from_header(cls, kind: str, meta: dict) -> "SynthesisSettings":
        """The settings a policy of ``kind`` with header ``meta`` was synthesised with
        (the inverse of :meth:`header`), or a ValueError naming what the header lacks."""
        try:
            if meta.get("links", 2) > 2:
                made = cls(kind, links=meta["links"], rule=meta["rule"],
                           context=meta["context"], gamma=meta["gamma"],
                           delta=meta["delta"], sweeps=meta["sweeps"])
                if made.header()["parameters"] != meta["parameters"]:
                    raise ValueError(f"the header's {meta['links']}-link arm is not "
                                     f"links_parameters({meta['links']}, {meta['rule']!r}) "
                                     "of Table I")
                return made
            robust = meta.get("robust", {})
            readout = meta.get("readout")
            return cls(kind, model=meta["model"], context=meta.get("context"),
                       gamma=meta["gamma"], delta=meta["delta"],
                       sweeps=meta.get("sweeps", "synchronous"), refine=meta.get("refine", 1),
                       robust=robust.get("mode"), draws=robust.get("draws", 1),
                       spread=robust.get("spread", 0.0), seed=robust.get("seed", 0),
                       levels=meta.get("levels", PAPER_LEVELS),
                       bins=meta.get("bins", "paper"),
                       readout=None if readout is None else Readout.from_dict(readout),
                       agent2_link1=meta.get("agent2_link1", "free"),
                       parameters=ArmParameters.from_dict(meta["parameters"]),
                       source=meta.get("parameters_source"))
        except KeyError as e:
            raise ValueError(f"a synthesised policy's header records {e.args[0]!r}; "
                             f"this one has none") from None

    def as_dict(self) -> dict:
        """Every field as JSON data (parameters and read-out as their dicts)."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out["parameters"] = self.parameters.as_dict()
        out["readout"] = None if self.readout is None else self.readout.as_dict()
        out["source"] = copy.deepcopy(self.source)
        return out

    @classmethod
    def from_dict(cls, data: dict) -> "SynthesisSettings":
        """The settings of :meth:`as_dict`'s dict (fields left out take their defaults),
        or a ValueError naming unknown fields."""
        if not isinstance(data, dict):
            raise ValueError(f"synthesis settings must be a dict, got {type(data).__name__}")
        names = [f.name for f in dataclasses.fields(cls)]
        unknown = sorted(set(data) - set(names))
        if unknown:
            raise ValueError(f"unknown synthesis setting(s) {', '.join(map(str, unknown))}; "
                             f"known: {', '.join(names)}")
        fields = dict(data)
        if "parameters" in fields:
            fields["parameters"] = ArmParameters.from_dict(fields["parameters"])
        if fields.get("readout") is not None:
            fields["readout"] = Readout.from_dict(fields["readout"])
        if "kind" not in fields:
            raise ValueError("synthesis settings need a kind (centralized or decentralized)")
        return cls(**fields)
