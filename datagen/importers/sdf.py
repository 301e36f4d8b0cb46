"""Gazebo SDF worlds and models (.world, .sdf, model.sdf).

Reads ``<model>`` (nested too), ``<include>`` of ``model://NAME`` (found through the model
search path), link and visual ``<pose>`` (x y z roll pitch yaw, R = Rz(yaw) Ry(pitch)
Rx(roll), as SDF defines it), the ``<visual>`` geometry only: ``<mesh>`` (with ``<scale>``),
``<box>``, ``<cylinder>``, ``<sphere>``, ``<plane>``, and the positions of the point and spot
``<light>``s (of the world, of links and of included light-only files). A horizontal plane (a
ground plane) is cut to the rest of the world's XY extent. A mesh URI that is relative
(``file://models/...``, ``meshes/a.dae``) is found next to the file naming it, else on the
resource path (``resource_roots``: the world's repository root first), else as a file name
differing only in case. A model or mesh that
cannot be found is counted, reported once and skipped; a model including itself (directly or
through others) is an error naming the files of the cycle.
"""

from __future__ import annotations

import logging
import os
import re
import xml.etree.ElementTree as ET
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from datagen.importers.meshfile import load_mesh_file
from datagen.mesh.building import Part, transformed

log = logging.getLogger(__name__)
#: An ``<sdf version="...">file</sdf>`` entry of a model.config, read as text.
SDF_ENTRY = re.compile(r"""<sdf(?:\s+version\s*=\s*["']([^"']*)["'])?[^>]*>\s*([^<\s]+)\s*</sdf>""")


def model_search_path(source: Path, extra: list[str]) -> list[Path]:
    """Folders searched for ``model://NAME``, in order: ``extra`` (the ``model_path``
    setting), the file's ``../models`` and its parent folder, ``$GAZEBO_MODEL_PATH``,
    ``$GZ_SIM_RESOURCE_PATH`` and ``~/.gazebo/models``."""
    env = [p for var in ("GAZEBO_MODEL_PATH", "GZ_SIM_RESOURCE_PATH")
           for p in os.environ.get(var, "").split(os.pathsep) if p]
    here = source.resolve().parent
    dirs = [*map(Path, extra), here.parent / "models", here.parent, *map(Path, env),
            Path.home() / ".gazebo" / "models"]
    out: list[Path] = []
    for d in dirs:
        if d.is_dir() and d.resolve() not in out:
            out.append(d.resolve())
    return out


def resource_roots(source: Path, search: list[Path]) -> list[Path]:
    """Folders a relative ``file://`` or plain mesh URI is resolved against after the
    referring file's own folder, as Gazebo's resource path does: the world's repository root
    (the parent of the world file's folder), the world file's folder, then each model search
    folder's parent and the folder itself."""
    here = source.resolve().parent
    out: list[Path] = []
    for d in (here.parent, here, *[x for s in search for x in (s.parent, s)]):
        if d.is_dir() and d not in out:
            out.append(d)
    return out


def parse_xml(path: Path) -> ET.Element:
    """The root element of an XML file; a clear error if it is not well-formed."""
    try:
        return ET.parse(path).getroot()
    except ET.ParseError as err:
        raise ValueError(f"{path}: not well-formed XML ({err})") from None


def _floats(text: str | None, n: int, default: list[float], where: str) -> np.ndarray:
    if text is None or not text.strip():
        return np.asarray(default, np.float64)
    try:
        values = np.array(text.split(), np.float64)
    except ValueError:
        raise ValueError(f"{where}: {text.strip()!r} is not {n} numbers") from None
    if len(values) != n:
        raise ValueError(f"{where}: {text.strip()!r} is not {n} numbers")
    return values


