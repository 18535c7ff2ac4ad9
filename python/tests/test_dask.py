"""eoir.dask: frames chunked along a Dask array, and files, equal eoir.run bit for bit."""

import numpy as np
import pytest

import eoir

da = pytest.importorskip("dask.array")
import eoir.dask as edask  # noqa: E402


def frames(scene, n):
    """n different frames: the scene scaled by 0.9 … 1.1 (a changing scene)."""
    f = np.linspace(0.9, 1.1, n, dtype=np.float32)
    return scene.radiance[None] * f[:, None, None, None]


def test_run_frames_any_chunking_equals_run(small_sensor, small_scene):
    c = small_scene
    seq = frames(c, 5)
    ref = eoir.run(small_sensor, seq, c.wavelength_um, c.fov_deg, seed=11, calibrate=False, range_m=c.range_m)
    for chunk in (1, 2, 5):
        x = da.from_array(seq, chunks=(chunk, -1, -1, -1))
        dn = edask.run_frames(small_sensor, x, c.wavelength_um, c.fov_deg, seed=11, range_m=c.range_m)
        assert dn.dtype == np.uint16 and dn.shape == (5, 32, 40)
        np.testing.assert_array_equal(dn.compute(scheduler="threads"), ref.dn)
    e = edask.run_frames(small_sensor, da.from_array(seq, chunks=(2, -1, -1, -1)), c.wavelength_um,
                         c.fov_deg, seed=11, product="electrons_mean", range_m=c.range_m)
    np.testing.assert_array_equal(e.compute(scheduler="threads"), ref.electrons_mean)


def test_run_frames_of_a_moving_camera_any_chunking_equals_run(small_scene):
    """A chunk of one frame is a rendered frame (``time_varying``), not a static scene the
    moving camera sweeps over: every chunking equals one run."""
    s = eoir.load_sensor("multimir", options={"sequence": "aircraft"},
                         overrides={"detector.rows": 32, "detector.cols": 40})
    c = small_scene
    seq = frames(c, 3)
    ref = eoir.run(s, seq, c.wavelength_um, c.fov_deg, seed=5, calibrate=False, range_m=c.range_m)
    for chunk in (1, 2):
        x = da.from_array(seq, chunks=(chunk, -1, -1, -1))
        dn = edask.run_frames(s, x, c.wavelength_um, c.fov_deg, seed=5, range_m=c.range_m)
        np.testing.assert_array_equal(dn.compute(scheduler="threads"), ref.dn)


def test_run_frames_temperature_equals_run(small_sensor, small_scene):
    """Calibration is rebuilt per chunk from the same sensor and seed: the same NUC, so the
    same temperatures as one calibrated run."""
    c = small_scene
    seq = frames(c, 3)
    ref = eoir.run(small_sensor, seq, c.wavelength_um, c.fov_deg, seed=13, range_m=c.range_m)
    t = edask.run_frames(small_sensor, da.from_array(seq, chunks=(2, -1, -1, -1)), c.wavelength_um,
                         c.fov_deg, seed=13, product="temperature", range_m=c.range_m)
    np.testing.assert_array_equal(t.compute(scheduler="threads"), ref.temperature)
    assert np.nanmedian(ref.temperature) > 250.0


def test_scene_gain_sensor_needs_one_chunk():
    s = eoir.load_sensor("threeband")
    assert s.gain_from_scene
    x = da.zeros((4, 3, 8, 8), chunks=(2, -1, -1, -1), dtype=np.float32)
    with pytest.raises(ValueError, match="scene_mean"):
        edask.run_frames(s, x, [0.5, 0.6, 0.7], (1.0, 1.0))


def test_persistence_sensor_needs_one_chunk(small_scene):
    s = eoir.load_sensor("multimir", overrides={
        "detector.rows": 32, "detector.cols": 40, "clock.frame_rate_hz": 50,
        "detector.persistence.tau_s": [0.01], "detector.persistence.density": [0.02]})
    assert s.has_persistence
    c = small_scene
    x = da.from_array(frames(c, 4), chunks=(2, -1, -1, -1))
    with pytest.raises(ValueError, match="persistence"):
        edask.run_frames(s, x, c.wavelength_um, c.fov_deg, range_m=c.range_m)


def test_run_frames_rejects_bad_input(small_sensor, small_scene):
    c = small_scene
    with pytest.raises(ValueError, match="product"):
        edask.run_frames(small_sensor, da.from_array(frames(c, 2)), c.wavelength_um, c.fov_deg, product="x")
    with pytest.raises(ValueError, match="dimensions"):
        edask.run_frames(small_sensor, da.from_array(c.radiance), c.wavelength_um, c.fov_deg)


def test_local_cluster_two_processes_bit_identical(small_sensor, small_scene):
    distributed = pytest.importorskip("distributed")
    c = small_scene
    seq = frames(c, 8)
    ref = eoir.run(small_sensor, seq, c.wavelength_um, c.fov_deg, seed=21, calibrate=False, range_m=c.range_m)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        x = da.from_array(seq, chunks=(3, -1, -1, -1))  # 3 + 3 + 2 frames over 2 workers
        dn = edask.run_frames(small_sensor, x, c.wavelength_um, c.fov_deg, seed=21, range_m=c.range_m)
        got = client.compute(dn).result()
        # Both workers did part of the work.
        assert len(client.scheduler_info()["workers"]) == 2
    np.testing.assert_array_equal(got, ref.dn)


def test_run_files_writes_zarr(small_sensor, small_scene, tmp_path):
    zarr = pytest.importorskip("zarr")
    c = small_scene
    paths = []
    for i, k in enumerate((1.0, 1.05)):
        p = tmp_path / f"scene{i}.npy"
        eoir.write_cube(p, eoir.Cube(c.radiance * np.float32(k), c.wavelength_um, c.fov_deg, range_m=c.range_m))
        paths.append(p)
    out = tmp_path / "products.zarr"
    with __import__("dask").config.set(scheduler="threads"):
        summary = edask.run_files(small_sensor, paths, out, seed=3)
    assert [s["name"] for s in summary] == ["0000_scene0", "0001_scene1"]
    root = zarr.open_group(str(out), mode="r")
    for p, s in zip(paths, summary):
        ref = eoir.run(small_sensor, eoir.read_cube(p), seed=3)
        g = root[s["name"]]
        np.testing.assert_array_equal(g["dn"][...], ref.dn)
        np.testing.assert_array_equal(g["temperature"][...], ref.temperature)
        assert g.attrs["report"]["detector"] == ref.report["detector"]
        assert eoir.sensor_from_toml(g.attrs["sensor_toml"]) == small_sensor
