"""world.details: a procedural floor's door leaves, architraves, recessed and framed windows,
window walls, glass sheets and columns (datagen/worlds/details.py, floor_mesh.py,
fittings.py), in the mesh, in rendered labels and in the model edges."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from core import classes as C
from core.config import compose_config
from core.imaging.camera import project
from core.poses import pose_from_xyz_rpy
from datagen.appearance.textures import sample_textures
from datagen.config import DetailsConfig, ProceduralWorldConfig, world_config
from datagen.flights.routes import plan_route
from datagen.job import make_camera
from datagen.mesh.edge_check import EdgeChecker, agreement, free_space_poses
from datagen.mesh.edges import EdgeSet
from datagen.worlds.details import any_details
from datagen.worlds.fittings import NEAR
from datagen.worlds.floor_mesh import COLUMN, DOORWAY, GLASS, SPACE
from datagen.worlds.procedural import build_floor, draw_plan
from datagen.worlds.scene import GLASS as GLASS_LOOK
from datagen.worlds.scene import HIDDEN, building_surfaces
from datagen.worlds.site import building_site

#: Every detail, most of them always: a small floor (3 x 2 corridor lines) with glass walls
#: and columns wherever the plan has room.
ALL = DetailsConfig(door_leaves=1.0, door_open=0.5, double_doors=0.3, glazed_doors=0.35,
                    architraves=0.7, window_recess=1.0, window_frames=1.0, sills=1.0,
                    window_walls=0.4, glass_sheets=0.7, round_columns=0.5, room_columns=1.0,
                    pilasters=1.0)
SMALL = ProceduralWorldConfig(size=[26.0, 22.0], grid_spacing=[6.0, 7.0], glass=0.5,
                              columns=1.0)
SPEC = replace(SMALL, seed=3, details=ALL)


def look_at(camera, eye, target) -> np.ndarray:
    """(4, 4) world_from_cam of a level camera at ``eye`` looking at ``target`` (m)."""
    d = np.asarray(target, float) - np.asarray(eye, float)
    rpy = [0.0, -np.arctan2(d[2], np.hypot(d[0], d[1])), np.arctan2(d[1], d[0])]
    return pose_from_xyz_rpy(np.asarray(eye, float)[None], np.asarray([rpy]))[0] \
        @ camera.body_from_cam


@pytest.fixture(scope="module")
def floor():
    return build_floor(SPEC)


@pytest.fixture(scope="module")
def site(floor):
    return building_site(floor[0], SPEC, "test details")


@pytest.fixture(scope="module")
def camera():
    return make_camera({"width": 160, "height": 120, "hfov_deg": 80})


@pytest.fixture(scope="module")
def renderer(site, camera):
    """The floor's scene in the real renderer, every light on."""
    from core.imaging.variant import choose_variant
    from datagen.rendering.render import Renderer

    choose_variant()
    tex = sample_textures(np.random.default_rng(0), 32)
    r = Renderer(site.scene, camera, tex, near_lights=True)
    r.set_lights(np.full((r.num_lights, 3), 8.0))
    return r


def render(renderer, pose):
    renderer.set_camera(pose)
    return renderer.render(spp=2, seed=0)


def pixel(camera, pose, point) -> tuple[int, int]:
    uv, z = project(camera.K, np.linalg.inv(pose), np.asarray(point, float)[None])
    assert z[0] > 0 and 0 <= uv[0, 0] < camera.width and 0 <= uv[0, 1] < camera.height
    return int(uv[0, 1]), int(uv[0, 0])


def door_pose(camera, free, fit, side: float = 0.0) -> tuple[np.ndarray | None, float]:
    """A camera in the corridor in front of a doorway, facing its middle at 1 m, at the
    farthest of 1.6, 1.2, 0.9 m from the wall whose place is free; (None, 0) if none is."""
    into = np.sign(fit.faces[1] - fit.faces[0])
    target = np.zeros(3)
    target[fit.along], target[1 - fit.along], target[2] = (fit.a0 + fit.a1) / 2, fit.faces[0], 1.0
    for dist in (1.6, 1.2, 0.9):
        eye = target.copy()
        eye[1 - fit.along] -= into * dist
        eye[fit.along] += side
        eye[2] = 1.3
        if free.contains(eye[None, :2])[0]:
            return look_at(camera, eye, target), dist
    return None, 0.0


