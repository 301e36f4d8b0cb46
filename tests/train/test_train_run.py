"""End-to-end training runs on the tiny synthetic dataset: outputs, resume, bad input."""

from __future__ import annotations

import csv
import json
import math
import time
from pathlib import Path

import pytest
import torch
from omegaconf import OmegaConf

import train.run as tt
from core.dataset import Dataset
from core.segmenter import read_metadata
from train.budget import MIN_FINISH_BY_SECONDS, fit_epochs, training_budget
from train.config_checks import resolve_precision
from train.data import AugmentConfig, downsample_split, load_split, to_float
from train.loop.checkpoint import load_init_weights
from train.loop.epoch import train_one_epoch
from train.loop.optim import make_ema, make_optimizer, make_scheduler
from train.losses import median_frequency_weights, segmentation_loss
from train.net.segnet import STEM_CONV_KEY, SegNet, finer_unshuffle_stem
from train.run_identity import training_config


@pytest.fixture(scope="module")
def trained(synthetic_dataset: Path, compose_train, tmp_path_factory) -> tuple[Path, dict]:
    """One uninterrupted 2-epoch run."""
    out_root = tmp_path_factory.mktemp("models")
    metrics = tt.run(compose_train(synthetic_dataset, out_root))
    return out_root / "demo", metrics


@pytest.mark.parametrize("bf16", [False, True], ids=["fp32", "bf16"])
def test_loss_falls(synthetic_dataset: Path, bf16: bool) -> None:
    data = load_split(Dataset(synthetic_dataset), "train", 8, limit=8)
    model = SegNet(
        8,
        width=0.125,
        stages=3,
        convs_per_stage=[1, 1, 1],
        generator=torch.Generator().manual_seed(0),
    )
    weights = median_frequency_weights(data.labels, 8, max_weight=10.0)
    opt = torch.optim.AdamW(model.parameters(), lr=1e-2)
    x, y = to_float(data.images), data.labels.long()
    losses = []
    for _ in range(12):
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
            logits = model(x)
        loss = segmentation_loss(logits.float(), y, weights)
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(loss.item())
    assert losses[-1] < 0.7 * losses[0], losses


@pytest.mark.parametrize(("stem", "full_labels", "head"),
                         [("average", False, "bilinear"), ("unshuffle", False, "bilinear"),
                          ("average", True, "bilinear"), ("unshuffle", True, "sharpen")])
def test_train_one_epoch_downsampled(synthetic_dataset: Path, stem: str,
                                     full_labels: bool, head: str) -> None:
    """The training loop at a quarter resolution: images box-averaged once (average stem) or
    kept whole and the labels reduced to the logits' blocks after augmentation (unshuffle);
    or the labels kept whole and the loss taken on upsampled logits (loss.resolution: input),
    through the learned full-resolution head (model.head: sharpen), which then trains too."""
    model = SegNet(8, width=0.125, stages=2, convs_per_stage=[1, 1], downsample=4, stem=stem,
                   head=head, generator=torch.Generator().manual_seed(0))
    full = load_split(Dataset(synthetic_dataset), "train", 8, limit=8)
    data = downsample_split(full, model.training_factor, keep_labels=full_labels)
    assert data.images.shape[-1] * (1 if stem == "unshuffle" else 4) == full.images.shape[-1]
    kept = full_labels or stem == "unshuffle"  # unshuffle: reduced after augmentation
    assert data.labels.shape[-1] == full.labels.shape[-1] // (1 if kept else 4)
    opt = torch.optim.AdamW(model.parameters(), lr=1e-2)
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda _: 1.0)
    gen = torch.Generator().manual_seed(0)
    aug = AugmentConfig().at_resolution(model.training_factor)
    losses = [train_one_epoch(model, data, None, opt, sched, aug, gen, 4,
                              full_labels=full_labels).loss
              for _ in range(8)]
    assert all(math.isfinite(v) for v in losses) and losses[-1] < 0.8 * losses[0], losses
    if model.sharpen_head is not None:
        assert model.sharpen_head[-1].weight.abs().sum() > 0  # was zero: the head learned


