"""LR-ASPP (Howard et al., "Searching for MobileNetV3", ICCV 2019) on a MobileNetV3-Small
encoder: a light encoder-decoder to compare with the SegNet at equal training time
(``model=lraspp``; docs/train.md, "LR-ASPP").

torchvision's pieces, trained from scratch (no weights are downloaded): the encoder is
``torchvision.models.mobilenet_v3_small(dilated=True).features`` (output stride 16, its last
stage dilated), the head ``torchvision.models.segmentation.lraspp.LRASPPHead``: the stride-16
features through a 1x1 convolution gated by their global average (squeeze-excite style),
upsampled to the stride-8 features and added to a 1x1 classifier of those. The logits are at
1/8 of the network's input; ``forward`` brings them to the input's resolution (bilinear), as
the SegNet does, so the exported graph gives ``(N, C, H, W)`` logits and ``(N, H, W)`` labels
like the SegNet's and the localizer reads them alike.

The interface the training loop and the export use is the SegNet's (train/net/segnet.py):
``forward``, ``forward_network_resolution``, ``to_input_resolution``, ``training_factor``,
``output_stride``, ``multiple``, ``mean``/``std`` buffers, ``describe``.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
import torch.nn.functional as F
from torch import nn
from torchvision.models import mobilenet_v3_small
from torchvision.models._utils import IntermediateLayerGetter
from torchvision.models.segmentation.lraspp import LRASPPHead

from train.config import IMAGENET_MEAN, IMAGENET_STD
from train.net.segnet import check_images, check_shape_options, init_weights, pad_to_multiple

#: Stride of the encoder's deepest features (MobileNetV3 with its last stage dilated).
ENCODER_STRIDE = 16
#: Stride of the head's logits (the stride-8 features it classifies).
HEAD_STRIDE = 8


def mobilenet_v3_small_encoder(width: float) -> tuple[IntermediateLayerGetter, int, int]:
    """MobileNetV3-Small's features (random weights) returning ``low`` (stride 8) and ``high``
    (stride 16) maps, as torchvision's ``lraspp_mobilenet_v3_large`` picks them for Large.

    Args:
        width: MobileNetV3's width multiplier (1.0: 16-576 channels).

    Returns:
        The encoder and the channels of its low and high maps.
    """
    features = mobilenet_v3_small(weights=None, dilated=True, width_mult=float(width),
                                  norm_layer=nn.BatchNorm2d).features
    # The strided blocks (torchvision's ``_is_cn``) bound the stages; C2 has stride 8.
    stage = [0] + [i for i, b in enumerate(features) if getattr(b, "_is_cn", False)]
    low, high = stage[-3], len(features) - 1
    channels = (features[low].out_channels, features[high].out_channels)
    return IntermediateLayerGetter(features, {str(low): "low", str(high): "high"}), *channels


class LRASPPNet(nn.Module):
    """LR-ASPP with a MobileNetV3-Small encoder, taking [0, 1] images like the SegNet.

    Args:
        num_classes: number of output classes C.
        width: MobileNetV3's width multiplier.
        downsample: the network runs at 1/downsample of the input resolution (each d x d
            block's mean colour in; the logits upsampled); 1, 2, 4, ...
        inter_channels: channels of the head's gated stride-16 branch (torchvision: 128).
        mean, std: per-channel normalization applied to the [0, 1] input inside the model.
        auto_pad: pad inputs whose size is not a multiple of ``multiple`` (reflect,
            bottom/right) and crop the logits back; if False such inputs raise ValueError.
        generator: draws the initial weights (He-normal convolutions); None = global RNG.

    Shapes:
        input (B, 3, H, W) float32 in [0, 1]; output (B, C, H, W) logits.
    """

    #: The SegNet attributes the training loop reads; LR-ASPP has none of these parts.
    sharpen_head = None
    context = None
    convs_per_stage = None

    def __init__(
        self,
        num_classes: int,
        width: float = 1.0,
        downsample: int = 1,
        inter_channels: int = 128,
        mean: Sequence[float] = IMAGENET_MEAN,
        std: Sequence[float] = IMAGENET_STD,
        auto_pad: bool = True,
        generator: torch.Generator | None = None,
    ) -> None:
        super().__init__()
        downsample = int(downsample)
        check_shape_options(num_classes, width, downsample)
        if int(inter_channels) < 1:
            raise ValueError(f"model.inter_channels must be >= 1, got {inter_channels}")
        self.num_classes = int(num_classes)
        self.width = float(width)
        self.downsample = downsample
        self.inter_channels = int(inter_channels)
        self.multiple = downsample * ENCODER_STRIDE
        self.auto_pad = bool(auto_pad)
        self.register_buffer("mean", torch.tensor(mean, dtype=torch.float32).view(1, 3, 1, 1))
        self.register_buffer("std", torch.tensor(std, dtype=torch.float32).view(1, 3, 1, 1))
        self.encoder, low, high = mobilenet_v3_small_encoder(width)
        self.head = LRASPPHead(low, high, self.num_classes, self.inter_channels)
        self.channels = [low, high, self.inter_channels]
        init_weights(self, generator)

    @property
    def training_factor(self) -> int:
        """How much smaller than the input the training images are (box-averaged once)."""
        return self.downsample

    @property
    def output_stride(self) -> int:
        """Input pixels per logit of ``forward_network_resolution`` (8 x ``downsample``)."""
        return HEAD_STRIDE * self.downsample

    def check_input(self, x: torch.Tensor) -> None:
        """Raise ValueError unless x is (B, 3, H, W) floating point with a usable size."""
        check_images(x, "LR-ASPP")
        h, w = x.shape[-2], x.shape[-1]
        if not self.auto_pad and (h % self.multiple or w % self.multiple):
            raise ValueError(f"LR-ASPP needs H and W divisible by {self.multiple}, got {h}x{w}; "
                             "build it with auto_pad=True or pad the images")

    def _network(self, x: torch.Tensor) -> torch.Tensor:
        """Normalized (B, 3, h, w), h and w multiples of 16 -> (B, C, h / 8, w / 8) logits."""
        return self.head(self.encoder(x))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Logits for a batch of images.

        Args:
            x: (B, 3, H, W) float32 RGB in [0, 1].

        Returns:
            (B, C, H, W) float32 class logits.
        """
        self.check_input(x)
        image, (h, w) = pad_to_multiple(x, self.multiple)
        z = image if self.downsample == 1 else F.avg_pool2d(image, self.downsample)
        logits = self._network((z - self.mean) / self.std)
        return self.to_input_resolution(logits, image)[..., :h, :w]

    def to_input_resolution(self, logits: torch.Tensor, image: torch.Tensor) -> torch.Tensor:
        """(B, C, h, w) logits -> (B, C, H, W) at ``image``'s size (bilinear)."""
        return F.interpolate(logits, size=image.shape[-2:], mode="bilinear", align_corners=False)

    def forward_network_resolution(self, x: torch.Tensor) -> torch.Tensor:
        """The head's logits before their upsampling; training takes the loss there (against
        labels reduced by ``output_stride / training_factor``) or upsampled (``loss.resolution:
        input``).

        Args:
            x: (B, 3, H / d, W / d) float32 RGB in [0, 1], box-averaged by d = ``downsample``.

        Returns:
            (B, C, ceil(H / 8d), ceil(W / 8d)) float32 class logits.
        """
        if x.ndim != 4 or x.shape[1] != 3 or not x.is_floating_point():
            raise ValueError(f"expected (B, 3, h, w) float images, got {tuple(x.shape)} {x.dtype}")
        x, (h, w) = pad_to_multiple(x, ENCODER_STRIDE)
        logits = self._network((x - self.mean) / self.std)
        return logits[..., : -(-h // HEAD_STRIDE), : -(-w // HEAD_STRIDE)]

    def describe(self) -> dict:
        """The ``model`` entry of the ONNX metadata."""
        return {
            "architecture": "LR-ASPP (MobileNetV3-Small encoder, dilated; bilinear logits)",
            "width": self.width,
            "channels": self.channels,  # low (stride 8), high (stride 16), head's gated branch
            "num_classes": self.num_classes,
            "downsample": self.downsample,
            "output_stride": self.output_stride,
        }

    def extra_repr(self) -> str:
        return (f"num_classes={self.num_classes}, width={self.width}, "
                f"downsample={self.downsample}, channels={self.channels}")
