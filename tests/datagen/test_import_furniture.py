"""The model's own furniture (standing on the floor, not reaching the ceiling) is classed
clutter at import, walls, columns and partitions that reach the ceiling stay walls: a CAD
room of separate boxes, and the same room fused into one mesh with its floor like a scan."""

from __future__ import annotations

import numpy as np
import trimesh

from core import classes as C
from datagen.importers import NameRule, load_building
from datagen.importers.classify import classify
from datagen.importers.config import default_name_rules
from datagen.mesh.building import Part, assemble, face_areas_normals

H = 2.8  # m, the walls


def box(lo, hi) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return trimesh.creation.box(extents=hi - lo, transform=trimesh.transformations
                                .translation_matrix((lo + hi) / 2))


#: The room's pieces: name -> boxes (lo, hi corners, m). A 6 x 5 m room inside 0.2 m walls;
#: the counter stands against the east wall.
ROOM = {
    "south": [((-0.2, -0.2, 0), (6.2, 0, H))], "north": [((-0.2, 5, 0), (6.2, 5.2, H))],
    "west": [((-0.2, 0, 0), (0, 5, H))], "east": [((6, 0, 0), (6.2, 5, H))],
    "column": [((3.0, 1.5, 0), (3.4, 1.9, H))],
    "partition": [((2.0, 3.0, 0), (2.1, 5.0, H))],
    "table": [((0.8, 0.8, 0.72), (2.0, 1.6, 0.75))]  # the top, on legs set in 5 cm
    + [((x, y, 0), (x + 0.06, y + 0.06, 0.72)) for x in (0.85, 1.89) for y in (0.85, 1.49)],
    "shelf": [((0.2, 4.5, 0), (1.4, 4.9, 1.8))],
    "counter": [((5.4, 3.7, 0), (6.0, 4.5, 1.0))],
}
FURNITURE = ("table", "shelf", "counter")
STRUCTURE = ("south", "north", "west", "east", "column", "partition")
SLAB = ((-0.2, -0.2, -0.2), (6.2, 5.2, 0.0))


def part_name(piece: str) -> str:
    """A name no default rule matches (``table``, ``shelf``, ``column`` would): geometry
    decides."""
    return f"piece{list(ROOM).index(piece)}" if piece in ROOM else piece


def cad_room(extra: dict | None = None) -> list[Part]:
    """Each box a separate mesh (named as its piece: ``part_name``) on a floor slab."""
    parts = [Part(*_vf(box(*SLAB)), "slab")]
    parts += [Part(*_vf(box(lo, hi)), part_name(name))
              for name, boxes in {**ROOM, **(extra or {})}.items() for lo, hi in boxes]
    return parts


def _vf(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)


def gridded(lo, hi, axis: int, side: int, cuts: list[np.ndarray]) -> np.ndarray:
    """(n, 3, 3) triangles of the face of box (lo, hi) normal to ``axis`` on ``side`` (0:
    lo, 1: hi), cut at every coordinate of ``cuts`` (per axis) inside it, facing out."""
    u, v = [k for k in range(3) if k != axis]
    cu = cuts[u][(cuts[u] >= lo[u]) & (cuts[u] <= hi[u])]
    cv = cuts[v][(cuts[v] >= lo[v]) & (cuts[v] <= hi[v])]
    gu, gv = np.meshgrid(cu, cv, indexing="ij")
    p = np.zeros((*gu.shape, 3))
    p[..., u], p[..., v], p[..., axis] = gu, gv, (lo, hi)[side][axis]
    a, b, c, d = p[:-1, :-1], p[1:, :-1], p[1:, 1:], p[:-1, 1:]
    tri = np.concatenate([np.stack([a, b, c], -2).reshape(-1, 3, 3),
                          np.stack([a, c, d], -2).reshape(-1, 3, 3)])
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, axis]
    out = (n > 0) == (side == 1)
    return np.where(out[:, None, None], tri, tri[:, ::-1])