def test_weight_average() -> None:
    """make_ema: the first update copies, later ones move by 1 - decay (warmed up)."""
    m = SegNet(8, width=0.125, stages=2, convs_per_stage=[1, 1],
               generator=torch.Generator().manual_seed(0))
    assert make_ema(m, 0.0) is None
    with pytest.raises(ValueError, match="ema_decay=1.5"):
        make_ema(m, 1.5)
    ema = make_ema(m, 0.99)
    p, e = next(m.parameters()), next(ema.module.parameters())
    rm, erm = m.encoder[0][0][1].running_mean, ema.module.encoder[0][0][1].running_mean
    ema.update_parameters(m)
    torch.testing.assert_close(e, p)
    with torch.no_grad():
        p.add_(1.0)
        rm.add_(1.0)
    ema.update_parameters(m)  # second update: decay min(0.99, 2 / 11)
    torch.testing.assert_close(e, p - 2.0 / 11.0)
    torch.testing.assert_close(erm, rm - 2.0 / 11.0)  # BatchNorm statistics too


def test_training_config_leaves_out_run_keys_only() -> None:
    """Every key is hashed at every value (model.stem=average too), but the keys that name,
    place or time a run."""
    cfg = OmegaConf.create({"seed": 0, "name": "x", "threads": 4, "init_from": None,
                            "eval": {"batch_size": 8, "select": "mean_iou"},
                            "model": {"stem": "average"}})
    assert training_config(cfg) == {"seed": 0, "init_from": None,
                                    "eval": {"select": "mean_iou"},
                                    "model": {"stem": "average"}}


def test_resolve_precision() -> None:
    assert resolve_precision("bf16") is True
    assert resolve_precision("fp32") is False
    assert isinstance(resolve_precision("auto"), bool)
    with pytest.raises(ValueError, match="precision='half'"):
        resolve_precision("half")


def test_fit_epochs() -> None:
    # 21 epochs of 85 s do not fit 10 minutes: 7 do.
    assert fit_epochs(21, 1, 85.0, 600.0, 85.0) == 7
    assert fit_epochs(21, 3, 120.0, 1080.0, 40.0) == 21  # 40 s each: all fit
    assert fit_epochs(21, 5, 500.0, 300.0, 100.0) == 5  # never before the epochs done
    assert fit_epochs(21, 1, 85.0, math.inf, 85.0) == 21
    # a slow first epoch (warm-up) then 60 s each: the epochs left are timed at the latest,
    # so the schedule grows back (the mean, 72 s, would give 14)
    assert fit_epochs(21, 2, 145.0, 1080.0, 60.0) == 17


def test_fit_epochs_does_not_flip_flop() -> None:
    """A budget ending near an epoch boundary: 60 s epochs with 5.95 epochs' time left after
    10 of them. The span shrinks at once when it no longer fits, and grows back only when a
    whole extra epoch fits with half an epoch to spare."""
    budget = 600.0 + 5.95 * 60.0
    assert fit_epochs(21, 10, 600.0, budget, 60.0, current=16) == 15  # 16 does not fit
    assert fit_epochs(21, 10, 600.0, budget, 58.0, current=15) == 15  # 16.2: not by 0.5
    assert fit_epochs(21, 10, 600.0, budget, 50.0, current=15) == 16  # 17.1: 16 more
    assert fit_epochs(21, 10, 600.0, budget, 46.0, current=15) == 17  # 17.8
    assert fit_epochs(21, 10, 600.0, budget, 58.0) == 16  # no hysteresis without current
    assert fit_epochs(21, 10, 600.0, math.inf, 58.0, current=15) == 21


