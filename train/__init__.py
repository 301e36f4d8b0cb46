"""train: SegNet on CPU, metrics, ONNX export (see docs/train.md)."""

from train import config as _config  # noqa: F401  (registers the schema)
