"""The up axis of a building mesh, found from its large horizontal planes, and the rotation
that turns a file's up axis into +Z.

The axis: the one with most face area perpendicular to it (floors, ceilings, desk tops are
large and flat; walls split between the two other axes), that area weighed by how evenly
the faces along it face both ways along the other two axes (walls stand all around a room; a
model without a ceiling seen on its side has its floor facing one way with nothing facing
back: ``side_balance``). Its sign: the floor is the large
upward-facing plane at the low end with the walls standing on it and the furniture on it; a
ceiling may be larger than the floor (a scan sees the floor under furniture less), so the
sign is a vote of three cues (``sign_cues``): floor against ceiling at the two ends, the
support surfaces in between (desk tops, seats, shelves: low in a room and facing up), and the
vertical faces standing on the low end without reaching the high one (furniture; walls span
the whole height and vote neither way); a cue resting on little area counts less.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from datagen.mesh.building import face_areas_normals

#: The axes a file may name as up (``world.up_axis``); ``x``, ``y``, ``z`` mean ``+x``, ...
AXES = ("+x", "-x", "+y", "-y", "+z", "-z")
HORIZONTAL = 0.9  # |normal . up| from which a face is horizontal (within ~25 deg)
VERTICAL = 0.3  # |normal . up| below which a face is vertical
END = 0.15  # the low and high ends: this share of the model's height from each side
CUE_MASS = 0.02  # area share from which a sign cue counts fully (less: in proportion)


def axis_name(text: str) -> str:
    """``text`` as one of AXES (``y`` -> ``+y``); ValueError naming the key otherwise."""
    axis = text if text[:1] in "+-" else f"+{text}"
    if axis not in AXES:
        raise ValueError(f"world.up_axis: {text!r} is not auto or one of {', '.join(AXES)} "
                         f"(x, y, z mean +x, +y, +z)")
    return axis


def to_z_up(axis: str) -> np.ndarray:
    """(4, 4) rotation taking the file's ``axis`` (one of AXES) to +Z: a quarter turn about
    ``axis x Z`` (+y: (x, y, z) -> (x, -z, y)), for -Z a half turn about X, for +Z none."""
    axis = axis_name(axis)
    u = np.zeros(3)
    u["xyz".index(axis[1])] = 1.0 if axis[0] == "+" else -1.0
    if u[2] != 0:
        return np.eye(4) if u[2] > 0 else np.diag([1.0, -1.0, -1.0, 1.0])
    m = trimesh.transformations.rotation_matrix(np.pi / 2, np.cross(u, [0.0, 0.0, 1.0]))
    return np.round(m, 12)


@dataclass
class UpAxis:
    """An up axis found from a mesh.

    axis: one of AXES. sureness: 0..1, how sure: the axis's margin (2 (best - second) / best
    score, the perpendicular area times ``side_balance``, at most 1) times the sign's net
    vote (|sum of weighted votes| / sum of the weights: 1 when every cue votes fully one
    way, 0 when they cancel or say nothing).
    perpendicular: area share (of the total) perpendicular to x, y, z. cues: the sign's votes
    (``sign_cues``) for the axis's + direction (positive: + is up).
    """

    axis: str
    sureness: float
    perpendicular: list[float]
    cues: dict[str, float]

    def as_info(self) -> dict:
        return {"axis": self.axis, "sureness": round(self.sureness, 3),
                "perpendicular_share": [round(v, 3) for v in self.perpendicular],
                "sign_cues": {k: round(v, 4) for k, v in self.cues.items()}}


def sign_cues(corners: np.ndarray, n: np.ndarray, area: np.ndarray, lo: float, hi: float
              ) -> dict[str, tuple[float, float]]:
    """The cues that +h is up: name -> (vote in [-1, 1], positive: +h is up; mass, the area
    share of the total behind the vote).

    ends: the up-facing area at the low end against the down-facing area at the high end
    (floor against ceiling; a model without a ceiling votes strongly). support: up-facing
    area in the lower half against down-facing area in the upper half, between the ends
    (desk tops, seats, shelves sit low and face up; a flipped model shows them as undersides
    high up). stand: the vertical faces reaching the low end but not the high one against
    those reaching the high end but not the low one (furniture stands on the floor; a wall
    of the full height reaches both and votes neither way).

    Args:
        corners: (F, 3) the faces' corners along the axis; n: (F,) normals' component
        along it; area: (F,) face areas; lo, hi: the model's low and high ends along it.
    """
    total = max(float(area.sum()), 1e-12)
    span = max(hi - lo, 1e-9)
    t = np.clip((corners.mean(axis=1) - lo) / span, 0, 1)  # 0 at the low end, 1 the high end
    up, down = n >= HORIZONTAL, n <= -HORIZONTAL
    inner = (t >= END) & (t <= 1 - END)

    def vote(pro: float, con: float) -> tuple[float, float]:
        return (pro - con) / max(pro + con, 1e-12), (pro + con) / total

    vertical = np.abs(n) < VERTICAL
    low = (corners.min(axis=1) - lo) / span < END
    high = (hi - corners.max(axis=1)) / span < END
    return {"ends": vote(float(area[up & (t < END)].sum()),
                         float(area[down & (t > 1 - END)].sum())),
            "support": vote(float(area[up & inner & (t < 0.5)].sum()),
                            float(area[down & inner & (t > 0.5)].sum())),
            "stand": vote(float(area[vertical & low & ~high].sum()),
                          float(area[vertical & high & ~low].sum()))}


def side_balance(facing: np.ndarray) -> float:
    """How evenly the vertical faces of an up axis face both ways along each horizontal axis
    (walls all around a room): sum over the two axes of min(area +b, area -b) over the sum of
    max(...), in [0, 1]; 1 without vertical faces.

    Args:
        facing: (2, 2) area facing +b and -b for the two horizontal axes b.
    """
    most = facing.max(axis=1).sum()
    return float(facing.min(axis=1).sum() / most) if most > 0 else 1.0


def find_up_axis(vertices: np.ndarray, faces: np.ndarray) -> UpAxis:
    """The up axis of a mesh in its file's frame (any of AXES): see the module docstring.

    Args:
        vertices (V, 3), faces (F, 3) int: the mesh, in any unit.
    """
    area, normal = face_areas_normals(vertices, faces)
    total = max(float(area.sum()), 1e-12)
    perp = np.array([area[np.abs(normal[:, a]) >= HORIZONTAL].sum() / total for a in range(3)])
    facing = np.array([[area[s * normal[:, a] >= HORIZONTAL].sum() for s in (1, -1)]
                       for a in range(3)])  # (3, 2): area facing +a, -a
    score = np.array([perp[a] * side_balance(facing[[b for b in range(3) if b != a]])
                      for a in range(3)])
    order = np.argsort(score)[::-1]
    best = int(order[0])
    margin = float((score[best] - score[order[1]]) / max(score[best], 1e-12))
    lo, hi = np.percentile(vertices[:, best], [1, 99])
    cues = sign_cues(vertices[faces][:, :, best], normal[:, best], area, float(lo), float(hi))
    weights = {k: min(1.0, mass / CUE_MASS) for k, (_, mass) in cues.items()}
    vote = sum(weights[k] * v for k, (v, _) in cues.items())
    sign = "+" if vote >= 0 else "-"
    sure = min(1.0, 2 * margin) * abs(vote) / max(sum(weights.values()), 1e-12)
    return UpAxis(f"{sign}{'xyz'[best]}", float(sure), perp.tolist(),
                  {k: v for k, (v, _) in cues.items()})
