"""The NumPy API against the CLI, closed forms and its own invariants."""

import math
import pickle
import subprocess

import numpy as np
import pytest

import eoir
from conftest import SMALL, read_tiff_u16


def test_run_dn_bit_identical_to_cli(cli, small_scene, small_sensor, tmp_path):
    scene = tmp_path / "scene.hdr"
    eoir.write_cube(scene, small_scene)
    out = tmp_path / "out"
    sets = [a for k, v in SMALL.items() for a in ("--set", f"{k}={v}")]
    subprocess.run(
        [cli, "run", "--sensor", "multimir", *sets, "--seed", "7", "--quiet", str(scene), "-o", str(out)],
        check=True,
    )
    dn_cli = read_tiff_u16(out / "dn.tiff")
    r = eoir.run(small_sensor, eoir.read_cube(scene), seed=7)
    assert r.dn.dtype == np.uint16 and r.dn.shape == (32, 40)
    np.testing.assert_array_equal(r.dn, dn_cli)
    # The DN carries signal and noise, not a constant image.
    assert r.dn.std() > 1.0
    # A different seed gives a different realisation.
    assert not np.array_equal(eoir.run(small_sensor, small_scene, seed=8, calibrate=False).dn, r.dn)
    # The report is the CLI's report.json (timings aside).
    import json

    report_cli = json.loads((out / "report.json").read_text())
    assert r.report["signal"]["mean_dn"] == report_cli["signal"]["mean_dn"]
    assert r.report["detector"] == report_cli["detector"]
    assert r.temperature is not None and r.temperature.shape == (32, 40)


def test_run_same_seed_bit_identical_and_input_not_modified(small_sensor, small_scene):
    before = small_scene.radiance.copy()
    a = eoir.run(small_sensor, small_scene, seed=5, calibrate=False)
    b = eoir.run(small_sensor, small_scene, seed=5, calibrate=False)
    np.testing.assert_array_equal(a.dn, b.dn)
    np.testing.assert_array_equal(small_scene.radiance, before)


def test_float64_and_strided_input_equal_float32(small_sensor, small_scene):
    c = small_scene
    ref = eoir.run(small_sensor, c.radiance, c.wavelength_um, c.fov_deg, seed=2, calibrate=False,
                   range_m=c.range_m)
    as64 = eoir.run(small_sensor, c.radiance.astype(np.float64), c.wavelength_um, c.fov_deg,
                    seed=2, calibrate=False, range_m=c.range_m)
    np.testing.assert_array_equal(ref.dn, as64.dn)
    # A Fortran-ordered (non-contiguous in C order) copy: borrowed with its strides.
    fort = np.asfortranarray(c.radiance)
    assert not fort.flags.c_contiguous
    r = eoir.run(small_sensor, fort, c.wavelength_um, c.fov_deg, seed=2, calibrate=False,
                 range_m=c.range_m)
    np.testing.assert_array_equal(ref.dn, r.dn)


def test_nan_radiance_raises_value_error(small_sensor, small_scene):
    bad = small_scene.radiance.copy()
    bad[3, 10, 12] = np.nan
    with pytest.raises(ValueError, match=r"band 3 .* row 10, col 12: radiance NaN is not a finite non-negative number"):
        eoir.run(small_sensor, bad, small_scene.wavelength_um, small_scene.fov_deg)
    bad[3, 10, 12] = -1.0
    with pytest.raises(ValueError, match="not a finite non-negative"):
        eoir.run(small_sensor, bad, small_scene.wavelength_um, small_scene.fov_deg)


def test_hostile_values_raise_value_error_not_a_crash(small_sensor, small_scene):
    # Issue 11: the same hostile values as on the command line reach the library through
    # the Python entry point and come back as one ValueError naming the setting.
    c = small_scene
    with pytest.raises(ValueError, match="nuc_degree"):
        eoir.run(small_sensor, c, nuc_degree=10**9)
    with pytest.raises(ValueError, match="nuc_degree"):
        eoir.run(small_sensor, c, nuc_degree=9)
    with pytest.raises(ValueError, match="frames"):
        eoir.run(small_sensor, c, frames=0)
    with pytest.raises(ValueError, match="field of view"):
        eoir.run(small_sensor, c.radiance, c.wavelength_um, (math.inf, math.inf))
    with pytest.raises(ValueError, match="field of view"):
        eoir.run(small_sensor, c.radiance, c.wavelength_um, (200.0, 4.0))
    with pytest.raises(ValueError, match="memory limit"):
        eoir.run(small_sensor, c, frames=10**12)


def test_missing_file_raises_os_error(tmp_path):
    with pytest.raises(OSError, match="missing.hdr"):
        eoir.read_cube(tmp_path / "missing.hdr")


