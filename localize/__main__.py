"""``python -m localize``: the edge particle filter on a dataset's flights (conf/localize.yaml)."""

from __future__ import annotations

import hydra
from omegaconf import DictConfig

from localize.runner import run


@hydra.main(version_base="1.3", config_path="../conf", config_name="localize")
def main(cfg: DictConfig) -> None:
    report = run(cfg)
    print(f"report: {report}")


if __name__ == "__main__":
    main()