def test_make_scheduler_respans_in_place() -> None:
    """A schedule replaced after 30 of 100 steps by one of 60 steps continues as the 60-step
    schedule would at step 30, and ends at its final learning rate."""
    cfg = {"name": "adamw", "lr": 3e-3, "weight_decay": 1e-4, "warmup": 0.1}

    def stepped(total: int, steps: int):
        opt, sched = make_optimizer(torch.nn.Linear(2, 2), cfg, total)
        for _ in range(steps):
            opt.step()
            sched.step()
        return opt, sched

    opt, sched = stepped(100, 30)
    _, ref = stepped(60, 30)
    assert sched.get_last_lr()[0] != pytest.approx(ref.get_last_lr()[0])
    sched = make_scheduler(opt, cfg, 60, sched.last_epoch)
    assert opt.param_groups[0]["lr"] == pytest.approx(ref.get_last_lr()[0])
    for _ in range(29):
        opt.step()
        sched.step()
    assert opt.param_groups[0]["lr"] == pytest.approx(3e-3 / 25 / 1e3)


def test_training_budget() -> None:
    now = time.time()
    cfg = OmegaConf.create({"max_minutes": 10.0, "finish_by": None})
    assert training_budget(cfg, 0.0) == 600.0
    cfg.finish_by = now + 300.0  # sooner than max_minutes: 300 s more
    assert training_budget(cfg, 50.0) == pytest.approx(350.0, abs=5.0)
    cfg.finish_by = now - 60.0  # already past: a minimum to end with a model
    assert training_budget(cfg, 0.0) == pytest.approx(MIN_FINISH_BY_SECONDS, abs=5.0)
    cfg.max_minutes, cfg.finish_by = None, None
    assert training_budget(cfg, 0.0) == math.inf