@dataclass
class _Walk:
    """State of one SDF import."""

    source: Path
    search: list[Path]
    roots: list[Path] = field(default_factory=list)  # resource_roots, for file:// URIs
    parts: list[Part] = field(default_factory=list)
    planes: list[int] = field(default_factory=list)  # indexes into parts
    missing: Counter = field(default_factory=Counter)  # model name -> includes not found
    missing_meshes: Counter = field(default_factory=Counter)  # mesh uri -> visuals
    meshes: dict[Path, list[Part]] = field(default_factory=dict)
    units: dict[Path, float] = field(default_factory=dict)  # mesh file -> metres per unit
    trees: dict[Path, ET.Element] = field(default_factory=dict)
    reading: list[Path] = field(default_factory=list)  # the files whose models are being
    # read, outermost first (resolved): an include of one of them is a cycle
    notes: set[str] = field(default_factory=set)
    includes: int = 0
    lights: list[list[float]] = field(default_factory=list)  # point and spot lights, m
    directional: int = 0  # directional lights (suns) seen, not placed

    def light(self, elem: ET.Element, matrix: np.ndarray) -> None:
        """Record a ``<light>``'s position (point and spot lights; directional ones are
        counted: they stand for the sun, not for a fixture in the building)."""
        kind = elem.get("type", "point")
        if kind == "directional":
            self.directional += 1
        elif kind in ("point", "spot"):
            self.lights.append((matrix @ self.pose(elem))[:3, 3].round(6).tolist())
        else:
            self.note(f"<light type={kind!r}> is not point, spot or directional; skipped")

    def note(self, text: str) -> None:
        if text not in self.notes:
            self.notes.add(text)
            log.warning("%s: %s", self.source, text)

    def pose(self, elem: ET.Element) -> np.ndarray:
        """(4, 4) transform of ``elem``'s own ``<pose>`` (identity without one)."""
        p = elem.find("pose")
        if p is None or not (p.text or "").strip():
            return np.eye(4)
        if p.get("relative_to"):
            self.note("<pose relative_to=...> is ignored (poses taken relative to the parent)")
        values = np.array(p.text.split(), np.float64)
        m = np.eye(4)
        if len(values) == 7:  # x y z qx qy qz qw (SDF 1.9 rotation_format quat_xyzw)
            m = trimesh.transformations.quaternion_matrix(values[[6, 3, 4, 5]])
        elif len(values) == 6:
            rpy = np.radians(values[3:]) if p.get("degrees") == "true" else values[3:]
            m = trimesh.transformations.euler_matrix(*rpy, axes="sxyz")
        else:
            raise ValueError(f"{self.source}: <pose>{p.text.strip()}</pose> is not "
                             f"'x y z roll pitch yaw'")
        m[:3, 3] = values[:3]
        return m

    def resolve(self, uri: str, base: Path) -> Path | None:
        """A file or folder for a ``model://``, ``package://``, ``file://`` or relative URI
        (relative to ``base``, the referring file's folder, else to ``roots``); None if it
        does not exist."""
        for scheme in ("model://", "package://"):
            if uri.startswith(scheme):
                name, _, rest = uri[len(scheme):].partition("/")
                for d in self.search:
                    if (d / name).is_dir():
                        target = d / name / rest
                        return target if target.exists() else None
                return None
        rel = uri[len("file://"):] if uri.startswith("file://") else uri
        for d in (base, *self.roots):
            path = d / rel
            if path.exists():
                return path
        for d in (base, *self.roots):
            path = _other_case(d / rel)
            if path is not None:
                self.note(f"{uri}: found as {path.name} (the name differs in case)")
                return path
        return None


def _other_case(path: Path) -> Path | None:
    """The file in ``path``'s folder whose name equals ``path``'s but for case (a model made
    on a case-blind system), or None."""
    if not path.parent.is_dir():
        return None
    name = path.name.lower()
    return next((p for p in sorted(path.parent.iterdir()) if p.name.lower() == name), None)


def _model_sdf(folder: Path) -> Path:
    """The SDF file of a model folder: model.config's ``<sdf>`` of the highest version,
    else model.sdf. A model.config that is not well-formed XML (a bare ``&`` is common) is
    searched for its ``<sdf>`` entries as text."""
    config = folder / "model.config"
    if not config.is_file():
        return folder / "model.sdf"
    text = config.read_text(errors="replace")
    try:
        entries = [(e.get("version") or "0", (e.text or "").strip())
                   for e in ET.fromstring(text).findall("sdf")]
    except ET.ParseError:
        entries = SDF_ENTRY.findall(text)
    found = [(v, f) for v, f in entries if (folder / f).is_file()]
    if not found:
        return folder / "model.sdf"
    return folder / max(found, key=lambda e: [int(x) for x in e[0].split(".") if x.isdigit()])[1]


