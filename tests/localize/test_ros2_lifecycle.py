"""The node's ROS 2 conventions over the real middleware (rclpy, Fast DDS), on loopback only:
the lifecycle transitions through ``~/change_state``, nav2 AMCL's
``reinitialize_global_localization`` (and ``global_localization``), the latched free-space
grid and model-edge markers, and settings from a ROS params file.

Every participant runs in the loopback rclpy context of ``ros`` (tests/localize/conftest.py)
(``localize.ros2.loopback.loopback_env``: UDPv4 on 127.0.0.1 only,
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, a random domain), set before ``rclpy.init``.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from lifecycle_msgs.msg import State, Transition  # noqa: E402
from lifecycle_msgs.srv import ChangeState, GetState  # noqa: E402
from nav_msgs.msg import OccupancyGrid  # noqa: E402
from omegaconf import OmegaConf  # noqa: E402
from std_srvs.srv import Empty  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

from core import classes as C  # noqa: E402
from localize.edge_model import scored_segments  # noqa: E402
from localize.ros2.node import LATCHED, LocalizerNode  # noqa: E402
from localize.ros2.parameters import config_with, parameter_values  # noqa: E402
from localize.ros2.play import PlayConfig, Player  # noqa: E402
from tests.localize import test_ros2_node as node_tests  # noqa: E402
from tests.localize.test_ros2_node import publish_frames, wait_until  # noqa: E402

#: The fixtures of the node's tests: the loopback rclpy context, the tiny flight's config.
setup = node_tests.setup


class Running:
    """A ``LocalizerNode`` (with ``settings`` over the config's; ``cli_args`` its ROS
    arguments) and a helper node (player, clients, subscribers) spinning on one executor
    thread; ``close()`` stops both."""

    def __init__(self, context, setup, settings=None, cli_args=None):
        from rclpy.executors import SingleThreadedExecutor

        cfg, ctx, self.pb = setup
        cfg = OmegaConf.merge(cfg, settings or {})
        self.node = LocalizerNode(cfg, ctx, context=context, cli_args=cli_args)
        self.helper = rclpy.create_node("helper", context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.helper)
        threading.Thread(target=self.executor.spin, daemon=True).start()
        self.player = Player(self.helper, PlayConfig(topics=self.node.topics))

    def call(self, srv_type, name: str, request=None):
        """Call a service; its response (fails the test after 10 s)."""
        client = self.helper.create_client(srv_type, name)
        assert client.wait_for_service(timeout_sec=10.0), f"no service {name}"
        future = client.call_async(request or srv_type.Request())
        assert wait_until(future.done, 30.0), f"{name}: no answer"
        self.helper.destroy_client(client)
        return future.result()

    def state(self) -> int:
        return self.call(GetState, f"/{self.node.get_name()}/get_state").current_state.id

    def transition(self, transition_id: int) -> bool:
        request = ChangeState.Request()
        request.transition.id = transition_id
        return self.call(ChangeState, f"/{self.node.get_name()}/change_state", request).success

    def frames(self, n: int, start: int = 0) -> None:
        """Frames start..start+n-1 of the flight, stamped from now at 10 Hz."""
        stamps = time.time() + 0.3 + 0.1 * np.arange(n)
        publish_frames(self.player, _Skip(self.pb, start), n, stamps)

    def latched(self, msg_type, topic: str) -> list:
        """The messages a subscriber joining now gets on a latched topic (waits up to 5 s)."""
        got = []
        sub = self.helper.create_subscription(msg_type, topic, got.append, LATCHED)
        wait_until(lambda: got, 5.0)
        self.helper.destroy_subscription(sub)
        return got

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        self.helper.destroy_node()


class _Skip:
    """A playback from frame ``start`` on (its frames, odometry and camera)."""

    def __init__(self, pb, start: int):
        self.camera, self.odometry = pb.camera, pb.odometry[start:]
        self._pb, self._start = pb, start

    def frames(self):
        for i, image in enumerate(self._pb.frames()):
            if i >= self._start:
                yield image


def test_lifecycle_transitions(ros, setup):
    """With ``autostart=false`` the node waits unconfigured; ``change_state`` configures it
    (the context, the outputs; no input subscribed), activates it (frames are processed and
    the free space is latched), deactivates it (frames are no longer taken; the filter keeps
    its state), activates it again, cleans it up and shuts it down."""
    run = Running(ros, setup, {"autostart": False})
    try:
        node, image_pub = run.node, run.player.image_pub
        assert run.state() == State.PRIMARY_STATE_UNCONFIGURED and node.live is None
        assert run.transition(Transition.TRANSITION_CONFIGURE)
        assert run.state() == State.PRIMARY_STATE_INACTIVE and node.live is not None
        time.sleep(0.5)
        assert image_pub.get_subscription_count() == 0  # inactive: no input taken
        assert run.transition(Transition.TRANSITION_ACTIVATE)
        assert run.state() == State.PRIMARY_STATE_ACTIVE
        assert wait_until(lambda: image_pub.get_subscription_count() == 1)
        run.frames(3)
        assert wait_until(lambda: node.live.counts.processed >= 2)
        assert run.latched(OccupancyGrid, node.topics.free_space)
        assert run.transition(Transition.TRANSITION_DEACTIVATE)
        assert run.state() == State.PRIMARY_STATE_INACTIVE
        assert wait_until(lambda: image_pub.get_subscription_count() == 0)
        live, received = node.live, node.live.counts.received
        run.frames(2, start=3)
        time.sleep(0.5)
        assert live.counts.received == received  # inactive: nothing taken
        assert run.transition(Transition.TRANSITION_ACTIVATE)
        assert wait_until(lambda: image_pub.get_subscription_count() == 1)
        processed = live.counts.processed
        run.frames(3, start=5)
        assert wait_until(lambda: live.counts.processed >= processed + 2)
        assert node.live is live  # the same filter went on
        assert run.transition(Transition.TRANSITION_DEACTIVATE)
        assert run.transition(Transition.TRANSITION_CLEANUP)
        assert run.state() == State.PRIMARY_STATE_UNCONFIGURED and node.live is None
        assert run.transition(Transition.TRANSITION_UNCONFIGURED_SHUTDOWN)
        assert run.state() == State.PRIMARY_STATE_FINALIZED
    finally:
        run.close()


def test_autostart_runs_alone(ros, setup):
    """By default the node configures and activates itself when made."""
    run = Running(ros, setup)
    try:
        assert run.state() == State.PRIMARY_STATE_ACTIVE
        assert wait_until(lambda: run.player.image_pub.get_subscription_count() == 1)
    finally:
        run.close()


def test_a_failed_configure_says_why(ros, setup, tmp_path, caplog):
    """A configuration that fails (a dataset that is not there) leaves the node unconfigured,
    answers the lifecycle manager ``success: false`` and logs the reason naming the
    setting; with autostart the node is not made and the error is raised."""
    missing = str(tmp_path / "no_such_dataset")
    run = Running(ros, setup, {"autostart": False},
                  cli_args=["--ros-args", "-p", f"dataset:={missing}"])
    try:
        assert not run.transition(Transition.TRANSITION_CONFIGURE)
        assert run.state() == State.PRIMARY_STATE_UNCONFIGURED
        assert missing in str(run.node.configure_error)
        assert "configure failed" in caplog.text
    finally:
        run.close()
    cfg, ctx, _ = setup
    with pytest.raises(Exception, match="no_such_dataset"):
        LocalizerNode(cfg, ctx, context=ros,
                      cli_args=["--ros-args", "-p", f"dataset:={missing}"]).destroy_node()


def test_reinitialize_global_localization(ros, setup):
    """nav2 AMCL's ``/reinitialize_global_localization`` restarts the global search (the next
    frame is a frame of the search: status ``ambiguous``, the reset counter up by one);
    ``/global_localization`` is the same service under ROS 1 AMCL's name."""
    run = Running(ros, setup)
    try:
        node = run.node
        run.frames(2)
        assert wait_until(lambda: node.live.counts.processed >= 2)
        assert node.live.last_output.status == "tracking"
        for k, name in enumerate((node.topics.reinitialize_global_localization,
                                  node.topics.global_localization), start=1):
            assert name == ("/reinitialize_global_localization", "/global_localization")[k - 1]
            run.call(Empty, name)
            processed = node.live.counts.processed
            run.frames(1, start=2 + k)
            assert wait_until(lambda p=processed: node.live.counts.processed > p)
            assert node.live.counts.resets == k
            out = node.live.last_output
            assert out.status == "ambiguous" and out.estimate.confidence == 0.0
            assert node.live.localizer.search is not None or len(
                node.live.localizer.filter.particles) > node.live.settings.filter.num_particles
    finally:
        run.close()


