"""``python -m train``: train a SegNet on a datagen dataset and export it (conf/train.yaml)."""

from __future__ import annotations

import hydra
from omegaconf import DictConfig

from train.train import run


@hydra.main(version_base="1.3", config_path="../conf", config_name="train")
def main(cfg: DictConfig) -> None:
    run(cfg)


if __name__ == "__main__":
    main()