def first_door(plan, free, camera, pred):
    """The first doorway fitting (and leaf) matching ``pred(fit, leaf)`` with a free view."""
    for fit in plan.details.doors.values():
        for leaf in [*fit.leaves, None]:
            if pred(fit, leaf):
                pose, dist = door_pose(camera, free, fit)
                if pose is not None:
                    return fit, leaf, pose, dist
    raise AssertionError("no such doorway with a free view")


class TestSettings:
    def test_off_draws_nothing(self):
        """All shares 0: the seed's own floor, whatever the other details' keys say."""
        a, pa = build_floor(replace(SMALL, seed=3))
        off = DetailsConfig(door_open=0.2, door_angle=[30.0, 60.0])
        assert not any_details(off)
        b, pb = build_floor(replace(SMALL, seed=3, details=off))
        for x, y in ((a.vertices, b.vertices), (a.faces, b.faces),
                     (a.face_class, b.face_class), (pa.rects, pb.rects)):
            np.testing.assert_array_equal(x, y)
        assert pb.details is None and "details" not in pb.info

    def test_details_keep_the_floor_they_are_added_to(self, floor):
        """The details draw from a stream of their own: the corridors, lobby and rooms are the
        seed's; only what the details change differs (doors widened to double doors, glass
        walls made sheets, square columns made round)."""
        base = draw_plan(SPEC, np.random.default_rng(SPEC.seed))
        _, plan = floor
        assert plan.info["rooms"] == base.info["rooms"] and plan.info["lobby"] == base.info[
            "lobby"]
        kept = np.flatnonzero(base.kinds == SPACE)  # before any column the details remove
        np.testing.assert_array_equal(plan.rects[kept], base.rects[kept])
        doors = plan.rects[plan.roles == "door"]
        assert len(doors) == (base.roles == "door").sum()

    def test_same_seed_same_floor(self, floor):
        b, plan = build_floor(SPEC)
        np.testing.assert_array_equal(b.vertices, floor[0].vertices)
        np.testing.assert_array_equal(b.face_class, floor[0].face_class)
        assert plan.info["details"] == floor[1].info["details"]

    @pytest.mark.parametrize("changes,match", [
        ({"door_leaves": 1.5}, r"world\.details\.door_leaves: 1\.5 must be a share"),
        ({"door_angle": [10.0, 120.0]}, r"world\.details\.door_angle"),
    ])
    def test_bad_settings(self, changes, match):
        with pytest.raises(ValueError, match=match):
            build_floor(replace(SMALL, details=replace(ALL, **changes)))

    def test_recessed_windows_need_an_outer_wall(self):
        with pytest.raises(ValueError, match=r"world\.outer_wall: 0\.05 m is too thin"):
            build_floor(replace(SPEC, outer_wall=0.05))
        build_floor(replace(SMALL, outer_wall=0.05, details=replace(
            ALL, window_recess=0.0, window_walls=0.0)))  # the rest need none

    def test_every_detail_on_the_test_floor(self, floor):
        counts = floor[1].info["details"]
        for key in ("leaves", "open_leaves", "glazed_leaves", "double_doors", "architraves",
                    "recessed_windows", "window_walls", "framed_windows", "sill_boards",
                    "glass_sheets", "round_columns", "room_columns", "pilasters"):
            assert counts[key] > 0, key
        assert set(np.unique(floor[0].face_class)) == {C.FLOOR, C.WALL, C.CEILING, C.DOOR,
                                                        C.WINDOW}

    def test_generalist_recipe_turns_them_on(self):
        """The generalist's training floors have details; the test floors (world=procedural's
        defaults, benchmarks/thirdparty.py) have none."""
        cfg = compose_config("datagen", ["datagen_experiment=generalist_floors",
                                         "world.seed=2"])
        assert any_details(world_config(cfg["world"]).details)
        cfg = compose_config("datagen", ["world=procedural", "world.seed=101"])
        assert not any_details(world_config(cfg["world"]).details)


