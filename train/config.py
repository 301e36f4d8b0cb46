"""The settings of ``python -m train``: the schema of conf/train.yaml, and its defaults.

Hydra composes conf/train.yaml's groups (``conf/model/``, ``conf/optim/``,
``conf/experiment/``) and the command line onto ``TrainConfig`` (registered as
``train_schema``), so every default is written here once, and an unknown key or a value of
the wrong type fails at start-up naming the key. ``model`` defaults to the compact CPU SegNet
(``model=segnet_small``), ``optim`` to AdamW. What the options do and what they measured:
docs/train.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

from core.config import register_schema
from core.model_folder import MODELS_ROOT

#: ImageNet statistics, the usual normalization for a VGG encoder.
IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)


@dataclass
class ModelConfig:
    """The network (``model``, train/net/segnet.py). The defaults are the compact SegNet for CPU
    (``model=segnet_small``): the VGG16-BN layout at 3/8 width and four stages of two
    convolutions, run at a quarter of the input resolution (4x4 average in, bilinear logits
    out), with the encoder maps added after each unpooling. ``model=segnet`` is the paper's
    network, ``model=segnet_wide`` the compact one at half width; ``model=lraspp`` is LR-ASPP
    on a MobileNetV3-Small encoder (train/net/lraspp.py).

    Attributes:
        name: the preset's name (metrics.json, logs).
        arch: ``segnet`` or ``lraspp`` (train/net/build.py). LR-ASPP reads ``width`` (as
            MobileNetV3's width multiplier), ``downsample``, ``inter_channels``, ``mean``,
            ``std`` and ``num_classes``; the SegNet's other keys do not apply to it.
        vgg: ``torchvision.models.vgg.cfgs`` key: D = VGG16.
        width: channel multiplier of VGG's (0.375: channels [24, 48, 96, 192]).
        stages: encoder stages; the input H, W are padded (in the graph) to a multiple of
            ``downsample * 2**stages``.
        convs_per_stage: convolutions per stage, mirrored in the decoder; None = VGG's
            ([2, 2, 3, 3, 3] for D).
        min_channels: lower bound on a scaled channel count.
        downsample: the network runs at 1/downsample of the input resolution (the logits
            upsampled); 1, 2, 4, ...
        num_classes: None = the dataset's class count; a number is checked against it.
        mean, std: per-channel normalization of the [0, 1] input, inside the model.
        skip: ``add``: SegNet-EncoderAddition (encoder maps added after unpooling); ``none``:
            the plain SegNet.
        stem: how a downsampled network sees the image: ``average`` (each d x d block's mean
            colour) or ``unshuffle`` (every pixel of the block, as 3 d^2 channels).
        head: ``bilinear``: the logits upsampled; ``sharpen``: plus a learned full-resolution
            residual from the upsampled logits and the image, which sharpens the class
            boundaries (needs ``stem: unshuffle`` and ``loss.resolution: input``).
        head_channels: hidden channels of the sharpen head.
        head_layers: hidden layers of the sharpen head (1: two 3x3 convolutions).
        context_layers: dilated 3x3 convolutions added as a residual at the bottleneck
            (whole-image context; 0 = none; ``init_from`` can add them to a trained network).
        inter_channels: LR-ASPP's head: channels of its gated stride-16 branch.
    """

    name: str = "segnet_small"
    arch: str = "segnet"
    vgg: str = "D"
    width: float = 0.375
    stages: int = 4
    convs_per_stage: list[int] | None = field(default_factory=lambda: [2, 2, 2, 2])
    min_channels: int = 4
    downsample: int = 4
    num_classes: int | None = None
    mean: list[float] = field(default_factory=lambda: list(IMAGENET_MEAN))
    std: list[float] = field(default_factory=lambda: list(IMAGENET_STD))
    skip: str = "add"
    stem: str = "average"
    head: str = "bilinear"
    head_channels: int = 8
    head_layers: int = 1
    context_layers: int = 0
    inter_channels: int = 128


@dataclass
class OptimConfig:
    """The optimizer (``optim``, train/loop/optim.py), with a one-cycle schedule (warm-up, then
    cosine decay) stepped every batch. The defaults are AdamW (``optim=adamw``).

    Attributes:
        name: ``adamw`` or ``sgd`` (the paper's: SGD with Nesterov momentum).
        lr: the schedule's peak learning rate.
        weight_decay: weight decay.
        momentum: SGD's momentum (adamw does not use it).
        warmup: fraction of all steps spent warming up.
    """

    name: str = "adamw"
    lr: float = 3.0e-3
    weight_decay: float = 1.0e-4
    momentum: float = 0.9
    warmup: float = 0.1


@dataclass
class AugmentConfig:
    """Augmentation parameters (``data.augment``; ``train.data.augment_batch``).

    Attributes:
        crop: output (height, width) of a training sample; None keeps the image size.
        scale: range of the zoom factor (output pixels per image pixel; 1.0 = native
            resolution, 2.0 = magnified twice). The crop box (output size / zoom) is kept
            inside the image, so zooms below ``max(crop_h / H, crop_w / W)`` are raised to it.
        hflip: probability of a horizontal flip.
        brightness: additive brightness shift drawn from [-b, b].
        contrast: contrast factor drawn from [1 - c, 1 + c].
        saturation: saturation factor drawn from [1 - s, 1 + s].
        hue: hue shift drawn from [-h, h] (fraction of a full turn).
        blur_prob: probability of a Gaussian blur.
        blur_sigma: range of the blur sigma in pixels of the input image.
        noise_std: standard deviation of additive Gaussian noise per input-image pixel,
            drawn per image from [0, noise_std].

    Sizes are in input-image pixels; ``at_resolution`` converts them for training at the
    network's lower resolution.
    """

    crop: tuple[int, int] | None = None
    scale: tuple[float, float] = (1.0, 1.6)
    hflip: float = 0.5
    brightness: float = 0.2
    contrast: float = 0.3
    saturation: float = 0.3
    hue: float = 0.03
    blur_prob: float = 0.3
    blur_sigma: tuple[float, float] = (0.3, 1.5)
    noise_std: float = 0.03

    def __post_init__(self) -> None:  # OmegaConf hands the pairs over as lists
        if self.crop is not None:
            self.crop = (int(self.crop[0]), int(self.crop[1]))
        self.scale = (float(self.scale[0]), float(self.scale[1]))
        self.blur_sigma = (float(self.blur_sigma[0]), float(self.blur_sigma[1]))

    def at_resolution(self, factor: int) -> AugmentConfig:
        """The same augmentation for images box-averaged by ``factor``: crop and blur sigma
        shrink by ``factor``; noise std shrinks by ``factor`` too (averaging factor^2
        independent pixels), so the network sees the noise it would see at full size."""
        if factor == 1:
            return self
        f = float(factor)
        crop = None if self.crop is None else (int(self.crop[0] // f), int(self.crop[1] // f))
        return replace(
            self,
            crop=crop,
            blur_sigma=(self.blur_sigma[0] / f, self.blur_sigma[1] / f),
            noise_std=self.noise_std / f,
        )


@dataclass
class DataConfig:
    """The splits in memory and their augmentation (``data``).

    Attributes:
        limit: use only the first N frames of each split (None: all; for tests).
        realism: the camera the training and validation images pass through once, at load
            (``train.data.through_camera``): a conf/realism preset, ``ideal`` (the renders
            as they are) or ``real`` (its sensor noise, exposure changes and JPEG).
        augment: the training split's augmentation.
    """

    limit: int | None = None
    realism: str = "ideal"
    augment: AugmentConfig = field(default_factory=AugmentConfig)


@dataclass
class LossConfig:
    """The cross-entropy, ignoring label 255 (``loss``, train/losses.py).

    Attributes:
        class_weighting: ``median_frequency`` (SegNet's class balancing) or ``none``.
        max_weight: clip the class weights at this value (None: no clipping).
        power: w = (median_freq / freq) ** power; 1.0 is SegNet's balancing, 0.5 keeps more
            global accuracy.
        boundary_weight: loss factor on pixels next to a class change (1 = off).
        resolution: ``network``: block-majority labels at the logits' resolution; ``input``:
            the logits upsampled (bilinear, as at inference) against the full-resolution
            labels.
    """

    class_weighting: str = "median_frequency"
    max_weight: float | None = 10.0
    power: float = 0.5
    boundary_weight: float = 1.0
    resolution: str = "network"


@dataclass
class EvalConfig:
    """Validation after every epoch and the test of the exported graph (``eval``).

    Attributes:
        batch_size: images per forward pass.
        select: the validation score that picks checkpoint_best.pt (``pixel_accuracy``,
            ``class_accuracy``, ``mean_iou`` or ``boundary_f``: the boundary F-score at 2 px
            of the class boundaries, what the edge likelihood reads).
    """

    batch_size: int = 8
    select: str = "mean_iou"


@dataclass
class ExportConfig:
    """segnet.onnx and its int8 copy (``export``; train/deploy/export.py, train/deploy/quantize.py).

    Attributes:
        parity_images: test images checked with onnxruntime against torch.
        tolerance: the export fails above this max |onnx - torch| of the logits.
        batch_size: images per onnxruntime run of the check.
        opset: the ONNX opset.
        int8: also write segnet_int8.onnx (the convolutions in int8), scored against the
            float graph on the test split in quantize.json (docs/train.md, "int8").
        int8_calibration: training images whose activation ranges set its scales.
    """

    parity_images: int = 8
    tolerance: float = 1.0e-4
    batch_size: int = 4
    opset: int = 20
    int8: bool = True
    int8_calibration: int = 64


@dataclass
class KeepConfig:
    """Which network a fine-tune ships (``keep``, train/keep.py): the fine-tuned one, or the
    one it started from (``init_from``) where its own validation images show no gain.

    Both networks segment the validation split; the fine-tune ships when its boundary F at
    2 px (what the edge likelihood reads) or its mean IoU is higher by more than that score's
    margin and neither is lower by more. A margin is the larger of ``min_gain`` and ``sigmas``
    standard errors of the score's difference, from a paired bootstrap over the validation
    images (docs/recipes.md, "A fine-tune that never hurts").

    Attributes:
        init_unless_gain: apply the rule (needs ``init_from``); off, the fine-tune ships.
        min_gain: the smallest gain that counts, whatever the validation split's size.
        sigmas: standard errors of the paired difference a gain must exceed.
        resamples: bootstrap resamples of the validation images (seeded by ``seed``).
    """

    init_unless_gain: bool = False
    min_gain: float = 0.01
    sigmas: float = 2.0
    resamples: int = 1000


@dataclass
class TrainConfig:
    """``python -m train``: SegNet on a datagen dataset, on CPU or a GPU, written to
    ``<out_root>/<name>/`` (docs/train.md).

    Attributes:
        name: the output folder's name.
        dataset: a dataset made by ``python -m datagen`` (relative to the working dir), or
            a glob pattern of several (``outputs/datasets/generalist/floor*``, with one class
            list and image size) whose splits are trained on together.
        out_root: the folder of the model folders.
        seed: seeds the initial weights, the shuffling and the augmentation.
        device: where the network trains: ``auto`` (CUDA where torch sees a GPU, else the
            CPU), ``cpu`` or ``cuda``; under torchrun each process takes the GPU of its
            ``LOCAL_RANK`` and the processes meet over NCCL (gloo on the CPU). Validation runs
            there too; export and test run on the CPU (``train.loop.distributed.training_device``).
        precision: ``fp32``, ``bf16`` or ``auto`` (bf16 where the CPU has AMX tiles; fp32 on
            a GPU): bfloat16 autocast for the training forward pass.
        threads: torch intra-op threads (and onnxruntime's for the export's check); under
            torchrun per process (cores / processes).
        epochs: the one-cycle schedule's span, sized to end within ``max_minutes`` on 2
            cores.
        batch_size: training images per step; under torchrun the global batch, split
            evenly between the processes (a multiple of their number; docs/train.md).
        ema_decay: exponential moving average of the weights (and BatchNorm statistics),
            spanning ~1 / (1 - decay) steps: what is validated, kept and exported (0 = off,
            the raw weights).
        max_minutes: wall-time budget for training (over resumes; None: none). When used up,
            training stops and still evaluates and exports. After each epoch the schedule is
            re-spanned to the epochs that fit the budget left, at most ``epochs``.
        finish_by: Unix time (s) by which training must end, or None; the budget is the
            smaller of the two (``make demo`` sets it; Makefile).
        budget_clock: what ``max_minutes`` counts: ``wall`` (elapsed time) or ``cpu`` (the
            process's CPU time, all its threads: two networks given the same CPU minutes get
            the same compute whatever else the machine runs; with 2 threads a CPU minute is
            about half a wall minute). ``cpu`` takes no ``finish_by`` (a wall-clock time).
        init_from: a model folder (or its checkpoint_best.pt) whose weights start the
            training (fine-tuning, same ``model.*`` settings); None = random initial weights.
        keep: whether the fine-tune or ``init_from``'s network ships (``KeepConfig``).
        overwrite: discard an output folder made with another config.
        localize: localize settings this model is tuned for, nested as in
            conf/localize.yaml (e.g. ``{edges: {cnn: {snap_px: 1}}}``), checked by localize
            when applied: written to <model>/localize.yaml and the ONNX metadata, not in the
            config hash (docs/recipes.md).
        progress: tqdm progress bars.
    """

    name: str = "demo"
    dataset: str = "outputs/datasets/demo"
    out_root: str = str(MODELS_ROOT)
    seed: int = 0
    device: str = "auto"
    precision: str = "auto"
    threads: int = 2
    epochs: int = 21
    batch_size: int = 8
    ema_decay: float = 0.999
    max_minutes: float | None = 18.0
    finish_by: float | None = None
    budget_clock: str = "wall"
    init_from: str | None = None
    overwrite: bool = False
    localize: dict[str, Any] = field(default_factory=dict)
    progress: bool = True
    model: ModelConfig = field(default_factory=ModelConfig)
    optim: OptimConfig = field(default_factory=OptimConfig)
    data: DataConfig = field(default_factory=DataConfig)
    loss: LossConfig = field(default_factory=LossConfig)
    eval: EvalConfig = field(default_factory=EvalConfig)
    export: ExportConfig = field(default_factory=ExportConfig)
    keep: KeepConfig = field(default_factory=KeepConfig)


register_schema("train_schema", TrainConfig)
