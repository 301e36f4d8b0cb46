"""The global search over a floor: the floor-boundary ray table and the search handing over."""