@pytest.mark.slow
class TestRun:
    def test_outputs(self, trained, capsys) -> None:
        out, metrics = trained
        for f in (
            "config.json",
            "checkpoint_last.pt",
            "checkpoint_best.pt",
            "segnet.onnx",
            "segnet_int8.onnx",
            "quantize.json",
            "metrics.json",
            "confusion.png",
            "train_log.csv",
        ):
            assert (out / f).is_file(), f
        on_disk = json.loads((out / "metrics.json").read_text())
        assert on_disk == json.loads(json.dumps(metrics))
        test = on_disk["test"]
        for k in ("pixel_accuracy", "class_accuracy", "mean_iou"):
            assert 0.0 <= test[k] <= 1.0
        assert set(test["per_class_iou"]) == {
            c["name"]
            for c in Dataset(json.loads((out / "config.json").read_text())["dataset"]).classes
        }
        assert 0.0 <= on_disk["onnx_max_abs_diff"] <= 1e-4
        # export.int8: the int8 copy's scores, from train.deploy.quantize's comparison
        quant = json.loads((out / "quantize.json").read_text())
        assert on_disk["int8"]["label_agreement"] == quant["label_agreement"] > 0.5
        assert on_disk["int8"]["mean_iou"] == quant["int8"]["mean_iou"]
        assert on_disk["train_seconds"] > 0.0
        rows = list(csv.DictReader((out / "train_log.csv").open()))
        assert [int(r["epoch"]) for r in rows] == [1, 2]
        meta = read_metadata(out / "segnet.onnx")
        assert (
            meta["config_hash"]
            == on_disk["config_hash"]
            == json.loads((out / "config.json").read_text())["config_hash"]
        )
        assert (meta["input_height"], meta["input_width"]) == (48, 64)
        assert meta["test_metrics"] == {k: test[k] for k in ("pixel_accuracy", "class_accuracy",
                                                             "mean_iou", "boundary_f")}
        assert 0.0 <= test["boundary_f"] <= 1.0 and test["per_pair_boundary"]
        assert meta["localize"] == on_disk["localize"] == {}
        assert (out / "localize.yaml").is_file()
        # The loss's class weights, by class name, for localize's prior correction.
        assert meta["class_weights"] == on_disk["class_weights"]
        assert set(on_disk["class_weights"]) == set(test["per_class_iou"])
        assert all(w >= 0.0 for w in on_disk["class_weights"].values())

    def test_rerun_same_config_reuses_checkpoint(
        self, trained, synthetic_dataset, compose_train
    ) -> None:
        out, metrics = trained
        again = tt.run(compose_train(synthetic_dataset, out.parent))
        assert again["epochs_done"] == 2
        assert again["train_seconds"] == metrics["train_seconds"]  # nothing trained again
        assert again["test"]["mean_iou"] == pytest.approx(metrics["test"]["mean_iou"])

    def test_other_config_refused_then_overwritten(
        self, synthetic_dataset, compose_train, tmp_path
    ) -> None:
        tt.run(compose_train(synthetic_dataset, tmp_path, "epochs=1"))
        with pytest.raises(RuntimeError, match=r"another config.*seed.*overwrite=true"):
            tt.run(compose_train(synthetic_dataset, tmp_path, "epochs=1", "seed=1"))
        m = tt.run(
            compose_train(synthetic_dataset, tmp_path, "epochs=1", "seed=1", "overwrite=true")
        )
        assert m["epochs_done"] == 1

    def test_schedule_fitted_to_budget(
        self, trained, synthetic_dataset, compose_train, tmp_path, monkeypatch
    ) -> None:
        """When the epochs left do not fit the budget, the schedule is shortened: a 4-epoch
        run cut to 2 ends at the learning rate of a 2-epoch run."""
        monkeypatch.setattr(tt, "fit_epochs", lambda req, done, seconds, budget, last, current: 2)
        m = tt.run(compose_train(synthetic_dataset, tmp_path, "epochs=4"))
        assert (m["epochs"], m["epochs_requested"], m["epochs_done"]) == (2, 4, 2)
        rows = list(csv.DictReader((tmp_path / "demo" / "train_log.csv").open()))
        assert len(rows) == 2
        two = list(csv.DictReader((trained[0] / "train_log.csv").open()))
        assert float(rows[-1]["lr"]) == pytest.approx(float(two[-1]["lr"]))
        assert float(rows[-1]["lr"]) < 0.1 * float(rows[0]["lr"])
        monkeypatch.setattr(tt, "fit_epochs", lambda req, done, seconds, budget, last, current: 2)
        again = tt.run(compose_train(synthetic_dataset, tmp_path, "epochs=4"))
        assert again["epochs_done"] == 2  # a resume keeps the fitted schedule

    def test_resume_after_interruption(
        self, trained, synthetic_dataset, compose_train, tmp_path, monkeypatch
    ) -> None:
        """Crash during epoch 2, re-run: the weights equal the uninterrupted run's."""
        real = tt.train_one_epoch
        calls = {"n": 0}

        def crash_on_second(*args, **kwargs):
            calls["n"] += 1
            if calls["n"] == 2:
                raise KeyboardInterrupt
            return real(*args, **kwargs)

        cfg = compose_train(synthetic_dataset, tmp_path)
        monkeypatch.setattr(tt, "train_one_epoch", crash_on_second)
        with pytest.raises(KeyboardInterrupt):
            tt.run(cfg)
        assert (
            torch.load(tmp_path / "demo" / "checkpoint_last.pt", weights_only=False)["epoch"] == 1
        )
        monkeypatch.setattr(tt, "train_one_epoch", real)
        tt.run(cfg)
        resumed = torch.load(tmp_path / "demo" / "checkpoint_last.pt", weights_only=False)
        reference = torch.load(trained[0] / "checkpoint_last.pt", weights_only=False)
        assert resumed["epoch"] == 2
        for k, v in reference["model"].items():
            torch.testing.assert_close(resumed["model"][k], v, rtol=1e-5, atol=1e-6)

    def test_real_camera_reaches_the_validation(
        self, trained, synthetic_dataset, compose_train, tmp_path
    ) -> None:
        """data.realism=real: the same weights (fine-tuned at a vanishing learning rate) score
        otherwise on validation images passed through the camera."""
        val = {}
        for realism in ("ideal", "real"):
            metrics = tt.run(compose_train(synthetic_dataset, tmp_path, f"name={realism}",
                                           "epochs=1", "optim.lr=1e-12",
                                           f"init_from={trained[0]}", f"data.realism={realism}"))
            val[realism] = metrics["val_best"]["val_mean_iou"]
            config = json.loads((tmp_path / realism / "config.json").read_text())
            assert config["config"]["data"]["realism"] == realism
        assert val["ideal"] != val["real"]

    def test_init_from_starts_from_the_weights(
        self, trained, synthetic_dataset, compose_train, tmp_path
    ) -> None:
        """Fine-tuning at a vanishing learning rate keeps the source's weights; without
        init_from the same run ends elsewhere (random start)."""
        source = torch.load(trained[0] / "checkpoint_best.pt", weights_only=False)["model"]
        runs = {}
        for name, extra in (("ft", [f"init_from={trained[0]}"]), ("scratch", [])):
            tt.run(compose_train(synthetic_dataset, tmp_path, f"name={name}", "epochs=1",
                                 "optim.lr=1e-12", *extra))
            runs[name] = torch.load(tmp_path / name / "checkpoint_best.pt",
                                    weights_only=False)["model"]
        weights = [k for k, v in source.items() if k.endswith("weight") and v.dim() == 4]
        assert weights
        for k in weights:
            torch.testing.assert_close(runs["ft"][k], source[k], rtol=1e-4, atol=1e-5)
        assert any(not torch.allclose(runs["scratch"][k], source[k], atol=1e-3)
                   for k in weights)
        config = json.loads((tmp_path / "ft" / "config.json").read_text())
        assert config["config"]["init_from"] == str(trained[0])
        assert json.loads(
            (tmp_path / "scratch" / "config.json").read_text())["config"]["init_from"] is None


