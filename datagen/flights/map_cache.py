"""Values derived from an occupancy map, computed once per map while the map lives.

Training images and flights query the same map many times (per-frame axes, sorted floor
cells); ``derived`` keeps what was computed from a map until the map is garbage collected.
Treat a map as read-only once something was derived from it.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from typing import TypeVar

from core.occupancy import OccupancyMap

T = TypeVar("T")

_CACHE: dict[tuple[int, str], tuple[weakref.ref, object]] = {}


def _forget(key: tuple[int, str], cache: dict = _CACHE) -> Callable[[weakref.ref], None]:
    """The callback that drops ``key`` when its map goes (the dict held, so it still works
    while the interpreter shuts down)."""
    return lambda _: cache.pop(key, None)


def derived(occ: OccupancyMap, name: str, build: Callable[[OccupancyMap], T]) -> T:
    """``build(occ)``, computed once per (map, name)."""
    key = (id(occ), name)
    hit = _CACHE.get(key)
    if hit is not None and hit[0]() is occ:
        return hit[1]  # type: ignore[return-value]
    value = build(occ)
    _CACHE[key] = (weakref.ref(occ, _forget(key)), value)
    return value
