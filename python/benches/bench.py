"""Benchmarks of the Python package (numbers recorded in BENCHMARKS.md, section Python).

    pip install ./python 'dask[array]' distributed
    cargo build --release                      # the CLI, for the comparison
    python python/benches/bench.py [--cli target/release/eoir] [--repeat 3]

1. Python-call overhead on the demo cube (`eoir demo`: thermal scene, MultimIR, 2×
   oversampled): the wall time of `eoir.run` on the in-memory cube against the engine's
   own total (report timings), and `read_cube` + `run` in Python against the whole
   `eoir run` process (which also writes its products).
2. Frames per second on 16 frames (the demo scene scaled 0.9 … 1.1, 1× oversampled): one
   `eoir.run` call in this process, against `eoir.dask.run_frames` on a
   `LocalCluster(n_workers=2, processes=True)` with one frame per chunk.
"""

import argparse
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

import eoir

REPO = Path(__file__).resolve().parents[2]


def timed(f, repeat):
    ts, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = f()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts), out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cli", default=str(REPO / "target" / "release" / "eoir"))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--frames", type=int, default=16)
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        subprocess.run([args.cli, "demo", "-o", str(tmp / "demo"), "--quiet"], check=True)
        scene = tmp / "demo" / "scene.hdr"
        sensor = eoir.load_sensor("multimir")

        t_cli, _ = timed(lambda: subprocess.run(
            [args.cli, "run", "--sensor", "multimir", str(scene), "-o", str(tmp / "cli"), "--quiet"],
            check=True), args.repeat)
        t_read, cube = timed(lambda: eoir.read_cube(scene), args.repeat)
        runs = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            r = eoir.run(sensor, cube, seed=1)
            runs.append((time.perf_counter() - t0, r.report["timings_s"]["total"]))
        # Median of the paired differences (wall time of the call minus the engine's own
        # total in the same call), so machine load cancels as far as possible.
        t_run = statistics.median(t for t, _ in runs)
        engine = statistics.median(e for _, e in runs)
        over = statistics.median(t - e for t, e in runs)
        print(f"demo cube {cube.radiance.shape} float32 ({cube.radiance.nbytes / 1e6:.0f} MB)")
        print(f"eoir run (CLI process, read+run+write): {t_cli:.3f} s")
        print(f"python read_cube: {t_read:.3f} s, eoir.run: {t_run:.3f} s, engine total inside it: {engine:.3f} s")
        print(f"binding overhead of eoir.run (paired): {over:.4f} s = {100 * over / engine:.2f} %")
        print(f"python read+run vs CLI: {100 * ((t_read + t_run) / t_cli - 1):+.1f} %")

    # Throughput on a sequence.
    import dask.array as da
    from dask.distributed import Client, LocalCluster

    import eoir.dask as edask

    base = eoir.demo_scene(sensor, oversampling=1, seed=1)
    n = args.frames
    k = np.linspace(0.9, 1.1, n, dtype=np.float32)
    seq = base.radiance[None] * k[:, None, None, None]
    print(f"sequence {seq.shape} float32 ({seq.nbytes / 1e6:.0f} MB)")
    t1, ref = timed(lambda: eoir.run(sensor, seq, base.wavelength_um, base.fov_deg, seed=1,
                                     calibrate=False, range_m=base.range_m), 1)
    print(f"1 process, one eoir.run call: {t1:.2f} s = {n / t1:.2f} frames/s")
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cl, \
            Client(cl) as client:
        # The base frame goes to the workers once (scattered), not inside every task.
        x = da.from_delayed(client.scatter(base.radiance, broadcast=True), base.radiance.shape,
                            dtype=np.float32)[None] * da.from_array(k, chunks=1)[:, None, None, None]
        dn = edask.run_frames(sensor, x, base.wavelength_um, base.fov_deg, seed=1, range_m=base.range_m)
        client.compute(dn[:2]).result()  # warm the workers (import, first sensor build)
        t0 = time.perf_counter()
        got = client.compute(dn).result()
        t2 = time.perf_counter() - t0
    print(f"LocalCluster 2 workers x 1 thread, 1 frame per chunk: {t2:.2f} s = {n / t2:.2f} frames/s")
    print("bit-identical to the single call:", bool(np.array_equal(got, ref.dn)))


if __name__ == "__main__":
    main()