class TestColumns:
    def test_round_column_in_mesh_labels_and_edges(self, floor, site, camera):
        b, plan = floor
        col = next(c for c in plan.details.columns if c.engaged is None)
        # mesh: a prism of wall faces at the column's radius, floor to ceiling
        tri = b.vertices[b.faces]
        r = np.linalg.norm(tri[:, :, :2] - col.centre, axis=2)
        on = (np.abs(r - col.radius) < 1e-6).all(axis=1)
        assert on.sum() == 2 * col.sides
        assert (b.face_class[on] == C.WALL).all()
        assert tri[on][:, :, 2].min() == 0.0 and tri[on][:, :, 2].max() == pytest.approx(
            col.top)
        # labels and edges: seen from 2.2 m, it stands out as wall over the floor; the model
        # edges along its foot match the label boundary there
        w = site.world
        checker = EdgeChecker(w.vertices, w.faces, w.face_class, w.segments,
                              w.segment_classes, camera.K, camera.width, camera.height,
                              w.normals)
        centre = np.array([*col.centre, 1.0])
        for ang in np.linspace(0, 2 * np.pi, 13)[:-1]:
            eye = centre + [2.2 * np.cos(ang), 2.2 * np.sin(ang), 0.3]
            if w.free.contains(eye[None, :2])[0]:
                break
        pose = look_at(camera, eye, centre)
        label = checker.labels(pose)
        row, col_px = pixel(camera, pose, centre)
        assert label[row, col_px] == C.WALL
        width = (label[row] == C.WALL)[max(col_px - 30, 0):col_px + 30].sum()
        expect = 2 * col.radius * camera.K[0, 0] / 2.2
        assert width >= 0.7 * expect
        toward = (eye[:2] - col.centre) / np.linalg.norm(eye[:2] - col.centre)
        foot_row, _ = pixel(camera, pose, [*(col.centre + col.radius * toward), 0.0])
        edges = checker.edges(pose)
        foot = edges[foot_row - 2:foot_row + 3, col_px - 3:col_px + 4]
        assert (foot == C.pair_code(C.FLOOR, C.WALL)).any()
        a = agreement(checker, pose[None])
        assert a.recall >= 0.9 and a.precision >= 0.9

    def test_columns_are_not_free_space(self, floor, site):
        b, plan = floor
        free = site.world.free
        centres = [c.centre for c in plan.details.columns]
        centres += [(r[:2] + r[2:]) / 2 for r, k in zip(plan.rects, plan.kinds, strict=True)
                    if k == COLUMN]
        assert len(centres) >= 5
        assert not free.contains(np.asarray(centres)).any()
        route = plan_route(free, np.random.default_rng(0))
        gaps = np.linalg.norm(route[:, None] - np.asarray(centres)[None], axis=2)
        assert gaps.min() > free.margin + 0.1  # the route keeps clear of every column


