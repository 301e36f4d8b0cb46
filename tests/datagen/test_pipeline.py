"""The one-worker pipeline of datagen: order, bounded depth, errors."""

from __future__ import annotations

import threading
import time

import pytest

from datagen.rendering.pipeline import Pipeline


class TestPipeline:
    def test_runs_in_order_on_one_worker(self):
        done, threads = [], set()

        def work(i):
            time.sleep(0.002 * (i % 3))
            threads.add(threading.get_ident())
            done.append(i)

        with Pipeline(depth=2) as pipe:
            for i in range(20):
                pipe.submit(work, i)
        assert done == list(range(20))
        assert threads and threading.get_ident() not in threads and len(threads) == 1

    def test_depth_bounds_calls_in_flight(self):
        started, release = [], threading.Event()

        def work(i):
            started.append(i)
            release.wait(5)

        pipe = Pipeline(depth=2)
        pipe.submit(work, 0)
        pipe.submit(work, 1)
        t = threading.Thread(target=pipe.submit, args=(work, 2))
        t.start()
        time.sleep(0.1)
        assert t.is_alive(), "a third call must wait while two are in flight"
        release.set()
        t.join(5)
        pipe.close()
        assert started == [0, 1, 2]

    def test_error_reaches_the_caller_and_stops_later_calls(self):
        done = []

        def work(i):
            if i == 3:
                raise KeyboardInterrupt("simulated kill")
            done.append(i)

        with pytest.raises(KeyboardInterrupt, match="simulated kill"):
            with Pipeline(depth=2) as pipe:
                for i in range(10):
                    pipe.submit(work, i)
        assert done == [0, 1, 2]

    def test_disabled_runs_in_the_caller(self):
        seen = []
        with Pipeline(enabled=False) as pipe:
            pipe.submit(lambda: seen.append(threading.get_ident()))
        assert seen == [threading.get_ident()]

    def test_bad_depth(self):
        with pytest.raises(ValueError, match="depth"):
            Pipeline(depth=0)
