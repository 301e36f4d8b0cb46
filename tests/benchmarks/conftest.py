"""The localize tests' fixtures the benchmarks' tests run on."""

from tests.localize.conftest import flat_dataset, flat_segnet  # noqa: F401