class TestDoors:
    def test_open_leaf_is_door_and_the_room_is_seen(self, floor, site, renderer, camera):
        _, plan = floor
        fit, leaf, pose, dist = first_door(
            plan, site.world.free, camera,
            lambda f, lf: (len(f.leaves) == 1 and lf is not None and lf.angle > 30
                           and lf.glazed is None))
        rgb, label, depth = render(renderer, pose)
        z = np.array([0.0, 0.0, 1.0])
        middle = leaf.hinge + leaf.w * leaf.width / 2 + leaf.t * leaf.thickness / 2 \
            + z * leaf.height / 2
        assert label[pixel(camera, pose, middle)] == C.DOOR
        # through the opening, beside the leaf: the room, well beyond the wall
        corners = []
        for a in (fit.a0, fit.a1):
            for h in (0.4, 1.6):
                p = np.zeros(3)
                p[fit.along], p[1 - fit.along], p[2] = a, fit.faces[0], h
                corners.append(pixel(camera, pose, p))
        rows, cols = np.array(corners).T
        box = np.s_[rows.min():rows.max(), cols.min():cols.max()]
        beyond = (depth[box] > dist + 0.6) & (label[box] != C.DOOR)
        assert beyond.mean() > 0.1

    def test_closed_leaf_fills_its_opening(self, floor, site, renderer, camera):
        _, plan = floor
        fit, _, pose, dist = first_door(
            plan, site.world.free, camera,
            lambda f, lf: bool(f.leaves) and all(x.angle == 0 and x.glazed is None
                                                 for x in f.leaves))
        _, label, depth = render(renderer, pose)
        inside = []
        for f in np.linspace(0.15, 0.85, 5):
            for h in (0.6, 1.0, 1.3):
                p = np.zeros(3)
                p[fit.along], p[1 - fit.along], p[2] = (fit.a0 + f * (fit.a1 - fit.a0),
                                                        fit.faces[1], h)
                inside.append(pixel(camera, pose, p))
        rows, cols = np.array(inside).T
        assert (label[rows, cols] == C.DOOR).all()
        assert (depth[rows, cols] < dist + 0.5).all()  # the room is not seen through it

    def test_glazed_leaf_pane_is_door_glass(self, floor, site, renderer, camera):
        """The glass pane of a glazed leaf is class door, drawn see-through (the scene's glass
        look); a render labels it door."""
        b, plan = floor
        fit, leaf, pose, _ = first_door(
            plan, site.world.free, camera,
            lambda f, lf: lf is not None and lf.glazed is not None and lf.angle == 0)
        glass = [s for s in building_surfaces(b)[0] if s.texture == GLASS_LOOK]
        assert {s.class_id for s in glass} == {C.DOOR, C.WINDOW}
        _, label, _ = render(renderer, pose)
        stile, bottom, top = leaf.glazed
        z = np.array([0.0, 0.0, 1.0])
        pane = leaf.hinge + leaf.w * leaf.width / 2 + leaf.t * leaf.thickness / 2 \
            + z * (bottom + (leaf.height - top - bottom) / 2)
        assert label[pixel(camera, pose, pane)] == C.DOOR
        stile = pane + leaf.w * (leaf.width / 2 - stile / 2)  # the frame around the pane
        assert label[pixel(camera, pose, stile)] == C.DOOR

    def test_architrave_edges(self, floor, site):
        """An architrave stands on both faces of the wall: model edges door|wall run up its
        outer sides, ``depth`` off the wall, and across its top."""
        _, plan = floor
        fit = next(f for f in plan.details.doors.values() if f.architrave is not None)
        width, depth = fit.architrave
        w = site.world
        seg, cls = w.segments, np.sort(w.segment_classes, axis=1)
        door_wall = (cls[:, 0] == C.WALL) & (cls[:, 1] == C.DOOR)
        vertical = np.abs(seg[:, 0, 2] - seg[:, 1, 2]) > 1.5
        for a in (fit.a0 - width, fit.a1 + width):
            for face in fit.faces:
                at = np.abs(seg[:, :, fit.along] - a).max(axis=1) < 0.01
                near = np.abs(seg[:, :, 1 - fit.along] - face).max(axis=1) < depth + 0.01
                assert (door_wall & vertical & at & near).any(), (a, face)