def fused_room() -> trimesh.Trimesh:
    """The room as one conforming mesh, like a scan's: every box face and the floor (z = 0)
    cut at every box's coordinates, so that feet, walls and the counter's edges share their
    vertices with the floor and the wall they meet; the parts hidden inside or against
    another box (and the boxes' bottoms, the floor under them) left out."""
    boxes = [(np.asarray(lo, float), np.asarray(hi, float)) for v in ROOM.values()
             for lo, hi in v]
    cuts = [np.unique(np.concatenate([[SLAB[0][k], SLAB[1][k]], *[(lo[k], hi[k])
                                                                for lo, hi in boxes]]))
            for k in range(3)]
    tris = [gridded(*(np.asarray(c) for c in SLAB), 2, 1, cuts)]  # the floor
    owner = [np.full(len(tris[0]), -1)]
    for i, (lo, hi) in enumerate(boxes):
        for axis, side in [(a, s) for a in range(3) for s in (0, 1)]:
            if not (axis == 2 and side == 0 and lo[2] == 0):  # no bottom on the floor
                tris.append(gridded(lo, hi, axis, side, cuts))
                owner.append(np.full(len(tris[-1]), i))
    tri, owner = np.concatenate(tris), np.concatenate(owner)
    centre = tri.mean(axis=1)
    hidden = np.zeros(len(tri), bool)
    for i, (lo, hi) in enumerate(boxes):  # a few boxes: inside or on another box's surface
        hidden |= (owner != i) & ((centre >= lo - 1e-9) & (centre <= hi + 1e-9)).all(axis=1)
    tri = tri[~hidden]
    return trimesh.Trimesh(tri.reshape(-1, 3), np.arange(3 * len(tri)).reshape(-1, 3),
                           process=False)


def faces_of(b, name: str) -> np.ndarray:
    return np.array([n == part_name(name) for n in b.names])[b.face_name]


def test_cad_furniture_is_clutter_structure_stays_wall():
    b = assemble(cad_room())
    classify(b, default_name_rules(), 0.3, "room")
    for name in FURNITURE:
        assert (b.face_class[faces_of(b, name)] == C.CLUTTER).all(), name
    _, normal = face_areas_normals(b.vertices, b.faces)
    vertical = np.abs(normal[:, 2]) < 0.3
    for name in STRUCTURE:
        assert (b.face_class[faces_of(b, name) & vertical] == C.WALL).all(), name
        assert not (b.face_class[faces_of(b, name)] == C.CLUTTER).any(), name
    z = b.vertices[b.faces][:, :, 2].mean(axis=1)
    top = faces_of(b, "table") & (z > 0.74)
    assert (normal[top, 2] > 0.9).any() and (b.face_class[top] == C.CLUTTER).all()
    floor = faces_of(b, "floor") & (normal[:, 2] > 0.9)
    assert (b.face_class[floor] == C.FLOOR).all()
    assert b.info["classed_by"]["furniture"] == sum(int(faces_of(b, n).sum())
                                                    for n in FURNITURE)


def test_a_name_rule_keeps_a_piece_structure():
    """A name rule decides before geometry: ``counter -> wall`` keeps the counter a wall;
    a low wall named ``..._wall`` (the default rule) stays wall; unnamed pieces are still
    furniture."""
    rules = [NameRule(f"^{part_name('counter')}$", "wall"), *default_name_rules()]
    b = assemble(cad_room({"low_wall": [((3.5, 0.5, 0), (5.0, 0.6, 1.1))]}))
    classify(b, rules, 0.3, "room")
    assert (b.face_class[faces_of(b, "counter")] == C.WALL).all()
    assert (b.face_class[faces_of(b, "low_wall")] == C.WALL).all()
    assert (b.face_class[faces_of(b, "table")] == C.CLUTTER).all()


def test_fused_scan_like_room(tmp_path):
    """One mesh, one name, the furniture's feet sharing the floor's vertices (the counter's
    also the east wall's): the table, the shelf and the counter are still clutter; the
    table top is not floor, its underside not ceiling."""
    path = tmp_path / "scan.ply"
    fused_room().export(path)
    b = load_building(path, {"up_axis": "z", "ceiling": "none"})
    area, normal = face_areas_normals(b.vertices, b.faces)
    centre = b.vertices[b.faces].mean(axis=1)

    def inside(lo, hi):
        return ((centre > np.asarray(lo) - 1e-6) & (centre < np.asarray(hi) + 1e-6)).all(axis=1)

    for name in FURNITURE:
        sel = np.zeros(len(b.faces), bool)
        for lo, hi in ROOM[name]:
            sel |= inside(lo, hi)
        assert sel.any() and (b.face_class[sel] == C.CLUTTER).all(), name
    table_top = inside((0.8, 0.8, 0.72), (2.0, 1.6, 0.75)) & (np.abs(normal[:, 2]) > 0.9)
    assert table_top.sum() >= 4 and (b.face_class[table_top] == C.CLUTTER).all()
    for name in STRUCTURE:
        lo, hi = ROOM[name][0]
        sel = inside(lo, hi) & (np.abs(normal[:, 2]) < 0.3)
        assert (b.face_class[sel] == C.WALL).all(), name
    floor = (centre[:, 2] < 1e-6) & (normal[:, 2] > 0.9)
    assert (b.face_class[floor] == C.FLOOR).all()
    assert b.info["classed_by"]["furniture"] > 0
