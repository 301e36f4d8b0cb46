"""What a localize run loads once and every pass shares (``Context``): the dataset, the camera
of the frames, the model edges, the typed settings, the SegNet, the output folder. The offline
runner (``localize.offline.runner``) and the live loop (``localize.live.loop``) both start from
one."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from omegaconf import DictConfig

from core import classes as C
from core.config import typed
from core.dataset import Camera, Dataset, World
from localize.config import AppConfig, LocalizeConfig, WorldFileConfig
from localize.edge_model import EdgeModel
from localize.frontend.front_end import FrontEnd
from localize.frontend.sources import EdgeSource, edge_source

#: Per edge mode, a function of the mode's own edge source giving the source to use instead
#: (benchmarks/class_swap.py: the SegNet's labels with some classes from the truth).
SourceWrappers = Mapping[str, Callable[[EdgeSource], EdgeSource]]


@dataclass
class Context:
    """What every pass shares: the dataset (None where the map is a building file,
    ``world=FILE``: ``world_digest`` then names its content), the camera of the frames (the
    dataset's, or a recording's), the model edges, the settings (the whole config, typed:
    ``settings_of``), the segmenter, the output folder."""

    cfg: DictConfig
    dataset: Dataset | None
    camera: Camera
    world: World
    settings: AppConfig  # LocalizeConfig offline, Ros2Config live
    model: EdgeModel
    out_dir: Path
    segmenter: object | None = None
    source_wrappers: SourceWrappers = field(default_factory=dict)
    world_digest: str | None = None
    _models: dict = field(default_factory=dict, repr=False)

    def model_for(self, mode: str) -> EdgeModel:
        """The model edges a mode scores (``EdgeModel.for_mode``), made once per mode."""
        if mode not in self._models:
            self._models[mode] = self.model.for_mode(self.world, mode)
        return self._models[mode]

    def edge_source(self, mode: str) -> EdgeSource:
        """The edge source of a mode: its own (the SegNet for cnn), or what
        ``source_wrappers[mode]`` makes of it."""
        own = edge_source(mode, self.segmenter, self.settings.edges.cnn)
        wrap = self.source_wrappers.get(mode)
        return own if wrap is None else wrap(own)

    def front_end(self, mode: str) -> FrontEnd:
        """A front end of the mode's edge source and the ``edges`` config."""
        return FrontEnd(self.edge_source(mode), self.settings.edges)


def settings_of(cfg: DictConfig) -> LocalizeConfig:
    """The composed localize config as its typed object (``localize.config.LocalizeConfig``;
    a config read back from a report's config.json is checked against it, naming any key it
    does not know)."""
    return typed(LocalizeConfig, cfg, "localize config")


def open_map(cfg: DictConfig) -> tuple[Dataset | None, World, list[dict], str | None]:
    """The map a run localizes in: ``world.path``'s (imported or from the cache,
    ``localize.world_file``) or the dataset's ``world/``.

    Returns:
        The dataset (None for a building file), the world, the class list a SegNet must have
        (the dataset's; for a file the project's, ``core.classes``) and the building file's
        content digest (None for a dataset).
    """
    if cfg.world.path:
        from localize.world_file import map_of

        found = map_of(typed(WorldFileConfig, cfg.world, "world"))
        return None, found.world(), C.as_json(), found.digest
    dataset = Dataset(cfg.dataset)
    return dataset, dataset.world(), dataset.classes, None


def report_folder(cfg: DictConfig) -> Path:
    """``<out_root>/<name>``: the report folder of a run."""
    return Path(cfg.out_root) / str(cfg.name)
