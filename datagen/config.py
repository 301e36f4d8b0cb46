"""The settings of ``python -m datagen``: the schema of conf/datagen.yaml, and its defaults.

Hydra composes conf/datagen.yaml's groups (``conf/world/``, ``conf/flights/``,
``conf/distractors/``, ``conf/realism/``, ``conf/appearance/``) and the command line onto
``DatagenConfig`` (registered as ``datagen_schema``), so every default is written here once,
and an unknown key or a value of the wrong type fails at start-up naming the key. Lengths are
in metres, angles in degrees, times in seconds. See docs/datagen.md for what the options do.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from omegaconf import MISSING

from core.config import register_schema
from core.imaging.camera import FORWARD_MOUNT_XYZ
from core.imaging.realism import RealismConfig
from datagen.importers.config import ImportConfig

# --------------------------------------------------------------------------- world


@dataclass
class DoorSize:
    """Size of every door recess (``world.door``); a door of ``world.doors`` may set its own
    width and height."""

    width: float = 0.9  # m
    height: float = 2.1  # m
    depth: float = 0.08  # m, how far the recess goes into the wall


@dataclass
class WindowSize:
    """Size of every window recess (``world.window``); a window of ``world.windows`` may set
    its own width, height and sill."""

    width: float = 1.2  # m
    height: float = 1.0  # m
    sill: float = 0.9  # m, height of the window's bottom above the floor
    depth: float = 0.12  # m


@dataclass
class DoorAt:
    """A door: ``side`` left (-X) | right (+X) | back (y = 0) | front (y = length), ``at`` its
    centre along that wall (m); width and height None: ``world.door``'s."""

    side: str = MISSING
    at: float = MISSING
    width: float | None = None
    height: float | None = None


@dataclass
class WindowAt:
    """A window (``side``, ``at`` as for a door); width, height and sill None:
    ``world.window``'s."""

    side: str = MISSING
    at: float = MISSING
    width: float | None = None
    height: float | None = None
    sill: float | None = None


@dataclass
class OpeningAt:
    """A side corridor or junction, full height (``side``, ``at`` as for a door)."""

    side: str = MISSING
    at: float = MISSING
    width: float = MISSING  # m, along the wall
    depth: float = MISSING  # m, into the wall


@dataclass
class LightPanels:
    """Ceiling light panels, evenly spaced along the corridor (``world.lights``)."""

    count: int = 5
    size: list[float] = field(default_factory=lambda: [0.6, 1.2])  # m, (x, y) of a panel


@dataclass
class WorldConfig:
    """The corridor (``world``, datagen/worlds/corridor.py): by default the paper's environment, a
    10 m office corridor, long side along +Y, doors on both sides. A recess's jambs, head and sill
    take the door's / window's class, so the class boundary is the recess's outer edge
    (docs/datagen.md)."""

    kind: str = "corridor"  # corridor (this) | file (FileWorldConfig: ``world=file``) |
    # procedural (ProceduralWorldConfig: ``world=procedural``)
    name: str = "corridor_paper"
    length: float = 10.0  # m, along +Y
    width: float = 2.0  # m, x in [-width/2, width/2]
    height: float = 2.8  # m
    crease_deg: float = 20.0  # faces meeting at a larger angle make a model edge
    camera_margin: float = 0.3  # m kept between a camera and any wall (free space for poses)
    z_range: list[float] = field(default_factory=lambda: [0.5, 2.2])  # m, camera heights
    # for training poses and flights
    door: DoorSize = field(default_factory=DoorSize)
    window: WindowSize = field(default_factory=WindowSize)
    doors: list[DoorAt] = field(default_factory=lambda: [
        DoorAt("left", 1.6), DoorAt("left", 4.0), DoorAt("left", 8.4), DoorAt("right", 2.4),
        DoorAt("right", 5.4), DoorAt("right", 8.0), DoorAt("back", 0.0)])
    windows: list[WindowAt] = field(default_factory=lambda: [
        WindowAt("front", 0.0), WindowAt("right", 3.9, width=0.8)])
    openings: list[OpeningAt] = field(default_factory=lambda: [
        OpeningAt("left", 6.2, width=1.6, depth=2.0)])
    lights: LightPanels = field(default_factory=LightPanels)


