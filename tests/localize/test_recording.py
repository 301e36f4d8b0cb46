"""Recordings: a rendered flight exported as a JPEG folder, a ROS 2 bag, a ROS 1 bag and a
distorted double-size folder, read back; and every error a user's recording can raise."""

from __future__ import annotations

import logging
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from core.atomic import read_png, write_png
from core.dataset import Camera, Dataset
from core.poses import interpolate_poses, odometry_increment, pose_from_xyzyaw, write_tum
from localize.recordings.export import export_bag, export_folder, main
from localize.recordings.read import read_recording
from localize.recordings.recording import Rectifier, SourceCamera, UnreadableFrame

FLIGHT = "paper"
#: The odometry's own frame: moved and turned against the world (only increments matter).
ODOM_FROM_WORLD = pose_from_xyzyaw([1.5, -2.0, 0.3, 0.7])[0]
DISTORTION = [-0.25, 0.08, 0.001, -0.002, 0.0]
GT_TOPIC = {"groundtruth": "/groundtruth"}
COMPRESSED = "/camera/image_raw/compressed"


def increments(poses: np.ndarray) -> np.ndarray:
    return np.stack([odometry_increment(poses[i - 1], poses[i]) for i in range(1, len(poses))])


@pytest.fixture(scope="module")
def dataset(tiny_dataset) -> Dataset:
    return Dataset(tiny_dataset)


@pytest.fixture(scope="module")
def flight(dataset):
    return dataset.flight(FLIGHT)


