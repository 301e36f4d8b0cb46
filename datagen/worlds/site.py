"""A built world: everything the datagen job reads of it, whatever it was built from.

``build_site`` makes one from the world settings: the procedural corridor (``WorldConfig``,
datagen/worlds/corridor.py), a building model file (``FileWorldConfig``, datagen/importers) or a
floor drawn from a seed (``ProceduralWorldConfig``, datagen/worlds/procedural.py; built as a file
is). All give the same structures: the ``World`` the localizer reads (classed mesh, model edges,
free space as an occupancy map), a map of where distractors and people may stand, and the world's
own flight route if it has one.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from core import classes as C
from core.dataset import World
from core.occupancy import OccupancyMap, lowest_above
from datagen.config import FileWorldConfig, ProceduralWorldConfig, WorldConfig, world_config
from datagen.importers import Building, load_building
from datagen.importers.classify import class_shares
from datagen.importers.summary import (
    edge_figures,
    import_summary,
    summary_lines,
    vertical_edges,
)
from datagen.mesh.edges import EdgeSet, extract_edges
from datagen.worlds.corridor import FREE_CELL, MAIN, OPENING, CorridorModel, build_world
from datagen.worlds.scene import Scene, building_scene, corridor_scene

log = logging.getLogger(__name__)

#: world.json's ``edges`` of a world built without model edges (``building_site(edges=False)``).
NO_EDGES = ("not extracted: a dataset without flights (training images only); make them with "
            "python -m datagen.mesh.rebuild_edges DATASET")
#: m above the floor: the heights a distractor or a person occupies (the floor map's band).
STANDING_BAND = (0.05, 1.9)
#: m above the floor: the heights an object taller than STANDING_BAND's top occupies (shelving
#: up to 2.4 m): where it may stand is this band's map (``Site.floor_for``), clear of door
#: heads and low ceilings.
TALL_BAND = (0.05, 2.45)


@dataclass
class Site:
    """A built world.

    world: the model the localizer reads (world/ files).
    scene: what the renderer draws: textured surfaces and light panels.
    floor: where distractors and people may stand: an occupancy map of STANDING_BAND above
        the floor with no margin (its clearance is the room an object has).
    route: (K, 2) m the world's own flight route (the corridor's centre line), or None: the
        flights plan theirs (``flights.<name>.route``).
    building: the classed mesh with the file's names and colours (for a corridor: its mesh).
    corridor: the corridor's boxes and lights, None for a file.
    """

    world: World
    scene: Scene
    floor: OccupancyMap
    route: np.ndarray | None
    building: Building
    corridor: CorridorModel | None = None
    _built: dict = field(default_factory=dict, repr=False)  # maps built on first use

    def floor_for(self, height: float) -> OccupancyMap | None:
        """Where an object ``height`` m tall may stand: ``floor`` up to STANDING_BAND's top,
        else the map of TALL_BAND (built on first use) up to its top; None where nothing
        that tall has room (taller than TALL_BAND, a corridor or a floor too low)."""
        if height <= STANDING_BAND[1]:
            return self.floor
        if height > TALL_BAND[1]:
            return None
        if "tall" not in self._built:
            self._built["tall"] = self._tall_floor()
        return self._built["tall"]

    def _tall_floor(self) -> OccupancyMap | None:
        if self.corridor is not None:
            return self.floor if self.corridor.height >= TALL_BAND[1] else None
        b = self.building
        try:
            return OccupancyMap.from_mesh(b.vertices, b.faces, b.face_class,
                                          float(b.info["floor_z"]) + np.asarray(TALL_BAND),
                                          0.0, self.floor.cell)
        except ValueError:  # no floor has that headroom
            return None

    def camera_top(self, xy: np.ndarray) -> np.ndarray:
        """(N,) m: the highest a camera may be at the points (N, 2) m: the lowest
        near-horizontal surface above the free space's band within its margin (a ceiling, a
        door's head; ``core.occupancy.lowest_above``) less the margin, but not below the
        band's top (built on first use)."""
        if "top" not in self._built:
            free, w = self.world.free, self.world
            lowest = lowest_above(w.vertices, w.faces, free, free.band[1])
            r = free.margin / free.cell + np.sqrt(2)  # cells whose points may lie that near
            k = int(np.ceil(r))
            y, x = np.ogrid[-k:k + 1, -k:k + 1]
            near = ndimage.minimum_filter(lowest, footprint=x * x + y * y <= r * r + 1e-9,
                                          mode="nearest")
            self._built["top"] = np.maximum(near - free.margin, free.band[1])
        rc, _ = self.world.free.cell_of(xy)
        return self._built["top"][rc[0], rc[1]]


