"""The toolbox from Python (issue 40): restore, edge MTF, NUC and EMVA 1288 against the
CLI's files bit for bit, run's Dataset, and the helpers around it."""

import json
import math
import subprocess

import numpy as np
import pytest

import eoir
from conftest import SMALL, read_tiff_f32, read_tiff_u16, write_tiff_u16

SETS = [a for k, v in SMALL.items() for a in ("--set", f"{k}={v}")]


def cli_run(cli, scene_path, out, seed, *extra):
    subprocess.run([cli, "run", "--sensor", "multimir", *SETS, "--seed", str(seed), "--quiet",
                    *extra, str(scene_path), "-o", str(out)], check=True, capture_output=True)


@pytest.fixture(scope="module")
def edge_run(cli, small_sensor, tmp_path_factory):
    """An edge scene run by the CLI: its folder, and the same run from Python."""
    d = tmp_path_factory.mktemp("edge")
    cube = eoir.scene("edge", sensor=small_sensor, oversampling=2, t_low_k=290.0, t_high_k=320.0)
    eoir.write_cube(d / "edge.hdr", cube)
    cli_run(cli, d / "edge.hdr", d / "run", 5)
    return d, eoir.run(small_sensor, eoir.read_cube(d / "edge.hdr"), seed=5)


def test_run_dataset_coordinates_and_attributes(edge_run, small_sensor):
    d, ds = edge_run
    assert ds.dn.dims == ("row", "col") and ds.dn.dtype == np.uint16
    np.testing.assert_array_equal(ds.dn.values, read_tiff_u16(d / "run" / "dn.tiff"))
    # Angular coordinates: pixel j at (j - (n - 1)/2)·IFOV, mrad, centred on the boresight.
    ifov = small_sensor.pitch_m / small_sensor.focal_length_m * 1e3
    assert ds.col.attrs["units"] == "mrad"
    assert ds.col.values[0] == pytest.approx(-(40 - 1) / 2 * ifov, rel=1e-12)
    assert ds.row.values[-1] == pytest.approx((32 - 1) / 2 * ifov, rel=1e-12)
    assert ds.col.values.sum() == pytest.approx(0.0, abs=1e-12)
    assert ds.attrs["sensor"] == "multimir" and ds.attrs["seed"] == 5
    assert ds.attrs["eoir_version"] == eoir.__version__
    assert ds.temperature.attrs["units"] == "K" and ds.dn.attrs["units"] == "DN"
    # Backward compatible access: ds.report is the report dict.
    assert ds.report["detector"] == json.loads((d / "run" / "report.json").read_text())["detector"]
    np.testing.assert_array_equal(eoir.run(small_sensor, eoir.read_cube(d / "edge.hdr"), seed=5,
                                           as_dataset=False).dn, ds.dn.values)


def test_restore_bit_identical_to_cli(cli, edge_run, small_sensor):
    d, ds = edge_run
    for noise in ("auto", "model"):
        out = d / f"restore-{noise}"
        subprocess.run([cli, "restore", str(d / "run" / "dn.tiff"), "--sensor", "multimir", *SETS,
                        "--noise", noise, "-o", str(out)], check=True, capture_output=True)
        r = eoir.restore(small_sensor, ds, noise=noise)
        assert r.restored.dtype == np.float32 and r.restored.dims == ("row", "col")
        np.testing.assert_array_equal(r.restored.values, read_tiff_f32(out / "restored.tiff"))
        rep = json.loads((out / "restore.json").read_text())
        for k in ("nsr_median", "noise_power", "noise_sigma", "object_spectrum_exponent",
                  "transfer_function", "output_stats", "pixels_replaced"):
            assert r.report[k] == rep[k], k
    # A constant NSR, from a file path.
    out = d / "restore-nsr"
    subprocess.run([cli, "restore", str(d / "run" / "dn.tiff"), "--sensor", "multimir", *SETS,
                    "--nsr", "0.01", "-o", str(out)], check=True, capture_output=True)
    r = eoir.restore(small_sensor, d / "run" / "dn.tiff", nsr=0.01)
    np.testing.assert_array_equal(r.restored.values, read_tiff_f32(out / "restored.tiff"))


def test_edge_mtf_bit_identical_to_cli(cli, edge_run, small_sensor):
    d, ds = edge_run
    out = d / "mtf"
    # An array carries no run instance: Python finds the defects in the image, as the CLI
    # does for an image without its run's instance.json beside it.
    bare = d / "bare"
    bare.mkdir(exist_ok=True)
    (bare / "dn.tiff").write_bytes((d / "run" / "dn.tiff").read_bytes())
    subprocess.run([cli, "edge-mtf", str(bare / "dn.tiff"), "--sensor", "multimir", *SETS,
                    "-o", str(out)], check=True, capture_output=True)
    m = eoir.edge_mtf(ds, sensor=small_sensor)
    rep = json.loads((out / "edge_mtf.json").read_text())
    for k in ("edge_angle_deg", "mtf50_cy_per_px", "mtf50_cy_per_mrad", "mtf_at_nyquist",
              "edge_contrast", "noise_rms", "roi"):
        assert m.report[k] == rep[k], k
    assert m.attrs["mtf50_cy_per_px"] == rep["mtf50_cy_per_px"]
    rows = (out / "edge_mtf.csv").read_text().splitlines()
    assert rows[0] == "freq_cy_per_px,freq_cy_per_mrad,mtf"
    ours = [f"{f:.6f},{g:.6f},{v:.6f}" for f, g, v in
            zip(m.freq.values, m.freq_cy_per_mrad.values, m.mtf.values)]
    assert ours == rows[1:]
    # The measured edge MTF is an MTF: 1 at zero frequency, falling.
    assert m.mtf.values[0] == pytest.approx(1.0, abs=0.02)
    assert 0.05 < m.attrs["mtf50_cy_per_px"] < 0.5