@dataclass
class FileWorldConfig(ImportConfig):
    """A building model read from a file (``world=file world.path=FILE``; datagen/worlds/site.py):
    a Gazebo world, a mesh or an IFC file (the import keys: ``ImportConfig``,
    docs/importers.md), with the free space a camera may fly in."""

    kind: str = "file"
    name: str = "file"  # the world's name in world.json
    crease_deg: float = 20.0  # faces meeting at a larger angle make a model edge
    camera_margin: float = 0.3  # m kept between a camera and any surface
    z_range: list[float] = field(default_factory=lambda: [0.5, 2.2])  # m above the floor,
    # camera heights
    free_cell: float = 0.1  # m, cell of the free-space map (world/free.npz)
    free_close: float = 0.5  # m, closing radius of the floor (and ceiling) footprint: fills
    # a scan's gaps and unseen floor (core.occupancy ``close``)
    free_max_hole: float = 4.0  # m2, enclosed holes of that footprint up to this are filled
    obstacle_span: float = 0.25  # share of the camera band a column's surfaces must cover to
    # be an obstacle (walls, cabinets; not a stray triangle, a table top, a door's head)
    light_spacing: float = 2.0  # m between the ceiling panels added along the free space when
    # the file has no lights (the hospital: 258 panels; 3 m: 121, half as bright)


@dataclass
class DetailsConfig:
    """The building's details on a procedural floor (``world.details``,
    datagen/worlds/details.py): door leaves and frames, recessed windows with frames and sills,
    window walls, thin glass partitions, more columns. Each is a share in [0, 1]; all 0 (the
    default) adds nothing and draws nothing, so a floor is the one its seed always gave (the
    details draw from a stream of their own). ``datagen_experiment=generalist_floors`` turns
    them on; the sizes are in datagen/worlds/details.py and docs/worlds.md."""

    door_leaves: float = 0.0  # share of doorways hung with a leaf (class door), or two
    door_open: float = 0.6  # share of the leaves standing open at door_angle (into the room;
    # the room behind is seen), the rest closed in the opening
    door_angle: list[float] = field(default_factory=lambda: [20.0, 90.0])  # deg from closed
    double_doors: float = 0.0  # share of hung doorways widened to 1.4-1.9 m with two leaves
    glazed_doors: float = 0.0  # share of leaves with a glass pane (the pane is class door)
    architraves: float = 0.0  # share of doorways with an architrave (class door) on both faces
    window_recess: float = 0.0  # share of windows set back into the outer wall: reveals,
    # head and sill class window, the outdoor view fitted to the opening; the rest flat
    window_frames: float = 0.0  # share of recessed windows with a frame, mullions and
    # transoms (class window)
    sills: float = 0.0  # share of recessed windows (sill >= 0.3 m) with a sill board
    window_walls: float = 0.0  # share of the spaces on an outer wall glazed floor to ceiling
    # across it (recessed, framed as window_frames says)
    glass_sheets: float = 0.0  # share of glass walls (world.glass) made a thin see-through
    # sheet with mullions (class window) instead of a wall showing an outdoor view
    round_columns: float = 0.0  # share of column sets that are round (8-16 sides)
    room_columns: float = 0.0  # share of rooms >= 3.6 m each way with a free-standing column
    pilasters: float = 0.0  # share of corridor sides with pillars engaged in the wall


