"""``python -m localize.ros2``: the live node (conf/ros2.yaml, docs/ros2.md).

Hydra composes the settings as for ``python -m localize`` (``dataset=``, ``onnx_model=``, the
filter) plus the node's; what follows ``--ros-args`` goes to ROS (``--params-file FILE``,
``-p name:=value``, remappings), whose parameters of the same names replace Hydra's values
(``localize.ros2.parameters``). The lifecycle node (``localize.ros2.node``) configures itself
(``localize.resolve.resolve`` adds the model's settings; the dataset, the model edges, the
SegNet) and activates unless ``autostart`` is false, then spins until Ctrl-C.
"""

from __future__ import annotations

import logging
import sys

from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from core.config import hydra_app
from localize.config import ALIASES
from localize.ros2.config import Ros2Config

log = logging.getLogger(__name__)


def split_ros_args(argv: list[str]) -> tuple[list[str], list[str]]:
    """(Hydra's arguments, ROS's): ROS's run from ``--ros-args`` to a ``--`` or the end (as
    ``ros2 run`` and launch files append them); the program name stays with Hydra's."""
    hydra, ros, in_ros = [], [], False
    for arg in argv:
        if arg == "--ros-args":
            in_ros = True
        elif in_ros and arg == "--":
            in_ros = False
            continue
        (ros if in_ros else hydra).append(arg)
    return hydra, ros


def serve(cfg: DictConfig, overrides: list[str] | None = None, choices: dict | None = None,
          ros_args: list[str] | None = None) -> None:
    """Make the node (configured and active with ``autostart``) and spin until interrupted
    (Ctrl-C, SIGTERM via rclpy)."""
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    from localize.ros2.node import LocalizerNode

    rclpy.init(args=["localize.ros2", *(ros_args or [])])
    node = None
    try:
        node = LocalizerNode(cfg, overrides=list(overrides or []), choices=choices)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        if rclpy.ok():
            raise
        # Ctrl-C shut the context down while the executor was taking a message
    finally:
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()


def main(argv: list[str] | None = None) -> None:
    """The command line: Hydra's overrides, then optionally ``--ros-args ...``."""
    hydra_argv, ros_args = split_ros_args(list(sys.argv if argv is None else argv))

    @hydra_app("ros2", Ros2Config, ALIASES)
    def run(cfg: DictConfig) -> None:
        hydra_cfg = HydraConfig.get()
        serve(cfg, list(hydra_cfg.overrides.task), dict(hydra_cfg.runtime.choices), ros_args)

    sys.argv = hydra_argv
    run()


if __name__ == "__main__":
    main()