def test_init_from_a_coarser_unshuffle_network(tmp_path) -> None:
    """init_from a downsample-4 unshuffle network into a downsample-2 one carries the stem
    (segnet.finer_unshuffle_stem) and every other weight as it is; another width is refused."""
    mcfg = dict(width=0.125, stages=3, convs_per_stage=[1, 1, 2], skip="add", stem="unshuffle",
                head="sharpen", downsample=4)
    coarse = SegNet(num_classes=5, **mcfg)
    torch.save({"model": coarse.state_dict(), "model_kwargs": dict(mcfg), "num_classes": 5},
               tmp_path / "checkpoint_best.pt")
    fine_cfg = {**mcfg, "downsample": 2}
    fine = SegNet(num_classes=5, **fine_cfg)
    assert load_init_weights(fine, tmp_path, fine_cfg, 5) == tmp_path / "checkpoint_best.pt"
    for k, v in coarse.state_dict().items():
        if k != STEM_CONV_KEY:
            torch.testing.assert_close(fine.state_dict()[k], v)
    torch.testing.assert_close(fine.state_dict()[STEM_CONV_KEY],
                               finer_unshuffle_stem(coarse.state_dict()[STEM_CONV_KEY], 4, 2))
    wider = {**fine_cfg, "width": 0.25}
    with pytest.raises(ValueError, match="downsample=4 there, 2 here; width=0.125 there"):
        load_init_weights(SegNet(num_classes=5, **wider), tmp_path, wider, 5)


def test_init_from_adds_a_context_branch(tmp_path) -> None:
    """init_from a network without context_layers into one with them: every trained weight is
    carried, the branch starts at zero, so the new network computes what the old one did."""
    mcfg = dict(width=0.125, stages=3, convs_per_stage=[1, 1, 2], skip="add")
    old = SegNet(num_classes=5, **mcfg).eval()
    torch.save({"model": old.state_dict(), "model_kwargs": dict(mcfg), "num_classes": 5},
               tmp_path / "checkpoint_best.pt")
    new_cfg = {**mcfg, "context_layers": 2}
    new = SegNet(num_classes=5, **new_cfg).eval()
    load_init_weights(new, tmp_path, new_cfg, 5)
    x = torch.rand(2, 3, 32, 48, generator=torch.Generator().manual_seed(0))
    with torch.no_grad():
        torch.testing.assert_close(new(x), old(x))