@dataclass
class ProceduralWorldConfig:
    """An office floor drawn from a seed (``world=procedural``, datagen/worlds/procedural.py):
    corridors on a coarse grid (L and T junctions, loops), a lobby, rooms behind door
    openings, recesses, columns, glass walls (class window) and windows on the outer walls;
    built into a world as an imported building is (the free-space keys as
    ``FileWorldConfig``'s). Pairs are [min, max] ranges, drawn per floor (or per corridor,
    room, door); probabilities in [0, 1]. Same seed, same floor."""

    kind: str = "procedural"
    name: str = "procedural"  # the world's name in world.json
    seed: int = 0  # the floor's seed (the plan and every size drawn)
    size: list[float] = field(default_factory=lambda: [36.0, 28.0])  # m, (x, y) outline (a
    # side too short for two corridor lines shrinks to one corridor with its rooms)
    grid_spacing: list[float] = field(default_factory=lambda: [7.0, 11.0])  # m between the
    # corridor grid's lines (the grid fills the outline, so the spacing is about this)
    corridor_width: list[float] = field(default_factory=lambda: [1.2, 4.0])  # m, per corridor
    height: list[float] = field(default_factory=lambda: [2.4, 4.0])  # m, ceiling of corridors
    # and rooms (the lobby's: drawn between that and the max)
    lobby_size: list[float] = field(default_factory=lambda: [5.0, 9.0])  # m, each side
    room_depth: list[float] = field(default_factory=lambda: [2.5, 4.5])  # m, away from the
    # corridor (rooms on the outer side of a perimeter corridor reach the outer wall)
    door_spacing: list[float] = field(default_factory=lambda: [3.0, 5.0])  # m between doors
    # along a corridor (a room's width; one door per room)
    door_width: list[float] = field(default_factory=lambda: [0.9, 1.2])  # m
    door_height: list[float] = field(default_factory=lambda: [2.0, 2.3])  # m, drawn per floor
    # (below height's min)
    window_spacing: list[float] = field(default_factory=lambda: [2.0, 4.0])  # m between window
    # centres along the outer walls
    window_width: list[float] = field(default_factory=lambda: [0.8, 1.6])  # m
    window_sill: list[float] = field(default_factory=lambda: [0.8, 1.0])  # m above the floor
    window_height: list[float] = field(default_factory=lambda: [1.0, 1.3])  # m
    recess_width: list[float] = field(default_factory=lambda: [0.8, 2.0])  # m, along the wall
    recess_depth: list[float] = field(default_factory=lambda: [0.3, 0.6])  # m, into the wall
    column_size: list[float] = field(default_factory=lambda: [0.3, 0.5])  # m, square side
    wall_thickness: float = 0.15  # m, between a corridor and its rooms, and between rooms
    outer_wall: float = 0.3  # m, the outer walls' thickness
    loops: float = 0.3  # probability each grid edge off the spanning tree is a corridor too
    # (at least one loop where the grid has 2 x 2 nodes)
    columns: float = 0.5  # probability the lobby, and each corridor >= 2.8 m wide, has columns
    recesses: float = 0.3  # probability of a recess on each side of each corridor
    glass: float = 0.2  # probability a room's corridor wall is glass (class window)
    details: DetailsConfig = field(default_factory=DetailsConfig)  # door leaves, window
    # frames, glass sheets, more columns (all off: DetailsConfig)
    crease_deg: float = 20.0  # faces meeting at a larger angle make a model edge
    camera_margin: float = 0.3  # m kept between a camera and any surface
    z_range: list[float] = field(default_factory=lambda: [0.5, 1.9])  # m above the floor,
    # camera heights (below door_height's min, so the rooms join the corridors through
    # their doors in the free space)
    free_cell: float = 0.1  # m, cell of the free-space map (world/free.npz)
    free_close: float = 0.5  # m, as FileWorldConfig's
    free_max_hole: float = 4.0  # m2, as FileWorldConfig's
    obstacle_span: float = 0.25  # as FileWorldConfig's
    light_spacing: float = 2.0  # m between the ceiling panels added along the free space


AnyWorldConfig = WorldConfig | FileWorldConfig | ProceduralWorldConfig


