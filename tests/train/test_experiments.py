"""conf/experiment/ (python -m train's recipes): the chain of `make best`, best1_fullres ->
best2_unweighted -> best3_highres -> best4_highres_longer -> best5_context, composes, each
stage starting from the previous one's folder and carrying its localize settings; a tiny chain
of two stages trains through init_from and hands its settings to localize."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch
import yaml
from hydra import compose, initialize_config_dir
from hydra.errors import ConfigCompositionException
from omegaconf import OmegaConf

import train.run as tt
from core.model_folder import MODELS_ROOT
from core.segmenter import read_metadata
from tests.train.conftest import CONF_DIR, TINY_OVERRIDES
from train.run_identity import training_config

CHAIN = ["best1_fullres", "best2_unweighted", "best3_highres", "best4_highres_longer",
         "best5_context"]


def compose_experiment(name: str, *overrides: str):
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        return compose("train", overrides=[f"experiment={name}", *overrides])


#: conf/experiment/'s other recipes (python -m train's), and conf/datagen_experiment/'s.
TRAIN_RECIPES = ["generalist", "finetune"]
DATAGEN_RECIPES = ["generalist_floors"]


def test_every_experiment_file_is_known() -> None:
    assert sorted(p.stem for p in (CONF_DIR / "experiment").glob("*.yaml")) == sorted(
        CHAIN + TRAIN_RECIPES)
    assert sorted(p.stem for p in (CONF_DIR / "datagen_experiment").glob("*.yaml")) == sorted(
        DATAGEN_RECIPES)


def test_generalist_recipes_compose() -> None:
    """The generalist trains on every procedural floor for its epochs, whatever they take;
    fine-tuning starts from the shipped generalist's folder with a 10-minute budget and keeps
    the generalist where it shows no gain."""
    cfg = compose_experiment("generalist")
    assert (cfg.name, cfg.dataset, cfg.init_from) == (
        "generalist", "outputs/datasets/generalist/floor*", None)
    assert cfg.max_minutes is None  # the epochs alone: the same network on any machine
    assert not cfg.keep.init_unless_gain
    cfg = compose_experiment("finetune", "dataset=outputs/datasets/office")
    assert (cfg.init_from, cfg.max_minutes) == ("models/generalist", 10)
    assert cfg.dataset == "outputs/datasets/office"
    assert cfg.keep.init_unless_gain  # the generalist ships where the fine-tune gains nothing


def test_finetune_of_ones_building() -> None:
    """`make building`'s training: the fine-tune of the shipped generalist on the building's
    dataset, written to outputs/models/NAME."""
    cfg = compose_experiment("finetune", "name=office", "dataset=outputs/datasets/office")
    assert (cfg.init_from, cfg.epochs, cfg.dataset) == ("models/generalist", 9,
                                                        "outputs/datasets/office")
    assert Path(cfg.out_root) / cfg.name == MODELS_ROOT / "office"
    assert (Path(CONF_DIR).parent / cfg.init_from / "checkpoint_best.pt").is_file()
    recipe = (Path(CONF_DIR).parent / "Makefile").read_text().split("\nbuilding:")[1]
    assert "-m train experiment=finetune name=$(NAME) dataset=outputs/datasets/$(NAME)" in recipe
    assert "onnx_model=outputs/models/$(NAME)/segnet.onnx" in recipe


@pytest.mark.parametrize("stage", range(len(CHAIN)), ids=CHAIN)
def test_experiment_composes(stage: int) -> None:
    """Each stage names its folder, starts from the previous stage's, keeps the recipe's
    network and carries localize settings of conf/localize.yaml's sections."""
    cfg = compose_experiment(CHAIN[stage], "out_root=/models")
    assert cfg.name == CHAIN[stage]
    assert cfg.init_from == (None if stage == 0 else f"/models/{CHAIN[stage - 1]}")
    assert (cfg.model.stem, cfg.model.head, cfg.loss.resolution) == ("unshuffle", "sharpen",
                                                                      "input")
    assert cfg.loss.boundary_weight == 6.0
    assert cfg.model.downsample == (4 if stage < 2 else 2)
    assert cfg.model.context_layers == (3 if CHAIN[stage] == "best5_context" else 0)
    assert cfg.loss.class_weighting == ("median_frequency" if stage == 0 else "none")
    settings = OmegaConf.to_container(cfg.localize)
    assert set(settings) == {"filter", "edges"}
    assert settings["edges"]["cnn"]["prior_correction"] == 0.0
    assert compose_experiment(CHAIN[stage], "epochs=3").epochs == 3  # the command line wins