class TestGlassAndWindows:
    def test_glass_sheet_is_window_and_see_through(self, floor, renderer, camera):
        b, plan = floor
        i, side = next((i, s) for i, s in plan.details.sheets.items() if s != 0)
        r = plan.rects[i]
        along = 0 if r[2] - r[0] > r[3] - r[1] else 1
        # the point of the sheet farthest from a doorway through it
        doors = plan.rects[plan.kinds == DOORWAY]
        doors = doors[(doors[:, along] < r[along + 2]) & (doors[:, along + 2] > r[along])
                      & (doors[:, 1 - along] <= r[1 - along]) & (doors[:, 3 - along]
                                                                   >= r[3 - along])]
        at = np.linspace(r[along] + 0.3, r[along + 2] - 0.3, 50)
        gap = np.min(np.abs(at[:, None] - doors[:, [along, along + 2]].mean(axis=1)), axis=1,
                     initial=np.inf)
        target = np.zeros(3)
        target[along], target[1 - along], target[2] = at[np.argmax(gap)], r[1 - along], 1.0
        eye = target.copy()
        eye[1 - along] += side * 1.2
        eye[2] = 1.3
        pose = look_at(camera, eye, target)
        rgb, label, depth = render(renderer, pose)
        row, col = pixel(camera, pose, target)
        patch = np.s_[row - 3:row + 4, col - 10:col + 11]
        assert (label[patch] == C.WINDOW).mean() > 0.5
        seen = label[patch] == C.WINDOW
        assert rgb[patch][seen].mean() > 5  # lit: the room behind shows through
        # the sheet's far face is in the model, not in the scene
        surfaces = building_surfaces(b)[0]
        assert not any(s.texture == HIDDEN for s in surfaces)
        assert HIDDEN in b.looks

    def test_framed_window(self, floor, site, renderer, camera):
        """A framed window: bars of class window in its recess, in front of the glass; the
        view is fitted to its panes; a render labels the frame window."""
        b, plan = floor
        win = next(w for w in plan.details.windows.values() if w.frame is not None)
        fw, fd = win.frame
        back = win.line + win.outward * win.depth
        tri = b.vertices[b.faces]
        across = tri[:, :, 1 - win.along]
        in_front = ((np.abs(across - back) >= NEAR - 1e-6).all(axis=1)
                    & (np.abs(across - back) <= fd + 1e-6).all(axis=1)
                    & ((across - back) * win.outward <= 0).all(axis=1))
        spans = ((tri[:, :, win.along] >= win.a0).all(axis=1)
                 & (tri[:, :, win.along] <= win.a1).all(axis=1))
        bars = in_front & spans
        assert bars.sum() >= 12 * (4 + win.panes - 1)  # 12 faces a box
        assert (b.face_class[bars] == C.WINDOW).all()
        view = [s for s in building_surfaces(b)[0] if s.name == "window_window"][0]
        assert view.uv[:, 1].min() >= -1e-6 and view.uv[:, 1].max() <= 1 + 1e-6
        # a render from the room: the bottom rail and the view are window
        target = np.zeros(3)
        target[win.along], target[1 - win.along] = (win.a0 + win.a1) / 2, back
        target[2] = win.sill + NEAR + fw / 2
        for dist in (2.0, 1.5, 1.2):
            eye = target.copy()
            eye[1 - win.along] -= win.outward * dist
            eye[2] = 1.3
            if site.world.free.contains(eye[None, :2])[0]:
                break
        pose = look_at(camera, eye, target)
        _, label, _ = render(renderer, pose)
        assert label[pixel(camera, pose, target)] == C.WINDOW
        assert label[pixel(camera, pose, target + [0, 0, 0.3])] == C.WINDOW

    def test_edge_check(self, floor, site, camera):
        """The model edges agree with the label maps of the mesh from the free space and from
        in front of every doorway with a fitting (``datagen.mesh.edge_check``)."""
        w = site.world
        cam = make_camera({})
        checker = EdgeChecker(w.vertices, w.faces, w.face_class, w.segments,
                              w.segment_classes, cam.K, cam.width, cam.height, w.normals)
        poses = list(free_space_poses(w.free, cam.body_from_cam, 20, np.random.default_rng(0)))
        for fit in floor[1].details.doors.values():
            pose, _ = door_pose(cam, w.free, fit, 0.4)
            if pose is not None:
                poses.append(pose)
        assert len(poses) >= 26
        a = agreement(checker, np.asarray(poses))
        assert a.recall >= 0.95 and a.precision >= 0.9, a.line()
        edges = EdgeSet(w.segments, w.segment_classes, w.crease_deg, w.normals)
        assert len(edges.segments) > 0


def test_plan_kinds_are_painted():
    """The kinds the details use are among the painter's (a typo would paint nothing)."""
    from datagen.worlds.floor_mesh import KINDS

    _, plan = build_floor(SPEC)
    assert set(plan.kinds) <= set(KINDS)
    assert {SPACE, DOORWAY, COLUMN} <= set(plan.kinds) and GLASS in KINDS
