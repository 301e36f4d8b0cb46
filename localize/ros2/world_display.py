"""The building as RViz shows it: the free space as a nav_msgs/OccupancyGrid and the model's
edges as a visualization_msgs/MarkerArray, both in the map frame (the node publishes them
latched: transient local).

The grid is the world's free space (``core.occupancy.OccupancyMap``: where a camera centre may
be, for the flyable band of heights): 0 (free) there, 100 (occupied) elsewhere; its origin is
the map's lower-left corner at the band's lower height. The edges are the segments the filter
scores (``localize.edge_model.scored_segments``), one LINE_LIST marker per class (namespace
``edges/<class>``), each segment in the colour (``core.classes.palette``) of the larger class
id of its two sides: a door's outline in the door's colour, a wall's foot in the wall's.
"""

from __future__ import annotations

import array

import numpy as np
from geometry_msgs.msg import Point
from nav_msgs.msg import OccupancyGrid
from visualization_msgs.msg import Marker, MarkerArray

from core import classes as C
from core.dataset import World
from core.occupancy import OccupancyMap
from localize.edge_model import scored_segments

#: Occupancy values of a free cell and of any other.
FREE, OCCUPIED = 0, 100
#: Line width of the edge markers, metres.
EDGE_WIDTH_M = 0.02


def grid_values(free: OccupancyMap) -> np.ndarray:
    """(H, W) int8 occupancy of the free space: ``FREE`` where a camera may be, ``OCCUPIED``
    elsewhere; row r is y = origin_y + (r + 0.5) cell (OccupancyGrid's row-major order)."""
    return np.where(free.free, FREE, OCCUPIED).astype(np.int8)


def edge_lines(world: World, min_length: float = 0.0) -> dict[int, np.ndarray]:
    """The scored model edges by display class: ``{class id: (M, 2, 3) segment ends, m}``,
    the class the larger id of a segment's two sides."""
    keep = scored_segments(world, min_length)
    seg = np.asarray(world.segments, dtype=np.float64).reshape(-1, 2, 3)[keep]
    cls = np.asarray(world.segment_classes).reshape(-1, 2)[keep].max(axis=1)
    return {int(c): seg[cls == c] for c in np.unique(cls)}


def occupancy_grid(free: OccupancyMap, frame: str, stamp: tuple[int, int]) -> OccupancyGrid:
    """The free space as an OccupancyGrid in ``frame``, stamped ``stamp`` (sec, nanosec)."""
    values = grid_values(free)
    msg = OccupancyGrid()
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp
    msg.info.map_load_time = msg.header.stamp
    msg.info.resolution = float(free.cell)
    msg.info.height, msg.info.width = (int(n) for n in values.shape)
    msg.info.origin.position.x, msg.info.origin.position.y = (float(v) for v in free.origin)
    msg.info.origin.position.z = float(free.band[0])
    msg.info.origin.orientation.w = 1.0
    msg.data = array.array("b", values.tobytes())
    return msg


def edge_markers(world: World, frame: str, stamp: tuple[int, int],
                 min_length: float = 0.0) -> MarkerArray:
    """The scored model edges as LINE_LIST markers in ``frame``, one per class
    (``edge_lines``), stamped ``stamp`` (sec, nanosec)."""
    table = C.palette()
    out = MarkerArray()
    for cls, seg in edge_lines(world, min_length).items():
        m = Marker()
        m.header.frame_id = frame
        m.header.stamp.sec, m.header.stamp.nanosec = stamp
        m.ns = f"edges/{C.NAMES[cls] if cls < len(C.NAMES) else cls}"
        m.id = cls
        m.type, m.action = Marker.LINE_LIST, Marker.ADD
        m.pose.orientation.w = 1.0
        m.scale.x = EDGE_WIDTH_M
        r, g, b = (float(v) / 255.0 for v in table[cls])
        m.color.r, m.color.g, m.color.b, m.color.a = r, g, b, 1.0
        m.points = [Point(x=x, y=y, z=z) for x, y, z in seg.reshape(-1, 3).tolist()]
        out.markers.append(m)
    return out
