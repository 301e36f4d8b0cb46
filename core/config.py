"""Config checks shared by the three stages."""

from __future__ import annotations

from collections.abc import Iterable, Mapping


def reject_unknown_keys(given: Iterable[str], known: Iterable[str], what: str) -> None:
    """Raise ValueError naming the keys of ``given`` that are not in ``known`` (a typo in a
    config or an override), and listing the known ones.

    Args:
        given: the keys found.
        known: the keys allowed.
        what: what the keys are, for the message, e.g. ``"filter settings"``.
    """
    known = set(known)
    unknown = set(given) - known
    if unknown:
        raise ValueError(f"unknown {what} {sorted(unknown)}; known: {sorted(known)}")


def drop_key(d: dict, dotted: str) -> None:
    """Remove ``a.b.c`` from nested dicts in place (nothing if a level is missing)."""
    head, _, rest = dotted.partition(".")
    if rest:
        if isinstance(d.get(head), dict):
            drop_key(d[head], rest)
    else:
        d.pop(head, None)


def drop_defaults(d: dict, defaults: Mapping[str, object]) -> None:
    """Remove, in place, each dotted key of ``defaults`` whose value in ``d`` (missing counts as
    the default) equals its default: options added after outputs were made, at the value that
    gives the earlier behaviour, stay out of a config hash, so those outputs keep theirs.
    """
    for key, old in defaults.items():
        node, *path = [d, *key.split(".")]
        for part in path[:-1]:
            node = node.get(part, {}) if isinstance(node, dict) else {}
        if not isinstance(node, dict) or node.get(path[-1], old) == old:
            drop_key(d, key)
