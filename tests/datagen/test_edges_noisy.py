"""Model edges of noisy meshes (scans): planar regions, straightened chains, minimum length;
the corridor's edges as they were; a third-party scan's edges (skipped where ../shared is
absent)."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest
import trimesh

from core import classes as C
from core.classes import pair_code
from core.imaging.outline import outline_side, seen_pairs
from core.imaging.rays import RayCaster
from datagen.mesh.edge_polylines import simplify_segments
from datagen.mesh.edges import EdgeExtractionConfig, extract_edges
from datagen.mesh.planar_regions import face_pairs, planar_regions
from datagen.worlds.corridor import build_world

SCAN = (Path(__file__).resolve().parents[2] / ".." / "shared" / "worlds" / "icl_office_scan"
        / "of_kt2_planeopt.obj")


def _noisy(mesh: trimesh.Trimesh, sigma: float, seed: int = 0, cell: float = 0.05
           ) -> tuple[np.ndarray, np.ndarray]:
    """The mesh cut into triangles of sides <= ``cell`` m, each vertex moved by isotropic
    Gaussian noise of ``sigma`` m."""
    v, f = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, cell)
    m = trimesh.Trimesh(v, f, process=True)  # merges the shared vertices
    rng = np.random.default_rng(seed)
    return m.vertices + rng.normal(0.0, sigma, m.vertices.shape), np.asarray(m.faces)


def _by_region(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Classes from geometry: faces of an up-facing planar region floor, the rest wall."""
    n = trimesh.Trimesh(v, f, process=False).face_normals
    _, count, f0, f1 = face_pairs(f)
    region, normal = planar_regions(v, f, n, np.stack([f0, f1], 1)[count == 2])
    up = np.abs(normal[region, 2]) > 0.7
    return np.where(up, C.FLOOR, C.WALL).astype(np.uint8)


def _lengths(seg: np.ndarray) -> np.ndarray:
    return np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1)


def test_a_noisy_plane_has_no_inner_edge():
    """A 2 m x 2 m floor, 5 cm triangles, 2 mm noise: no crease inside; its border (meeting
    nothing) is its four sides, straight."""
    plane = trimesh.Trimesh([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0]], [[0, 1, 2], [0, 2, 3]])
    v, f = _noisy(plane, 0.002)
    seg, cls, crease, _ = extract_edges(v, f, np.full(len(f), C.FLOOR, np.uint8))
    mid = seg.mean(axis=1)[:, :2]
    inner = (np.abs(mid - 1.0) < 0.9).all(axis=1)
    assert not inner.any()
    assert (cls == [C.VOID, C.FLOOR]).all()
    assert len(seg) == 4 and _lengths(seg) == pytest.approx(np.full(4, 2.0), abs=0.03)


def test_a_noisy_box_has_its_twelve_edges():
    """A closed 2 x 3 x 1.5 m box, 5 cm triangles, 2 mm noise: 12 creases near 90 degrees
    along the box's edges (single faces of the noise meet at tens of degrees)."""
    box = trimesh.creation.box(extents=(2.0, 3.0, 1.5))
    v, f = _noisy(box, 0.002)
    normals = trimesh.Trimesh(v, f, process=False).face_normals
    _, count, f0, f1 = face_pairs(f)
    two = count == 2
    face_deg = np.degrees(np.arccos(np.clip(
        np.einsum("ij,ij->i", normals[f0[two]], normals[f1[two]]), -1, 1)))
    assert (face_deg > 5).sum() > 100  # the noise alone tilts many faces against each other
    seg, cls, crease, _ = extract_edges(v, f, np.full(len(f), C.WALL, np.uint8))
    assert len(seg) == 12
    assert crease == pytest.approx(np.full(12, 90.0), abs=3)
    expect = np.sort(np.repeat([1.5, 2.0, 3.0], 4))
    assert np.sort(_lengths(seg)) == pytest.approx(expect, abs=0.05)


def test_a_scanned_room_keeps_its_vertical_corners():
    """An open-topped 3 x 4 x 2.5 m room seen from inside (one noisy mesh, classed by
    geometry): its 4 vertical corners (wall|wall), its floor|wall foot lines, the walls' top
    boundary, and nothing else."""
    room = trimesh.creation.box(extents=(3.0, 4.0, 2.5))
    room.invert()  # normals into the room
    top = room.triangles_center[:, 2] > 1.2
    room.update_faces(~top)
    v, f = _noisy(room, 0.002, seed=1)
    classes = _by_region(v, f)
    seg, cls, crease, _ = extract_edges(v, f, classes)
    d = seg[:, 1] - seg[:, 0]
    vertical = np.abs(d[:, 2]) > 0.9 * _lengths(seg)
    assert vertical.sum() == 4
    assert (cls[vertical] == [C.WALL, C.WALL]).all()
    assert _lengths(seg[vertical]) == pytest.approx(np.full(4, 2.5), abs=0.05)
    assert crease[vertical] == pytest.approx(np.full(4, 90.0), abs=3)
    rim = (cls == [C.VOID, C.WALL]).all(axis=1)
    assert rim.sum() == 4 and _lengths(seg[rim]).sum() == pytest.approx(14.0, abs=0.1)
    # the floor|wall class boundary runs along the triangle sides the classes change at, as
    # a label image shows it: its pieces of at least 5 cm, all on the room's foot lines
    floor = (cls == [C.FLOOR, C.WALL]).all(axis=1)
    assert (vertical | rim | floor).all() and floor.any()
    assert np.abs(seg[floor][:, :, 2] + 1.25).max() < 0.02
    assert _lengths(seg[floor]).min() >= 0.05
    # straightened too, it is the room's four foot lines
    seg, cls, _, _ = extract_edges(v, f, classes,
                                settings=EdgeExtractionConfig(straighten_class_changes=True))
    floor = (cls == [C.FLOOR, C.WALL]).all(axis=1)
    assert floor.sum() == 4 and _lengths(seg[floor]).sum() == pytest.approx(14.0, abs=0.1)
    assert len(seg) == 12