def test_nuc_fit_and_apply_bit_identical_to_cli(cli, small_sensor, tmp_path):
    temps = [285.0, 300.0, 315.0]
    frames = []
    for t in temps:
        bb = eoir.scene("blackbody", sensor=small_sensor, oversampling=1, temperature_k=t)
        r = eoir.run(small_sensor, bb, seed=4, frames=2, calibrate=False)
        frames.extend(r.dn.values)
    paths = []
    for i, f in enumerate(frames):
        p = tmp_path / f"f{i}.tiff"
        write_tiff_u16(p, f)
        paths.append(str(p))
    subprocess.run([cli, "nuc", "fit", *paths, "--temperatures-k", ",".join(str(t) for t in temps),
                    "-o", str(tmp_path / "cli.json")], check=True, capture_output=True)
    nuc = eoir.nuc_fit(np.stack(frames), temps)
    assert nuc.degree == 1 and nuc.shape == (32, 40)
    nuc.save(tmp_path / "py.json")
    assert (tmp_path / "py.npy").read_bytes() == (tmp_path / "cli.npy").read_bytes()
    # From the file paths too.
    np.testing.assert_array_equal(eoir.nuc_fit(paths, temps).coefficients, nuc.coefficients)
    subprocess.run([cli, "nuc", "apply", paths[2], "--nuc", str(tmp_path / "cli.json"),
                    "-o", str(tmp_path / "corrected.tiff")], check=True, capture_output=True)
    c = eoir.nuc_apply(nuc, frames[2])
    np.testing.assert_array_equal(c.corrected.values.astype(np.float32),
                                  read_tiff_f32(tmp_path / "corrected.tiff"))
    # The CLI's files load back to the same correction.
    np.testing.assert_array_equal(eoir.nuc_apply(tmp_path / "cli.json", frames[2]).corrected.values,
                                  c.corrected.values)
    # The correction flattens the fixed pattern: the spatial spread of a blackbody frame
    # drops well below the raw frame's.
    assert np.std(c.corrected.values) < 0.5 * np.std(frames[2].astype(float))
    with pytest.raises(ValueError, match="temperatures_k"):
        eoir.nuc_fit(np.stack(frames), [285.0, 285.0, 300.0])
    with pytest.raises(ValueError, match="frames"):
        eoir.nuc_fit(np.stack(frames[:5]), temps)


def test_characterize_matches_cli(cli, tmp_path):
    s = eoir.load_sensor("ccd")
    truth = eoir.simulate_acquisition_set(s, tmp_path / "py-set", seed=3, window=32)
    subprocess.run([cli, "characterize", "--simulate", "--sensor", "ccd", "--seed", "3", "--window", "32",
                    "-o", str(tmp_path / "cli-set")], check=True, capture_output=True)
    assert truth == json.loads((tmp_path / "cli-set" / "truth.json").read_text())
    subprocess.run([cli, "characterize", str(tmp_path / "cli-set"), "-o", str(tmp_path / "cli-out")],
                   check=True, capture_output=True)
    c = eoir.characterize(tmp_path / "py-set", output=tmp_path / "py-out")
    assert c == json.loads((tmp_path / "cli-out" / "characterization.json").read_text())
    assert (tmp_path / "py-out" / "characterization.json").exists()
    # The analysis recovers the simulated camera's gain (EMVA 1288 photon transfer).
    assert c["K_DN_per_e"] == pytest.approx(truth["K_DN_per_e"], rel=0.1)


def test_scene_extent_and_paraxial_fov():
    s = eoir.load_sensor("multimir", options={"optics": "15mm"})
    ifov = s.pitch_m / s.focal_length_m
    h, v = s.paraxial_fov_deg
    assert h == pytest.approx(math.degrees(s.cols * ifov), rel=1e-12)
    assert v == pytest.approx(math.degrees(s.rows * ifov), rel=1e-12)
    # The datasheet angle (flat focal plane) is smaller: a scene sized to it is refused.
    assert s.fov_deg[0] < h
    eh, ev = s.scene_extent_deg()
    assert eh == pytest.approx(math.degrees((s.cols + 8) * ifov), rel=1e-12)
    assert ev == pytest.approx(math.degrees((s.rows + 8) * ifov), rel=1e-12)
    assert s.scene_extent_deg(margin_px=0) == pytest.approx((h, v), rel=1e-12)
    # The scene eoir.scene sizes to the sensor covers exactly scene_extent_deg.
    small = eoir.load_sensor("multimir", overrides=SMALL)
    c = eoir.scene("blackbody", sensor=small, oversampling=1)
    assert c.fov_deg[0] == pytest.approx(small.scene_extent_deg()[0], rel=1e-12)
    with pytest.raises(ValueError, match="field of view"):
        bb = eoir.scene("blackbody", rows=32, cols=40, oversampling=1, fov_deg=small.fov_deg[0] * 0.9)
        eoir.run(small, bb)


