"""What the renderer draws, whatever the geometry came from: textured surfaces and light panels.

A ``Scene`` is a list of ``Surface``s (unshared triangle soups with a class, a procedural
texture key and UVs in texture repeats, or the file's own per-vertex colours) and the corners
of the emitting ceiling panels. ``corridor_scene`` makes it from the procedural corridor,
``building_scene`` from an imported ``datagen.importers.Building`` and its free space.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from core import classes as C
from core.occupancy import OccupancyMap
from datagen.mesh.building import Building
from datagen.worlds.corridor import CorridorModel

#: Physical size (u, v) in metres each texture image covers; the corridor's doors and windows
#: cover their panel exactly (None).
TEXTURE_EXTENT = {"floor": (2.0, 2.0), "ceiling": (2.0, 2.0), "wall": (4.0, 2.8),
                  "frame": (0.5, 0.5), "door": None, "window": None}
#: The same for imported buildings, whose doors and windows are not boxes: one door or window
#: image repeats every (u, v) metres from the floor up.
BUILDING_TEXTURE_EXTENT = {**TEXTURE_EXTENT, "door": (1.0, 2.1), "window": (1.2, 1.2),
                           "window_frame": (0.5, 0.5)}
#: Procedural texture of each class of an imported building; other classes (clutter, person)
#: keep the file's colours, void faces are dropped.
CLASS_TEXTURE = {C.FLOOR: "floor", C.CEILING: "ceiling", C.WALL: "wall", C.DOOR: "door",
                 C.WINDOW: "window"}
#: Looks of a procedural floor's faces with no texture: a see-through glass sheet (the
#: renderer's thin dielectric), and a face in the model that is not drawn (the far side of a
#: thin glass sheet: a ray meets one sheet only, the path tracer's depth).
GLASS, HIDDEN = "glass", "hidden"
#: Reflectance (linear RGB) of faces drawn in the file's colours where the file gives none.
DEFAULT_COLOUR = (0.4, 0.4, 0.4)
QUAD = np.array([[0, 1, 2], [0, 2, 3]])  # the two triangles of a light panel's corners


@dataclass
class Surface:
    """One part of the scene: unshared triangle soup of one class and one look.

    vertices (3T, 3) m; uv (3T, 2) texture coordinates (v up) into ``texture``: a key of
    ``sample_textures`` (in repeats of its ``TEXTURE_EXTENT``) or of
    ``Scene.images`` (the file's own image); colour: None, or (3T, 3) linear-RGB reflectance
    per vertex (the file's own colours), in which case ``texture`` is not used.
    """

    name: str
    class_id: int
    texture: str
    vertices: np.ndarray
    uv: np.ndarray
    colour: np.ndarray | None = None


@dataclass
class Scene:
    """Everything ``render.Renderer`` draws besides the distractors.

    surfaces: the textured or coloured parts (names unique). lights: (L, 4, 3) m corners of
    the emitting ceiling panels, wound so they emit downwards (labelled ceiling). images:
    the file's own texture images by key ((H, W, 3) float32 linear RGB, row 0 at the top),
    fixed (``Renderer.set_textures`` redraws the procedural ones only).
    """

    surfaces: list[Surface]
    lights: np.ndarray
    images: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def num_lights(self) -> int:
        return len(self.lights)


def _face_uv(tri: np.ndarray, axis: np.ndarray, origin: np.ndarray,
             extent: np.ndarray) -> np.ndarray:
    """Planar UVs of triangles: u along the wall (or x on floors), v up (or y on floors).

    Args:
        tri: (T, 3, 3) corners; axis: (T,) normal axis; origin: (T, 2) uv origin in metres;
        extent: (T, 2) metres per texture repeat.
    """
    u_axis = np.where(axis == 0, 1, 0)  # walls facing x run along y; else along x
    v_axis = np.where(axis == 2, 1, 2)  # floors/ceilings: v along y; walls: v up
    u = np.take_along_axis(tri, u_axis[:, None, None], 2)[..., 0]
    v = np.take_along_axis(tri, v_axis[:, None, None], 2)[..., 0]
    uv = np.stack([(u - origin[:, None, 0]) / extent[:, None, 0],
                   (v - origin[:, None, 1]) / extent[:, None, 1]], axis=-1)
    return uv


def _normals(tri: np.ndarray) -> np.ndarray:
    """(T, 3) unnormalised right-hand normals of (T, 3, 3) triangles."""
    return np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])


def corridor_scene(model: CorridorModel) -> Scene:
    """The corridor's surfaces (UVs from its boxes, see ``TEXTURE_EXTENT``; frames textured
    as frames whatever their class) and its ceiling light panels."""
    w = model.world
    tri = w.vertices[w.faces]  # (F, 3, 3)
    axis = np.argmax(np.abs(_normals(tri)), axis=1)
    lo = np.array([b.lo for b in model.boxes])[model.face_box]
    hi = np.array([b.hi for b in model.boxes])[model.face_box]
    frame = model.frame  # jambs, heads and sills
    fc = w.face_class
    groups = {
        "floor": (C.FLOOR, "floor", fc == C.FLOOR),
        "ceiling": (C.CEILING, "ceiling", fc == C.CEILING),
        "wall": (C.WALL, "wall", (fc == C.WALL) & ~frame),
        "frame": (C.WALL, "frame", (fc == C.WALL) & frame),
        "door_frame": (C.DOOR, "frame", (fc == C.DOOR) & frame),
        "window_frame": (C.WINDOW, "frame", (fc == C.WINDOW) & frame),
        "door": (C.DOOR, "door", (fc == C.DOOR) & ~frame),
        "window": (C.WINDOW, "window", (fc == C.WINDOW) & ~frame),
    }
    out = []
    for name, (cls, tex, mask) in groups.items():
        if not mask.any():
            continue
        ext = TEXTURE_EXTENT[tex]
        if ext is None:  # the panel's own box: u across it, v from its bottom to its top
            u_axis = np.where(axis[mask] == 0, 1, 0)
            r = np.arange(mask.sum())
            origin = np.stack([lo[mask][r, u_axis], lo[mask][r, 2]], axis=1)
            extent = np.stack([hi[mask][r, u_axis] - lo[mask][r, u_axis],
                               hi[mask][r, 2] - lo[mask][r, 2]], axis=1)
        else:
            origin = np.zeros((mask.sum(), 2))
            extent = np.tile(ext, (mask.sum(), 1))
        uv = _face_uv(tri[mask], axis[mask], origin, extent)
        out.append(Surface(name, cls, tex, tri[mask].reshape(-1, 3), uv.reshape(-1, 2)))
    return Scene(out, light_quads(model.lights[:, :2], model.lights[:, 2:],
                                  np.full(len(model.lights), model.height - 0.01)))


def light_quads(centre: np.ndarray, size: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Horizontal light panels wound to emit downwards.

    Args:
        centre: (L, 2) m x, y; size: (L, 2) or (2,) m along x, y; z: (L,) m heights.

    Returns:
        (L, 4, 3) m corners.
    """
    c = np.asarray(centre, np.float64).reshape(-1, 2)
    h = np.broadcast_to(np.asarray(size, np.float64), c.shape) / 2
    sx, sy = h[:, 0], h[:, 1]
    x = c[:, :1] + np.stack([-sx, -sx, sx, sx], 1)
    y = c[:, 1:] + np.stack([-sy, sy, sy, -sy], 1)
    zz = np.broadcast_to(np.asarray(z, np.float64).reshape(-1, 1), x.shape)
    return np.stack([x, y, zz], axis=-1)


def box_uv(tri: np.ndarray, extent: tuple[float, float], v0: float) -> np.ndarray:
    """Box-projected UVs of triangles in texture repeats: each triangle is projected on the
    plane of its dominant normal axis. On vertical faces u runs to the right seen from the
    front (the side the normal points to) and v up from ``v0``; on horizontal faces u = x,
    v = y.

    Args:
        tri: (T, 3, 3) m corners; extent: (u, v) m one texture image covers; v0: m, the
        height of v = 0 (the floor, so skirting boards and door bottoms sit on it).

    Returns:
        (T, 3, 2) texture coordinates.
    """
    n = _normals(tri)
    axis = np.argmax(np.abs(n), axis=1)
    origin = np.zeros((len(tri), 2))
    origin[axis != 2, 1] = v0
    uv = _face_uv(tri, axis, origin, np.tile(np.asarray(extent, np.float64), (len(tri), 1)))
    # seen from the front, +y runs right on a wall facing +x, -x on one facing +y
    flip = np.where(axis == 0, n[:, 0] < 0, (axis == 1) & (n[:, 1] > 0))
    uv[flip, :, 0] *= -1
    return uv


def building_scene(building: Building, free: OccupancyMap, light_spacing: float = 3.0,
                   light_size: tuple[float, float] = (0.6, 0.6), file_lights: bool = True,
                   file_look: bool = False,
                   extents: Mapping[str, tuple[float, float]] | None = None,
                   floor_z: float | None = None) -> Scene:
    """The scene of an imported building: ``building_surfaces`` and its lights, the file's
    (``info["lights"]``, see ``lights_from_file``) if it has any and ``file_lights``, else
    ``lattice_lights`` over ``free``.

    Args:
        building: a ``datagen.importers.Building``.
        free: the free space the camera flies in (``OccupancyMap.from_mesh`` of the building).
        light_spacing: m between lattice lights. light_size: m (x, y) of a panel.
        file_lights: use the file's lights where it has them.
        file_look, extents, floor_z: as ``building_surfaces``.
    """
    surfaces, images = building_surfaces(building, file_look, extents, floor_z)
    points = np.asarray(building.info.get("lights") or np.zeros((0, 3)), np.float64)
    if file_lights and len(points):
        lights = lights_from_file(building, points.reshape(-1, 3), free, light_size)
    else:
        lights = lattice_lights(building, free, light_spacing, light_size)
    return Scene(surfaces, lights, images)


def building_surfaces(building: Building, file_look: bool = False,
                      extents: Mapping[str, tuple[float, float]] | None = None,
                      floor_z: float | None = None
                      ) -> tuple[list[Surface], dict[str, np.ndarray]]:
    """An imported building's surfaces, by class (void faces dropped) and look.

    Floor, wall, ceiling, door and window faces get the procedural textures
    (``CLASS_TEXTURE``, redrawn per image) through ``box_uv``, or the texture their part's
    look names (``Building.face_look``: a procedural floor's frames, fitted door leaves and
    window views, ``GLASS`` see-through sheets; ``HIDDEN`` faces are in the model, not
    drawn), with the look's own UVs where given; the other classes (clutter,
    person) the file's look: its image textures (surfaces ``<class>_image<k>``, texture key
    ``image<k>``), else its face colours (``<class>_colour``; ``DEFAULT_COLOUR`` where it
    gives none). With ``file_look`` the structural faces take the file's look too where it
    has one.

    Args:
        building: a ``datagen.importers.Building``.
        extents: metres per procedural texture image, by key (``BUILDING_TEXTURE_EXTENT``).
        floor_z: m, where v = 0 on walls, doors and windows (default ``info["floor_z"]``, 0).

    Returns:
        the surfaces, and the file's images they use (key -> (H, W, 3) linear RGB).
    """
    ext = {**BUILDING_TEXTURE_EXTENT, **(extents or {})}
    v0 = float(building.info.get("floor_z", 0.0) if floor_z is None else floor_z)
    tri = np.asarray(building.vertices, np.float64)[building.faces]
    fc = np.asarray(building.face_class)
    image = np.asarray(building.face_texture)
    colour = np.asarray(building.face_colour, np.float64)
    has_colour = ~np.isnan(colour).any(axis=1)
    look = np.asarray(building.face_look)
    face_uv = np.asarray(building.face_uv, np.float64)
    out, images = [], {}
    for cls in np.unique(fc[(fc != C.VOID) & (fc < C.NUM_CLASSES)]):
        name, cls = C.NAMES[cls], int(cls)
        structural = cls in CLASS_TEXTURE
        faces = fc == cls
        own = faces if file_look or not structural else np.zeros(len(fc), bool)  # file look
        for k in np.unique(image[own & (image >= 0)]):
            m = own & (image == k)
            images[f"image{k}"] = building.textures[k]
            out.append(Surface(f"{name}_image{k}", cls, f"image{k}", tri[m].reshape(-1, 3),
                               np.asarray(building.face_uv[m], np.float64).reshape(-1, 2)))
        m = own & (image < 0) & (has_colour | (not structural))
        if m.any():
            rgb = np.where(has_colour[m, None], colour[m], np.asarray(DEFAULT_COLOUR))
            out.append(Surface(f"{name}_colour", cls, "", tri[m].reshape(-1, 3),
                               np.zeros((3 * m.sum(), 2)),
                               np.clip(np.repeat(rgb, 3, axis=0), 0.0, 1.0)))
        procedural = faces & ~(own & ((image >= 0) | has_colour | (not structural)))
        for k in np.unique(look[procedural]):
            m = procedural & (look == k)
            tex = CLASS_TEXTURE[cls] if k < 0 else building.looks[k]
            if tex == HIDDEN:
                continue
            uv = box_uv(tri[m], ext.get(tex, (1.0, 1.0)), v0)
            given = np.isfinite(face_uv[m]).all(axis=(1, 2))
            uv[given] = face_uv[m][given]
            out.append(Surface(name if k < 0 else f"{name}_{tex}", cls, tex,
                               tri[m].reshape(-1, 3), uv.reshape(-1, 2)))
    return out, images


def ceiling_above(vertices: np.ndarray, faces: np.ndarray, xyz: np.ndarray,
                  chunk: int = 1 << 22) -> np.ndarray:
    """Height of the lowest surface straight above each point (a ray cast up).

    Args:
        vertices (V, 3), faces (F, 3): the mesh, m. xyz: (N, 3) m the rays' origins.
        chunk: point-face pairs tested at once (memory bound).

    Returns:
        (N,) m, NaN where nothing is above.
    """
    p = np.asarray(xyz, np.float64).reshape(-1, 3)
    tri = np.asarray(vertices, np.float64)[faces]
    tri = tri[tri[:, :, 2].max(axis=1) > p[:, 2].min()]
    lo, hi = tri[:, :, :2].min(axis=1), tri[:, :, :2].max(axis=1)
    a, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    out = np.full(len(p), np.nan)
    step = max(1, chunk // max(len(tri), 1))
    for s in range(0, len(p), step):
        q = p[s:s + step]
        i, j = np.nonzero((q[:, None, :2] >= lo).all(-1) & (q[:, None, :2] <= hi).all(-1)
                          & (np.abs(det) > 1e-12))
        d = q[i, :2] - a[j, :2]
        u = (d[:, 0] * e2[j, 1] - d[:, 1] * e2[j, 0]) / det[j]
        v = (e1[j, 0] * d[:, 1] - e1[j, 1] * d[:, 0]) / det[j]
        z = a[j, 2] + u * e1[j, 2] + v * e2[j, 2]
        hit = (u >= 0) & (v >= 0) & (u + v <= 1) & (z > q[i, 2])
        best = np.full(len(q), np.inf)
        np.minimum.at(best, i[hit], z[hit])
        out[s:s + step] = np.where(np.isfinite(best), best, np.nan)
    return out


def light_centres(free: OccupancyMap, spacing: float) -> np.ndarray:
    """Points over the free space at least ``spacing`` apart, every free cell within
    ``spacing`` of one: free cells taken greedily, farthest from obstacles first (clearance
    capped at spacing / 2, so corridors get their centre line and open rooms a regular
    grid), ties in row order (a sweep: regular steps along straight corridors).

    Returns:
        (N, 2) m cell centres.
    """
    if not spacing > 0:
        raise ValueError(f"light_spacing must be > 0, got {spacing}")
    rc = np.array(np.nonzero(free.free))
    clear = np.round(np.minimum(free.clearance[rc[0], rc[1]], spacing / 2) / free.cell)
    xy = free.centres(rc)[np.argsort(-clear, kind="stable")]
    picked = []
    while len(xy):  # one step per light, each over the cells left
        picked.append(xy[0])
        xy = xy[np.sum((xy - xy[0]) ** 2, axis=1) >= spacing**2]
    return np.array(picked).reshape(-1, 2)


def lattice_lights(building: Building, free: OccupancyMap, spacing: float,
                   size: tuple[float, float]) -> np.ndarray:
    """Ceiling panels over the free space (``light_centres``), 1 cm below the surface
    above each (panels with nothing above are left out).

    Returns:
        (L, 4, 3) m corners.
    """
    xy = light_centres(free, spacing)
    start = np.concatenate([xy, np.full((len(xy), 1), free.band[1])], axis=1)
    z = ceiling_above(building.vertices, building.faces, start)
    ok = np.isfinite(z)
    return light_quads(xy[ok], size, z[ok] - 0.01)


def lights_from_file(building: Building, points: np.ndarray, free: OccupancyMap,
                     size: tuple[float, float]) -> np.ndarray:
    """Panels for the file's lights (N, 3) m, facing down, 1 cm under the surface above each
    light's x, y (seen from the top of ``free``'s band): labelled ceiling, they belong there,
    whatever height the file gives its (invisible) point lights; at the light's own height
    where nothing is above.

    Returns:
        (N, 4, 3) m corners.
    """
    start = np.concatenate([points[:, :2], np.full((len(points), 1), free.band[1])], axis=1)
    z = ceiling_above(building.vertices, building.faces, start)
    return light_quads(points[:, :2], size, np.where(np.isfinite(z), z - 0.01, points[:, 2]))
