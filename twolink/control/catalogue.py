"""The controller catalogue: every named controller, one entry each.

An :class:`Entry` says what a controller is (``kind``), for which arm (``links``,
``rule``), how it is tagged (:data:`TAGS`: ``paper``, ``benchmark``, ``baseline``,
``tuned``, ``learned``, ``n-link``, ``user``), and how it is made: a lazy
``module:callable`` entry point called with the keyword arguments ``data``. Nothing is
imported until :meth:`Entry.load`.

The shipped entries are read from the registries that define them, so nothing is spelt
twice: the shipped fuzzy policies (:data:`twolink.policy.registry.SHIPPED`), the
classical baselines (:data:`twolink.control.baselines.BASELINES`), the per-joint PD of
N-link arms with its tuned gains (:data:`twolink.control.links_pd.TUNED`, entries
``pd_<N>link_<rule>``, tagged ``baseline`` and ``n-link``), the handovers between two
fuzzy designs (:data:`twolink.control.handover.HANDOVERS`) and the shipped learned agents
(:data:`twolink.control.learned.LEARNED_AGENTS`). :data:`BENCHMARK` names the rows of
the default leaderboard.

A user extends the catalogue with JSON files (``--catalogue FILE`` on the commands that
take controllers, or the ``TWOLINK_CATALOGUE`` environment variable, a
``os.pathsep``-separated list of files)::

    {"format": "twolink-catalogue", "version": 1,
     "controllers": [
       {"name": "my_pd", "entry": "my_package.control:make_pd", "data": {"gain": 2.0},
        "links": 2, "tags": ["mine"], "description": "my PD"},
       {"name": "ppo_mine", "entry": "twolink.control.sb3_agent:sb3_agent",
        "data": {"path": "runs/ppo_mine.zip"}, "tags": ["learned"]}]}

A file is checked whole before any entry is used: a wrong format, a name given twice
(or already shipped), an unknown field or a wrong type is one :class:`CatalogueError`
line naming the file and the entry. An entry point that does not import is one line
naming the entry when it is loaded.
"""
from __future__ import annotations

import dataclasses
import difflib
import json
import os
from pathlib import Path

from twolink.control.entry_points import import_entry_point
from twolink.sim.controller import ControllerError

#: The tags an entry may carry, with what each means (``twolink controllers`` prints them).
TAGS = {
    "paper": "the paper's policies: centralized (16) and decentralized (18) on (11)",
    "benchmark": "the default leaderboard's rows",
    "baseline": "classical controllers tuned off the evaluation set",
    "tuned": "fuzzy designs chosen on tuning seeds",
    "fuzzy": "policies synthesised by fuzzy Q-iteration (Alg. 1)",
    "learned": "agents trained by deep RL",
    "n-link": "controllers of arms with more than two links",
    "user": "entries of a user's catalogue file",
}
#: The default leaderboard's rows: the paper's policies, the recommended fuzzy design of
#: each kind (the one that meets every target of its kind, ``docs/results/fuzzy-designs.md``:
#: ``centralized_handover`` and ``decentralized_handover``), the classical baselines and
#: the learned agents trained for a challenge level (``ppo_seed0``, trained on the nominal
#: arm only, is in ``--all``).
BENCHMARK = ("centralized", "decentralized", "decentralized_propagated",
             "centralized_handover", "decentralized_handover",
             "pd", "pd_deadzone", "lqr", "lqr_delay", "bang_bang", "ppo_medium", "ppo_hard")
#: What an entry's ``kind`` may be: a controller that reads the whole state and sets every
#: torque, one made of per-joint agents, or (a user's entry that does not say) unknown.
KINDS = ("centralized", "decentralized", "unknown")
#: The environment variable naming user catalogue files.
ENV_VAR = "TWOLINK_CATALOGUE"
#: The ``format`` and ``version`` a catalogue file declares.
FORMAT, VERSION = "twolink-catalogue", 1
#: The largest catalogue file read (a catalogue is a short list of entries).
MAX_FILE_BYTES = 1 << 20
_FIELDS = {"name", "entry", "data", "kind", "links", "rule", "tags", "description"}


