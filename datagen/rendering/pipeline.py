"""A one-worker pipeline: finish frame i on a background thread while the caller traces i+1.

A training frame costs ~60 ms of Mitsuba passes (``Renderer.trace``, which the caller
must run in order) and ~15 ms of numpy / OpenCV work on their arrays (the denoiser, sRGB
encoding, PNG compression, the atomic writes) on the 2-core machine. The second half releases
the GIL for most of its time, so running it beside the next frame's trace gains ~9 % images/s
(docs/datagen.md). The order of the randomness is the caller's, so the bytes written are those
of a sequential run."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any


class Pipeline:
    """Runs submitted calls one at a time, in order, on one worker thread.

    At most ``depth`` calls wait or run at once: ``submit`` blocks (and re-raises the error
    of the oldest call, if it failed) until there is room, so memory stays bounded and an
    error stops the caller within ``depth`` frames; calls queued after a failed one do not
    run. Use as a context manager: leaving the block waits for every call and re-raises the
    first error.

    Args:
        depth: calls in flight (>= 1).
        enabled: False runs each call at once, in the caller (the sequential run the
            pipelined one's bytes are tested against).
    """

    def __init__(self, depth: int = 2, enabled: bool = True):
        if depth < 1:
            raise ValueError(f"Pipeline depth must be >= 1, got {depth}")
        self.depth = depth
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="datagen-finish") if enabled else None
        self._pending: deque[Future] = deque()
        self._failed = False

    def submit(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> None:
        """Queue ``fn(*args, **kwargs)``; runs it at once when the pipeline is disabled."""
        if self._pool is None:
            fn(*args, **kwargs)
            return
        self._pending.append(self._pool.submit(self._run, fn, args, kwargs))
        while len(self._pending) > self.depth:
            self._pending.popleft().result()

    def _run(self, fn: Callable[..., Any], args: tuple, kwargs: dict) -> None:
        """On the worker: skip every call after one that failed, so nothing is written past
        the frame where the error arose."""
        if self._failed:
            return
        try:
            fn(*args, **kwargs)
        except BaseException:
            self._failed = True
            raise

    def drain(self) -> None:
        """Wait for every queued call; re-raise the first error."""
        while self._pending:
            self._pending.popleft().result()

    def close(self) -> None:
        """Drain, then stop the worker (also after an error: the rest are cancelled)."""
        try:
            self.drain()
        finally:
            for f in self._pending:
                f.cancel()
            self._pending.clear()
            if self._pool is not None:
                self._pool.shutdown(wait=True)

    def __enter__(self) -> Pipeline:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
