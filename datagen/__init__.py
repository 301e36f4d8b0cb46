"""datagen: labeled corridor renders and evaluation flights with Mitsuba 3."""

from datagen import config as _config  # noqa: F401  (registers the schema)