class CatalogueError(ControllerError):
    """A catalogue file or entry is unusable (one line: which file or entry, and why)."""


@dataclasses.dataclass(frozen=True)
class Entry:
    """One named controller: what it is and how to make it (see the module docstring)."""

    name: str
    kind: str                       # "centralized", "decentralized" or "unknown"
    entry: str                      # "module:callable" (or "path/file.py:callable")
    data: dict = dataclasses.field(default_factory=dict)   # keyword arguments of entry
    links: int = 2
    rule: str | None = None         # how links beyond the second are made (N > 2)
    tags: tuple = ()
    description: str = ""
    source: str = "twolink"         # "twolink" or the catalogue file it came from

    def load(self):
        """The controller: ``entry(**data)``; a one-line CatalogueError naming the entry
        when its entry point does not import or is not callable."""
        try:
            make = import_entry_point(self.entry)
        except ControllerError as exc:
            raise CatalogueError(f"catalogue entry {self.name!r} ({self.source}): {exc}") \
                from None
        try:
            controller = make(**self.data)
        except ControllerError as exc:
            if self.source == "twolink":         # a shipped entry's own line says it all
                raise
            raise CatalogueError(f"catalogue entry {self.name!r} ({self.source}): {exc}") \
                from None
        except Exception as exc:
            raise CatalogueError(f"catalogue entry {self.name!r} ({self.source}): "
                                 f"{self.entry}(**data) raised {type(exc).__name__}: {exc}") \
                from None
        links = getattr(controller, "links", self.links)
        if isinstance(links, int) and links != self.links:
            raise CatalogueError(f"catalogue entry {self.name!r} ({self.source}) is for "
                                 f"{self.links} links, and what {self.entry} made is for "
                                 f"{links}")
        return controller

    def as_dict(self) -> dict:
        """JSON-ready: every field."""
        return {"name": self.name, "kind": self.kind, "links": self.links, "rule": self.rule,
                "tags": list(self.tags), "entry": self.entry, "data": dict(self.data),
                "description": self.description, "source": self.source}


def _shipped_policies() -> list:
    from twolink.policy.registry import SHIPPED

    out = []
    for p in SHIPPED.values():
        tags = ["fuzzy"]
        tags += ["paper"] if p.paper else []
        tags += ["tuned"] if p.tuned else []
        tags += ["n-link"] if p.links > 2 else []
        tags += ["benchmark"] if p.name in BENCHMARK else []
        if p.table_owner == p.name:
            entry, data = "twolink.policy.fuzzy_policy:load_policy", {"name_or_path": p.name}
        else:                       # a read-out over a stored table, named by its settings
            entry = "twolink.policy.fuzzy_policy:policy_with_readout"
            data = {"table": p.table, "readout": p.readout().as_dict()}
        out.append(Entry(name=p.name, kind=p.kind, links=p.links,
                         rule=p.rule if p.links > 2 else None, tags=tuple(tags),
                         entry=entry, data=data, description=p.description))
    return out


def _baselines() -> list:
    from twolink.control.baselines import BASELINES

    return [Entry(name=name, kind=b.kind, tags=("baseline", *(
                      ("benchmark",) if name in BENCHMARK else ())),
                  entry="twolink.control.baselines:baseline", data={"name": name},
                  description=b.description)
            for name, b in BASELINES.items()]


def _handovers() -> list:
    from twolink.control.handover import HANDOVERS

    return [Entry(name=name, kind=h.kind, tags=("fuzzy", "tuned", *(
                      ("benchmark",) if name in BENCHMARK else ())),
                  entry="twolink.control.handover:handover_policy",
                  data=h.data(name),
                  description=h.description)
            for name, h in HANDOVERS.items()]


def _learned() -> list:
    from twolink.control.learned import LEARNED

    return [Entry(name=name, kind=a.kind, links=a.links, rule=a.rule,
                  tags=("learned", *(("n-link",) if a.links > 2 else ()),
                        *(("benchmark",) if name in BENCHMARK else ())),
                  entry="twolink.control.learned:learned_agent", data={"name": name},
                  description=f"{a.description}: {a.path}")
            for name, a in LEARNED.items()]