def test_free_space_grid_and_edge_markers_are_latched(ros, setup):
    """A subscriber joining after the node started gets the free space (an OccupancyGrid of
    the world's free cells: 0 free, 100 elsewhere, at its origin and cell size, in the map
    frame) and the model's edges (a LINE_LIST per class, in the class's palette colour, two
    points a segment)."""
    run = Running(ros, setup)
    try:
        time.sleep(0.3)
        grids = run.latched(OccupancyGrid, run.node.topics.free_space)
        marks = run.latched(MarkerArray, run.node.topics.model_edges)
    finally:
        run.close()
    cfg, ctx, _ = setup
    free = ctx.world.free
    assert len(grids) == 1 and len(marks) == 1
    g = grids[0]
    assert g.header.frame_id == "map"
    assert (g.info.height, g.info.width) == free.free.shape
    assert g.info.resolution == pytest.approx(free.cell)
    np.testing.assert_allclose([g.info.origin.position.x, g.info.origin.position.y],
                               free.origin, atol=1e-6)
    data = np.array(g.data, dtype=np.int8).reshape(free.free.shape)
    np.testing.assert_array_equal(data == 0, free.free)
    assert set(np.unique(data)) <= {0, 100} and (data == 0).any() and (data == 100).any()
    keep = scored_segments(ctx.world, float(cfg.model_edges.min_length))
    sides = np.asarray(ctx.world.segment_classes)[keep].max(axis=1)
    markers = marks[0].markers
    assert {m.id for m in markers} == set(np.unique(sides).tolist())
    palette = C.palette()
    for m in markers:
        assert m.type == m.LINE_LIST and m.header.frame_id == "map"
        assert m.ns == f"edges/{C.NAMES[m.id]}"
        assert len(m.points) == 2 * np.count_nonzero(sides == m.id)
        np.testing.assert_allclose([m.color.r, m.color.g, m.color.b],
                                   palette[m.id] / 255.0, atol=1e-6)
    first = np.asarray(ctx.world.segments)[keep][sides == markers[0].id][0]
    np.testing.assert_allclose([[p.x, p.y, p.z] for p in markers[0].points[:2]], first,
                               atol=1e-9)