def test_units_spellings_like_the_readers(small_sensor, small_scene, tmp_path):
    c = small_scene
    ref = eoir.run(small_sensor, c, seed=2, calibrate=False)
    # The same radiance in W m-2 sr-1 nm-1 (values / 1000) gives the same electrons within
    # float32 rounding of the scaling.
    per_nm = (c.radiance / np.float32(1000.0)).astype(np.float32)
    r = eoir.run(small_sensor, per_nm, c.wavelength_um, c.fov_deg, seed=2, calibrate=False,
                 range_m=c.range_m, units="W m-2 sr-1 nm-1")
    np.testing.assert_allclose(r.electrons_mean.values, ref.electrons_mean.values, rtol=1e-5)
    # Bit for bit with the file reader given the same values and units (NPY + sidecar).
    np.save(tmp_path / "nm.npy", per_nm)
    (tmp_path / "nm.json").write_text(json.dumps({
        "wavelength_um": list(map(float, c.wavelength_um)), "fov_deg": list(c.fov_deg),
        "units": "W m-2 sr-1 nm-1", "range_m": c.range_m}))
    from_file = eoir.run(small_sensor, eoir.read_cube(tmp_path / "nm.npy"), seed=2, calibrate=False)
    np.testing.assert_array_equal(r.dn.values, from_file.dn.values)
    # A sidecar that states no units: `radiance_units=` supplies them (the CLI's
    # --radiance-units); a unit it does not know is an error naming the Python parameter.
    (tmp_path / "bare.json").write_text(json.dumps({
        "wavelength_um": list(map(float, c.wavelength_um)), "fov_deg": list(c.fov_deg)}))
    np.save(tmp_path / "bare.npy", per_nm)
    with pytest.raises(ValueError) as e:
        eoir.read_cube(tmp_path / "bare.npy", radiance_units="furlongs")
    assert "radiance_units" in str(e.value) and "--radiance-units" not in str(e.value)
    bare = eoir.read_cube(tmp_path / "bare.npy", radiance_units="W m-2 sr-1 nm-1")
    np.testing.assert_array_equal(bare.radiance, eoir.read_cube(tmp_path / "nm.npy").radiance)
    for u in ("uW cm-2 sr-1 nm-1", "W/(m2 sr um)", "spectral"):
        eoir.run(small_sensor, c.radiance, c.wavelength_um, c.fov_deg, units=u, calibrate=False)
    with pytest.raises(ValueError, match="units"):
        eoir.run(small_sensor, c, units="furlongs")


def test_layout_and_band_hint(small_sensor, small_scene):
    c = small_scene
    ref = eoir.run(small_sensor, c, seed=6, calibrate=False)
    bip = np.ascontiguousarray(np.moveaxis(c.radiance, 0, -1))  # SPy [row, col, band]
    with pytest.raises(ValueError, match=r'layout="row,col,band"'):
        eoir.run(small_sensor, bip, c.wavelength_um, c.fov_deg)
    r = eoir.run(small_sensor, bip, c.wavelength_um, c.fov_deg, seed=6, calibrate=False,
                 range_m=c.range_m, layout="row,col,band")
    np.testing.assert_array_equal(r.dn.values, ref.dn.values)
    with pytest.raises(ValueError, match="layout"):
        eoir.run(small_sensor, bip, c.wavelength_um, c.fov_deg, layout="row,band")


def test_xarray_input_dims_and_wavelength_units_kept(small_sensor, small_scene):
    xr = pytest.importorskip("xarray")
    c = small_scene
    da = xr.DataArray(c.radiance, dims=("wavelength", "y", "x"),
                      coords={"wavelength": ("wavelength", c.wavelength_um * 1000.0, {"units": "nm"})},
                      attrs={"fov_deg": c.fov_deg, "range_m": c.range_m})
    ds = eoir.run(small_sensor, da, seed=9)
    assert ds.dn.dims == ("y", "x") and ds.y.attrs["units"] == "mrad"
    ref = eoir.run(small_sensor, c, seed=9)
    np.testing.assert_array_equal(ds.dn.values, ref.dn.values)
    # A Cube's own DataArray round-trips.
    np.testing.assert_array_equal(eoir.run(small_sensor, c.to_xarray(), seed=9).dn.values, ref.dn.values)
    # Sequences keep a frame dimension with the sequence index.
    seq = eoir.run(small_sensor, c, seed=9, frames=2, first_frame=3, calibrate=False)
    assert seq.dn.dims == ("frame", "row", "col") and list(seq.frame.values) == [3, 4]
