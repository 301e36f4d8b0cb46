"""train: SegNet on CPU, metrics, ONNX export (see docs/train.md)."""
