"""The focal plane's memory from Python: its truth arrays, the Dataset variables, and Dask
pieces that replay the memory bit for bit (docs/focal-plane.md)."""

import numpy as np
import pytest

import eoir

from conftest import SMALL

MEMORY = {
    **SMALL,
    "clock.frame_rate_hz": 50.0,
    "motion.enabled": False,
    "detector.rts.fraction": 0.05,
    "detector.rts.tau_high_s": 0.03,
    "detector.rts.tau_low_s": 0.05,
    "detector.rts.dark_step_e_per_s": 2e6,
    "detector.drift.offset_walk_e_per_sqrt_s": 500.0,
    "detector.drift.walk_step_s": 0.01,
}


@pytest.fixture(scope="module")
def memory_sensor():
    return eoir.load_sensor("multimir", overrides=MEMORY)


def test_truth_arrays_and_dataset(memory_sensor, small_scene):
    c = small_scene
    r = eoir.run(memory_sensor, c.radiance, c.wavelength_um, c.fov_deg, frames=4,
                 calibrate=False, range_m=c.range_m, as_dataset=False)
    fp = r.focal_plane
    n = len(fp["rts_row"])
    assert n > 0 and fp["rts_high_fraction"].shape == (4, n)
    assert fp["rts_high_at_readout"].dtype == bool
    assert fp["drift_gain"].shape == (4, 32, 40) and fp["drift_offset_e"].shape == (4, 32, 40)
    assert "trapped_e" not in fp
    # The drift grows from nothing at t = 0.
    assert np.all(fp["drift_offset_e"][0] == 0)
    assert fp["drift_offset_e"][3].std() > fp["drift_offset_e"][1].std() > 0
    assert r.report["focal_plane"]["effects"] == ["rts", "drift"]
    ds = eoir.run(memory_sensor, c.radiance, c.wavelength_um, c.fov_deg, frames=4,
                  calibrate=False, range_m=c.range_m)
    assert ds["rts_high_fraction"].dims == ("frame", "rts_pixel")
    assert ds["drift_offset_e"].attrs["units"] == "e-"
    np.testing.assert_array_equal(ds["rts_row"].values, fp["rts_row"])


def test_a_still_sensor_has_no_focal_plane(small_sensor, small_scene):
    c = small_scene
    r = eoir.run(small_sensor, c.radiance, c.wavelength_um, c.fov_deg, calibrate=False,
                 range_m=c.range_m, as_dataset=False)
    assert r.focal_plane is None and "focal_plane" not in r.report


def test_dask_pieces_replay_the_memory(memory_sensor, small_scene):
    da = pytest.importorskip("dask.array")
    import eoir.dask as edask

    c = small_scene
    seq = np.repeat(c.radiance[None], 5, axis=0)
    ref = eoir.run(memory_sensor, seq, c.wavelength_um, c.fov_deg, seed=4, calibrate=False,
                   range_m=c.range_m, as_dataset=False)
    dn = edask.run_frames(memory_sensor, da.from_array(seq, chunks=(2, -1, -1, -1)),
                          c.wavelength_um, c.fov_deg, seed=4, range_m=c.range_m)
    np.testing.assert_array_equal(dn.compute(scheduler="threads"), ref.dn)


def test_persistence_in_a_later_piece_of_a_sequence_is_refused(small_scene):
    c = small_scene
    s = eoir.load_sensor("multimir", overrides={
        **SMALL, "clock.frame_rate_hz": 50.0, "motion.enabled": False,
        "detector.persistence.tau_s": [0.01, 0.1], "detector.persistence.density": [0.02, 0.03],
    })
    seq = np.repeat(c.radiance[None], 2, axis=0)
    with pytest.raises(ValueError, match="persistence"):
        eoir.run(s, seq, c.wavelength_um, c.fov_deg, first_frame=2, sequence_frames=4,
                 calibrate=False, range_m=c.range_m)


def test_find_rts_pixels_in_a_dark_sequence():
    """Planted two-level pixels in Gaussian noise are found; the rest are not."""
    rng = np.random.default_rng(5)
    stack = rng.normal(1000.0, 5.0, size=(60, 16, 20))
    planted = [(3, 4), (10, 17), (12, 2)]
    for k, (r, c) in enumerate(planted):
        high = (np.arange(60) // (4 + k)) % 2 == 1
        stack[high, r, c] += 60.0
    found = eoir.find_rts_pixels(stack)
    assert sorted(zip(found["row"], found["col"])) == sorted(planted)
    assert np.all(np.abs(found["step"] - 60.0) < 5.0)
