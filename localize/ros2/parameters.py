"""The node's settings as ROS parameters: one set of names for Hydra and ROS.

Every key of ``conf/ros2.yaml`` (``Ros2Config``) but ``node_name`` is a ROS parameter of the
same dotted name: ``filter.num_particles=300`` on the Hydra command line, ``-p
filter.num_particles:=300`` after ``--ros-args``, or nested in a params file
(``--ros-args --params-file FILE``)::

    edgeloc:                    # the node's name, or /** for any node
      ros__parameters:
        dataset: outputs/datasets/demo
        filter:
          num_particles: 300    # the parameter filter.num_particles

The node declares each parameter with the value Hydra composed (the defaults, the presets and
the Hydra overrides); a ROS value (params file, ``-p``) replaces it. Values keep their types;
a nested list is given flat, row-major, as ROS parameters hold no nested lists:
``body_from_cam`` as 16 numbers, a polygon ``hint.region`` as x0, y0, x1, y1, ... (6 or more
numbers; 4 are a rectangle). A null (``hint.pose``) is a parameter with no value. No rclpy
here: ``localize.ros2.node`` declares and reads the parameters.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from omegaconf import DictConfig, OmegaConf, open_dict
from omegaconf.errors import OmegaConfBaseException

from core.outputs import flatten, without

#: Settings that are no ROS parameter: the node's name (ROS: ``-r __node:=NAME``) and what
#: ``localize.resolve`` records.
NOT_PARAMETERS = ("node_name", "set_by")
#: Settings only the node reads, not its context (``live.load_context``): a context loaded
#: for a config serves another that differs in these alone (``same_context``).
NODE_ONLY = ("topics", "frames", "qos", "realtime", "mavlink", "mavlink_rate_hz", "node_name",
             "autostart", "seed", "hint", "viz", "viz_connect", "body_from_cam", "set_by")
#: Where the settings are listed, for messages.
SETTINGS_DOC = "every key of localize/ros2/config.py, Ros2Config; docs/ros2.md"
#: Nested-list settings given flat: (name, columns of a row, fewest values that are nested).
FLAT_NESTED = {"body_from_cam": (4, 16), "hint.region": (2, 6)}


def parameter_values(cfg: DictConfig) -> dict[str, Any]:
    """The ROS parameters of a config: ``{"dotted.name": value}``, nested lists flat
    (``FLAT_NESTED``), None for a null."""
    out = {}
    for name, value in flatten(OmegaConf.to_container(cfg, resolve=True)).items():
        if name.split(".", 1)[0] in NOT_PARAMETERS or value == {}:
            continue
        if isinstance(value, list) and value and isinstance(value[0], list):
            value = [v for row in value for v in row]
        out[name] = value
    return out


def same_context(a: DictConfig, b: DictConfig) -> bool:
    """Whether configs ``a`` and ``b`` load the same context (they differ in ``NODE_ONLY``
    settings at most)."""
    def part(cfg):
        return without(OmegaConf.to_container(cfg, resolve=True), NODE_ONLY)
    return part(a) == part(b)


def config_with(cfg: DictConfig, values: Mapping[str, Any], where: str) -> DictConfig:
    """A copy of ``cfg`` with the ROS parameters ``values`` set (``{"dotted.name": value}``;
    flat nested lists reshaped, ``FLAT_NESTED``).

    Args:
        cfg: the Hydra-composed config.
        values: the parameters whose value the ROS side gives.
        where: where they come from, for messages (e.g. "ROS parameters of node edgeloc").

    Raises:
        ValueError: a name that is no setting or a value of the wrong type (``Ros2Config``),
            naming ``where``, the name and where the settings are listed.
    """
    from core.config import typed
    from localize.ros2.config import Ros2Config

    out = cfg.copy()
    with open_dict(out):
        for name, value in values.items():
            parent = name.rpartition(".")[0]
            if (name.split(".", 1)[0] in NOT_PARAMETERS
                    or (parent and not isinstance(OmegaConf.select(out, parent), DictConfig))):
                raise ValueError(f"{where}: {name} is not a setting of python -m localize.ros2 "
                                 f"({SETTINGS_DOC}, but {', '.join(NOT_PARAMETERS)}); fix or "
                                 "remove it")
            try:
                OmegaConf.update(out, name, _nested(name, plain_value(value)), merge=False)
            except OmegaConfBaseException as err:
                raise ValueError(f"{where}: {name}: {err.msg.splitlines()[0]} "
                                 f"({SETTINGS_DOC}); fix or remove it") from None
    try:
        typed(Ros2Config, out, "")
    except ValueError as err:
        raise ValueError(f"{where}: {err} ({SETTINGS_DOC})") from None
    return out


def plain_value(value: Any) -> Any:
    """A ROS parameter's value as a config value: arrays as lists, a byte array (an empty list's
    ROS type) as []."""
    if isinstance(value, (bytes, bytearray)):
        return list(value)
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return list(value)
    return value


def _nested(name: str, value: Any) -> Any:
    """A flat list of a ``FLAT_NESTED`` setting as rows; any other value as it is."""
    shape = FLAT_NESTED.get(name)
    if shape is None or not isinstance(value, list) or len(value) < shape[1]:
        return value
    cols = shape[0]
    if len(value) % cols:
        raise ValueError(f"{name}: {len(value)} numbers are no rows of {cols}; give "
                         f"{name} flat, row-major (docs/ros2.md)")
    return [value[i:i + cols] for i in range(0, len(value), cols)]