def test_bad_values_raise_value_error(small_sensor, small_scene):
    c = small_scene
    with pytest.raises(ValueError, match="wavelength_um"):
        eoir.run(small_sensor, c.radiance, c.wavelength_um[:-1], c.fov_deg)
    with pytest.raises(ValueError, match="strictly increasing"):
        eoir.run(small_sensor, c.radiance, c.wavelength_um[::-1].copy(), c.fov_deg)
    with pytest.raises(ValueError, match="fov_deg"):
        eoir.run(small_sensor, c.radiance, c.wavelength_um, None)
    with pytest.raises(ValueError, match="field of view"):
        eoir.run(small_sensor, c.radiance, c.wavelength_um, (0.0, 1.0))
    with pytest.raises(ValueError, match="dimensions"):
        eoir.run(small_sensor, c.radiance[0], c.wavelength_um, c.fov_deg)
    with pytest.raises(ValueError, match="seed"):
        eoir.run(small_sensor, c, seed=-1)
    with pytest.raises(ValueError, match="units"):
        eoir.run(small_sensor, c, units="furlongs")
    with pytest.raises(ValueError, match="unknown cube format"):
        eoir.read_cube("scene.xyz")
    # A scene smaller than the sensor's field of view.
    with pytest.raises(ValueError):
        eoir.run(small_sensor, c.radiance[:, :8, :8], c.wavelength_um, (0.01, 0.01))


def test_load_sensor_options_overrides_and_properties():
    s = eoir.load_sensor("multimir", options={"filter": "3", "optics": "15mm"},
                         overrides={"detector.integration_time_s": 2e-3})
    assert s.options == {"filter": "3", "optics": "15mm", "sequence": "still"}
    assert s.integration_time_s == 2e-3
    assert s.ifov_rad == pytest.approx(s.pitch_m / s.focal_length_m, rel=1e-15)
    assert s.aperture_diameter_m == pytest.approx(s.focal_length_m / s.f_number, rel=1e-15)
    h, v = s.fov_deg
    # Flat focal plane: 2 atan(n p / 2f).
    assert h == pytest.approx(math.degrees(2 * math.atan(s.cols * s.pitch_m / (2 * s.focal_length_m))), rel=1e-12)
    assert v == pytest.approx(math.degrees(2 * math.atan(s.rows * s.pitch_m / (2 * s.focal_length_m))), rel=1e-12)
    assert s.thermal and not eoir.load_sensor("ccd").thermal
    with pytest.raises(ValueError, match="filter"):
        eoir.load_sensor("multimir", options={"filter": "9"})
    with pytest.raises(ValueError, match="no_such_key"):
        eoir.load_sensor("multimir", overrides={"detector.no_such_key": 1})
    with pytest.raises(ValueError, match="preset name"):
        eoir.load_sensor("no-such-sensor")
    names = [p["name"] for p in eoir.presets()]
    assert "multimir" in names and "qwip" in names
    multimir = next(p for p in eoir.presets() if p["name"] == "multimir")
    assert "3" in multimir["options"]["filter"]


def test_sensor_toml_and_pickle_round_trip(tmp_path):
    s = eoir.load_sensor("emerald", options={"band": "3"}, overrides={"jitter.sigma_rad": 1e-5})
    again = eoir.sensor_from_toml(s.to_toml())
    assert again == s
    assert pickle.loads(pickle.dumps(s)) == s
    f = tmp_path / "sensor.toml"
    f.write_text(s.to_toml())
    # Same description; only the directory relative paths resolve against differs.
    assert eoir.load_sensor(str(f)).to_toml() == s.to_toml()


def test_mtf_diffraction_matches_closed_form():
    s = eoir.load_sensor("multimir")
    lam = 4.0
    cutoff = s.aperture_diameter_m / (lam * 1e-6) * 1e-3  # cycles/mrad
    f = np.linspace(0.0, 1.2 * cutoff, 41)
    m = eoir.mtf(s, f, wavelength_um=lam)
    v = np.clip(f / cutoff, 0, 1)
    closed = 2 / np.pi * (np.arccos(v) - v * np.sqrt(1 - v * v))
    np.testing.assert_allclose(m["diffraction"], closed, atol=1e-12)
    assert m["system"][0] == pytest.approx(1.0, abs=1e-12)
    # The system is the product of its components.
    prod = np.ones_like(f)
    for k, col in m.items():
        if k not in ("wavelength_um", "freq_cy_per_mrad", "system"):
            prod = prod * col
    np.testing.assert_allclose(m["system"], prod, rtol=1e-12, atol=1e-15)
    assert eoir.mtf(s, [1.0])["wavelength_um"] == pytest.approx(s.mean_wavelength_um)


