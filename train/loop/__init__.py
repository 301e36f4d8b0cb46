"""The training loop: epochs, evaluation, optimizer, checkpoints, the log, data parallelism."""
