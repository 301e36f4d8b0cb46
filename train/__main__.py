"""``python -m train``: train a SegNet on a datagen dataset and export it (conf/train.yaml).

Under ``torchrun`` (docs/train.md) every process runs this; the processes of rank > 0 keep
Hydra's run folder and log file to rank 0 (their log goes to the console only).
"""

from __future__ import annotations

import os
import sys

from omegaconf import DictConfig

from core.config import hydra_app
from train.config import TrainConfig
from train.run import run

#: Hydra overrides for the torchrun processes of rank > 0: no .hydra/ record, no log file,
#: warnings and errors only.
SILENT_HYDRA = ("hydra.output_subdir=null", "hydra/job_logging=stdout",
                "hydra.job_logging.root.level=WARNING", "hydra.run.dir=.")


@hydra_app("train", TrainConfig)
def main(cfg: DictConfig) -> None:
    run(cfg)


if __name__ == "__main__":
    if int(os.environ.get("RANK", "0")) > 0:
        sys.argv += SILENT_HYDRA
    main()