def floor_boxes(model: CorridorModel, margin: float) -> np.ndarray:
    """(B, 4) floor regions of the corridor and its openings, shrunk by margin (m)."""
    out = [[b.lo[0] + margin, b.lo[1] + margin, b.hi[0] - margin, b.hi[1] - margin]
           for b in model.boxes if b.kind in (MAIN, OPENING)]
    return np.array(out)


def corridor_site(spec: WorldConfig) -> Site:
    """The procedural corridor; its route runs along the main corridor's centre line (+Y)."""
    model = build_world(spec)
    w = model.world
    floor = OccupancyMap.from_boxes(floor_boxes(model, 0.0), STANDING_BAND, FREE_CELL, 0.0)
    main = model.free_boxes[0]
    cx = (main[0] + main[2]) / 2
    route = np.array([[cx, main[1]], [cx, main[3]]])
    b = Building(w.vertices, w.faces, w.face_class, np.zeros(len(w.faces), np.int32),
                 [spec.name], np.full((len(w.faces), 3), np.nan), {"floor_z": 0.0})
    b.info["class_shares"] = w.info["class_shares"] = class_shares(b)
    return Site(w, corridor_scene(model), floor, route, b, model)


def camera_free_space(b: Building, spec: FileWorldConfig | ProceduralWorldConfig,
                      source: str | None = None) -> OccupancyMap:
    """Where a camera may be in a building: ``spec.z_range`` above its floor,
    ``spec.camera_margin`` from every surface, ``spec.free_cell`` cells; the floor's and the
    ceiling's footprint closed by ``spec.free_close`` and its holes up to
    ``spec.free_max_hole`` filled, obstacles where surfaces cover ``spec.obstacle_span`` of
    the band (``OccupancyMap.from_mesh``).

    Raises:
        ValueError: a bad z_range, a grid of too many cells (``core.occupancy.MAX_CELLS``) or
            no free space left, naming ``source`` (None: the file, ``spec.path``) and the
            keys.
    """
    z = np.asarray(spec.z_range, dtype=np.float64)
    if z.shape != (2,) or not 0 <= z[0] < z[1]:
        raise ValueError(f"world.z_range {z.tolist()} must be [lo, hi] m above the floor with "
                         "0 <= lo < hi")
    try:
        return OccupancyMap.from_mesh(b.vertices, b.faces, b.face_class,
                                      float(b.info["floor_z"]) + z, spec.camera_margin,
                                      spec.free_cell, ceiling_classes=(C.CEILING,),
                                      close=spec.free_close, max_hole=spec.free_max_hole,
                                      obstacle_span=spec.obstacle_span)
    except ValueError as err:
        raise ValueError(f"{source or spec.path}: world.camera_margin / world.z_range / "
                         f"world.free_cell / world.free_close / world.free_max_hole / "
                         f"world.obstacle_span: {err}") from None