def world_config(world: object, where: str = "world") -> AnyWorldConfig:
    """The typed world settings of ``world``: a ``WorldConfig``, ``FileWorldConfig`` or
    ``ProceduralWorldConfig``, or a mapping with ``kind`` corridor (the default), file or
    procedural (None: the corridor's defaults)."""
    if isinstance(world, (WorldConfig, FileWorldConfig, ProceduralWorldConfig)):
        return world
    from core.config import typed

    kind = (world or {}).get("kind", "corridor")
    kinds = {"corridor": WorldConfig, "file": FileWorldConfig,
             "procedural": ProceduralWorldConfig}
    if kind not in kinds:
        raise ValueError(f"{where}.kind: unknown world kind {kind!r}; use one of "
                         f"{sorted(kinds)} (world=corridor_paper, world=file or "
                         "world=procedural)")
    return typed(kinds[kind], world, where)


# --------------------------------------------------------------------------- camera, render


@dataclass
class MountConfig:
    """The camera on the copter (``camera.mount``): body_from_cam, body frame x forward,
    y left, z up."""

    xyz: list[float] = field(default_factory=lambda: list(FORWARD_MOUNT_XYZ))  # m, camera centre
    pitch_deg: float = 0.0  # positive tilts the camera down


@dataclass
class CameraConfig:
    """The forward camera (``camera``). The image size must stay fixed for one dataset."""

    width: int = 320  # px
    height: int = 240  # px
    hfov_deg: float = 70.0  # horizontal field of view
    mount: MountConfig = field(default_factory=MountConfig)


@dataclass
class RenderConfig:
    """Mitsuba's rendering (``render``, datagen/rendering/render.py)."""

    variant: str = "auto"  # auto: llvm_ad_rgb if LLVM works, else scalar_rgb (with a warning)
    spp: int = 1  # path-tracer samples per pixel (RGB; the denoiser removes the noise)
    max_depth: int = 3  # path length (3 = direct light + one bounce)
    denoise_sigma_px: float = 4.0  # shading blur of the albedo-demodulation denoiser (0 = off)
    exposure: float = 1.6  # linear scale before sRGB encoding
    depth: bool = False  # also write depth/NNNNNN.png (uint16 millimetres)


# --------------------------------------------------------------------------- appearance


@dataclass
class FeatureProbs:
    """Probability of each optional texture feature per sample (``appearance.prob``)."""

    dado: float = 0.5  # dado rail at ~0.8-1.05 m
    two_tone: float = 0.35  # different paint below the dado height
    sockets: float = 0.6  # wall socket and light switch plates
    door_panels: float = 0.65  # inset panels on the door
    door_glass: float = 0.3  # vision pane in the door
    door_number: float = 0.5  # room-number plate
    kick_plate: float = 0.3  # metal plate at the bottom of the door
    ceiling_vent: float = 0.6  # a ventilation grille tile
    ceiling_stain: float = 0.3  # a water stain on a ceiling tile
    frame_matches_door: float = 0.3  # the door frame has the door's texture
    window_frame_colour: float = 0.0  # window frames (a procedural floor's details) get a
    # colour of their own (white, dark, metal, wood), else the door frame's; 0: never (no draw)
    accent_wall: float = 0.0  # the wall's paint (or wallpaper / block / panel colour) is a
    # saturated accent colour; 0: never (no draw)
    glossy_floor: float = 0.0  # the floor is glossy: a rough plastic lobe over its texture
    # (weight materials.floor_gloss, GGX alpha materials.roughness.floor); 0: never, and the
    # renderer keeps today's diffuse floor
    dark_floor: float = 0.0  # the floor is darkened to 15-45 % of its drawn brightness (slate,
    # dark vinyl, dark wood); 0: never (no draw)


