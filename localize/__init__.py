"""localize: the edge particle filter (python -m localize)."""

from localize import config as _config  # noqa: F401  (registers the schema)