def _shape(tag: str, g: ET.Element, where: str) -> trimesh.Trimesh | None:
    """A primitive (box, cylinder, sphere, plane) as a mesh in the visual's frame."""
    if tag == "box":
        return trimesh.creation.box(extents=_floats(g.findtext("size"), 3, [1, 1, 1], where))
    if tag == "cylinder":
        r = _floats(g.findtext("radius"), 1, [0.5], where)[0]
        return trimesh.creation.cylinder(radius=r, height=_floats(g.findtext("length"), 1,
                                                                   [1], where)[0], sections=32)
    if tag == "sphere":
        return trimesh.creation.icosphere(subdivisions=2, radius=_floats(
            g.findtext("radius"), 1, [0.5], where)[0])
    if tag == "plane":
        sx, sy = _floats(g.findtext("size"), 2, [1, 1], where) / 2
        normal = _floats(g.findtext("normal"), 3, [0, 0, 1], where)
        quad = trimesh.Trimesh([[-sx, -sy, 0], [sx, -sy, 0], [sx, sy, 0], [-sx, sy, 0]],
                               [[0, 1, 2], [0, 2, 3]], process=False)
        return quad.apply_transform(trimesh.geometry.align_vectors([0, 0, 1], normal))
    return None


def _visual(w: _Walk, vis: ET.Element, matrix: np.ndarray, name: str, base: Path) -> None:
    """Add the parts of one ``<visual>``."""
    geometry = vis.find("geometry")
    if geometry is None:
        return
    diffuse = (vis.findtext("material/diffuse") or "").split()
    colour = _floats(" ".join(diffuse[:3]) or None, 3, [np.nan] * 3, f"{name} diffuse")
    script = (vis.findtext("material/script/name") or "").strip()
    name = f"{name}/{script}" if script else name
    for g in geometry:
        if g.tag == "mesh":
            uri = (g.findtext("uri") or "").strip()
            path = w.resolve(uri, base)
            if path is None or path.is_dir():
                w.missing_meshes[uri] += 1
                continue
            if g.find("submesh") is not None:
                w.note("<submesh> is not supported: the whole mesh is used")
            if path not in w.meshes:
                w.meshes[path], info = load_mesh_file(path)
                w.units[path] = info["units"]
            scaled = matrix @ np.diag([*_floats(g.findtext("scale"), 3, [1, 1, 1],
                                                f"{name} scale"), 1.0])
            for p in w.meshes[path]:
                w.parts.append(p.moved(scaled, f"{name}/{p.name}",
                                       None if np.isnan(colour).all() else colour))
            continue
        mesh = _shape(g.tag, g, name)
        if mesh is None:
            w.note(f"<{g.tag}> geometry is not supported; skipped")
            continue
        if g.tag == "plane":
            w.planes.append(len(w.parts))
        v, f = transformed(matrix, mesh.vertices, mesh.faces)
        w.parts.append(Part(v, f, f"{name}/{g.tag}", colour))


def _model(w: _Walk, elem: ET.Element, parent: np.ndarray, prefix: str, base: Path,
           pose: np.ndarray | None = None, name: str | None = None) -> None:
    """Add a ``<model>``: its links' visuals, nested models and includes."""
    matrix = parent @ (w.pose(elem) if pose is None else pose)
    mname = f"{prefix}/{name or elem.get('name', 'model')}".lstrip("/")
    for link in elem.findall("link"):
        lm = matrix @ w.pose(link)
        for light in link.findall("light"):
            w.light(light, lm)
        for vis in link.findall("visual"):
            _visual(w, vis, lm @ w.pose(vis), f"{mname}/{link.get('name')}/{vis.get('name')}",
                    base)
    for child in elem.findall("model"):
        _model(w, child, matrix, mname, base)
    for inc in elem.findall("include"):
        _include(w, inc, matrix, mname, base)


def _include(w: _Walk, inc: ET.Element, parent: np.ndarray, prefix: str, base: Path) -> None:
    """Add an ``<include>``d model (its ``<pose>`` and ``<name>`` replace the model's)."""
    w.includes += 1
    uri = (inc.findtext("uri") or "").strip()
    label = uri.split("://", 1)[-1].strip("/").split("/")[0] if "://" in uri else Path(uri).stem
    target = w.resolve(uri, base)
    if target is None:
        w.missing[label] += 1
        return
    sdf = _model_sdf(target) if target.is_dir() else target
    if not sdf.is_file():
        w.missing[label] += 1
        return
    key = sdf.resolve()
    if key in w.reading:
        cycle = " -> ".join(map(str, [*w.reading[w.reading.index(key):], key]))
        raise ValueError(f"{w.source}: <include> cycle: {cycle} ({uri} includes a model that "
                         f"is being read); remove the <include> that closes the cycle")
    if sdf not in w.trees:
        w.trees[sdf] = parse_xml(sdf)
    model = w.trees[sdf].find("model")
    pose = w.pose(inc) if inc.find("pose") is not None else None
    if model is None:  # a light (e.g. Gazebo's sun) or an actor
        for light in w.trees[sdf].findall("light"):
            w.light(light, parent @ (np.eye(4) if pose is None else pose))
        return
    w.reading.append(key)
    _model(w, model, parent, prefix, sdf.parent, pose, (inc.findtext("name") or "").strip())
    w.reading.pop()


