"""Walking people of a flight: each person's track over the frames (``person_tracks``),
walking towards goals in sight around the others."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.occupancy import OccupancyMap
from core.poses import wrap_angle
from datagen.config import DistractorPreset
from datagen.distractors.placement import _Floor, place_objects
from datagen.flights.routes import first_blocked

GOAL_CANDIDATES = 32  # goals drawn per new goal, among those in sight a far one is taken
FAR_SHARE = 0.7  # a goal is far at >= this share of the farthest candidate's distance
ARRIVED_M = 0.3  # m from its goal a walker picks a new one
GOAL_ROOM = 0.1  # m a goal keeps from the walls beyond a person's radius


@dataclass
class _Crowd:
    """The walkers of ``person_tracks``: P people on a floor map.

    floor: where people stand; walk_map: the cells a person's centre may occupy (clearance
    >= radius; the lines of sight to goals); goals: flat indices of the cells goals are drawn
    from; speed: (P,) m/s; pos, goal: (P, 2) m; heading: (P,) rad; blocked: (P,) frames a
    person has been blocked for.
    """

    rng: np.random.Generator
    radius: float
    floor: _Floor
    walk_map: OccupancyMap
    goals: np.ndarray
    speed: np.ndarray
    pos: np.ndarray
    goal: np.ndarray
    heading: np.ndarray
    blocked: np.ndarray

    @classmethod
    def start(cls, rng: np.random.Generator, n: int, floor: OccupancyMap, radius: float,
              speed: tuple[float, float], keepout: np.ndarray) -> _Crowd:
        """n people placed like objects (clear of the keep-outs and each other), each
        walking towards a goal in sight."""
        where = _Floor.of(floor)
        walkable = where.fitting(radius)
        if not len(walkable):
            raise ValueError(f"no floor is {radius} m from the walls: people of radius "
                             f"{radius} m cannot stand anywhere; lower person_radius")
        start, ok = place_objects(rng, np.full(n, radius), floor, keepout)
        if not ok.all():
            start[~ok, :2] = where.points(rng, walkable[rng.integers(len(walkable),
                                                                     size=int((~ok).sum()))])
        roomy = where.fitting(radius + GOAL_ROOM)
        crowd = cls(rng, radius, where, floor.eroded(max(radius - floor.margin, 0.0)),
                    roomy if len(roomy) else walkable, rng.uniform(speed[0], speed[1], n),
                    start[:, :2].copy(), np.zeros((n, 2)), np.zeros(n), np.zeros(n, int))
        crowd.new_goals(np.ones(n, bool))
        crowd.heading = np.arctan2(*(crowd.goal - crowd.pos)[:, ::-1].T)
        return crowd

    def new_goals(self, mask: np.ndarray, back: np.ndarray | None = None) -> None:
        """New goals for the people of ``mask`` (P,): of ``GOAL_CANDIDATES`` random floor
        cells, the farthest one in a straight line of walkable cells (any one if none is);
        for those of ``back`` (P,), behind them if there is one."""
        idx = np.flatnonzero(mask)
        if not len(idx):
            return
        k = GOAL_CANDIDATES
        cand = self.floor.points(self.rng, self.goals[self.rng.integers(len(self.goals),
                                                                        size=len(idx) * k)])
        origin = np.repeat(self.pos[idx], k, axis=0)
        seen = ~np.isfinite(first_blocked(self.walk_map, origin, cand))
        score = np.linalg.norm(cand - origin, axis=1) * np.where(seen, 1.0, 1e-6)
        if back is not None:
            heading = np.repeat(self.heading[idx], k)
            rel = cand - origin
            ahead = rel[:, 0] * np.cos(heading) + rel[:, 1] * np.sin(heading) > 0
            score *= np.where(np.repeat(back[idx], k) & ahead, 1e-3, 1.0)
        score = score.reshape(len(idx), k)
        far = score >= FAR_SHARE * score.max(axis=1, keepdims=True)  # the far ones: any
        pick = np.argmax(far * self.rng.random(far.shape), axis=1)
        self.goal[idx] = cand.reshape(len(idx), k, 2)[np.arange(len(idx)), pick]

    def turn_around(self, stuck: np.ndarray) -> None:
        """Who arrived at their goal picks a new goal, who is ``stuck`` (P,) one behind."""
        arrived = np.linalg.norm(self.goal - self.pos, axis=1) < ARRIVED_M
        turn = arrived | stuck
        if turn.any():
            self.new_goals(turn, back=stuck)
            self.blocked[turn] = 0

    def clearance(self, p: np.ndarray, circles: np.ndarray) -> np.ndarray:
        """(P, O) free distance from each person placed at p (P, 2) to each of the (O, 3)
        circles, the first P of which are the people themselves (inf to oneself)."""
        n = len(self.pos)
        dist = np.linalg.norm(p[:, None, :] - circles[None, :, :2], axis=-1)
        clear = dist - self.radius - circles[None, :, 2]
        clear[:, :n][np.eye(n, dtype=bool)] = np.inf
        return clear

    def steer(self, circles: np.ndarray, clear: np.ndarray) -> np.ndarray:
        """(P, 2) wanted walking directions: towards the goal, pushed away from the circles
        ahead (a sidestep away from each thing, to the right of each person; to the other
        side where a wall leaves no room), and off the walls (the clearance's gradient)."""
        pos = self.pos
        want = self.goal - pos
        want /= np.linalg.norm(want, axis=1, keepdims=True) + 1e-9
        diff = pos[:, None, :] - circles[None, :, :2]  # (P, O, 2) from the others to each
        away = diff / (np.linalg.norm(diff, axis=-1, keepdims=True) + 1e-9)
        fwd = np.stack([np.cos(self.heading), np.sin(self.heading)], 1)
        ahead = np.einsum("poc,pc->po", -away, fwd) > -0.2
        weight = np.exp(-np.clip(clear, 0, None) / 0.4) * ahead * np.isfinite(clear)
        perp = np.stack([-want[:, 1], want[:, 0]], 1)  # left of the wanted direction
        side = np.sign(np.einsum("poc,pc->po", away, perp) + 1e-6)  # sidestep away
        side[:, : len(pos)] = -1.0  # people keep right of each other
        occ = self.floor.occ
        reach = occ.cell  # a sidestep with no room for one cell goes the other way
        room = [occ.distance(pos + sign * reach * perp) >= self.radius for sign in (1, -1)]
        side = np.where((side > 0) & ~room[0][:, None] & room[1][:, None], -1.0, side)
        side = np.where((side < 0) & ~room[1][:, None] & room[0][:, None], 1.0, side)  # not
        # into a wall: to the side with room
        push = away + side[..., None] * perp[:, None, :]
        steer = want + 1.5 * np.sum(weight[..., None] * push, axis=1)
        gap = self.floor.occ.distance(pos) - self.radius
        return steer + 0.5 * np.exp(-np.clip(gap, 0, None) / 0.2)[:, None] * self.floor.away(pos)

    def walk(self, circles: np.ndarray, dt: float, max_turn: float) -> None:
        """One frame: turn (at most max_turn rad) towards ``steer``'s direction and step;
        a step into a wall slides along it, and a step that comes nearer a wall than the
        radius or overlaps a circle (or another's step) more than now is not taken."""
        clear = self.clearance(self.pos, circles)
        steer = self.steer(circles, clear)
        target = np.arctan2(steer[:, 1], steer[:, 0])
        turn = np.clip(wrap_angle(target - self.heading), -max_turn, max_turn)
        self.heading = wrap_angle(self.heading + turn)
        step = self.speed[:, None] * dt * np.stack([np.cos(self.heading),
                                                    np.sin(self.heading)], 1)
        new = self.pos + step
        off = self.floor.distance(new) < self.radius
        if off.any():  # slide: drop the part of the step towards the wall
            g = self.floor.away(self.pos[off])
            into = np.minimum(np.einsum("pc,pc->p", step[off], g), 0.0)
            new[off] = self.pos[off] + step[off] - into[:, None] * g
        new_clear = self.clearance(new, circles)
        bad = (np.any((new_clear < 0) & (new_clear < clear), axis=1)
               | (self.floor.distance(new) < self.radius))
        # people step at once: who would overlap another's step more stays too
        n = len(self.pos)
        moved = np.where(bad[:, None], self.pos, new)
        both = self.clearance(moved, np.column_stack([moved, np.full(n, self.radius)]))
        bad |= np.any((both < 0) & (both < clear[:, :n]), axis=1)
        self.pos = np.where(bad[:, None], self.pos, new)
        self.blocked = np.where(bad, self.blocked + 1, 0)


def person_tracks(rng: np.random.Generator, num_people: int, num_frames: int, fps: float,
                  floor: OccupancyMap,
                  speed: tuple[float, float] = tuple(DistractorPreset().person_speed),
                  radius: float = DistractorPreset.person_radius,
                  obstacles: np.ndarray | None = None,
                  avoid: np.ndarray | None = None,
                  avoid_radius: float = DistractorPreset.person_camera_keepout,
                  max_turn_deg_s: float = DistractorPreset.person_max_turn_deg_s,
                  patience_s: float = DistractorPreset.person_patience_s) -> np.ndarray:
    """Trajectories of people walking about the floor.

    Each person walks towards a goal: of a few random floor cells, the farthest one in
    sight (in a corridor: towards its far end); on arrival, or when blocked for patience_s,
    it picks a new one. The heading turns at a bounded rate towards the goal, steered around
    other people, static obstacles and the avoid track (a small social-force model: a push
    away from what is ahead plus a sidestep) and off the walls (the clearance's gradient). A
    step that would overlap someone or something more is not taken; a step into a wall
    slides along it. People never stand nearer a wall than ``radius`` (within the map's
    cell); they rarely overlap each other.

    Args:
        rng: random generator.
        num_people, num_frames: counts.
        fps: frame rate (Hz).
        floor: where people may walk (margin 0; its clearance is the distance to walls).
        speed: (min, max) walking speed in m/s, drawn per person.
        radius: body radius (m) kept from the walls and used for avoidance.
        obstacles: (Q, 3) x, y, radius static circles to walk around (e.g. clutter).
        avoid: (num_frames, 2) x, y of something to keep clear of at each frame (the camera).
        avoid_radius: radius (m) of that keep-out.
        max_turn_deg_s: largest heading change rate.
        patience_s: how long a blocked person waits before choosing a new goal.

    Returns:
        (num_people, num_frames, 3) x, y (m), yaw (rad, walking direction).
    """
    if fps <= 0:
        raise ValueError(f"fps must be positive, got {fps}")
    P, N, dt = int(num_people), int(num_frames), 1.0 / float(fps)
    out = np.zeros((P, N, 3))
    if P == 0 or N == 0:
        return out
    obs = (np.zeros((0, 3)) if obstacles is None
           else np.asarray(obstacles, dtype=np.float64).reshape(-1, 3))
    avoid_xy = None if avoid is None else np.asarray(avoid, dtype=np.float64).reshape(N, 2)
    keep = obs if avoid_xy is None else np.vstack([obs, [*avoid_xy[0], avoid_radius]])
    crowd = _Crowd.start(rng, P, floor, radius, speed, keep)
    max_turn = np.deg2rad(max_turn_deg_s) * dt
    for t in range(N):
        out[:, t, :2] = crowd.pos
        out[:, t, 2] = crowd.heading
        crowd.turn_around(crowd.blocked > patience_s * fps)
        circles = [np.column_stack([crowd.pos, np.full(P, radius)]), obs]
        if avoid_xy is not None:
            circles.append(np.array([[*avoid_xy[t], avoid_radius]]))
        crowd.walk(np.concatenate(circles), dt, max_turn)
    return out
