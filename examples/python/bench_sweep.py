"""Benchmark of eoir.dask.sweep (issue 37): the same trade study on a LocalCluster of one
worker process and of two, alternating, REPEAT times each; prints the medians and the
speed-up, and checks the two tables are identical.

    python examples/python/bench_sweep.py [POINTS] [REPEAT]

The grid varies MultimIR's integration time over POINTS values; every point simulates and
measures (analytic_only=False), so each task costs what a real trade study's does. Every
worker process runs the engine on one thread (RAYON_NUM_THREADS=1, set before the workers
start), so one worker uses one core, as a worker per core of a cluster does.
"""

import os
import statistics
import sys
import time

import numpy as np
import distributed

import eoir.dask


def main():
    os.environ["RAYON_NUM_THREADS"] = "1"
    points = int(sys.argv[1]) if len(sys.argv) > 1 else 16
    repeat = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    vary = {"detector.integration_time_s": (0.5e-3, 2.6e-3, points)}
    times = {1: [], 2: []}
    tables = {}
    clusters = {
        n: distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                    dashboard_address=None)
        for n in (1, 2)
    }
    clients = {n: distributed.Client(c) for n, c in clusters.items()}
    try:
        for n, c in clients.items():  # warm-up: workers import eoir once
            eoir.dask.sweep("multimir", {"detector.integration_time_s": [1e-3, 2e-3]},
                            client=c, analytic_only=False, ranges_km=[0.5, 1, 2, 4])
        for _ in range(repeat):
            for n, c in clients.items():
                t0 = time.perf_counter()
                ds = eoir.dask.sweep("multimir", vary, client=c, analytic_only=False,
                                     ranges_km=[0.5, 1, 2, 4])
                times[n].append(time.perf_counter() - t0)
                tables[n] = ds
    finally:
        for c in clients.values():
            c.close()
        for c in clusters.values():
            c.close()
    for name in tables[1].data_vars:
        np.testing.assert_array_equal(tables[1][name].values, tables[2][name].values)
    m1, m2 = statistics.median(times[1]), statistics.median(times[2])
    ratios = [a / b for a, b in zip(times[1], times[2])]
    print(f"| {points} points, analytic and measured | 1 worker {m1:.2f} s | 2 workers {m2:.2f} s "
          f"| speed-up (median of pairs) {statistics.median(ratios):.2f}x | tables identical |")


if __name__ == "__main__":
    main()