def _cut_planes(w: _Walk) -> None:
    """Cut horizontal planes to the XY extent of the other parts (if any)."""
    planes = set(w.planes)
    others = [p for i, p in enumerate(w.parts) if i not in planes]
    if not w.planes or not others:
        return
    pts = np.concatenate([p.vertices for p in others])
    lo, hi = pts[:, :2].min(axis=0), pts[:, :2].max(axis=0)
    for i in w.planes:
        p = w.parts[i]
        if np.ptp(p.vertices[:, 2]) > 1e-9:
            continue
        a, b = np.maximum(p.vertices[:, :2].min(axis=0), lo), np.minimum(
            p.vertices[:, :2].max(axis=0), hi)
        z = p.vertices[0, 2]
        up = np.cross(*(p.vertices[p.faces[0, 1:]] - p.vertices[p.faces[0, 0]]))[2] > 0
        faces = np.array([[0, 1, 2], [0, 2, 3]]) if up else np.array([[0, 2, 1], [0, 3, 2]])
        p.vertices = np.array([[a[0], a[1], z], [b[0], a[1], z], [b[0], b[1], z],
                               [a[0], b[1], z]])
        p.faces = faces if np.all(b > a) else np.zeros((0, 3), np.int64)


def load_sdf(path: Path, model_path: list[str]) -> tuple[list[Part], dict]:
    """The visual geometry of a Gazebo world or model file, in metres, Z up.

    Returns:
        parts (face_class UNSET, named ``model/.../link/visual[/script]/geometry/material``)
        and info: ``includes``, ``missing_models`` (name -> count), ``missing_meshes``,
        ``model_path`` (the folders searched), ``units`` (metres per file unit -> mesh files),
        ``lights`` ([[x, y, z], ...] m, the point and spot lights of the world and its
        models' links) and ``directional_lights`` (their count, not placed).

    Raises:
        ValueError: XML that is not well-formed, no ``<sdf>`` root or no ``<world>`` or
            ``<model>`` in it, a bad ``<pose>`` or number, an ``<include>`` cycle (a model
            including itself, directly or through others: the files of the cycle named).
    """
    root = parse_xml(path)
    if root.tag != "sdf":
        raise ValueError(f"{path}: the root element is <{root.tag}>, not <sdf>; is this a "
                         f"Gazebo world or model file?")
    search = model_search_path(path, model_path)
    w = _Walk(path, search, resource_roots(path, search), reading=[path.resolve()])
    tops = root.findall("world") + root.findall("model")
    if not tops:
        raise ValueError(f"{path}: no <world> or <model> in the file")
    for top in tops:
        if top.tag == "model":
            _model(w, top, np.eye(4), "", path.parent)
            continue
        for child in top:
            if child.tag == "model":
                _model(w, child, np.eye(4), "", path.parent)
            elif child.tag == "include":
                _include(w, child, np.eye(4), "", path.parent)
            elif child.tag == "light":
                w.light(child, np.eye(4))
    _cut_planes(w)
    if w.missing:
        listed = ", ".join(f"{n} x{c}" for n, c in w.missing.most_common())
        log.warning("%s: %d models not found, skipped (%d includes): %s. Searched: %s; add "
                    "their folders to model_path or $GAZEBO_MODEL_PATH", path, len(w.missing),
                    sum(w.missing.values()), listed, ", ".join(map(str, w.search)))
    if w.missing_meshes:
        log.warning("%s: %d mesh files not found, skipped: %s", path, len(w.missing_meshes),
                    ", ".join(w.missing_meshes))
    return w.parts, {"includes": w.includes, "missing_models": dict(w.missing.most_common()),
                     "missing_meshes": dict(w.missing_meshes),
                     "model_path": [str(d) for d in w.search],
                     "units": dict(Counter(w.units.values()).most_common()),
                     "lights": w.lights, "directional_lights": w.directional}
