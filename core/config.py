"""Config checks shared by the three stages."""

from __future__ import annotations

from collections.abc import Iterable


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
