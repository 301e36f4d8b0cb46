"""``python -m localize``: the edge particle filter on a dataset's flights (conf/localize.yaml).

Hydra composes the defaults, the presets and the command line; ``localize.resolve.resolve``
adds the localize settings the model folder carries (under the command line) and records
which layer set each value that differs from its default (report.md prints them).
"""

from __future__ import annotations

from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from core.config import hydra_app
from localize.config import ALIASES, LocalizeConfig
from localize.offline.runner import run
from localize.resolve import resolve


@hydra_app("localize", LocalizeConfig, ALIASES)
def main(cfg: DictConfig) -> None:
    hydra_cfg = HydraConfig.get()
    resolve(cfg, hydra_cfg.overrides.task, hydra_cfg.runtime.choices)
    if cfg.recording is None:
        report = run(cfg)
    else:
        from localize.offline.recorded import run_recording

        report = run_recording(cfg)
    print(f"report: {report}")


if __name__ == "__main__":
    main()