@dataclass
class LightsAppearance:
    """The ceiling lights of a scene (``appearance.lights``)."""

    on_fraction: list[float] = field(default_factory=lambda: [0.4, 1.0])  # fraction of the
    # panels switched on (at least one), [min, max]
    intensity: list[float] = field(default_factory=lambda: [4.0, 12.0])  # emitted radiance
    # of a panel (linear RGB luminance), [min, max]
    jitter: float = 0.15  # relative per-panel intensity variation
    temperature_k: list[float] = field(default_factory=lambda: [2700.0, 6500.0])  # colour
    # temperature, [min, max] (one per scene, +/-150 K per panel)
    dim: float = 0.0  # share of scenes whose panels are dimmed by a factor drawn in
    # dim_factor (night, corridor lights on a sensor); 0: none (no draw)
    dim_factor: list[float] = field(default_factory=lambda: [0.15, 0.5])  # [min, max]
    daylight: float = 0.0  # share of scenes with daylight: the windows' emitted outdoor view
    # is multiplied by a gain drawn in daylight_gain and lights the rooms; 0: none (no draw)
    daylight_gain: list[float] = field(default_factory=lambda: [4.0, 20.0])  # [min, max]; 1 is
    # the plain view (radiance <= 1, a few % of a panel's)


@dataclass
class Roughness:
    """Uniform [min, max] roughness per surface (``appearance.materials.roughness``)."""

    floor: list[float] = field(default_factory=lambda: [0.15, 0.7])  # also a glossy floor's
    # GGX alpha (prob.glossy_floor)
    wall: list[float] = field(default_factory=lambda: [0.5, 1.0])
    ceiling: list[float] = field(default_factory=lambda: [0.7, 1.0])
    door: list[float] = field(default_factory=lambda: [0.3, 0.8])
    frame: list[float] = field(default_factory=lambda: [0.2, 0.7])
    clutter: list[float] = field(default_factory=lambda: [0.3, 0.9])
    person: list[float] = field(default_factory=lambda: [0.5, 1.0])


@dataclass
class Materials:
    """Surface materials (``appearance.materials``)."""

    roughness: Roughness = field(default_factory=Roughness)
    tint_jitter: float = 0.08  # per-channel darkening of textured surfaces (tint <= 1)
    floor_gloss: list[float] = field(default_factory=lambda: [0.3, 1.0])  # [min, max] weight
    # of a glossy floor's rough plastic lobe (prob.glossy_floor)


@dataclass
class AppearanceConfig:
    """Appearance randomization (``appearance``, the conf/appearance/ group: ``default``,
    today's space, or ``varied``, the wide one; datagen/appearance/): procedural textures,
    materials and lights. Every texture is (resolution, resolution, 3) linear RGB; 512 costs
    about 4x the time of 256 (sharper posters and grout). A style weight or probability of 0
    draws nothing, so the defaults draw what they always drew."""

    resolution: int = 256
    floor_styles: dict[str, float] = field(default_factory=lambda: {
        "tiles": 0.45, "wood": 0.3, "carpet": 0.25, "vinyl": 0.0, "concrete": 0.0,
        "terrazzo": 0.0})  # probabilities (normalized)
    wall_styles: dict[str, float] = field(default_factory=lambda: {
        "paint": 1.0, "wallpaper": 0.0, "block": 0.0, "brick": 0.0, "panels": 0.0,
        "tiles": 0.0})  # probabilities (normalized); only paint: no draw
    ceiling_styles: dict[str, float] = field(default_factory=lambda: {
        "tiles": 1.0, "plaster": 0.0})  # probabilities (normalized); only tiles: no draw
    door_styles: dict[str, float] = field(default_factory=lambda: {
        "wood": 0.5, "painted": 0.5, "metal": 0.0})  # probabilities (normalized)
    posters: list[int] = field(default_factory=lambda: [1, 4])  # posters / signs / notice
    # boards per 4 m of wall, [min, max]
    prob: FeatureProbs = field(default_factory=FeatureProbs)
    lights: LightsAppearance = field(default_factory=LightsAppearance)
    materials: Materials = field(default_factory=Materials)


# --------------------------------------------------------------------------- distractors