def test_best5_context_localize_settings() -> None:
    cfg = compose_experiment("best5_context")
    assert OmegaConf.to_container(cfg.localize) == {
        "filter": {"mode_likelihood": {"cnn": {"k": 50.0}}},
        "edges": {"cnn": {"prior_correction": 0.0, "snap_nearest": True, "refine": "none",
                          "snap_px": 1}},
    }
    assert cfg.init_from == "outputs/models/best4_highres_longer"


def test_localize_settings_left_out_of_the_hash() -> None:
    """Re-tuning a model's localize settings does not make its folder another config."""
    a = training_config(compose_experiment("best4_highres_longer"))
    b = training_config(compose_experiment("best4_highres_longer",
                                           "localize.edges.cnn.refine=union"))
    assert a == b and "localize" not in a


def test_bad_localize_section(synthetic_dataset, compose_train, tmp_path) -> None:
    """A localize key that is not a mapping is refused when the config is composed, or, for a
    plain mapping, when run reads it (train.config.TrainConfig)."""
    with pytest.raises(ConfigCompositionException, match="localize=3"):
        compose_train(synthetic_dataset, tmp_path, "localize=3")
    with pytest.raises(ValueError, match="train.localize: Cannot assign int"):
        tt.run({"dataset": str(synthetic_dataset), "out_root": str(tmp_path), "localize": 3})
    assert not (tmp_path / "demo").exists()


@pytest.mark.slow
def test_tiny_chain(synthetic_dataset: Path, tmp_path: Path) -> None:
    """best1_fullres then best2_unweighted, a few steps each: the second starts from the
    first's weights (at a vanishing learning rate it keeps them), each folder carries its
    stage's settings, and localize's config takes them."""
    from localize.resolve import apply_model_settings

    tiny = [f"dataset={synthetic_dataset}", f"out_root={tmp_path}", *TINY_OVERRIDES,
            "epochs=1", "data.limit=8", "export.int8=false", "model.head_channels=4"]
    first = tt.run(compose_experiment("best1_fullres", *tiny))
    assert first["localize"]["filter"]["mode_likelihood"]["cnn"]["k"] == 25.0
    second = tt.run(compose_experiment("best2_unweighted", *tiny, "optim.lr=1e-12",
                                       "export.tolerance=1e-4"))
    def weights(stage: str) -> dict:
        return torch.load(tmp_path / stage / "checkpoint_best.pt", weights_only=False)["model"]

    src, dst = weights("best1_fullres"), weights("best2_unweighted")
    convs = [k for k, v in src.items() if k.endswith("weight") and v.dim() == 4]
    for k in convs:
        torch.testing.assert_close(dst[k], src[k], rtol=1e-4, atol=1e-5)
    config = json.loads((tmp_path / "best2_unweighted" / "config.json").read_text())["config"]
    assert config["init_from"] == str(tmp_path / "best1_fullres")
    assert second["class_weights"] is None  # the stage's loss.class_weighting=none

    onnx_path = tmp_path / "best2_unweighted" / "segnet.onnx"
    carried = yaml.safe_load((tmp_path / "best2_unweighted" / "localize.yaml").read_text())
    assert carried == read_metadata(onnx_path)["localize"] == second["localize"]
    assert carried["edges"]["cnn"]["snap_nearest"] is True
    overrides = [f"onnx_model={onnx_path}"]
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose("localize", overrides=overrides)
    apply_model_settings(cfg, overrides)
    assert cfg.filter.mode_likelihood.cnn.k == 50.0 and cfg.edges.cnn.snap_nearest is True


@pytest.mark.slow
def test_finetune_starts_from_the_shipped_generalist(synthetic_dataset: Path,
                                                     tmp_path: Path) -> None:
    """The finetune recipe trains on another dataset from models/generalist's weights."""
    root = Path(CONF_DIR).parent
    cfg = compose_experiment("finetune", f"dataset={synthetic_dataset}", f"out_root={tmp_path}",
                             "name=office", f"init_from={root / 'models' / 'generalist'}",
                             "epochs=1", "data.limit=8", "export.int8=false", "progress=false")
    metrics = tt.run(cfg)
    assert (tmp_path / "office" / "segnet.onnx").is_file() and metrics["epochs_done"] == 1
    config = json.loads((tmp_path / "office" / "config.json").read_text())["config"]
    assert config["init_from"] == str(root / "models" / "generalist")
