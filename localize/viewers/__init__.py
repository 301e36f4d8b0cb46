"""Viewers: the model-edge overlay image and the rerun log."""
