"""SegNet (Badrinarayanan et al., PAMI 2017): VGG16-BN encoder, decoder unpooling with indices.

The encoder is torchvision's VGG16-BN layer configuration (``cfgs["D"]``: 13 convolutions in 5
stages, each stage ending in a 2x2 max-pool). The decoder mirrors it: every stage starts with a
``MaxUnpool2d`` that puts values back at the positions the encoder's pool picked, followed by
convolutions; a 3x3 convolution gives per-pixel class logits.

A width multiplier scales every channel count and ``stages`` / ``convs_per_stage`` shorten the
network, which gives the compact CPU model (``conf/model/segnet_small.yaml``).

The model takes images in [0, 1] and normalizes them itself (mean/std are buffers), so the
exported ONNX graph takes [0, 1] input too. Spatial size must be divisible by
``2 ** stages`` (32 for the full model); with ``auto_pad=True`` (the default) other sizes are
reflect-padded bottom/right to the next multiple inside the forward pass and the logits are
cropped back, so callers always get logits at the input resolution.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict

import torch
import torch.nn.functional as F
from torch import nn
from torchvision.models.vgg import cfgs

from train.config import IMAGENET_MEAN, IMAGENET_STD, ModelConfig
from train.net.window_pool import (
    WindowMaxPool,
    WindowMaxUnpool,
    code_to_plane_index,
    plane_index_to_code,
)


def vgg_stages(cfg: str = "D") -> list[list[int]]:
    """Channel counts per stage of a torchvision VGG configuration.

    Args:
        cfg: key of ``torchvision.models.vgg.cfgs`` ("A" VGG11, "B" VGG13, "D" VGG16, "E" VGG19).

    Returns:
        One list of output channels per conv for each stage, e.g. VGG16:
        ``[[64, 64], [128, 128], [256, 256, 256], [512, 512, 512], [512, 512, 512]]``.
    """
    if cfg not in cfgs:
        raise ValueError(
            f"model.vgg={cfg!r} is not a torchvision VGG config; use one of {list(cfgs)}"
        )
    stages: list[list[int]] = [[]]
    for v in cfgs[cfg]:
        if v == "M":
            stages.append([])
        else:
            stages[-1].append(int(v))
    return [s for s in stages if s]


def init_weights(module: nn.Module, generator: torch.Generator | None) -> None:
    """He-normal convolutions drawn from ``generator`` (in ``module.modules()`` order), zero
    biases, unit BatchNorm: every layer of ``module``."""
    for m in module.modules():
        if isinstance(m, nn.Conv2d):
            nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="relu",
                                    generator=generator)
            if m.bias is not None:
                nn.init.zeros_(m.bias)
        elif isinstance(m, nn.BatchNorm2d):
            nn.init.ones_(m.weight)
            nn.init.zeros_(m.bias)


def check_images(x: torch.Tensor, name: str) -> None:
    """Raise ValueError, naming the network ``name``, unless x is a (B, 3, H, W) floating
    point batch."""
    if x.ndim != 4 or x.shape[1] != 3:
        raise ValueError(f"{name} expects (B, 3, H, W) images, got shape {tuple(x.shape)}")
    if not x.is_floating_point():
        raise ValueError(f"{name} expects float images in [0, 1], got dtype {x.dtype}")


def pad_to_multiple(x: torch.Tensor, multiple: int) -> tuple[torch.Tensor, tuple[int, int]]:
    """Reflect-pad an image batch bottom/right so H and W are multiples of ``multiple``.

    Args:
        x: (B, C, H, W) float tensor.
        multiple: required divisor of the padded size, e.g. 32.

    Returns:
        The padded (B, C, H', W') tensor and the original (H, W).
    """
    h, w = x.shape[-2], x.shape[-1]
    ph, pw = (-h) % multiple, (-w) % multiple
    if ph or pw:
        mode = "reflect" if ph < h and pw < w else "replicate"
        x = F.pad(x, (0, pw, 0, ph), mode=mode)
    return x, (h, w)


def _conv_bn_relu(cin: int, cout: int, dilation: int = 1) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(cin, cout, 3, padding=dilation, dilation=dilation, bias=False),
        nn.BatchNorm2d(cout),
        nn.ReLU(inplace=True),
    )


#: Dilation of the ``context_layers`` convolutions: at the bottleneck of the compact model
#: (10 x 8 cells for a 320 x 240 image at half resolution) three of them see the whole map.
CONTEXT_DILATION = 2


def context_block(channels: int, layers: int) -> nn.Sequential:
    """Residual branch at the bottleneck: ``layers`` dilated 3x3 convolutions, the last one
    with BatchNorm and no ReLU, its BatchNorm scale set to zero by the caller so the branch
    starts as nothing (a trained network gains it without changing its function).

    Shapes: (B, channels, h, w) -> (B, channels, h, w).
    """
    body = [_conv_bn_relu(channels, channels, CONTEXT_DILATION) for _ in range(layers)]
    conv, bn, _relu = body[-1]
    return nn.Sequential(*body[:-1], conv, bn)


def sharpen_block(num_classes: int, channels: int, layers: int) -> nn.Sequential:
    """The sharpen head's convolutions: (B, C + 3, H, W) upsampled logits and normalized image
    -> (B, C, H, W) residual logits; ``layers`` hidden 3x3 convolutions of ``channels``, then
    one to the classes."""
    convs = [nn.Conv2d(num_classes + 3, channels, 3, padding=1), nn.ReLU(inplace=True)]
    for _ in range(layers - 1):
        convs += [nn.Conv2d(channels, channels, 3, padding=1), nn.ReLU(inplace=True)]
    return nn.Sequential(*convs, nn.Conv2d(channels, num_classes, 3, padding=1))


def stage_layout(vgg: str, stages: int, width: float, min_channels: int,
                 convs_per_stage: Sequence[int] | None) -> tuple[list[int], list[int]]:
    """Channels and convolutions of each encoder stage: the first ``stages`` stages of VGG
    configuration ``vgg``, channels scaled by ``width`` (at least ``min_channels``), and
    ``convs_per_stage`` convolutions (None: VGG's counts)."""
    base = vgg_stages(vgg)
    if not 1 <= stages <= len(base):
        raise ValueError(f"model.stages must be in 1..{len(base)}, got {stages}")
    base = base[:stages]
    if convs_per_stage is None:
        convs_per_stage = [len(s) for s in base]
    convs = [int(n) for n in convs_per_stage]
    if len(convs) != stages or min(convs) < 1:
        raise ValueError(
            f"model.convs_per_stage={convs} must have {stages} entries >= 1 (one per stage)"
        )
    return [max(min_channels, round(s[0] * width)) for s in base], convs


def encoder_stages(chans: Sequence[int], convs: Sequence[int], cin: int) -> nn.ModuleList:
    """The encoder: stage k has ``convs[k]`` conv-BN-ReLU layers to ``chans[k]`` channels, the
    first from the previous stage's (``cin`` input channels for the first stage)."""
    stages = nn.ModuleList()
    for c, n in zip(chans, convs, strict=True):
        stages.append(nn.Sequential(*[_conv_bn_relu(cin if i == 0 else c, c) for i in range(n)]))
        cin = c
    return stages


def decoder_stages(chans: Sequence[int], convs: Sequence[int]) -> nn.ModuleList:
    """The decoder, deepest stage first: stage k mirrors encoder stage k with n convs, the last
    one mapping c_k -> c_{k-1}; the first stage's keeps c_1 (one conv fewer, at least one)
    and is followed by the classifier."""
    stages = nn.ModuleList()
    for k in range(len(chans) - 1, -1, -1):
        c, n = chans[k], convs[k]
        cout = chans[k - 1] if k > 0 else c
        n_dec = n if k > 0 else max(n - 1, 1)
        layers = [_conv_bn_relu(c, c) for _ in range(n_dec - 1)]
        layers.append(_conv_bn_relu(c, cout))
        stages.append(nn.Sequential(*layers))
    return stages


def check_shape_options(num_classes: int, width: float, downsample: int) -> None:
    """Raise ValueError naming the ``model.*`` key of an option every network has (the class
    count, the width multiplier, the input downsampling) out of range."""
    if num_classes < 2:
        raise ValueError(f"num_classes must be >= 2, got {num_classes}")
    if width <= 0:
        raise ValueError(f"model.width must be positive, got {width}")
    if downsample < 1 or downsample & (downsample - 1):
        raise ValueError(f"model.downsample must be 1, 2, 4, ..., got {downsample}")


def _check_options(num_classes: int, width: float, downsample: int, skip: str, stem: str,
                   head: str, head_channels: int, head_layers: int, context_layers: int) -> None:
    """Raise ValueError naming the ``model.*`` key of a SegNet option out of range."""
    check_shape_options(num_classes, width, downsample)
    if skip not in ("none", "add"):
        raise ValueError(f"model.skip must be 'none' or 'add', got {skip!r}")
    if stem not in ("average", "unshuffle"):
        raise ValueError(f"model.stem must be 'average' or 'unshuffle', got {stem!r}")
    if head not in ("bilinear", "sharpen"):
        raise ValueError(f"model.head must be 'bilinear' or 'sharpen', got {head!r}")
    if head == "sharpen" and downsample > 1 and stem != "unshuffle":
        raise ValueError(
            "model.head=sharpen needs model.stem=unshuffle: the head works on the "
            "full-resolution image, which the average stem's training never sees"
        )
    if int(head_channels) < 1:
        raise ValueError(f"model.head_channels must be >= 1, got {head_channels}")
    if int(head_layers) < 1:
        raise ValueError(f"model.head_layers must be >= 1, got {head_layers}")
    if int(context_layers) < 0:
        raise ValueError(f"model.context_layers must be >= 0, got {context_layers}")


class SegNet(nn.Module):
    """SegNet encoder-decoder with pooling-index upsampling.

    The argument defaults are the paper's SegNet (``model=segnet``); ``python -m train``
    passes every ``model.*`` setting (``train.config.ModelConfig``, ``build_segnet``).

    Args:
        num_classes: number of output classes C.
        width: channel multiplier applied to the VGG widths (1.0 = the paper's SegNet).
        stages: number of encoder stages used (1..5); the input size must be divisible by
            ``2 ** stages``.
        convs_per_stage: convolutions in each stage (mirrored in the decoder); ``None`` keeps
            the VGG counts (2, 2, 3, 3, 3). Values above the VGG count are allowed.
        vgg: torchvision VGG configuration key ("D" = VGG16).
        min_channels: lower bound on any scaled channel count.
        mean, std: per-channel normalization applied to the [0, 1] input inside the model.
        auto_pad: pad inputs whose size is not a multiple of ``2 ** stages`` (reflect,
            bottom/right) and crop the logits back; if False such inputs raise ValueError.
        pooling: "indices" (``nn.MaxPool2d`` / ``nn.MaxUnpool2d``, fastest in torch) or
            "window" (``WindowMaxPool`` / ``WindowMaxUnpool``, the same function, fastest in
            onnxruntime); switch with ``set_pooling`` (no weights involved).
        skip: "none" (SegNet: the decoder sees only the unpooled maps) or "add" (the paper's
            SegNet-EncoderAddition variant, Badrinarayanan et al. 2017 Table 1: the encoder's
            feature map of the same stage, before pooling, is added to the unpooled map; it
            learns several times faster and keeps boundaries sharper).
        downsample: the network runs at 1/downsample of the input resolution (bilinear
            upsampling of the logits last); 2 makes training and inference about 4x cheaper,
            which on a CPU buys many more training steps.
        stem: how a downsampled network sees the image: "average" (each d x d block's mean
            colour: 3 channels) or "unshuffle" (every pixel of the block, as 3 d^2 channels:
            ``F.pixel_unshuffle``; the first convolution sees the full-resolution image, e.g.
            where in its block a thin frame or an edge lies, for ~1.2x the compute).
        head: how a downsampled network's logits reach the input resolution: "bilinear"
            (upsampled, nothing learned) or "sharpen" (upsampled, then a learned residual from
            two 3x3 convolutions at full resolution on the upsampled logits and the image:
            the network learns where, between the image's pixels, a class boundary lies, e.g.
            a window's outline on its frame's outer edge; trained with ``loss.resolution:
            input``).
        head_channels: hidden channels of the "sharpen" head.
        head_layers: hidden layers of the "sharpen" head (1: two 3x3 convolutions, a 5x5 view;
            each more adds a 3x3 convolution and 2 pixels of reach).
        context_layers: dilated 3x3 convolutions (``CONTEXT_DILATION``) on the deepest pooled
            map, added to it as a residual between the encoder and the decoder: context from
            the whole image (a door reaches the floor, a poster does not) for a few percent
            of the compute. 0 = none (the plain SegNet). The branch starts at zero, so
            ``init_from`` a network without it starts as that network (docs/train.md).
        generator: draws the initial weights (He-normal convolutions); None = global RNG.

    Shapes:
        input (B, 3, H, W) float32 in [0, 1]; output (B, C, H, W) logits.
    """

    def __init__(
        self,
        num_classes: int,
        width: float = 1.0,
        stages: int = 5,
        convs_per_stage: Sequence[int] | None = None,
        vgg: str = "D",
        min_channels: int = 4,
        mean: Sequence[float] = IMAGENET_MEAN,
        std: Sequence[float] = IMAGENET_STD,
        auto_pad: bool = True,
        pooling: str = "indices",
        downsample: int = 1,
        skip: str = "none",
        stem: str = "average",
        head: str = "bilinear",
        head_channels: int = 8,
        head_layers: int = 1,
        context_layers: int = 0,
        generator: torch.Generator | None = None,
    ) -> None:
        super().__init__()
        downsample = int(downsample)
        chans, convs_per_stage = stage_layout(vgg, stages, width, min_channels, convs_per_stage)
        _check_options(num_classes, width, downsample, skip, stem, head, head_channels,
                       head_layers, context_layers)
        self.num_classes = int(num_classes)
        self.stages = int(stages)
        self.downsample = downsample
        self.skip = skip
        self.stem = stem if downsample > 1 else "average"  # at full resolution both are the same
        self.multiple = downsample * 2**self.stages
        self.auto_pad = bool(auto_pad)
        self.channels = chans
        self.convs_per_stage = convs_per_stage
        self.register_buffer("mean", torch.tensor(mean, dtype=torch.float32).view(1, 3, 1, 1))
        self.register_buffer("std", torch.tensor(std, dtype=torch.float32).view(1, 3, 1, 1))
        self.encoder = encoder_stages(chans, convs_per_stage,
                                      3 * downsample**2 if self.stem == "unshuffle" else 3)
        self.set_pooling(pooling)
        self.decoder = decoder_stages(chans, convs_per_stage)
        self.classifier = nn.Conv2d(chans[0], num_classes, 3, padding=1)
        self.head = head
        self.head_channels = int(head_channels)
        self.head_layers = int(head_layers)
        self.sharpen_head: nn.Module | None = None
        if head == "sharpen":
            self.sharpen_head = sharpen_block(num_classes, self.head_channels, self.head_layers)
        self.context_layers = int(context_layers)
        self.context: nn.Module | None = None
        if self.context_layers:
            self.context = context_block(chans[-1], self.context_layers)
        self._init_weights(generator)

    def set_pooling(self, pooling: str) -> SegNet:
        """Use "indices" (nn.MaxPool2d/MaxUnpool2d) or "window" pooling; returns self."""
        if pooling == "indices":
            self.pool: nn.Module = nn.MaxPool2d(2, 2, return_indices=True)
            self.unpool: nn.Module = nn.MaxUnpool2d(2, 2)
        elif pooling == "window":
            self.pool, self.unpool = WindowMaxPool(), WindowMaxUnpool()
        else:
            raise ValueError(f"pooling={pooling!r}: use 'indices' or 'window'")
        self.pooling = pooling
        return self

    def _init_weights(self, generator: torch.Generator | None) -> None:
        """He-normal convolutions drawn from ``generator``, zero biases, unit BatchNorm; the
        context branch and the sharpen head start at zero."""
        init_weights(self, generator)
        if self.context is not None:  # the residual branch starts as nothing
            nn.init.zeros_(self.context[-1].weight)
        if self.sharpen_head is not None:  # the head starts as the identity: plain bilinear logits
            nn.init.zeros_(self.sharpen_head[-1].weight)
            nn.init.zeros_(self.sharpen_head[-1].bias)

    def check_input(self, x: torch.Tensor) -> None:
        """Raise ValueError unless x is (B, 3, H, W) floating point with a usable size."""
        check_images(x, "SegNet")
        h, w = x.shape[-2], x.shape[-1]
        if not self.auto_pad and (h % self.multiple or w % self.multiple):
            raise ValueError(
                f"SegNet with {self.stages} stages needs H and W divisible by {self.multiple}, "
                f"got {h}x{w}. Pad bottom/right with train.net.segnet.pad_to_multiple(x, "
                f"{self.multiple}) and crop the logits back, resize the image, or build the "
                f"model with auto_pad=True."
            )

    def preprocess(self, x: torch.Tensor) -> tuple[torch.Tensor, tuple[int, int]]:
        """Check, pad to ``multiple``, downsample and normalize a batch.

        Args:
            x: (B, 3, H, W) float32 RGB in [0, 1].

        Returns:
            The network input (B, 3 or 3 d^2, H' / d, W' / d) for downsample d (``stem``) and
            the original (H, W).
        """
        self.check_input(x)
        x, size = pad_to_multiple(x, self.multiple)
        return self._stem(x), size

    def _stem(self, x: torch.Tensor) -> torch.Tensor:
        """Padded (B, 3, H, W) [0, 1] images -> normalized network input at 1/downsample."""
        if self.stem == "unshuffle":
            return F.pixel_unshuffle((x - self.mean) / self.std, self.downsample)
        if self.downsample > 1:
            x = F.avg_pool2d(x, self.downsample)
        return (x - self.mean) / self.std

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Logits for a batch of images.

        Args:
            x: (B, 3, H, W) float32 RGB in [0, 1].

        Returns:
            (B, C, H, W) float32 class logits.
        """
        return self.forward_with_indices(x)[0]

    def forward_with_indices(
        self, x: torch.Tensor, indices: Sequence[torch.Tensor] | None = None
    ) -> tuple[torch.Tensor, list[torch.Tensor]]:
        """Logits and the encoder's max-pooling indices, optionally imposing given indices.

        Imposing indices lets an export check compare torch and onnxruntime with the same
        pooling choices: where two values in a 2x2 window differ by float rounding only, the
        two runtimes may pick different maxima, which moves a value in the decoder by one pixel.

        Args:
            x: (B, 3, H, W) float32 RGB in [0, 1].
            indices: one (B, C_k, H_k, W_k) int64 tensor per stage, as returned here (indices
                into each H*W plane before pooling, as ``nn.MaxPool2d`` gives them); None
                computes them.

        Returns:
            (B, C, H, W) logits and the list of per-stage indices.
        """
        self.check_input(x)
        image, (h, w) = pad_to_multiple(x, self.multiple)
        x, pooled_idx = self._network(self._stem(image), indices)
        return self.to_input_resolution(x, image)[..., :h, :w], pooled_idx

    def to_input_resolution(self, logits: torch.Tensor, image: torch.Tensor) -> torch.Tensor:
        """The network's logits brought to the image's resolution (``head``).

        Args:
            logits: (B, C, H / d, W / d) logits at the network's resolution.
            image: (B, 3, H, W) float32 RGB in [0, 1] that the logits are for (used by the
                "sharpen" head only).

        Returns:
            (B, C, H, W) logits: bilinear, plus the sharpen head's residual.
        """
        if self.downsample > 1:
            logits = F.interpolate(logits, size=image.shape[-2:], mode="bilinear",
                                   align_corners=False)
        if self.sharpen_head is None:
            return logits
        return logits + self.sharpen_head(torch.cat([logits, (image - self.mean) / self.std], 1))

    @property
    def output_stride(self) -> int:
        """Input pixels per logit of ``forward_network_resolution`` (``downsample``)."""
        return self.downsample

    def describe(self) -> dict:
        """The ``model`` entry of the ONNX metadata."""
        return {
            "architecture": "SegNet (VGG16-BN encoder, max-unpooling decoder)",
            "stages": self.stages,
            "channels": self.channels,
            "convs_per_stage": self.convs_per_stage,
            "num_classes": self.num_classes,
            "pooling": "window",  # the exported graph's (train.deploy.export.GRAPH_POOLING)
            "downsample": self.downsample,
            "skip": self.skip,  # add: SegNet-EncoderAddition
        }

    @property
    def training_factor(self) -> int:
        """How much smaller than the input the training images are: d with the ``average``
        stem (box-averaged once, before augmentation), 1 with ``unshuffle`` (the stem needs
        every pixel). See ``forward_network_resolution``."""
        return self.downsample if self.stem == "average" else 1

    def forward_network_resolution(self, x: torch.Tensor) -> torch.Tensor:
        """Logits at the network's own resolution, what ``forward`` computes before its
        bilinear upsampling. Training takes the loss there.

        With the ``average`` stem and ``downsample`` d the input is an image box-averaged over
        d x d blocks once (``train.data.downsample_split``), so augmentation costs 1/d^2 as
        much; with ``unshuffle`` it is the full-resolution image (``training_factor``).

        Args:
            x: (B, 3, H / f, W / f) float32 RGB in [0, 1], f = ``training_factor``.

        Returns:
            (B, C, H / d, W / d) float32 class logits.
        """
        if x.ndim != 4 or x.shape[1] != 3 or not x.is_floating_point():
            raise ValueError(f"expected (B, 3, h, w) float images, got {tuple(x.shape)} {x.dtype}")
        if self.stem == "unshuffle":
            x, (h, w) = pad_to_multiple(x, self.multiple)
            logits, _ = self._network(self._stem(x))
            d = self.downsample
            return logits[..., : -(-h // d), : -(-w // d)]
        x, (h, w) = pad_to_multiple(x, 2**self.stages)
        logits, _ = self._network((x - self.mean) / self.std)
        return logits[..., :h, :w]

    def _network(
        self, x: torch.Tensor, indices: Sequence[torch.Tensor] | None = None
    ) -> tuple[torch.Tensor, list[torch.Tensor]]:
        """Encoder, decoder and classifier on a normalized, padded (B, 3, h, w) input."""
        window = self.pooling == "window"
        pooled_idx: list[torch.Tensor] = []  # what self.unpool takes (indices or codes)
        features: list[torch.Tensor] = []  # encoder maps before pooling
        for k, stage in enumerate(self.encoder):
            x = stage(x)
            features.append(x)
            if indices is None:
                x, idx = self.pool(x)
            else:
                flat = indices[k]
                x = x.flatten(2).gather(2, flat.flatten(2)).view(flat.shape)
                idx = plane_index_to_code(flat) if window else flat
            pooled_idx.append(idx)
        if self.context is not None:
            x = x + self.context(x)
        for stage, idx, feat in zip(
            self.decoder, reversed(pooled_idx), reversed(features), strict=True
        ):
            x = self.unpool(x, idx, output_size=feat.shape[-2:])
            if self.skip == "add":
                x = x + feat
            x = stage(x)
        x = self.classifier(x)
        if window:
            pooled_idx = [code_to_plane_index(c) for c in pooled_idx]
        return x, pooled_idx

    def extra_repr(self) -> str:
        return (
            f"num_classes={self.num_classes}, stages={self.stages}, channels={self.channels}, "
            f"convs_per_stage={self.convs_per_stage}, auto_pad={self.auto_pad}, "
            f"pooling={self.pooling}, downsample={self.downsample}, skip={self.skip}, "
            f"stem={self.stem}, head={self.head}, context_layers={self.context_layers}"
        )


def build_segnet(
    model_cfg: ModelConfig | Mapping, num_classes: int, generator: torch.Generator | None = None
) -> SegNet:
    """Build a SegNet from the ``model`` config (``train.config.ModelConfig``).

    Args:
        model_cfg: the settings, or a mapping of some of them (the others: SegNet's defaults).
        num_classes: number of classes of the dataset.
        generator: draws the initial weights.
    """
    return SegNet(num_classes=num_classes, generator=generator, **model_kwargs(model_cfg))


#: The ``model`` settings that are SegNet constructor arguments (all but name, num_classes).
MODEL_KWARGS = ("width", "stages", "convs_per_stage", "vgg", "min_channels", "mean", "std",
                "downsample", "skip", "stem", "head", "head_channels", "head_layers",
                "context_layers")


def model_kwargs(model_cfg: ModelConfig | Mapping) -> dict:
    """The SegNet constructor arguments held in a ``model`` config or a mapping of some of
    its keys (the checkpoints' ``model_kwargs``); None values are left out."""
    cfg = asdict(model_cfg) if isinstance(model_cfg, ModelConfig) else model_cfg
    out = {k: cfg[k] for k in MODEL_KWARGS if k in cfg and cfg[k] is not None}
    for k in ("convs_per_stage", "mean", "std"):
        if k in out:
            out[k] = list(out[k])
    return out


#: The state-dict key of the first convolution: the stem's, which ``downsample`` shapes.
STEM_CONV_KEY = "encoder.0.0.0.weight"


def finer_unshuffle_stem(weight: torch.Tensor, d_from: int, d_to: int) -> torch.Tensor:
    """The first convolution of an ``unshuffle`` stem carried to a finer block size.

    The stem feeds the network every pixel of each d x d block as 3 d^2 channels (channel
    c d^2 + i d + j: colour c, row i, column j). A network trained with blocks of ``d_from``
    pixels becomes one with blocks of ``d_to`` (a divisor: the network at ``d_from / d_to``
    times its resolution) by giving each new pixel the summed weights of the
    (d_from / d_to)^2 old pixels whose place it takes. Exactly: the new network on an image
    computes what the old one computed on that image enlarged d_from / d_to times (nearest),
    so it starts as the old network seeing everything that much closer.

    Args:
        weight: (O, 3 d_from^2, kh, kw) the old stem convolution's weights.
        d_from, d_to: the old and the new ``downsample``.

    Returns:
        (O, 3 d_to^2, kh, kw) weights.
    """
    o, cin, kh, kw = weight.shape
    if d_to < 1 or d_from % d_to or cin != 3 * d_from**2:
        raise ValueError(
            f"cannot carry a stem of {cin} channels from downsample {d_from} to {d_to}: "
            "the new downsample must divide the old, the weights be (O, 3 d^2, kh, kw)")
    r = d_from // d_to
    w = weight.reshape(o, 3, d_to, r, d_to, r, kh, kw)  # row i = i' r + di, column j = j' r + dj
    return w.sum(dim=(3, 5)).reshape(o, 3 * d_to**2, kh, kw)


def count_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())