@dataclass
class CountRange:
    """How many objects of a kind per image or flight, uniform in [min, max]."""

    min: int = 0
    max: int = 0


@dataclass
class DistractorPreset:
    """A distractors preset (``distractor_presets.<name>``, the ``conf/distractors/`` group;
    datagen/distractors/): furniture-like objects (class clutter) and walking people. The
    defaults are the ``none`` preset: no distractors."""

    clutter: CountRange = field(default_factory=CountRange)  # furniture-like objects
    people: CountRange = field(default_factory=CountRange)  # person figures
    kinds: list[str] = field(default_factory=lambda: [
        "box", "cabinet", "chair", "table", "plant"])  # clutter kinds, drawn uniformly (a kind
    # listed twice, twice as often); also trolley, bin, bench, sofa, whiteboard
    # (conf/distractors/varied.yaml) and the furnished-room kinds shelf, shelf_rows, desk,
    # counter, bed (conf/distractors/furnished.yaml)
    against_walls: float = 0.7  # probability an object stands against a wall
    aligned: float = 0.0  # probability an object not against a wall turns square to the
    # nearest wall (rows of desks and shelving); 0: a uniform yaw (no draw)
    near_camera_m: float = 0.0  # m; training images: objects stand where the camera sees
    # the floor (walls block) within this distance and its field of view widened 30 deg a
    # side (furnishing what it sees); 0: anywhere on the floor
    wall_margin: float = 0.05  # m kept between an object's footprint and a wall
    camera_keepout_m: float = 0.6  # m kept clear around the camera (and along a flight path)
    person_radius: float = 0.3  # m, footprint used for placement and walking
    person_speed: list[float] = field(default_factory=lambda: [0.6, 1.4])  # m/s, [min, max]
    person_camera_keepout: float = 0.5  # m people keep from the flying camera
    person_max_turn_deg_s: float = 180.0  # fastest heading change of a walker
    person_patience_s: float = 2.0  # s a blocked walker waits before choosing a new goal


# --------------------------------------------------------------------------- flights


@dataclass
class TrajectoryConfig:
    """A hand-flown pass along a route (``flights.<name>.trajectory``,
    datagen/flights/trajectories.py ``flight_trajectory``); pairs are [min, max], drawn per flight.
    The flight covers speed x duration metres of its route (less if the route is shorter)."""

    speed: list[float] = field(default_factory=lambda: [0.3, 0.45])  # m/s, mean forward
    # speed (capped so the flight ends inside)
    speed_variation: float = 0.25  # relative smooth variation of the forward speed
    ramp_s: float = 2.0  # s of speed-up at the start and slow-down at the end
    start_offset: list[float] = field(default_factory=lambda: [0.0, 0.4])  # m past the start
    # of the route (its end when reversed), at most a quarter of the route
    height: list[float] = field(default_factory=lambda: [1.0, 1.5])  # m, centre height (sway
    # added, kept inside world.z_range)
    sway_x: float = 0.3  # m, lateral sway amplitude (across the route; less where the free
    # space is narrower)
    sway_z: float = 0.15  # m, height sway amplitude
    sway_freq_hz: list[float] = field(default_factory=lambda: [0.04, 0.25])
    yaw_amplitude_deg: list[float] = field(default_factory=lambda: [20.0, 35.0])  # yaw swings
    # about the flight direction
    yaw_freq_hz: list[float] = field(default_factory=lambda: [0.02, 0.12])
    tilt_noise_deg: float = 1.0  # roll/pitch wobble on top of the acceleration tilt
    max_tilt_deg: float = 8.0
    reverse: bool = False  # true: fly the route backwards (the corridor: along -Y)