class TestBadInput:
    def test_init_from_missing_or_other_network(
        self, trained, synthetic_dataset, compose_train, tmp_path
    ) -> None:
        with pytest.raises(FileNotFoundError, match="init_from=.*checkpoint_best.pt"):
            tt.run(compose_train(synthetic_dataset, tmp_path, f"init_from={tmp_path / 'none'}"))
        with pytest.raises(ValueError, match="init_from=.*width=0.125 there, 0.25 here"):
            tt.run(compose_train(synthetic_dataset, tmp_path, f"init_from={trained[0]}",
                                 "model.width=0.25"))
        assert not (tmp_path / "demo").exists()  # refused before any output

    def test_missing_dataset(self, compose_train, tmp_path) -> None:
        with pytest.raises(FileNotFoundError, match="dataset not found"):
            tt.run(compose_train(tmp_path / "nope", tmp_path))

    def test_class_count_mismatch(self, synthetic_dataset, compose_train, tmp_path) -> None:
        with pytest.raises(ValueError, match="class-count mismatch"):
            tt.run(compose_train(synthetic_dataset, tmp_path, "model.num_classes=5"))

    def test_wrong_image_size(self, make_dataset, compose_train, tmp_path) -> None:
        from core.atomic import write_png

        root = make_dataset(tmp_path / "ds", {"train": 2, "val": 1, "test": 1})
        write_png(
            root / "val" / "rgb" / "000000.png", torch.zeros(48, 60, 3, dtype=torch.uint8).numpy()
        )
        with pytest.raises(ValueError, match="does not match the dataset camera"):
            tt.run(compose_train(root, tmp_path))

    def test_zero_budget(self, synthetic_dataset, compose_train, tmp_path) -> None:
        with pytest.raises(RuntimeError, match="time budget"):
            tt.run(compose_train(synthetic_dataset, tmp_path, "max_minutes=0"))

    @pytest.mark.parametrize("override,match", [
        ("epochs=0", "epochs=0 must be an integer >= 1"),
        ("batch_size=0", "batch_size=0 must be an integer >= 1"),
        ("eval.batch_size=-1", "eval.batch_size=-1 must be"),
        ("threads=0", "threads=0 must be"),
        ("max_minutes=-5", "max_minutes=-5 must be >= 0"),
    ])
    def test_bad_count(self, synthetic_dataset, compose_train, tmp_path, override, match
                       ) -> None:
        with pytest.raises(ValueError, match=match):
            tt.run(compose_train(synthetic_dataset, tmp_path, override))
        assert not any(tmp_path.iterdir())  # nothing written

    def test_bad_loss_weight(self, synthetic_dataset, compose_train, tmp_path) -> None:
        with pytest.raises(ValueError, match="loss.boundary_weight=-2 must be positive"):
            tt.run(compose_train(synthetic_dataset, tmp_path, "loss.boundary_weight=-2"))
        assert not any(tmp_path.iterdir())  # nothing written

    def test_bad_loss_resolution(self, synthetic_dataset, compose_train, tmp_path) -> None:
        with pytest.raises(ValueError, match="loss.resolution='full': use network or input"):
            tt.run(compose_train(synthetic_dataset, tmp_path, "loss.resolution=full"))

    def test_sharpen_head_needs_input_resolution(self, synthetic_dataset, compose_train,
                                                tmp_path) -> None:
        with pytest.raises(ValueError, match="model.head=sharpen .* loss.resolution=input"):
            tt.run(compose_train(synthetic_dataset, tmp_path, "model.head=sharpen",
                                 "model.stem=unshuffle"))
        assert not (tmp_path / "demo").exists()  # failed before writing anything

    def test_unknown_camera(self, synthetic_dataset, compose_train, tmp_path) -> None:
        with pytest.raises(ValueError, match=r"data.realism = 'phone'.*'ideal', 'real'"):
            tt.run(compose_train(synthetic_dataset, tmp_path, "data.realism=phone"))
        assert not (tmp_path / "demo").exists()  # failed before writing anything

    def test_bad_precision(self, synthetic_dataset, compose_train, tmp_path) -> None:
        with pytest.raises(ValueError, match="precision='half': use auto, bf16 or fp32"):
            tt.run(compose_train(synthetic_dataset, tmp_path, "precision=half"))
        assert not (tmp_path / "demo").exists()  # failed before writing anything
