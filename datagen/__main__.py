"""``python -m datagen``: render a labeled corridor dataset (config: conf/datagen.yaml)."""

from __future__ import annotations

import hydra
from omegaconf import DictConfig


@hydra.main(version_base="1.3", config_path="../conf", config_name="datagen")
def main(cfg: DictConfig) -> None:
    from datagen.generate import run

    out = run(cfg)
    print(f"dataset written to {out}")


if __name__ == "__main__":
    main()
