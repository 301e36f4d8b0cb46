"""Fixtures for the localize tests: a small corridor, a camera, a renderer, a palette "SegNet"
in ONNX, a synthetic copy of the tiny dataset and the real composed config."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import onnx
import pytest
from hydra import compose, initialize_config_dir
from omegaconf import DictConfig
from onnx import TensorProto, helper

from core import classes as C
from core.atomic import read_png, write_png
from core.config import CONF, compose_config
from core.dataset import Camera
from core.imaging.camera import intrinsics
from datagen.worlds.corridor import build_world

#: body x forward -> camera z, body y left -> camera -x, body z up -> camera -y; 10 cm ahead.
BODY_FROM_CAM = np.array([[0.0, 0.0, 1.0, 0.1], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.0],
                          [0.0, 0.0, 0.0, 1.0]])


@pytest.fixture(scope="module")
def ros(tmp_path_factory):
    """An rclpy context confined to loopback (the environment set before init): the ROS 2
    node tests' (skipped where rclpy is missing)."""
    rclpy = pytest.importorskip("rclpy")
    from localize.ros2.loopback import loopback_env

    env = loopback_env(tmp_path_factory.mktemp("dds"))
    with pytest.MonkeyPatch.context() as mp:
        for k, v in env.items():
            mp.setenv(k, v)
        context = rclpy.Context()
        rclpy.init(context=context)
        yield context
        rclpy.shutdown(context=context)


def small_spec() -> dict:
    """A 4 m corridor with a door on each side, a window and a side opening."""
    spec = compose_config("datagen")["world"]
    spec.update(length=4.0, doors=[{"side": "left", "at": 1.0}, {"side": "right", "at": 2.6}],
                windows=[{"side": "front", "at": 0.0}],
                openings=[{"side": "left", "at": 2.6, "width": 1.0, "depth": 1.2}],
                lights={"count": 2, "size": [0.6, 1.0]})
    return spec


@pytest.fixture(scope="session")
def small_world():
    return build_world(small_spec()).world


@pytest.fixture(scope="session")
def camera() -> Camera:
    return Camera(intrinsics(160, 120, 70.0), 160, 120, BODY_FROM_CAM.copy())


@pytest.fixture(scope="session")
def renderer(small_world, camera):
    from localize.paper.render import ModelRenderer

    return ModelRenderer(small_world, camera)


def palette_segnet(path: Path, height: int, width: int, classes: list[dict] | None = None,
                   extra_metadata: dict | None = None) -> Path:
    """An ONNX "SegNet" that labels each pixel with the class of the nearest palette colour.

    ``logits_c = 2 x . p_c - |p_c|^2`` (a 1x1 convolution, x and p in [0, 1]) is largest for
    the palette colour p_c nearest to x, so on ``colorize(labels)`` images it returns the
    labels exactly. It has the interface and metadata of ``train``'s segnet.onnx.
    """
    classes = classes if classes is not None else C.as_json()
    pal = C.palette()[: C.NUM_CLASSES].astype(np.float32) / 255.0
    w = (2.0 * pal)[:, :, None, None].astype(np.float32)  # (C, 3, 1, 1)
    b = -(pal ** 2).sum(axis=1).astype(np.float32)
    graph = helper.make_graph(
        [helper.make_node("Conv", ["image", "w", "b"], ["logits"])], "palette",
        [helper.make_tensor_value_info("image", TensorProto.FLOAT, ["N", 3, height, width])],
        [helper.make_tensor_value_info("logits", TensorProto.FLOAT,
                                       ["N", C.NUM_CLASSES, height, width])],
        [helper.make_tensor("w", TensorProto.FLOAT, w.shape, w.ravel()),
         helper.make_tensor("b", TensorProto.FLOAT, b.shape, b)])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    meta = {"classes": classes, "input_height": height, "input_width": width,
            **(extra_metadata or {})}
    for k, v in meta.items():
        model.metadata_props.add(key=k, value=json.dumps(v))
    onnx.save(model, str(path))
    return path


@pytest.fixture(scope="session")
def flat_dataset(tiny_dataset, tmp_path_factory) -> Path:
    """The tiny dataset with every flight image replaced by its colourized true labels, so
    Canny sees exactly the class boundaries and the palette SegNet is exact."""
    out = tmp_path_factory.mktemp("localize") / "flat"
    shutil.copytree(tiny_dataset, out)
    for label in sorted(out.glob("flights/*/label/*.png")):
        write_png(label.parent.parent / "rgb" / label.name,
                  C.colorize(read_png(label, rgb=False)))
    return out


@pytest.fixture(scope="session")
def flat_segnet(flat_dataset, tmp_path_factory) -> Path:
    meta = json.loads((flat_dataset / "dataset.json").read_text())
    cam = meta["camera"]
    return palette_segnet(tmp_path_factory.mktemp("onnx") / "segnet.onnx", int(cam["height"]),
                          int(cam["width"]))


def localize_cfg(overrides: list[str]) -> DictConfig:
    """conf/localize.yaml composed with overrides (a DictConfig, as Hydra passes it)."""
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        return compose(config_name="localize", overrides=overrides)


#: Shrinks the evaluation to seconds: few particles, a coarse occlusion grid.
QUICK = ["progress=false", "seeds=[0]", "filter.num_particles=200",
         "filter.global_particles=2000", "filter.global_frames=5", "model_edges.spacing=0.2",
         "visibility.cell_xy=0.4", "visibility.cell_z=0.5"]