@dataclass
class OdometryConfig:
    """The drifting VIO-like odometry of a flight (``flights.<name>.odometry``,
    datagen/flights/trajectories.py ``noisy_odometry``)."""

    trans_noise_m: float = 0.004  # per-frame translation noise std (each axis)
    yaw_noise_deg: float = 0.1  # per-frame heading-increment noise std
    scale_error: float = 0.03  # std of the constant scale error (fraction of distance)
    scale_walk: float = 0.003  # random walk of the scale error per sqrt(s)
    yaw_bias_deg_s: float = 0.15  # std of the constant heading-rate bias
    yaw_bias_walk_deg_s: float = 0.01  # random walk of that bias, deg/s per sqrt(s)
    velocity_bias_walk: float = 0.002  # random walk of a velocity bias, m/s per sqrt(s)


@dataclass
class RouteConfig:
    """A route planned through the free space (datagen/flights/routes.py ``plan_route``): the
    cheapest path between two far-apart cells on the free space's ridge (the middle of
    corridors and rooms), simplified and its corners rounded; where none has min_length /
    min_turns, one fitted to the free space (fewer turns, or laps of a loop; a warning)."""

    extra_margin: float = 0.3  # m the route keeps from obstacles beyond the map's margin
    # (room for the flight's sway; narrower passages such as doors are left out)
    wall_cost: float = 1.0  # m; a step costs its length x (1 + wall_cost / clearance), so
    # routes keep to the middle of corridors
    far_fraction: float = 0.9  # the far end is drawn among the cells at >= this fraction of
    # the costliest route from the near end (1: the farthest cell)
    simplify_m: float = 0.25  # m the simplified route may leave the cell path
    turn_radius: float = 1.0  # m; a corner is rounded from this far before to this far after
    # it (less where the free space is tighter)
    spacing: float = 0.05  # m between the route's points
    min_length: float = 0.0  # m; a shorter route (or one under 2 m) is drawn again (up to
    # `tries` routes)
    min_turns: int = 0  # turns of >= turn_deg a route must have (else drawn again)
    turn_deg: float = 60.0
    tries: int = 8  # routes drawn before fitting one to the free space


@dataclass
class FlightConfig:
    """An evaluation flight preset (``flights.<name>``): a smooth hand-flown pass along a
    route with ground truth and noisy odometry. The defaults are the ``paper`` preset, like
    the paper's: the 10 m corridor flown by hand along +Y."""

    num_frames: int = 240
    seed: int = 0  # another flight of the preset: each seed draws its own trajectory, scene
    # and planned route from the dataset's seed (datagen.job.flight_stream)
    fps: float = 10.0
    distractors: str = "paper"  # a key of distractor_presets (conf/distractors/<name>.yaml)
    route: Any = "auto"  # "auto": the world's own route (the corridor's centre line), else
    # one planned through the free space (route_settings); or waypoints [[x, y], ...] (m)
    route_settings: RouteConfig = field(default_factory=lambda: RouteConfig(min_turns=2))
    # planning of an `auto` route; its min_length is raised to what the flight needs (speed
    # x duration); where none has them, one fitted to the free space is flown (a warning:
    # fewer turns, or laps of a loop around a room or down and up a short corridor)
    trajectory: TrajectoryConfig = field(default_factory=TrajectoryConfig)
    odometry: OdometryConfig = field(default_factory=OdometryConfig)


def default_flights() -> dict[str, FlightConfig]:
    """The flight presets: ``paper``, and ``cluttered``, the same kind of flight through a
    busy corridor."""
    cluttered = TrajectoryConfig(speed_variation=0.3, sway_x=0.35, sway_z=0.2,
                                 sway_freq_hz=[0.04, 0.3], yaw_amplitude_deg=[25.0, 40.0],
                                 yaw_freq_hz=[0.02, 0.15])
    return {"paper": FlightConfig(),
            "cluttered": FlightConfig(distractors="cluttered", trajectory=cluttered)}


# --------------------------------------------------------------------------- the job


@dataclass
class Splits:
    """Images per split (training data is what the SegNet's accuracy depends on most;
    docs/train.md)."""

    train: int = 6400
    val: int = 40
    test: int = 60


