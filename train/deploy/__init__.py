"""ONNX export, int8 quantization and prediction with the exported model."""
