"""A model folder, what ``python -m train`` writes and localize reads: where model folders go
(``MODELS_ROOT``) and the localize settings a model carries.

Layout of ``<MODELS_ROOT>/<name>/``: ``segnet.onnx`` (and its int8 copy), ``localize.yaml``
(the localize settings the model is tuned for), ``metrics.json``, checkpoints (docs/train.md).
"""

from __future__ import annotations

from pathlib import Path

from core.segmenter import read_metadata

#: Where ``python -m train`` writes its model folders (``TrainConfig.out_root``'s default) and
#: where localize's ``onnx_model=auto`` looks for a dataset's own SegNet.
MODELS_ROOT = Path("outputs/models")
#: The model folder's file of the localize settings its model is tuned for (beside segnet.onnx).
LOCALIZE_SETTINGS_NAME = "localize.yaml"
#: The metadata key of the same settings in the ONNX file (a JSON object).
LOCALIZE_METADATA_KEY = "localize"


def model_localize_settings(onnx_path: str | Path) -> tuple[dict, str | None]:
    """The localize settings a model carries (``python -m train``'s ``localize`` key).

    From the model folder's ``localize.yaml`` beside the file (shared by segnet.onnx and its
    int8 copy), else from the file's metadata key ``localize``.

    Args:
        onnx_path: a segnet.onnx (or its int8 copy).

    Returns:
        The settings, nested as in conf/localize.yaml ({} when the model carries none, or the
        file does not exist), and where they were read (None when nowhere).
    """
    import yaml

    onnx_path = Path(onnx_path)
    folder_file = onnx_path.parent / LOCALIZE_SETTINGS_NAME
    if folder_file.is_file():
        settings = yaml.safe_load(folder_file.read_text()) or {}
        source = str(folder_file)
    elif onnx_path.is_file():
        settings = read_metadata(onnx_path).get(LOCALIZE_METADATA_KEY) or {}
        source = f"{onnx_path} (metadata key {LOCALIZE_METADATA_KEY!r})"
    else:
        return {}, None
    if not isinstance(settings, dict):
        raise ValueError(f"{source}: the localize settings must be a mapping of "
                         f"conf/localize.yaml keys, got {settings!r}; re-train or fix the file")
    return settings, source