def test_settings_from_a_params_file(ros, setup, tmp_path):
    """``--ros-args --params-file FILE``: the settings of the same names as Hydra's, nested
    as ROS params files nest them, replace the config's: a filter setting (the context is
    loaded for it), a topic, the start pose; a name that is no setting fails the configuration
    naming it."""
    cfg, ctx, pb = setup
    pose = [float(v) for v in cfg.hint.pose]
    params = tmp_path / "edgeloc.yaml"
    params.write_text(f"""edgeloc:
  ros__parameters:
    filter:
      num_particles: 123
    topics:
      pose: /custom/pose
    hint:
      pose: {pose}
""")
    run = Running(ros, setup, cli_args=["--ros-args", "--params-file", str(params)])
    try:
        node = run.node
        assert node.get_parameter("filter.num_particles").value == 123
        assert node.live.ctx is not ctx and node.live.ctx.settings.filter.num_particles == 123
        assert node.topics.pose == "/custom/pose"
        got = []
        run.helper.create_subscription(type(_pose_msg()), "/custom/pose", got.append, 10)
        time.sleep(0.5)
        run.frames(2)
        assert wait_until(lambda: len(got) >= 2)
        assert len(node.live.localizer.filter.particles) == 123
    finally:
        run.close()
    bad = tmp_path / "bad.yaml"
    bad.write_text("edgeloc:\n  ros__parameters:\n    filter:\n      num_particle: 5\n")
    with pytest.raises(ValueError, match=r"ROS parameters of node edgeloc: "
                                         r"filter.num_particle: Key 'num_particle' not in"):
        LocalizerNode(cfg, ctx, context=ros, cli_args=["--ros-args", "--params-file", str(bad)])


def _pose_msg():
    from geometry_msgs.msg import PoseWithCovarianceStamped

    return PoseWithCovarianceStamped()


class TestParameterNames:
    """The one set of names: every Hydra key is a ROS parameter, nested lists flat."""

    def test_round_trip(self, setup):
        cfg, _, _ = setup
        values = parameter_values(cfg)
        assert values["filter.num_particles"] == cfg.filter.num_particles
        assert values["topics.image"] == "/camera/image_raw" and "node_name" not in values
        back = config_with(cfg, values, "test")
        assert OmegaConf.to_container(back) == OmegaConf.to_container(cfg)

    def test_nested_lists_are_flat(self, setup):
        cfg, _, _ = setup
        mount = np.eye(4)
        mount[:3, 3] = [0.1, 0.0, -0.05]
        out = config_with(cfg, {"body_from_cam": mount.ravel().tolist(),
                                "hint.region": [0, 0, 1, 0, 1, 1]}, "test")
        np.testing.assert_allclose(out.body_from_cam, mount)
        assert OmegaConf.to_container(out.hint.region) == [[0, 0], [1, 0], [1, 1]]
        rect = config_with(cfg, {"hint.region": [0.0, 0.0, 8.0, 3.0]}, "test")
        assert OmegaConf.to_container(rect.hint.region) == [0.0, 0.0, 8.0, 3.0]
        with pytest.raises(ValueError, match="body_from_cam: 17 numbers are no rows of 4"):
            config_with(cfg, {"body_from_cam": list(range(17))}, "test")

    def test_unknown_names_are_refused(self, setup):
        cfg, _, _ = setup
        with pytest.raises(ValueError, match=r"here: topics.imagee: Key 'imagee' not in"):
            config_with(cfg, {"topics.imagee": "/x"}, "here")
        with pytest.raises(ValueError, match="node_name is not a setting"):
            config_with(cfg, {"node_name": "x"}, "here")
