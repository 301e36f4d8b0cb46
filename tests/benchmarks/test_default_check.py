"""benchmarks/default_check.py: the defaults against their neighbours on validation flights."""

from __future__ import annotations

from benchmarks.default_check import VARIANTS, errors, table


def test_errors_pool_flights_and_seeds():
    metrics = {"flights": {"paper_val": {"cnn": {"per_seed_mean_m": [0.01, 0.03]}},
                           "cluttered_val": {"cnn": {"per_seed_mean_m": [0.02, 0.04]},
                                             "oracle": {"per_seed_mean_m": [0.01, 0.01]}}}}
    assert errors(metrics) == {"cnn": [0.01, 0.03, 0.02, 0.04], "oracle": [0.01, 0.01]}


def test_table_gives_the_ratio_to_the_defaults():
    rows = table({"defaults": {"cnn": [0.02, 0.02]}, "cnn_k_30": {"cnn": [0.03, 0.03]}})
    assert rows[2].startswith("| defaults | cnn | 0.0200 (std 0.0000, 2 runs) | 1.00")
    assert rows[3] == "| cnn_k_30 | cnn | 0.0300 | 1.50 |"


def test_every_variant_sets_real_keys():
    """Each variant's overrides compose onto conf/localize.yaml (a typo would fail here)."""
    from hydra import compose, initialize_config_dir

    from benchmarks.default_check import ROOT
    from localize.context import settings_of

    for name, (_, overrides) in VARIANTS.items():
        with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
            cfg = compose(config_name="localize", overrides=overrides)
        settings_of(cfg)  # typed: a wrong key or value raises
        assert name == "defaults" or overrides