def test_regions_of_a_noisy_box_are_its_six_sides():
    box = trimesh.creation.box(extents=(2.0, 3.0, 1.5))
    v, f = _noisy(box, 0.002)
    n = trimesh.Trimesh(v, f, process=False).face_normals
    _, count, f0, f1 = face_pairs(f)
    region, normal = planar_regions(v, f, n, np.stack([f0, f1], 1)[count == 2])
    assert len(normal) == 6
    axis = np.argmax(np.abs(normal), axis=1)
    assert sorted(axis.tolist()) == [0, 0, 1, 1, 2, 2]
    assert np.abs(normal).max(axis=1) == pytest.approx(np.ones(6), abs=1e-3)


def test_a_zigzag_chain_becomes_one_segment_and_a_corner_stays():
    """Pieces zig-zagging 5 mm about the x axis for 1 m, then turning up the y axis: two
    segments at 2 cm tolerance; a second group on the same points chains apart."""
    x = np.linspace(0, 1, 21)
    pts = np.c_[x, 0.005 * (-1) ** np.arange(21), np.zeros(21)]
    pts = np.r_[pts, [[1.0, 0.5, 0.0], [1.0, 1.0, 0.0]]]
    seg = np.stack([pts[:-1], pts[1:]], axis=1)
    out, member = simplify_segments(seg, np.zeros(len(seg), int), 0.02)
    assert len(out) == 2
    assert _lengths(out).sum() == pytest.approx(2.0, abs=0.02)
    out, _ = simplify_segments(np.r_[seg, seg], np.r_[np.zeros(len(seg)), np.ones(len(seg))],
                               0.02)
    assert len(out) == 4


def test_a_closed_loop_is_straightened_into_its_sides():
    sq = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    ring = np.concatenate([np.linspace(sq[i], sq[(i + 1) % 4], 5)[:-1] for i in range(4)])
    seg = np.stack([ring, np.roll(ring, -1, axis=0)], axis=1)
    out, _ = simplify_segments(seg, np.zeros(len(seg), int), 0.01)
    assert _lengths(out).sum() == pytest.approx(4.0)
    assert 4 <= len(out) <= 5  # the loop is cut once, possibly inside a side


#: the default corridor's 132 edges, as they were before planar regions and straightening
#: (sha256 of the segments rounded to 0.1 mm, sorted, with classes and crease).
CORRIDOR_DIGEST = "97f6f423a376c535"


def _digest(seg: np.ndarray, cls: np.ndarray, crease: np.ndarray) -> str:
    rows = np.c_[np.round(seg.reshape(len(seg), -1), 4), cls, np.round(crease, 3)]
    rows = rows[np.lexsort(rows.T[::-1])]
    return hashlib.sha256(np.ascontiguousarray(rows).tobytes()).hexdigest()[:16]


def test_the_corridor_edges_are_unchanged():
    """Its 132 edges as they were; its creases carry their faces' normals. Its outlines (a
    crease seen with one face turned away) are edges of the door and window recesses: seen
    from its free space they show a wall against the door or window inside the recess, or
    one class (a frame against the door leaf), nothing else."""
    w = build_world().world
    assert len(w.segments) == 132
    assert _lengths(w.segments).sum() == pytest.approx(169.0)
    assert _digest(w.segments, w.segment_classes, w.crease_deg) == CORRIDOR_DIGEST
    crease = ~np.isnan(w.normals[:, 0, 0])
    assert (crease == (w.crease_deg > 20)).all()
    cells = w.free.centres(np.nonzero(w.free.free))
    eyes = np.c_[cells, np.full(len(cells), 1.4)]
    caster = RayCaster(w.vertices, w.faces)
    shown = set()
    for s, n, c in zip(w.segments[crease], w.normals[crease], w.segment_classes[crease],
                       strict=True):
        mid = np.repeat(s.mean(axis=0)[None], len(eyes), axis=0)
        side = outline_side(np.repeat(n[None], len(eyes), axis=0), mid, eyes)
        seen = (side >= 0) & ~caster.hidden(eyes, mid, 0.02)
        k = int(seen.sum())
        shown |= set(seen_pairs(np.repeat(c[None], k, axis=0), np.repeat(n[None], k, axis=0),
                                mid[seen], eyes[seen], caster, w.face_class).tolist())
    assert shown == {0, int(pair_code(C.WALL, C.DOOR)), int(pair_code(C.WALL, C.WINDOW))}


@pytest.mark.slow
def test_the_icl_scan_gives_few_straight_edges_with_vertical_corners():
    """The ICL office scan (../shared/worlds, imported with the defaults): a few hundred
    straight segments instead of the ~10,000 of single-face creases, vertical corners among
    them (most of them the desks', classed clutter as the scan's own furniture)."""
    if not SCAN.is_file():
        pytest.skip(f"{SCAN} is absent (../shared/worlds not here)")
    from datagen.importers import load_building

    b = load_building(SCAN)
    seg, cls, crease, _ = extract_edges(b.vertices, b.faces, b.face_class)
    assert 300 < len(seg) < 3000
    length = _lengths(seg)
    assert length.min() >= 0.05
    vertical = (np.abs(seg[:, 1, 2] - seg[:, 0, 2]) > 0.9 * length) & (length > 0.5)
    assert np.isin(cls[vertical], [C.WALL, C.CLUTTER]).all(axis=1).sum() >= 4
