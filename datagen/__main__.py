"""``python -m datagen``: render a labeled corridor dataset (config: conf/datagen.yaml)."""

from __future__ import annotations

from omegaconf import DictConfig

from core.config import hydra_app
from datagen.config import DatagenConfig


@hydra_app("datagen", DatagenConfig)
def main(cfg: DictConfig) -> None:
    from datagen.generate import run

    out = run(cfg)
    print(f"dataset written to {out}")


if __name__ == "__main__":
    main()