def building_site(b: Building, spec: FileWorldConfig | ProceduralWorldConfig,
                  source: str, t0: float | None = None, edges: bool = True) -> Site:
    """A classed building mesh (imported, or drawn by datagen/worlds/procedural.py) made a site:
    camera free space, standing map, model edges, lights (``building_scene``).

    Args:
        b: the building; ``info["floor_z"]`` its floor height (m).
        spec: the free-space keys (``z_range``, ``camera_margin``, ``free_cell``,
            ``crease_deg``, ``light_spacing``), ``name`` and ``kind``.
        source: what errors and the log name (the file, or the procedural seed).
        t0: ``time.perf_counter()`` when building began (the log's time; None: now).
        edges: extract the model edges (``extract_edges``); False: the world has none
            (``NO_EDGES``; no flight is localized against it, e.g. a training-only dataset).

    Raises:
        ValueError: no free space left, naming the source and keys.
    """
    t0 = time.perf_counter() if t0 is None else t0
    free = camera_free_space(b, spec, source)
    floor_z = float(b.info["floor_z"])
    try:
        floor = OccupancyMap.from_mesh(b.vertices, b.faces, b.face_class,
                                       floor_z + np.asarray(STANDING_BAND), 0.0, spec.free_cell)
    except ValueError as err:
        raise ValueError(f"{source}: {err}") from None
    if edges:
        segments, seg_classes, crease, normals = extract_edges(b.vertices, b.faces,
                                                               b.face_class, spec.crease_deg)
    else:
        segments, seg_classes = np.zeros((0, 2, 3)), np.zeros((0, 2), np.uint8)
        crease, normals = np.zeros(0), np.zeros((0, 2, 3))
    info = {
        "name": spec.name, "kind": spec.kind, **b.info,
        "free_space": {"z_range": list(free.band), "cell": spec.free_cell,
                       "margin": float(spec.camera_margin), "close": float(spec.free_close),
                       "max_hole": float(spec.free_max_hole),
                       "obstacle_span": float(spec.obstacle_span),
                       "area_m2": round(free.area, 3)},
        "num_faces": int(len(b.faces)),
        "num_edges": int(len(segments)) if edges else None,
    }
    if not edges:
        info["edges"] = NO_EDGES
    world = World(vertices=b.vertices, faces=b.faces, face_class=b.face_class,
                  segments=segments, segment_classes=seg_classes, crease_deg=crease,
                  free=free, info=info, normals=normals)
    scene = building_scene(b, free, light_spacing=spec.light_spacing)
    log.info("%s: %d faces, %s model edges, %.0f m2 free, %d lights, built in %.1f s",
             source, len(b.faces), len(segments) if edges else "no", free.area,
             scene.num_lights, time.perf_counter() - t0)
    return Site(world, scene, floor, None, b)


def file_site(spec: FileWorldConfig) -> Site:
    """A building model file (``world.path``): import, model edges, free space, and the
    import summary (logged, its flags as warnings; ``world.info["import_summary"]``, saved
    as ``world/import_summary.json``).

    Raises:
        FileNotFoundError, ValueError: from the import (unknown extension, no floor, no walls,
            a storey that does not exist, ...) or no free space left, naming the file or key.
    """
    t0 = time.perf_counter()
    site = building_site(load_building(settings=spec), spec, spec.path, t0)
    w = site.world
    edges = EdgeSet(w.segments, w.segment_classes, w.crease_deg, w.normals)
    report = import_summary(site.building, w.free.area, vertical_edges(w.segments),
                            edge_figures(site.building, edges, w.free))
    w.info["import_summary"] = report
    log.info("%s: import summary:\n  %s", spec.path, "\n  ".join(summary_lines(report)))
    for f in report["flags"]:
        log.warning("%s: %s%s", spec.path, f["what"], f" (set {f['key']})" if f["key"] else "")
    return site


def procedural_site(spec: ProceduralWorldConfig, edges: bool = True) -> Site:
    """A floor drawn from ``spec.seed`` (datagen/worlds/procedural.py), built as a file's building
    (``edges``: as ``building_site``'s).

    Raises:
        ValueError: a bad setting (naming the ``world.`` key) or no free space left.
    """
    from datagen.worlds.procedural import build_floor

    t0 = time.perf_counter()
    b, _ = build_floor(spec)
    return building_site(b, spec, f"world=procedural seed {spec.seed}", t0, edges)


def build_site(spec: object, edges: bool = True) -> Site:
    """The site of world settings (``WorldConfig``, ``FileWorldConfig``,
    ``ProceduralWorldConfig`` or a mapping with ``kind``; None: the corridor's defaults).

    edges: False skips a procedural floor's model edges (``building_site``; ~80 % of its
    build): for a dataset no flight is localized in. A file's are always extracted (its import
    summary checks them), the corridor's cost nothing.
    """
    spec = world_config(spec)
    if isinstance(spec, FileWorldConfig):
        return file_site(spec)
    if isinstance(spec, ProceduralWorldConfig):
        return procedural_site(spec, edges)
    return corridor_site(spec)
