"""``--policy`` and ``--controller`` of ``rollout`` and ``render``: the controllers a run
drives, labelled, resolved and checked before any file is written."""
from __future__ import annotations

from twolink.commands._options import check_policy_links, default_policy, policy_label

CONTROLLER_HELP = ("any controller: module:callable, path/to/file.py:callable (a callable "
                   "mapping states (n, 2N) to torques (n, N)), a baseline name, a shipped "
                   "policy, a policy .npz or a saved Stable-Baselines3 agent .zip (PPO or SAC); "
                   "labelled by the callable's name")


def add_controller_option(p, *, extra: str = "") -> None:
    """``--controller SPEC`` (repeatable), read by :func:`twolink.control.controllers.
    resolve_controller`."""
    p.add_argument("--controller", action="append", default=[], metavar="SPEC",
                   help=f"{CONTROLLER_HELP}; repeatable, run after the --policy values"
                        + extra)


def _inner(controller):
    """The object a checked controller wraps (its own ``links`` tells its arm)."""
    return getattr(controller, "controller", controller)


def controllers_of(args, links: int, *, most: int | None = None) -> dict:
    """``{label: controller}`` of ``args.policy`` (shipped names or .npz files, loaded as
    policies) then ``args.controller`` (any spec :func:`twolink.control.controllers.
    resolve_controller` takes); the shipped default policy when neither is given. One
    ValueError line for an unknown or broken spec, a label given twice, an arm of another
    number of links, or more than ``most`` controllers."""
    from twolink.control.controllers import resolve_controller
    from twolink.policy.fuzzy_policy import load_policy

    given = len(args.policy or []) + len(args.controller or [])
    if most is not None and given > most:
        raise ValueError(f"give one or two --policy or --controller values (side by side), "
                         f"got {given}")
    names = list(dict.fromkeys(args.policy or []))
    specs = list(dict.fromkeys(args.controller or []))
    if not names and not specs:
        names = [default_policy(links, args.rule)]
    out = {}

    def twice(label):
        return ValueError(f"two --policy or --controller values share the label {label!r}; "
                          f"give each once (a file is labelled by its stem, a callable by "
                          f"its name)")

    labels = [policy_label(n) for n in names]
    for i, label in enumerate(labels):
        if label in labels[:i]:
            raise twice(label)                   # before any file is read

    def add(label, controller):
        if label in out:
            raise twice(label)
        inner = _inner(controller)
        if hasattr(inner, "links") and hasattr(inner, "kind"):
            check_policy_links(label, inner, links)
        out[label] = controller

    for label, name in zip(labels, names):
        add(label, load_policy(name))
    for spec in specs:
        c = resolve_controller(spec, links=links)
        add(c.name, c)
    return out


def kind_of(controller) -> str:
    """What a controller is, for a file's metadata: a policy's kind, else ``controller``."""
    return str(getattr(controller, "kind", "") or "controller")


def context_of(controller):
    """A policy's training context (its meta's ``context``), else None."""
    meta = getattr(controller, "meta", None)
    return meta.get("context") if isinstance(meta, dict) else None
