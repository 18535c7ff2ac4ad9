"""A training set for detection / restoration algorithms: N synthetic scenes × sensor
presets × noise seeds, rendered by eoir on a Dask cluster and written to Zarr.

    pip install ./python 'dask[array]' distributed zarr
    python examples/python/training_set.py --scenes 4 --seeds 2 -o training.zarr
    # small and fast (what CI runs): 40 x 32 pixel detectors, into a temporary folder
    python examples/python/training_set.py --scenes 2 --seeds 2 --detector 32x40
    # the same on a remote cluster (workers need `pip install ./python` too, and the
    # output path must be on storage every worker and this machine see):
    python examples/python/training_set.py --scheduler tcp://scheduler:8786 -o /shared/training.zarr

Layout of the store: one group per preset, each with

    dn              uint16 [scene, seed, row, col]   the raw frames
    electrons_mean  float32 [scene, row, col]        noise-free ground truth
    temperature     float32 [scene, seed, row, col]  apparent temperature, K (thermal sensors)

and attributes `sensor_toml` (the resolved sensor), `scene_seeds`, `noise_seeds`.
Every element is reproducible from those attributes: the scene from its seed, the frame
from the sensor and the noise seed.
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np


def render(sensor, scene_seed: int, noise_seed: int, oversampling: int):
    """One task: a synthetic scene sized to the sensor, through the sensor (on a worker)."""
    import eoir

    scene = eoir.demo_scene(sensor, oversampling=oversampling, seed=scene_seed)
    ds = eoir.run(sensor, scene, seed=noise_seed, calibrate=sensor.thermal)
    t = ds.temperature.values if "temperature" in ds else np.full(ds.dn.shape, np.nan, np.float32)
    return np.stack([ds.dn.values.astype(np.float32), ds.electrons_mean.values, t])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", type=int, default=4, help="number of scenes (scene seeds 1..N)")
    ap.add_argument("--seeds", type=int, default=2, help="noise seeds per scene and sensor")
    ap.add_argument("--presets", default="multimir,qwip", help="comma-separated sensor presets")
    ap.add_argument("--oversampling", type=int, default=2, help="scene samples per detector pixel")
    ap.add_argument("--scheduler", help="address of a running dask scheduler (default: a local cluster)")
    ap.add_argument("--workers", type=int, default=2, help="local cluster: worker processes")
    ap.add_argument("--detector", help="ROWSxCOLS: cut every detector to this size (same optics and pitch)")
    ap.add_argument("-o", "--output", help="Zarr store to write (default: training.zarr in a temporary folder)")
    args = ap.parse_args()
    if args.output is None:
        args.output = str(Path(tempfile.mkdtemp(prefix="eoir-training-")) / "training.zarr")
    overrides = {}
    if args.detector:
        rows, cols = (int(v) for v in args.detector.lower().split("x"))
        overrides = {"detector.rows": rows, "detector.cols": cols}

    import dask
    import dask.array as da
    from dask.distributed import Client, LocalCluster

    import eoir

    if args.scheduler:
        client = Client(args.scheduler)
    else:
        client = Client(LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                                     dashboard_address=":0"))
    print(f"dask dashboard: {client.dashboard_link}")

    scene_seeds = list(range(1, args.scenes + 1))
    noise_seeds = list(range(1, args.seeds + 1))
    t0 = time.perf_counter()
    for name in args.presets.split(","):
        sensor = eoir.load_sensor(name.strip(), overrides=overrides)
        shape = (3, sensor.rows, sensor.cols)
        task = dask.delayed(render, pure=True)
        blocks = [
            [da.from_delayed(task(sensor, s, n, args.oversampling), shape, dtype=np.float32)
             for n in noise_seeds]
            for s in scene_seeds
        ]
        stack = da.stack([da.stack(row) for row in blocks])  # [scene, seed, 3, row, col]
        products = {
            "dn": stack[:, :, 0].astype(np.uint16),
            "electrons_mean": stack[:, 0, 1],
            "temperature": stack[:, :, 2],
        }
        if not sensor.thermal:
            del products["temperature"]
        stores = [
            da.to_zarr(a, args.output, component=f"{sensor.name}/{k}", overwrite=True, compute=False)
            for k, a in products.items()
        ]
        dask.compute(*stores)
        import zarr

        g = zarr.open_group(args.output, mode="a")[sensor.name]
        g.attrs.update({"sensor_toml": sensor.to_toml(), "scene_seeds": scene_seeds,
                        "noise_seeds": noise_seeds, "oversampling": args.oversampling})
        print(f"{sensor.name}: {len(scene_seeds)} scenes x {len(noise_seeds)} seeds -> {args.output}/{sensor.name}")
    n = len(scene_seeds) * len(noise_seeds) * len(args.presets.split(","))
    print(f"{n} frames in {time.perf_counter() - t0:.1f} s")
    # Every element is reproducible: the last one again, in this process, bit for bit.
    import zarr

    last = eoir.load_sensor(args.presets.split(",")[-1].strip(), overrides=overrides)
    scene = eoir.demo_scene(last, oversampling=args.oversampling, seed=scene_seeds[-1])
    again = eoir.run(last, scene, seed=noise_seeds[-1], calibrate=last.thermal)
    stored = zarr.open_group(args.output, mode="r")[last.name]["dn"][-1, -1]
    assert np.array_equal(stored, again.dn.values), "a stored frame differs from a fresh run"
    print(f"{last.name} scene {scene_seeds[-1]} seed {noise_seeds[-1]}: stored frame equals a fresh run bit for bit")
    client.close()


if __name__ == "__main__":
    main()