def links_pd_name(links: int, rule: str) -> str:
    """The catalogue name of the tuned per-joint PD of an N-link arm: ``pd_3link_tapered``
    .. ``pd_6link_copied`` (one entry per (links, rule) of
    :data:`twolink.control.links_pd.TUNED`)."""
    return f"pd_{links}link_{rule}"


def links_pd(links: int, rule: str):
    """The tuned per-joint saturated PD of the arm ``links_parameters(links, rule)``
    (:func:`twolink.control.links_pd.tuned`), named by :func:`links_pd_name`: the entry
    point of the ``pd_<N>link_<rule>`` entries."""
    from twolink.arm.parameters import links_parameters
    from twolink.control.links_pd import tuned

    return tuned(links_parameters(links, rule), name=links_pd_name(links, rule))


def _links_pd() -> list:
    from twolink.control.links_pd import TUNED

    return [Entry(name=links_pd_name(n, rule), kind="decentralized", links=n, rule=rule,
                  tags=("baseline", "n-link"), entry="twolink.control.catalogue:links_pd",
                  data={"links": n, "rule": rule},
                  description=f"per-joint saturated PD of {n} {rule} links (sat "
                              f"{t['sat_deg']:g} deg, zeta {t['zeta']:g}; "
                              f"twolink.control.links_pd.TUNED)")
            for (n, rule), t in sorted(TUNED.items())]


def shipped_entries() -> list:
    """The entries twolink ships, in report order: fuzzy policies, the handovers between
    two of them (:mod:`twolink.control.handover`), baselines (the two-link ones, then the
    tuned N-link PD: :func:`links_pd_name`), learned."""
    return [*_shipped_policies(), *_handovers(), *_baselines(), *_links_pd(), *_learned()]


def catalogue_files(files=()) -> list:
    """The user catalogue files: ``files`` then those of :data:`ENV_VAR`."""
    env = [f for f in os.environ.get(ENV_VAR, "").split(os.pathsep) if f.strip()]
    return [Path(f) for f in (*files, *env)]


def _check_entry(raw, i: int, where: str) -> Entry:
    at = f"catalogue {where}: entry {i + 1}"
    if not isinstance(raw, dict):
        raise CatalogueError(f"{at} is {type(raw).__name__}, not an object")
    name = raw.get("name")
    if not isinstance(name, str) or not name.strip() or len(name) > 80 \
            or any(c.isspace() for c in name):
        raise CatalogueError(f"{at}: 'name' must be a non-empty word of at most 80 "
                             f"characters, got {name!r:.60}")
    at = f"catalogue {where}: entry {name!r}"
    unknown = sorted(set(raw) - _FIELDS)
    if unknown:
        raise CatalogueError(f"{at}: unknown field(s) {', '.join(unknown)}; the fields are "
                             f"{', '.join(sorted(_FIELDS))}")
    entry = raw.get("entry")
    if not isinstance(entry, str) or ":" not in entry or entry.endswith(":") \
            or entry.startswith(":"):
        raise CatalogueError(f"{at}: 'entry' must be 'module:callable' or "
                             f"'path/file.py:callable', got {entry!r:.60}")
    data = raw.get("data", {})
    if not isinstance(data, dict) or not all(isinstance(k, str) for k in data):
        raise CatalogueError(f"{at}: 'data' must be an object of keyword arguments")
    links = raw.get("links", 2)
    if isinstance(links, bool) or not isinstance(links, int) or not 2 <= links <= 12:
        raise CatalogueError(f"{at}: 'links' must be an integer in [2, 12], got {links!r:.30}")
    tags = raw.get("tags", [])
    if not isinstance(tags, list) or not all(isinstance(t, str) and t for t in tags):
        raise CatalogueError(f"{at}: 'tags' must be a list of words")
    for key in ("kind", "rule", "description"):
        if raw.get(key) is not None and not isinstance(raw[key], str):
            raise CatalogueError(f"{at}: {key!r} must be text")
    kind = raw.get("kind") or "unknown"
    if kind not in KINDS:
        raise CatalogueError(f"{at}: 'kind' must be one of {', '.join(KINDS)}, got "
                             f"{kind!r:.40}")
    return Entry(name=name, kind=kind, entry=entry, data=dict(data),
                 links=links, rule=raw.get("rule"), tags=tuple(dict.fromkeys(["user", *tags])),
                 description=raw.get("description") or "", source=where)