@dataclass
class TrainingConfig:
    """Poses and distractors of the training images (``training``)."""

    distractors: dict[str, float] = field(default_factory=lambda: {
        "none": 0.2, "paper": 0.4, "cluttered": 0.4})  # preset mix of training images
    max_roll_pitch_deg: float = 5.0  # roll and pitch of spread-out poses, uniform in +/- this
    handheld: float = 0.0  # share of spread-out poses tilted as a handheld camera is: pitch
    # uniform in +/- handheld_pitch_deg, roll in +/- handheld_roll_deg; 0: none (no draw)
    handheld_pitch_deg: float = 20.0
    handheld_roll_deg: float = 15.0
    z_range: list[float] | None = None  # m above the floor, [min, max] heights of the
    # spread-out poses; above world.z_range only where the ceiling and door heads leave
    # world.camera_margin; None: world.z_range (docs/datagen.md)
    yaw_along_corridor: float = 0.75  # share of images looking along the free space's local
    # axis (the corridor's: +/-Y), as flights do, within +/- yaw_spread_deg; the rest have a
    # uniform yaw
    yaw_spread_deg: float = 50.0
    flight_views: float = 0.5  # share of images posed as a random frame of a flight (a
    # `flights` preset, along its route either way): the flights' heights, sway, yaw swings
    # and tilts; 0 = none (docs/datagen.md)
    min_view_m: float = 0.0  # m of free space a spread-out pose must see ahead (along its
    # yaw); one that sees less is drawn again, so rooms give fewer wall-filling close-ups
    # (0 = off; the flight views keep theirs)
    chunk: int = 40  # images sharing one set of distractor meshes (one scene load)


@dataclass
class DatagenConfig:
    """``python -m datagen``: labeled renders and evaluation flights of a world."""

    name: str = "demo"  # dataset name
    out_dir: str = "outputs/datasets/${name}"  # where the dataset is written
    seed: int = 0
    splits: Splits = field(default_factory=Splits)
    training: TrainingConfig = field(default_factory=TrainingConfig)
    render_flights: list[str] = field(default_factory=lambda: ["paper", "cluttered"])  # keys
    # of `flights` to render: the test flights, flights/<name>/
    val_flights: list[str] | None = None  # keys of `flights` also rendered as validation
    # flights, flights/<name>_val/: the same preset drawn from another generator (another
    # trajectory, start, scene and, for a planned route, route); settings are tuned on them,
    # figures reported on the test flights. None: the render_flights; []: none
    shard: int = 0  # this process renders shard `shard` of `num_shards` frame ranges
    num_shards: int = 1
    overwrite: bool = False  # true: empty an existing dataset made with another config (one
    # that differs only by larger `splits` counts or more `render_flights` / `val_flights` is
    # grown, not emptied; docs/outputs.md)
    progress: bool = True  # tqdm progress bars (not part of the dataset's config hash)
    world: Any = None  # WorldConfig (conf/world/corridor_paper, also None), FileWorldConfig
    # (conf/world/file) or ProceduralWorldConfig (conf/world/procedural); ``world_config``
    # types a mapping
    camera: CameraConfig = field(default_factory=CameraConfig)
    render: RenderConfig = field(default_factory=RenderConfig)
    appearance: AppearanceConfig = field(default_factory=AppearanceConfig)
    flights: dict[str, FlightConfig] = field(default_factory=default_flights)
    distractor_presets: dict[str, DistractorPreset] = field(default_factory=dict)  # name ->
    # preset, from the conf/distractors/ group (conf/datagen.yaml's defaults list)
    realism: RealismConfig = field(default_factory=RealismConfig)  # the imperfections of the
    # flights (conf/realism/{ideal,real}.yaml)

    def __post_init__(self) -> None:
        self.world = world_config(self.world)


register_schema("datagen_schema", DatagenConfig)
register_schema("corridor_schema", WorldConfig, group="world")
register_schema("file_schema", FileWorldConfig, group="world")
register_schema("procedural_schema", ProceduralWorldConfig, group="world")