@pytest.fixture(scope="module")
def recordings(tiny_dataset, tmp_path_factory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("recordings")
    return {
        "folder": export_folder(tiny_dataset, FLIGHT, d / "jpeg", odometry_frame=ODOM_FROM_WORLD),
        "ros2": main([str(tiny_dataset), FLIGHT, str(d / "ros2"), "--bag"]),
        "mcap": main([str(tiny_dataset), FLIGHT, str(d / "mcap"), "--bag", "--mcap",
                      "--jpeg-quality", "95", "--image-topic", COMPRESSED]),
        "ros1": export_bag(tiny_dataset, FLIGHT, d / "flight.bag", ros1=True,
                           odometry_frame=ODOM_FROM_WORLD),
        "distorted": export_folder(tiny_dataset, FLIGHT, d / "distorted", jpeg_quality=0,
                                   scale=2.0, distortion=DISTORTION),
    }


def copy_of(recordings, key: str, tmp_path: Path) -> Path:
    out = tmp_path / key
    shutil.copytree(recordings[key], out)
    return out


class TestFolderRecording:
    def test_reads_back_the_flight(self, recordings, dataset, flight):
        rec = read_recording(recordings["folder"], dataset.camera)
        assert len(rec) == len(flight.timestamps) and rec.name == "jpeg"
        np.testing.assert_allclose(rec.timestamps, flight.timestamps, atol=1e-9)
        # TUM files keep 9 decimals: each coordinate is rounded by up to 5e-10
        np.testing.assert_allclose(increments(rec.odometry), increments(flight.odometry),
                                   atol=3e-9)
        assert np.abs(rec.odometry[:, :3, 3] - flight.odometry[:, :3, 3]).max() > 0.5
        np.testing.assert_allclose(rec.groundtruth, flight.groundtruth, atol=1e-9)
        np.testing.assert_allclose(rec.camera.K, dataset.camera.K, atol=1e-9)
        np.testing.assert_allclose(rec.camera.body_from_cam, dataset.camera.body_from_cam)
        assert rec.rectifier.identity

    def test_jpeg_frames_close_to_the_pngs(self, recordings, dataset, flight):
        rec = read_recording(recordings["folder"], dataset.camera)
        frames = list(rec.images())
        assert len(frames) == len(rec)
        diff = [np.abs(f.astype(int) - read_png(p).astype(int)).mean()
                for f, p in zip(frames, flight.rgb, strict=True)]
        assert max(diff) < 4.0  # JPEG quality 95
        np.testing.assert_array_equal(rec.image(7), frames[7])
        with pytest.raises(IndexError, match="out of range"):
            rec.image(len(rec))

    def test_frames_named_by_time(self, recordings, dataset, flight, tmp_path):
        root = copy_of(recordings, "folder", tmp_path)
        (root / "images.txt").unlink()
        for i, t in enumerate(flight.timestamps):
            (root / "images" / f"{i:06d}.jpg").rename(root / "images" / f"{t + 1e9:.3f}.jpg")
        t, T = flight.timestamps + 1e9, ODOM_FROM_WORLD @ flight.odometry
        write_tum(root / "odometry.txt", t, T)
        (root / "groundtruth.txt").unlink()
        rec = read_recording(root, dataset.camera)
        np.testing.assert_allclose(rec.timestamps, t, atol=1e-6)
        assert rec.groundtruth is None
        (root / "images" / "frame.jpg").write_bytes(b"")
        with pytest.raises(ValueError, match=r"frame\.jpg.*not a time"):
            read_recording(root, dataset.camera)

    def test_frames_outside_the_odometry_are_dropped(self, recordings, dataset, flight, tmp_path,
                                                     caplog):
        root = copy_of(recordings, "folder", tmp_path)
        write_tum(root / "odometry.txt", flight.timestamps[5:], flight.odometry[5:])
        with caplog.at_level(logging.WARNING):
            rec = read_recording(root, dataset.camera)
        assert "5 of 30 frames lie outside the odometry" in caplog.text
        np.testing.assert_allclose(rec.timestamps, flight.timestamps[5:])
        np.testing.assert_allclose(rec.image(0), read_recording(
            recordings["folder"], dataset.camera).image(5))
        write_tum(root / "odometry.txt", flight.timestamps[:2] + 100, flight.odometry[:2])
        with pytest.raises(ValueError, match="no frame .* inside"):
            read_recording(root, dataset.camera)


class TestBagRecording:
    @pytest.mark.parametrize("kind", ["ros2", "ros1"])
    def test_reads_back_the_flight_exactly(self, recordings, dataset, flight, kind):
        rec = read_recording(recordings[kind], dataset.camera, topics=GT_TOPIC)
        assert len(rec) == len(flight.timestamps)
        np.testing.assert_allclose(rec.timestamps, flight.timestamps, atol=1e-9)
        np.testing.assert_allclose(increments(rec.odometry), increments(flight.odometry),
                                   atol=1e-9)
        np.testing.assert_allclose(rec.groundtruth, flight.groundtruth, atol=1e-9)
        for i, frame in enumerate(rec.images()):
            np.testing.assert_array_equal(frame, read_png(flight.rgb[i]))
        np.testing.assert_array_equal(rec.image(12), read_png(flight.rgb[12]))
        np.testing.assert_allclose(rec.camera.K, dataset.camera.K)

    def test_compressed_images_in_mcap(self, recordings, dataset, flight):
        assert list(recordings["mcap"].glob("*.mcap"))
        rec = read_recording(recordings["mcap"], dataset.camera,
                             topics={**GT_TOPIC, "image": COMPRESSED})
        np.testing.assert_allclose(rec.timestamps, flight.timestamps, atol=1e-9)
        np.testing.assert_allclose(rec.groundtruth, flight.groundtruth, atol=1e-9)
        diff = [np.abs(f.astype(int) - read_png(p).astype(int)).mean()
                for f, p in zip(rec.images(), flight.rgb, strict=True)]
        assert len(diff) == len(flight.rgb) and max(diff) < 4.0  # JPEG quality 95

    def test_steps_give_what_the_localizer_takes(self, recordings, dataset, flight):
        rec = read_recording(recordings["ros1"], dataset.camera)
        steps = list(rec.steps())
        assert [s.index for s in steps] == list(range(len(rec)))
        assert steps[0].odometry_increment is None
        np.testing.assert_allclose(np.stack([s.odometry_increment for s in steps[1:]]),
                                   increments(flight.odometry), atol=1e-9)
        np.testing.assert_array_equal(steps[4].attitude, rec.odometry[4])
        np.testing.assert_array_equal(steps[4].image, read_png(flight.rgb[4]))
        assert steps[4].timestamp == rec.timestamps[4]

    def test_without_groundtruth_topic(self, recordings, dataset):
        assert read_recording(recordings["ros2"], dataset.camera).groundtruth is None

    def test_missing_topic_lists_the_bag_topics(self, recordings, dataset):
        with pytest.raises(ValueError, match=r"'/cam/rgb' not in the bag; set "
                                             r"recording_topics\.image .*/camera/image_raw"):
            read_recording(recordings["ros2"], dataset.camera, topics={"image": "/cam/rgb"})
        with pytest.raises(ValueError, match="recording_topics.groundtruth"):
            read_recording(recordings["ros1"], dataset.camera, topics={"groundtruth": "/gt"})

    def test_wrong_topic_type_and_unknown_key(self, recordings, dataset):
        with pytest.raises(ValueError, match="carries .*Odometry"):
            read_recording(recordings["ros2"], dataset.camera, topics={"image": "/odom"})
        with pytest.raises(ValueError,
                           match=r"recording_topics.imu: Key 'imu' not in 'BagTopicsConfig'"):
            read_recording(recordings["ros2"], dataset.camera, topics={"imu": "/imu"})


class TestRectify:
    def test_distorted_double_size_reads_back(self, recordings, dataset, flight):
        raw = yaml.safe_load((recordings["distorted"] / "camera.yaml").read_text())
        assert (raw["image_width"], raw["image_height"]) == (256, 192)
        rec = read_recording(recordings["distorted"], dataset.camera)
        cam = dataset.camera
        assert (rec.camera.width, rec.camera.height) == (cam.width, cam.height)
        np.testing.assert_allclose(rec.camera.K, cam.K, atol=1e-9)
        for i in (0, 15, 29):
            got = rec.image(i).astype(int)
            want = read_png(flight.rgb[i]).astype(int)
            # resampled twice (into the distorted camera and back): within 4 levels on average
            assert np.abs(got - want)[4:-4, 4:-4].mean() < 4.0

    def test_cover_and_crop_keeps_the_geometry(self):
        """A blob projected with the source K lands where the delivered K projects it."""
        K = np.array([[150.0, 0, 99.5], [0, 150.0, 49.5], [0, 0, 1]])
        src = SourceCamera(K, 200, 100, np.array([-0.1, 0.01, 0, 0, 0]))
        rect = Rectifier(src, 64, 48)  # scale 0.48 covers 64x48 as 96x48, 16 px cut each side
        X = np.array([[0.1, -0.05, 1.0], [-0.2, 0.1, 1.0]])
        import cv2

        uv, _ = cv2.projectPoints(X, np.zeros(3), np.zeros(3), K, src.distortion)
        v, u = np.mgrid[0:100, 0:200]
        image = np.zeros((100, 200, 3), np.uint8)
        for p in uv[:, 0]:
            image[..., 1] = np.maximum(image[..., 1], 255 * np.exp(
                -((u - p[0]) ** 2 + (v - p[1]) ** 2) / (2 * 3.0 ** 2)))
        out = rect(image)
        assert out.shape == (48, 64, 3)
        want = (X @ rect.K.T)[:, :2] / X[:, 2:]
        vv, uu = np.mgrid[0:48, 0:64]
        for w in want:
            m = ((uu - w[0]) ** 2 + (vv - w[1]) ** 2 < 16) * out[..., 1].astype(float)
            got = [(m * uu).sum() / m.sum(), (m * vv).sum() / m.sum()]
            np.testing.assert_allclose(got, w, atol=0.15)

    def test_no_target_keeps_the_recorded_size(self, recordings, dataset):
        rec = read_recording(recordings["distorted"], None)
        assert (rec.camera.width, rec.camera.height) == (256, 192)
        assert rec.image(0).shape == (192, 256, 3)


def test_interpolate_poses_midpoint():
    a, b = pose_from_xyzyaw([[0, 0, 0, 0.0], [2, -4, 1, 0.8]])
    mid = interpolate_poses(np.array([0.5, 1.0, 1.25]), np.array([0.0, 1.0]), np.stack([a, b]))
    np.testing.assert_allclose(mid[0], pose_from_xyzyaw([1, -2, 0.5, 0.4])[0], atol=1e-12)
    np.testing.assert_allclose(mid[1], b, atol=1e-12)
    np.testing.assert_allclose(mid[2], b, atol=1e-12)  # clamped at the end


class TestErrors:
    def test_unreadable_image_is_named(self, recordings, dataset, tmp_path):
        root = copy_of(recordings, "folder", tmp_path)
        (root / "images" / "000003.jpg").write_bytes(b"not a jpeg")
        rec = read_recording(root, dataset.camera)
        rec.image(2)
        with pytest.raises(ValueError, match=r"cannot read image .*000003\.jpg"):
            rec.image(3)

    def test_unreadable_frame_is_dropped(self, recordings, dataset, flight, tmp_path):
        """A frame that cannot be decoded is skipped as a dropped frame: the next frame's
        increment spans from the last frame read."""
        root = copy_of(recordings, "folder", tmp_path)
        (root / "images" / "000003.jpg").write_bytes(b"not a jpeg")
        steps = list(read_recording(root, dataset.camera).steps())
        assert [s.index for s in steps] == [i for i in range(len(flight.timestamps)) if i != 3]
        np.testing.assert_allclose(steps[3].odometry_increment,
                                   increments(flight.odometry[[2, 4]])[0], atol=1e-6)

    def test_cut_short_jpeg_is_dropped(self, recordings, dataset, flight, tmp_path, caplog):
        """A JPEG cut short (OpenCV decodes it, grey below the cut) is an unreadable frame:
        named, and dropped from the steps with a warning naming the file."""
        root = copy_of(recordings, "folder", tmp_path)
        path = root / "images" / "000003.jpg"
        path.write_bytes(path.read_bytes()[:-300])
        rec = read_recording(root, dataset.camera)
        with pytest.raises(UnreadableFrame, match=r"000003\.jpg: the file is cut short"):
            rec.image(3)
        with caplog.at_level(logging.WARNING):
            steps = list(rec.steps())
        assert [s.index for s in steps] == [i for i in range(len(flight.timestamps)) if i != 3]
        assert "000003.jpg: the file is cut short" in caplog.text

    def test_cut_short_compressed_image(self, recordings, dataset):
        """The bag path: a CompressedImage cut short is an unreadable frame."""
        from rosbags.typesys import Stores, get_typestore

        from localize.recordings.messages import decode_image

        msgtype = "sensor_msgs/msg/CompressedImage"
        data = (recordings["folder"] / "images" / "000003.jpg").read_bytes()
        msg = get_typestore(Stores.ROS2_HUMBLE).types[msgtype](
            None, "jpeg", np.frombuffer(data[:-300], dtype=np.uint8))
        with pytest.raises(UnreadableFrame, match=r"frame 3: the CompressedImage .*cut short"):
            decode_image(msg, msgtype, "frame 3")
        msg.data = np.frombuffer(data, dtype=np.uint8)
        assert decode_image(msg, msgtype, "frame 3").shape[2] == 3

    def test_image_size_not_the_calibrated_one(self, recordings, dataset, tmp_path):
        root = copy_of(recordings, "distorted", tmp_path)
        write_png(root / "images" / "000001.png", np.zeros((10, 10, 3), np.uint8))
        with pytest.raises(ValueError, match=r"000001\.png: image is 10x10.*256x192"):
            read_recording(root, dataset.camera).image(1)

    @pytest.mark.parametrize("field", ["camera_matrix", "image_width"])
    def test_camera_yaml_field_missing(self, recordings, dataset, tmp_path, field):
        root = copy_of(recordings, "folder", tmp_path)
        cal = yaml.safe_load((root / "camera.yaml").read_text())
        del cal[field]
        (root / "camera.yaml").write_text(yaml.safe_dump(cal))
        with pytest.raises(ValueError, match=f"camera.yaml: field '{field}' missing"):
            read_recording(root, dataset.camera)

    def test_camera_yaml_bad_values(self, recordings, dataset, tmp_path):
        root = copy_of(recordings, "folder", tmp_path)
        cal = yaml.safe_load((root / "camera.yaml").read_text())
        (root / "camera.yaml").write_text(yaml.safe_dump(
            {**cal, "distortion_model": "equidistant",
             "distortion_coefficients": {"data": [0.1, 0, 0, 0]}}))
        with pytest.raises(ValueError, match="distortion_model 'equidistant' is not supported"):
            read_recording(root, dataset.camera)
        (root / "camera.yaml").write_text(yaml.safe_dump({**cal, "image_width": 0}))
        with pytest.raises(ValueError, match="camera.yaml: the camera needs a positive image"):
            read_recording(root, dataset.camera)
        (root / "camera.yaml").write_text(yaml.safe_dump(
            {**cal, "body_from_cam": {"data": np.diag([2.0, 1, 1, 1]).ravel().tolist()}}))
        with pytest.raises(ValueError, match="not a rigid transform"):
            read_recording(root, dataset.camera)

    def test_body_from_cam_txt_and_override(self, recordings, dataset, tmp_path):
        root = copy_of(recordings, "folder", tmp_path)
        cal = yaml.safe_load((root / "camera.yaml").read_text())
        del cal["body_from_cam"]
        (root / "camera.yaml").write_text(yaml.safe_dump(cal))
        other = Camera(dataset.camera.K, dataset.camera.width, dataset.camera.height, np.eye(4))
        assert np.array_equal(read_recording(root, other).camera.body_from_cam, np.eye(4))
        mount = pose_from_xyzyaw([0.1, 0, 0.05, 0.2])[0]
        np.savetxt(root / "body_from_cam.txt", mount)
        np.testing.assert_allclose(read_recording(root, other).camera.body_from_cam, mount)
        np.testing.assert_allclose(read_recording(root, other, body_from_cam=np.eye(4))
                                   .camera.body_from_cam, np.eye(4))
        (root / "body_from_cam.txt").unlink()
        with pytest.raises(ValueError, match="no body_from_cam"):
            read_recording(root, None)

    def test_image_timestamps_going_backwards(self, recordings, dataset, tmp_path):
        root = copy_of(recordings, "folder", tmp_path)
        lines = (root / "images.txt").read_text().splitlines()
        lines[4], lines[5] = lines[5], lines[4]  # data lines 4 and 5 (line 1 is a comment)
        (root / "images.txt").write_text("\n".join(lines) + "\n")
        with pytest.raises(ValueError, match=r"images\.txt: timestamps must strictly increase, "
                                             r"but line 6 has"):
            read_recording(root, dataset.camera)

    def test_odometry_going_backwards(self, recordings, dataset, tmp_path):
        root = copy_of(recordings, "folder", tmp_path)
        lines = (root / "odometry.txt").read_text().splitlines()
        lines.insert(3, "# a comment")
        lines[10] = lines[2]
        (root / "odometry.txt").write_text("\n".join(lines) + "\n")
        with pytest.raises(ValueError, match=r"odometry\.txt: timestamps .* line 11 has"):
            read_recording(root, dataset.camera)

    @pytest.mark.parametrize("text", ["0 1 2 3\n1 2 3 4\n", "0 0 0 0 0 0 0 0\n1 0 0 0 0 0 0 1\n",
                                      "a b c d e f g h\n"])
    def test_groundtruth_not_tum(self, recordings, dataset, tmp_path, text):
        root = copy_of(recordings, "folder", tmp_path)
        (root / "groundtruth.txt").write_text(text)
        with pytest.raises(ValueError, match=r"groundtruth\.txt: the ground truth file is not "
                                             r"TUM"):
            read_recording(root, dataset.camera)

    def test_not_a_recording(self, tmp_path, dataset):
        with pytest.raises(ValueError, match="not a recording"):
            read_recording(tmp_path, dataset.camera)
        with pytest.raises(FileNotFoundError, match="recording not found"):
            read_recording(tmp_path / "nothing", dataset.camera)
        (tmp_path / "images").mkdir()
        with pytest.raises(FileNotFoundError, match="camera.yaml not found"):
            read_recording(tmp_path, dataset.camera)

    def test_random_bytes_bag_is_named(self, tmp_path, dataset):
        bag = tmp_path / "noise.bag"
        bag.write_bytes(np.random.default_rng(0).bytes(4096))
        with pytest.raises(ValueError, match=r"noise\.bag: cannot be read as a ROS 1 \.bag"):
            read_recording(bag, dataset.camera)

    def test_fake_ros2_bag_folder_is_named(self, tmp_path, dataset):
        root = tmp_path / "fake"
        root.mkdir()
        (root / "metadata.yaml").write_text("rosbag2_bagfile_information:\n"
                                            "  storage_identifier: sqlite3\n")
        with pytest.raises(ValueError, match=r"fake: cannot be read as a ROS 2 bag folder "
                                             r".*metadata\.yaml"):
            read_recording(root, dataset.camera)

    def test_export_refuses_to_overwrite(self, recordings, tiny_dataset):
        with pytest.raises(FileExistsError, match="exists"):
            export_folder(tiny_dataset, FLIGHT, recordings["folder"])


def write_small_bag(path: Path, image_stamps: list[float], odom_stamps: list[float],
                    encoding: str = "rgb8") -> Path:
    """A ROS 2 bag with 8x6 images, a CameraInfo and odometry at the given header stamps."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    from localize.recordings.export import _camera_info, _header, _odometry

    store = get_typestore(Stores.ROS2_HUMBLE)
    types = store.types
    cam = Camera(np.array([[8.0, 0, 3.5], [0, 8.0, 2.5], [0, 0, 1]]), 8, 6, np.eye(4))
    with Writer(path, version=9) as w:
        ci = w.add_connection("/camera/image_raw", "sensor_msgs/msg/Image", typestore=store)
        cc = w.add_connection("/camera/camera_info", "sensor_msgs/msg/CameraInfo",
                              typestore=store)
        co = w.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        for k, t in enumerate(image_stamps):
            ns = round(t * 1e9)
            h = _header(types, False, ns, "camera", k)
            ch = 1 if encoding == "mono8" else 3
            img = types["sensor_msgs/msg/Image"](h, 6, 8, encoding, 0, 8 * ch,
                                                 np.full(6 * 8 * ch, k, np.uint8))
            w.write(ci, 1000 + k, store.serialize_cdr(img, "sensor_msgs/msg/Image"))
            w.write(cc, 1000 + k, store.serialize_cdr(
                _camera_info(types, False, h, cam, np.zeros(5)), "sensor_msgs/msg/CameraInfo"))
        for k, t in enumerate(odom_stamps):
            msg = _odometry(types, _header(types, False, round(t * 1e9), "odom", k),
                            pose_from_xyzyaw([k, 0, 0, 0])[0])
            w.write(co, 1000 + k, store.serialize_cdr(msg, "nav_msgs/msg/Odometry"))
    return path


class TestSmallBags:
    def test_bag_time_and_header_stamps(self, tmp_path):
        """Frames are fetched by bag time; their times are header stamps (here different)."""
        path = write_small_bag(tmp_path / "b", [10.0, 10.5, 11.0], [9.0, 12.0], "mono8")
        rec = read_recording(path, None, body_from_cam=np.eye(4))
        np.testing.assert_allclose(rec.timestamps, [10.0, 10.5, 11.0])
        np.testing.assert_allclose(rec.odometry[:, 0, 3], [1 / 3, 0.5, 2 / 3])
        np.testing.assert_array_equal(rec.image(1), np.ones((6, 8, 3), np.uint8))
        assert [int(im[0, 0, 0]) for im in rec.images()] == [0, 1, 2]

    def test_odometry_stamps_going_backwards(self, tmp_path):
        path = write_small_bag(tmp_path / "b", [10.0, 10.5], [9.0, 12.0, 11.0])
        with pytest.raises(ValueError, match=r"topic /odom: timestamps must strictly increase, "
                                             r"but message 2 has"):
            read_recording(path, None, body_from_cam=np.eye(4))

    def test_unsupported_encoding(self, tmp_path):
        path = write_small_bag(tmp_path / "b", [10.0, 10.5], [9.0, 12.0], "yuv422")
        rec = read_recording(path, None, body_from_cam=np.eye(4))
        with pytest.raises(ValueError, match=r"frame 0: image encoding 'yuv422' is not "
                                             r"supported"):
            rec.image(0)


def test_decode_image_encodings():
    from rosbags.typesys import Stores, get_typestore

    from localize.recordings.messages import decode_image

    Image = get_typestore(Stores.ROS2_HUMBLE).types["sensor_msgs/msg/Image"]
    rgb = np.arange(2 * 3 * 3, dtype=np.uint8).reshape(2, 3, 3)
    bgra = np.concatenate([rgb[..., ::-1], np.full((2, 3, 1), 255, np.uint8)], axis=2)
    padded = np.concatenate([bgra.reshape(2, 12), np.zeros((2, 4), np.uint8)], axis=1)
    for enc, data, step in (("rgb8", rgb, 9), ("bgr8", rgb[..., ::-1], 9),
                            ("bgra8", padded, 16)):
        msg = Image(None, 2, 3, enc, 0, step, np.ascontiguousarray(data).reshape(-1))
        np.testing.assert_array_equal(decode_image(msg, "sensor_msgs/msg/Image", "x"), rgb)
    mono = Image(None, 2, 3, "mono8", 0, 3, rgb[..., 0].reshape(-1).copy())
    np.testing.assert_array_equal(decode_image(mono, "sensor_msgs/msg/Image", "x")[..., 2],
                                  rgb[..., 0])
    short = Image(None, 2, 3, "rgb8", 0, 9, rgb.reshape(-1)[:10].copy())
    with pytest.raises(ValueError, match="too short"):
        decode_image(short, "sensor_msgs/msg/Image", "x")
