"""An imported building: one triangle mesh with a class, a name and a colour per face.

Readers (``sdf``, ``meshfile``, ``ifc``) return ``Part``s, pieces of mesh in world
coordinates (metres, Z up) that share a name; ``assemble`` joins them into one mesh with
coincident vertices merged (so ``datagen.mesh.edges`` finds creases from adjacency).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Class id of a face the format did not class (name rules and geometry decide later).
UNSET = 255


@dataclass
class Part:
    """A piece of a building from a reader.

    vertices (n, 3) float64 metres, world frame, Z up; faces (m, 3) int; name: what the name
    rules see (e.g. ``model/link/visual/material``); colour (3,) or (m, 3) linear RGB in
    [0, 1], NaN where the file gives none; face_class (m,) uint8 or one int, UNSET where the
    format gives no class; texture: the file's image, (H, W, 3) float32 linear RGB, row 0 at
    the top (one array object per image file: parts share it), or None; uv: (m, 3, 2)
    texture coordinates of each face's corners (v = 0 at the image's bottom) with a texture,
    or with a look; look: the procedural texture the renderer draws the faces in ("": their
    class's; a procedural world's details: ``datagen.worlds.scene.building_surfaces``), its
    uv in texture repeats where given (NaN: box-projected).
    """

    vertices: np.ndarray
    faces: np.ndarray
    name: str
    colour: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    face_class: np.ndarray | int = UNSET
    texture: np.ndarray | None = None
    uv: np.ndarray | None = None
    look: str = ""

    def moved(self, matrix: np.ndarray, name: str | None = None,
              colour: np.ndarray | None = None) -> Part:
        """The part through a (4, 4) transform (``transformed``; corner UVs follow a reversed
        winding), optionally renamed or recoloured."""
        v, f = transformed(matrix, self.vertices, self.faces)
        uv = self.uv
        if uv is not None and np.linalg.det(matrix[:3, :3]) < 0:
            uv = uv[:, ::-1]
        return Part(v, f, self.name if name is None else name,
                    self.colour if colour is None else colour, self.face_class, self.texture, uv,
                    self.look)


@dataclass
class Building:
    """An imported building model.

    vertices (V, 3) float64 metres, Z up; faces (F, 3) int64 (coincident vertices merged);
    face_class (F,) uint8 ids of core.classes; face_name (F,) int32 index into ``names``;
    face_colour (F, 3) float64 linear RGB in [0, 1] where the file gives colours, else NaN;
    info: format, counts, missing models (name -> count), class area shares, units, timing,
    lights; textures: the file's images ((H, W, 3) float32 linear RGB, row 0 at the top);
    face_texture (F,) int32 index into ``textures``, -1 where none; face_uv (F, 3, 2) float32
    texture coordinates of the corners (v = 0 at the image's bottom), NaN where no texture;
    looks: the procedural textures named by parts (``Part.look``); face_look (F,) int16 index
    into ``looks``, -1 where none (the class's texture); face_uv then holds the look's
    coordinates, NaN where box-projected.
    """

    vertices: np.ndarray
    faces: np.ndarray
    face_class: np.ndarray
    face_name: np.ndarray
    names: list[str]
    face_colour: np.ndarray
    info: dict
    textures: list[np.ndarray] = field(default_factory=list)
    face_texture: np.ndarray | None = None
    face_uv: np.ndarray | None = None
    looks: list[str] = field(default_factory=list)
    face_look: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.face_texture is None:
            self.face_texture = np.full(len(self.faces), -1, np.int32)
        if self.face_uv is None:
            self.face_uv = np.full((len(self.faces), 3, 2), np.nan, np.float32)
        if self.face_look is None:
            self.face_look = np.full(len(self.faces), -1, np.int16)

    def add_faces(self, vertices: np.ndarray, faces: np.ndarray, face_class: int,
                  name: str) -> int:
        """Append untextured, uncoloured faces (indices into ``vertices``, appended too) of
        one class and a new name; returns their number."""
        n = len(faces)
        self.faces = np.concatenate([self.faces, np.asarray(faces, np.int64)
                                     + len(self.vertices)])
        self.vertices = np.concatenate([self.vertices, vertices])
        self.face_class = np.concatenate([self.face_class, np.full(n, face_class, np.uint8)])
        self.names = [*self.names, name]
        self.face_name = np.concatenate([self.face_name,
                                         np.full(n, len(self.names) - 1, np.int32)])
        self.face_colour = np.concatenate([self.face_colour, np.full((n, 3), np.nan)])
        self.face_texture = np.concatenate([self.face_texture, np.full(n, -1, np.int32)])
        self.face_uv = np.concatenate([self.face_uv, np.full((n, 3, 2), np.nan, np.float32)])
        self.face_look = np.concatenate([self.face_look, np.full(n, -1, np.int16)])
        return n


def check_finite(parts: list[Part], source: object) -> None:
    """Raise ValueError naming ``source`` (the file) and the parts if any vertex of
    ``parts`` has a coordinate that is NaN or infinite (a broken export): such a vertex has
    no place in the building, and the faces using it would break the classes and the free
    space."""
    bad = [(p.name, int((~np.isfinite(p.vertices).all(axis=1)).sum())) for p in parts]
    count = sum(n for _, n in bad)
    if not count:
        return
    total = sum(len(p.vertices) for p in parts)
    names = [name for name, n in bad if n]
    listed = ", ".join(names[:5]) + (f" and {len(names) - 5} more" if len(names) > 5 else "")
    raise ValueError(f"{source}: {count} of {total} vertices are not finite numbers (NaN or "
                     f"infinite) in {listed}; repair or export the model again")


def assemble(parts: list[Part], merge_tol: float = 1e-6) -> Building:
    """Join parts into one mesh; vertices closer than about ``merge_tol`` metres are merged
    and faces that become degenerate dropped. ``info`` is left empty."""
    parts = [p for p in parts if len(p.faces)]
    if not parts:
        raise ValueError("the model has no triangles")
    counts = np.array([len(p.faces) for p in parts])
    offsets = np.cumsum([0] + [len(p.vertices) for p in parts])[:-1]
    vertices = np.concatenate([np.asarray(p.vertices, np.float64) for p in parts])
    faces = np.concatenate([np.asarray(p.faces, np.int64) + o
                            for p, o in zip(parts, offsets, strict=True)])
    names, name_idx = np.unique([p.name for p in parts], return_inverse=True)
    face_name = np.repeat(name_idx.astype(np.int32), counts)
    face_class = np.concatenate([np.broadcast_to(np.asarray(p.face_class, np.uint8), (n,))
                                 for p, n in zip(parts, counts, strict=True)])
    colour = np.concatenate([np.broadcast_to(np.asarray(p.colour, np.float64), (n, 3))
                             for p, n in zip(parts, counts, strict=True)])
    textures, face_texture, face_uv = _textures(parts)
    looks = sorted({p.look for p in parts if p.look})
    face_look = np.concatenate([np.full(n, looks.index(p.look) if p.look else -1, np.int16)
                                for p, n in zip(parts, counts, strict=True)])
    key = np.round(vertices / merge_tol).astype(np.int64)
    uniq, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    vertices = vertices[first]
    faces = inverse.ravel()[faces]
    tri = vertices[faces]
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    keep = ((faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2])
            & (faces[:, 0] != faces[:, 2]) & (area2 > merge_tol**2))
    return Building(vertices=vertices, faces=faces[keep], face_class=face_class[keep].copy(),
                    face_name=face_name[keep], names=[str(n) for n in names],
                    face_colour=colour[keep].copy(), info={}, textures=textures,
                    face_texture=face_texture[keep], face_uv=face_uv[keep], looks=looks,
                    face_look=face_look[keep])


def _textures(parts: list[Part]) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """The distinct images of the parts (by array identity), (F,) int32 image index per face
    (-1 none) and (F, 3, 2) float32 corner UVs (NaN where none: no image and no look)."""
    images: list[np.ndarray] = []
    index: dict[int, int] = {}
    face_texture, face_uv = [], []
    for p in parts:
        n = len(p.faces)
        if p.texture is None or p.uv is None:
            face_texture.append(np.full(n, -1, np.int32))
            face_uv.append(np.full((n, 3, 2), np.nan, np.float32) if p.uv is None or not p.look
                           else np.asarray(p.uv, np.float32).reshape(n, 3, 2))
            continue
        if id(p.texture) not in index:
            index[id(p.texture)] = len(images)
            images.append(p.texture)
        face_texture.append(np.full(n, index[id(p.texture)], np.int32))
        face_uv.append(np.asarray(p.uv, np.float32).reshape(n, 3, 2))
    return images, np.concatenate(face_texture), np.concatenate(face_uv)


def weighted_quantile(values: np.ndarray, weights: np.ndarray, q: float) -> float:
    """The ``q`` quantile (0..1) of ``values`` weighted by ``weights``."""
    order = np.argsort(values)
    cum = np.cumsum(weights[order])
    return float(values[order][np.searchsorted(cum, q * cum[-1])])


def face_areas_normals(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Areas (F,) m^2 and unit normals (F, 3) (right-hand rule) of triangles."""
    tri = vertices[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(n, axis=1)
    return norm / 2, n / np.maximum(norm, 1e-300)[:, None]


def transformed(matrix: np.ndarray, vertices: np.ndarray, faces: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) vertices through a (4, 4) homogeneous transform, and the (m, 3) faces with their
    winding reversed where the transform mirrors (negative determinant), so normals stay
    outward."""
    v = np.asarray(vertices, np.float64) @ matrix[:3, :3].T + matrix[:3, 3]
    f = np.asarray(faces, np.int64)
    return v, (f[:, ::-1] if np.linalg.det(matrix[:3, :3]) < 0 else f)
