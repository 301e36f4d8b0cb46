"""localize.ros2: the edge particle filter as a ROS 2 node (python -m localize.ros2,
docs/ros2.md). Only ``node``, ``listen`` and ``__main__`` import rclpy; ``config``, ``sync``,
``convert``, ``live`` and ``loopback`` run without it."""
