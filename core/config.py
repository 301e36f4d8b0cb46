"""Typed configs shared by the three stages.

Each stage's settings are dataclasses (``datagen/config.py``, ``train/config.py``,
``localize/config.py``): their field defaults are the only defaults, and Hydra composes the
YAML presets of ``conf/`` onto them (``register_schema``), so a typo or a wrong type in a YAML
file or on the command line fails at start-up, naming the key. ``typed`` does the same check
for a plain mapping (library use, tests, settings read back from a model folder);
``compose_config`` composes a conf/ file as a stage's command line would (benchmarks, tests).

``hydra_app`` makes a stage's entry point: Hydra's composition, every key checked against the
stage's schema (also one added with ``+``), and a user's error (``USER_ERRORS``) reported as
one line ``error: <message>`` with exit status 2; ``user_errors`` does the same for the
argparse tools. ``HYDRA_FULL_ERROR=1`` in the environment shows the traceback instead. In a
multirun (``-m``) a job's user error is reported the same way and the other jobs still run
(``JobFailed``).
"""

from __future__ import annotations

import dataclasses
import functools
import os
import sys
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

import hydra
from hydra import compose, initialize_config_dir
from hydra.core.config_store import ConfigStore
from hydra.core.hydra_config import HydraConfig
from hydra.errors import CompactHydraException
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import ConfigAttributeError, ConfigKeyError, OmegaConfBaseException

from core.atomic import DiskFullError
from core.outputs import OutputFolderError

T = TypeVar("T")
#: The repository's Hydra config folder.
CONF = Path(__file__).resolve().parents[1] / "conf"
#: Overrides that shrink conf/datagen.yaml to seconds of rendering (128x96, 20 images, three
#: 30-frame flights): the tests' and benchmarks' tiny dataset.
TINY_DATAGEN = [
    "camera.width=128", "camera.height=96",
    "splits.train=12", "splits.val=4", "splits.test=4",
    "render.spp=2", "training.chunk=6",
    "flights.paper.num_frames=30", "flights.cluttered.num_frames=30",
    "render_flights=[paper,cluttered]", "val_flights=[paper]",
]


def _cycle(index: int, values: list) -> Any:
    """``${cycle:${world.seed},[60,80,100]}``: ``values[index % len(values)]`` (a setting that
    varies along a sweep, e.g. each procedural floor's camera)."""
    return values[int(index) % len(values)]


if not OmegaConf.has_resolver("cycle"):
    OmegaConf.register_new_resolver("cycle", _cycle)


def register_schema(name: str, node: type, group: str | None = None) -> None:
    """Store dataclass ``node`` in Hydra's ConfigStore as ``name`` (in config group ``group``),
    for a defaults list (``defaults: [name, ...]``): every key then has its type and
    default."""
    ConfigStore.instance().store(name=name, node=node, group=group)


def typed(cls: type[T], cfg: Mapping | None, where: str) -> T:
    """An instance of dataclass ``cls``: its defaults updated by ``cfg`` (a mapping or a
    DictConfig, possibly partial), checked by OmegaConf against the field types.

    Args:
        cls: a dataclass whose fields have OmegaConf-compatible annotations.
        cfg: the values to set (None: the defaults).
        where: the config key the values come from, for messages (e.g. ``"filter"``).

    Raises:
        ValueError: an unknown key or a value of the wrong type, naming ``where.key``, the
            value and (for an unknown key) the keys its node knows; or a check of ``cls``
            failing, prefixed with ``where`` unless its message starts with it.
    """
    base = OmegaConf.structured(cls)
    if isinstance(cfg, DictConfig):  # a plain copy: merged, its unknown keys are refused
        cfg = OmegaConf.to_container(cfg, resolve=False)
    try:
        merged = OmegaConf.merge(base, cfg or {})
    except OmegaConfBaseException as err:
        full_key = getattr(err, "full_key", None) or ""
        key = ".".join(k for k in (where, full_key) if k) or cls.__name__
        msg = f"{key}: {err.msg.splitlines()[0]}"
        if isinstance(err, (ConfigKeyError, ConfigAttributeError)):
            parent = full_key.rpartition(".")[0]
            node = OmegaConf.select(base, parent) if parent else base
            if isinstance(node, DictConfig):
                owner = ".".join(k for k in (where, parent) if k)
                msg += (f" (known keys{f' of {owner}' if owner else ''}: "
                        f"{', '.join(map(str, node.keys()))})")
        raise ValueError(msg) from None
    try:
        return OmegaConf.to_object(merged)
    except ValueError as err:  # a check of the dataclass's own (``__post_init__``)
        if str(err).startswith(where):  # names the key already
            raise
        raise ValueError(f"{where}: {err}") from None


def check_positive(settings: Any, keys: Sequence[str], where: str) -> None:
    """Raise ValueError naming ``where.key`` for the first of ``keys`` whose value in
    ``settings`` (attributes) is not above 0."""
    for key in keys:
        value = getattr(settings, key)
        if value <= 0:
            raise ValueError(f"{where}.{key} must be positive, got {value}")


def as_config(cls: type[T], cfg: Any, where: str) -> T:
    """``cfg`` if it is a ``cls`` already, else ``typed(cls, cfg, where)`` (a mapping or a
    DictConfig, possibly partial; None: the defaults)."""
    return cfg if isinstance(cfg, cls) else typed(cls, cfg, where)


def compose_config(name: str, overrides: list[str] | None = None) -> dict:
    """Compose ``conf/<name>.yaml`` with ``overrides`` (Hydra's command-line syntax), resolved
    to plain containers."""
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(config_name=name, overrides=overrides or [])
    return OmegaConf.to_container(cfg, resolve=True)


