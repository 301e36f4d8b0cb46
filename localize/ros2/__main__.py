"""``python -m localize.ros2``: the live node (conf/ros2.yaml, docs/ros2.md).

Hydra composes the settings as for ``python -m localize`` (``dataset=``, ``onnx_model=``, the
filter; ``localize.resolve.resolve`` adds the model's settings) plus the node's; the node
loads the dataset, the model edges and the SegNet, then spins until Ctrl-C.
"""

from __future__ import annotations

import logging
import time

from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from core.config import hydra_app
from localize.config import ALIASES
from localize.live.loop import load_context
from localize.resolve import resolve
from localize.ros2.config import Ros2Config

log = logging.getLogger(__name__)


def serve(cfg: DictConfig, args: list[str] | None = None) -> None:
    """Load, start the node and spin until interrupted (Ctrl-C, SIGTERM via rclpy)."""
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    from localize.ros2.node import LocalizerNode

    t0 = time.perf_counter()
    ctx = load_context(cfg)
    rclpy.init(args=args)
    node = LocalizerNode(cfg, ctx, start_s=time.perf_counter() - t0)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        if rclpy.ok():
            raise
        # Ctrl-C shut the context down while the executor was taking a message
    finally:
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()


@hydra_app("ros2", Ros2Config, ALIASES)
def main(cfg: DictConfig) -> None:
    hydra_cfg = HydraConfig.get()
    resolve(cfg, hydra_cfg.overrides.task, hydra_cfg.runtime.choices, Ros2Config,
            "conf/ros2.yaml")
    serve(cfg)


if __name__ == "__main__":
    main()