@pytest.mark.parametrize("ext", ["npy", "hdr", "exr"])
def test_cube_write_read_round_trip(small_scene, tmp_path, ext):
    p = tmp_path / f"cube.{ext}"
    eoir.write_cube(p, small_scene)
    back = eoir.read_cube(p)
    np.testing.assert_array_equal(back.radiance, small_scene.radiance)
    np.testing.assert_allclose(back.wavelength_um, small_scene.wavelength_um, rtol=1e-9)
    assert back.fov_deg == pytest.approx(small_scene.fov_deg, rel=1e-9)
    assert back.units == "W m-2 sr-1 um-1"


def test_sequence_and_frames(small_sensor, small_scene):
    c = small_scene
    # A static scene exposed 3 times: identical mean, fixed pattern shared, noise independent.
    r = eoir.run(small_sensor, c, seed=4, frames=3, calibrate=False)
    assert r.dn.shape == (3, 32, 40)
    np.testing.assert_array_equal(r.electrons_mean[0], r.electrons_mean[2])
    assert not np.array_equal(r.dn[0], r.dn[1])
    # The same frames as a 4-D sequence give the same DN.
    seq = np.stack([c.radiance] * 3)
    s = eoir.run(small_sensor, seq, c.wavelength_um, c.fov_deg, seed=4, calibrate=False, range_m=c.range_m)
    np.testing.assert_array_equal(r.dn, s.dn)
    # Frame 2 alone, told it is frame 2 of the sequence, equals frame 2 of the whole run.
    alone = eoir.run(small_sensor, c, seed=4, calibrate=False, first_frame=2)
    np.testing.assert_array_equal(alone.dn, r.dn[2])


def test_xarray_in_xarray_out(small_sensor, small_scene):
    xr = pytest.importorskip("xarray")
    c = small_scene
    cube = xr.DataArray(c.radiance, dims=("wavelength", "y", "x"),
                        coords={"wavelength": c.wavelength_um},
                        attrs={"fov_deg": c.fov_deg, "range_m": c.range_m})
    r = eoir.run(small_sensor, cube, seed=9)
    # The input's image dim names are kept (issue 40).
    assert isinstance(r.dn, xr.DataArray) and r.dn.dims == ("y", "x")
    assert r.temperature.attrs["units"].startswith("K")
    ref = eoir.run(small_sensor, c, seed=9)
    np.testing.assert_array_equal(r.dn.values, ref.dn)
    np.testing.assert_array_equal(r.temperature.values, ref.temperature)
    # Band order of the DataArray does not matter: dims are transposed by name.
    np.testing.assert_array_equal(eoir.run(small_sensor, cube.transpose("y", "wavelength", "x"), seed=9).dn.values, ref.dn)


def test_temperature_of_blackbody_scene():
    """Apparent temperature of a uniform 300 K blackbody through the full chain, NUC and
    inversion: 300 K within the noise (NETD tens of mK)."""
    s = eoir.load_sensor("multimir", overrides=SMALL)
    lo, hi = s.band_um
    bb = eoir.scene("blackbody", rows=32, cols=40, oversampling=1, lo_um=lo, hi_um=hi, bands=40,
                    fov_deg=s.fov_deg[0] * 1.05, temperature_k=300.0)
    r = eoir.run(s, bb, seed=1)
    temperature = r.temperature.values
    t = temperature[np.isfinite(temperature)]
    assert t.size > 0.9 * temperature.size
    assert np.median(t) == pytest.approx(300.0, abs=0.1)


def test_degenerate_inputs_raise_not_crash(small_sensor):
    """Empty, tiny and oddly shaped inputs give Python exceptions, never an abort."""
    with pytest.raises(ValueError):
        eoir.run(small_sensor, np.zeros((0, 4, 4), np.float32), [], (1.0, 1.0))
    with pytest.raises(ValueError):
        eoir.run(small_sensor, np.zeros((2, 0, 4), np.float32), [4.0, 4.5], (1.0, 1.0))
    with pytest.raises(ValueError):
        eoir.run(small_sensor, np.zeros((0, 2, 4, 4), np.float32), [4.0, 4.5], (1.0, 1.0))
    with pytest.raises(ValueError):  # one pixel cannot cover the sensor's field of view
        eoir.run(small_sensor, np.ones((2, 1, 1), np.float32), [4.0, 4.5], (1e-3, 1e-3))
    with pytest.raises(ValueError):
        eoir.run(small_sensor, np.ones((2, 4, 4), np.float32), [4.0, np.inf], (1.0, 1.0))
    with pytest.raises(ValueError):
        eoir.load_sensor("multimir", overrides={"detector.rows": 0})
    with pytest.raises(ValueError):
        eoir.mtf(small_sensor, [np.nan])