#: The errors that are the user's to fix (a setting, a path, an output folder, the disk): an
#: entry point reports them as one line (``user_errors``), anything else with its traceback.
USER_ERRORS: tuple[type[BaseException], ...] = (
    ValueError, FileNotFoundError, FileExistsError, NotADirectoryError, IsADirectoryError,
    PermissionError, DiskFullError, OutputFolderError, OmegaConfBaseException,
    CompactHydraException)


class JobFailed(CompactHydraException):
    """A job of a multirun (``-m``) stopped on a user error, already reported on stderr as
    ``error: <message>``: Hydra runs the other jobs, then exits 1 with the first such message."""


#: The environment variable (Hydra's) that keeps a user error's traceback: ``1``.
FULL_ERROR = "HYDRA_FULL_ERROR"


def _one_line(text: str) -> str:
    """Hydra's message on one line: a line's indented items joined by commas (``Available
    options in 'filter':`` then one option a line), its config search path left out."""
    out = ""
    for raw in text.split("Config search path:")[0].splitlines():
        line = raw.strip()
        if not line:
            continue
        if not out:
            out = line
        elif raw[0] in " \t":
            out += (" " if out.endswith(":") else ", ") + line
        else:
            out += (" " if out.endswith((".", ":")) else ". ") + line
    return out


def error_message(err: BaseException) -> str:
    """A user error as one line: OmegaConf's naming its key, Hydra's with its cause, an
    ``OSError`` its file."""
    if isinstance(err, OmegaConfBaseException):
        key = getattr(err, "full_key", None)
        msg = str(err.msg).splitlines()[0] if err.msg else type(err).__name__
        return f"{key}: {msg}" if key else msg
    if isinstance(err, CompactHydraException):
        text, cause = str(err), err.__cause__
        if dataclasses.is_dataclass(getattr(cause, "object_type", None)):
            # a key its schema does not know: the `+key=value` Hydra suggests is refused too
            text = "\n".join(line for line in text.splitlines()
                             if not line.startswith("To append to your config use"))
        msg = _one_line(text)
        return f"{msg.rstrip('.')} ({error_message(cause)})" if cause is not None else msg
    if isinstance(err, OSError) and err.strerror:
        return f"{err.filename}: {err.strerror}" if err.filename else err.strerror
    return str(err)


def full_error() -> bool:
    """Whether ``HYDRA_FULL_ERROR=1`` asks for every error's traceback."""
    return os.environ.get(FULL_ERROR) == "1"


@contextmanager
def user_errors(go_on: bool = False) -> Iterator[None]:
    """Report a user error (``USER_ERRORS``) raised inside as ``error: <message>`` on stderr
    and exit with status 2, or with ``go_on`` (one job of a multirun) raise ``JobFailed`` so
    that Hydra runs the other jobs; with ``HYDRA_FULL_ERROR=1``, let it raise (its
    traceback)."""
    try:
        yield
    except USER_ERRORS as err:
        if full_error():
            raise
        print(f"error: {error_message(err)}", file=sys.stderr)
        raise (JobFailed(error_message(err)) if go_on else SystemExit(2)) from None


def expand_aliases(argv: list[str], aliases: Mapping[str, str]) -> list[str]:
    """Command-line arguments with each ``alias=value`` written ``key=value`` (``aliases``:
    alias -> key), e.g. localize's ``world=FILE`` -> ``world.path=FILE``: ``world`` names a
    config group of datagen's in the shared ``conf/``, which Hydra would take the word for."""
    out = []
    for arg in argv:
        name, eq, value = arg.partition("=")
        out.append(f"{aliases[name]}={value}" if eq and name in aliases else arg)
    return out


def hydra_app(config_name: str, schema: type, aliases: Mapping[str, str] | None = None
              ) -> Callable[[Callable[[DictConfig], Any]], Callable[[], None]]:
    """Decorate a stage's main: ``@hydra_app("localize", LocalizeConfig)`` over
    ``def main(cfg: DictConfig)`` gives the ``python -m localize`` entry point.

    Hydra composes ``conf/<config_name>.yaml`` with the command line, every key of the result
    is checked against ``schema`` (a key added with ``+`` too; ``typed``), then ``main`` runs.
    A user error, in composition or in ``main``, prints ``error: <message>`` and exits 2
    (``user_errors``). For Hydra's composition errors to reach this function,
    ``HYDRA_FULL_ERROR=1`` is set until ``main`` starts (Hydra then raises them rather than
    print them), unless the user set it. ``main.__wrapped__(cfg)`` runs a composed config
    (tests). ``aliases`` (alias -> key) rewrite the command line first (``expand_aliases``).
    """
    def decorate(task: Callable[[DictConfig], Any]) -> Callable[[], None]:
        set_here = False  # HYDRA_FULL_ERROR set by main below, not by the user

        def unset() -> None:
            nonlocal set_here
            if set_here:
                os.environ.pop(FULL_ERROR, None)
                set_here = False

        @functools.wraps(task)
        def checked(cfg: DictConfig) -> Any:
            unset()  # the task's own failures as Hydra reports them
            multirun = HydraConfig.initialized() and HydraConfig.get().mode == RunMode.MULTIRUN
            with user_errors(go_on=multirun):
                typed(schema, cfg, "")
                return task(cfg)

        hydra_main = hydra.main(version_base="1.3", config_path=str(CONF),
                                config_name=config_name)(checked)

        @functools.wraps(hydra_main)
        def main() -> None:
            nonlocal set_here
            with user_errors():
                if not full_error():
                    os.environ[FULL_ERROR] = "1"
                    set_here = True
                if aliases:
                    sys.argv[1:] = expand_aliases(sys.argv[1:], aliases)
                try:
                    hydra_main()
                finally:
                    unset()

        return main

    return decorate