def read_catalogue_file(path) -> list:
    """The entries of the user catalogue file ``path``, checked whole (see the module
    docstring); one CatalogueError line naming the file otherwise."""
    path = Path(path)
    if not path.is_file():
        raise CatalogueError(f"catalogue {path} does not exist" if not path.exists()
                             else f"catalogue {path} is not a file")
    if path.stat().st_size > MAX_FILE_BYTES:
        raise CatalogueError(f"catalogue {path} is {path.stat().st_size} bytes, more than "
                             f"the {MAX_FILE_BYTES} a catalogue file may have")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise CatalogueError(f"catalogue {path} is not valid JSON ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise CatalogueError(f"catalogue {path} is not a twolink catalogue (its 'format' "
                             f"must be {FORMAT!r})")
    if doc.get("version") != VERSION:
        raise CatalogueError(f"catalogue {path} has version {doc.get('version')!r}; this "
                             f"twolink reads version {VERSION}")
    raw = doc.get("controllers")
    if not isinstance(raw, list):
        raise CatalogueError(f"catalogue {path}: 'controllers' must be a list of entries")
    entries = [_check_entry(r, i, str(path)) for i, r in enumerate(raw)]
    seen = set()
    for e in entries:
        if e.name in seen:
            raise CatalogueError(f"catalogue {path}: the name {e.name!r} is given twice")
        seen.add(e.name)
    return entries


def catalogue(files=()) -> dict:
    """``{name: Entry}``: the shipped entries, then those of the user catalogue files
    (:func:`catalogue_files`); a user entry may not reuse a name (one CatalogueError line
    naming both places)."""
    out = {e.name: e for e in shipped_entries()}
    for path in catalogue_files(files):
        for e in read_catalogue_file(path):
            if e.name in out:
                raise CatalogueError(f"catalogue {path}: the name {e.name!r} is already "
                                     f"taken by {out[e.name].source}'s entry; rename it")
            out[e.name] = e
    return out


def suggest(name: str, names) -> str:
    """`` (did you mean 'x'?)`` for the closest of ``names``, or an empty string."""
    close = difflib.get_close_matches(str(name), list(names), n=3, cutoff=0.6)
    if not close:
        return ""
    return " (did you mean " + " or ".join(repr(c) for c in close) + "?)"


def entries(*, tag: str | None = None, links: int | None = None, files=()) -> list:
    """The catalogue's entries, those with ``tag`` and for ``links`` links when given; an
    unknown tag is one CatalogueError line with the tags there are."""
    found = list(catalogue(files).values())
    if tag is not None:
        known = set(TAGS) | {t for e in found for t in e.tags}
        if tag not in known:
            raise CatalogueError(f"unknown tag {tag!r}{suggest(tag, known)}; the tags are "
                                 f"{', '.join(sorted(known))}")
        found = [e for e in found if tag in e.tags]
    if links is not None:
        found = [e for e in found if e.links == links]
    return found


def lookup(name: str, files=()) -> Entry:
    """The entry named ``name``; an unknown name is one CatalogueError line with the
    closest names."""
    cat = catalogue(files)
    if name not in cat:
        raise CatalogueError(f"unknown controller {name!r}{suggest(name, cat)}; "
                             f"`twolink controllers` lists the {len(cat)} names")
    return cat[name]


def load(name: str, files=()):
    """The controller of the catalogue entry ``name`` (:meth:`Entry.load`)."""
    return lookup(name, files).load()