def test_scene_sized_to_a_sensor_runs_as_written(small_sensor):
    """`eoir.scene(kind, sensor=S)` covers the sensor as `eoir scene --sensor` does: k samples
    per detector pixel plus 4 pixels of margin each side, and runs with no other argument."""
    c = eoir.scene("edge", sensor=small_sensor, oversampling=2)
    assert c.radiance.shape[1:] == ((32 + 8) * 2, (40 + 8) * 2)
    assert c.fov_deg[0] == pytest.approx(math.degrees(48 * small_sensor.ifov_rad), rel=1e-12)
    r = eoir.run(small_sensor, c, seed=1, calibrate=False)
    assert r.dn.shape == (32, 40)
    assert r.report["sampling"]["ratio_x"] == pytest.approx(2.0, rel=1e-9)
    assert r.report["sampling"]["ratio_y"] == pytest.approx(2.0, rel=1e-9)
    # Without a sensor or an explicit size, the scene is sized to the default sensor.
    d = eoir.scene("blackbody", oversampling=1, margin_px=0, seed=2)
    full = eoir.load_sensor("multimir")
    assert d.radiance.shape[1:] == (full.rows, full.cols)
    assert d.fov_deg[0] == pytest.approx(math.degrees(full.cols * full.ifov_rad), rel=1e-12)
    with pytest.raises(ValueError, match="not both"):
        eoir.scene("edge", sensor=small_sensor, rows=10)


def test_calibration_temperatures_default_to_the_sensor_range_and_can_be_given(small_sensor, small_scene):
    auto = eoir.run(small_sensor, small_scene, seed=3)
    levels = auto.report["calibration"]["temperatures_k"]
    assert len(levels) == 3 and levels != [280.0, 300.0, 320.0]
    given = eoir.run(small_sensor, small_scene, seed=3, calibration_temperatures_k=[285.0, 300.0, 315.0])
    assert given.report["calibration"]["temperatures_k"] == [285.0, 300.0, 315.0]
    np.testing.assert_array_equal(given.dn, auto.dn)
    with pytest.raises(ValueError):
        eoir.run(small_sensor, small_scene, calibration_temperatures_k=[300.0, 300.0])


def test_a_moving_camera_returns_its_truth_table(small_sensor, small_scene):
    """MultimIR's aircraft clock: a static scene drifts 2.0 px per frame (46.1 m/s at
    1900 m, 50 frames/s, 24 um / 100 mm), and the truth table says so."""
    c = small_scene
    aircraft = eoir.load_sensor("multimir", options={"sequence": "aircraft"}, overrides=SMALL)
    assert eoir.run(small_sensor, c, frames=2, calibrate=False, as_dataset=False).line_of_sight is None
    small_sensor = aircraft
    r = eoir.run(small_sensor, c, seed=4, frames=2, calibrate=False, as_dataset=False)
    los = r.line_of_sight
    assert los is not None
    assert list(los["frame"]) == [0, 1]
    step = 46.1 / 1900.0 / 50.0 / (24e-6 / 0.1)
    np.testing.assert_allclose(los["dx_px"], [0.0, step], atol=1e-9)
    np.testing.assert_allclose(los["dy_px"], [0.0, 0.0], atol=1e-12)
    # The frames moved: the mean images differ (a still camera's would be equal).
    assert not np.array_equal(r.electrons_mean[0], r.electrons_mean[1])
    ds = eoir.run(small_sensor, c, seed=4, frames=2, calibrate=False)
    np.testing.assert_allclose(ds["los_dx_px"].values, los["dx_px"])


def test_unblurred_run_is_the_cli_unblurred_run(cli, small_scene, small_sensor, tmp_path):
    """``run(..., unblurred=True)`` and ``Sensor.unblurred()`` are ``eoir run --unblurred``."""
    scene = tmp_path / "scene.hdr"
    eoir.write_cube(scene, small_scene)
    out = tmp_path / "out"
    sets = [a for k, v in SMALL.items() for a in ("--set", f"{k}={v}")]
    subprocess.run(
        [cli, "run", "--sensor", "multimir", *sets, "--unblurred", "--quiet", str(scene), "-o", str(out)],
        check=True,
    )
    r = eoir.run(small_sensor, eoir.read_cube(scene), unblurred=True, as_dataset=False)
    np.testing.assert_array_equal(r.dn, read_tiff_u16(out / "dn.tiff"))
    assert r.report["unblurred"] is True and r.report["optics"]["components"] == []
    u = small_sensor.unblurred()
    assert "enabled = false" in u.to_toml()
    blurred = eoir.run(small_sensor, eoir.read_cube(scene), calibrate=False, as_dataset=False)
    assert blurred.report["unblurred"] is False
