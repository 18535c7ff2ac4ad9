"""The wavefront pictures from Python (issue 36): `eoir.psf` against the CLI's psf.json bit
for bit and the closed-form image shift of a tilt, `eoir.mtf(field=...)` against the CLI's
`mtf --field` columns and the astigmatism split."""

import csv
import io
import json
import subprocess

import numpy as np
import pytest

import eoir

# A 50 mm aperture (f = 100 mm, F/2), clear, coefficients at 4 µm, evaluated at 4 µm:
# λ/D = 80 µrad.
BASE = {
    "optics.focal_length_m": 0.1,
    "optics.f_number": 2.0,
    "optics.obscuration_ratio": 0.0,
    "optics.wavefront.reference_wavelength_um": 4.0,
}
LAMBDA_OVER_D_URAD = 4e-6 / 0.05 * 1e6


def cli_sets(overrides):
    return [a for k, v in overrides.items() for a in ("--set", f"{k}={v}")]


def test_psf_matches_psf_json_and_the_tilt_shift(cli, tmp_path):
    # Distortion tilt W311 H³ y (Seidel field law): the image moves by 2 W311 H³ λ/D along y,
    # 1/4 λ/D (one sample) at H = 0.5, 2 λ/D at H = 1.
    over = dict(BASE, **{"optics.wavefront.w311_waves": 1.0})
    sensor = eoir.load_sensor("multimir", overrides=over)
    field = [0.0, 0.5, 1.0]
    ds = eoir.psf(sensor, field=field, wavelength_um=4.0, half_width_lambda_over_d=4)
    subprocess.run([cli, "psf", "--sensor", "multimir", *cli_sets(over), "--wavelength-um", "4",
                    "--field", "0,0.5,1", "--half-width-lambda-over-d", "4", "-o", str(tmp_path / "p")],
                   check=True, capture_output=True)
    doc = json.loads((tmp_path / "p" / "psf.json").read_text())
    assert doc["wavelength_um"] == ds.attrs["wavelength_um"] == 4.0
    assert len(doc["fields"]) == ds.sizes["field"] == 3
    for k, f in enumerate(doc["fields"]):
        assert f["field_h"] == ds.field.values[k]
        for name in ("centroid_x_urad", "centroid_y_urad", "fwhm_urad", "strehl", "samples_across_pupil"):
            assert f[name] == ds[name].values[k], (k, name)  # bit for bit (JSON round-trips)

    # ±4 λ/D at λ/(4D): 33 × 33 samples centred on the grid centre.
    assert ds.psf.dims == ("field", "y", "x") and ds.psf.shape == (3, 33, 33)
    assert ds.attrs["psf_sample_urad"] == pytest.approx(LAMBDA_OVER_D_URAD / 4, rel=1e-12)
    np.testing.assert_allclose(ds.y_lambda_over_d.values, np.arange(-16, 17) / 4, rtol=0, atol=1e-15)
    np.testing.assert_allclose(ds.x.values, ds.x_lambda_over_d.values * LAMBDA_OVER_D_URAD * 1e-3,
                               rtol=1e-12)
    for k, h in enumerate(field):
        img = ds.psf.isel(field=k)
        assert float(img.sum()) <= 1.0 + 1e-12
        # Peak on the tilt's shifted image point.
        r, c = np.unravel_index(int(np.argmax(img.values)), img.shape)
        assert float(ds.x_lambda_over_d[c]) == 0.0
        assert float(ds.y_lambda_over_d[r]) == 2.0 * h**3, (h, r)
        # The image is symmetric about its tangential plane (x → −x).
        np.testing.assert_allclose(img.values, img.values[:, ::-1], rtol=0, atol=1e-12 * float(img.max()))
        # Centroid: the pupil-averaged slope 2 W311 H³ λ/D, 2 %.
        want = 2.0 * h**3 * LAMBDA_OVER_D_URAD
        assert float(ds.centroid_y_urad[k]) == pytest.approx(want, rel=0.02, abs=1e-9)
    # Diffraction-limited on axis: Strehl 1, FWHM ≈ 1.03 λ/D (Airy; area-equivalent on the
    # λ/(4D) grid, 5 %).
    assert float(ds.strehl[0]) == pytest.approx(1.0, abs=1e-12)
    assert abs(float(ds.fwhm_urad[0]) / LAMBDA_OVER_D_URAD - 1.029) < 0.05
    # A pure tilt moves the PSF without blurring it.
    np.testing.assert_allclose(ds.strehl.values, 1.0, rtol=0, atol=1e-9)

    with pytest.raises(ValueError, match=r"field.*\[0, 1\]"):
        eoir.psf(sensor, field=1.5, wavelength_um=4.0)
    with pytest.raises(ValueError, match="half_width_lambda_over_d"):
        eoir.psf(sensor, field=0.0, half_width_lambda_over_d=0.5)


def test_mtf_field_matches_cli_and_splits_with_astigmatism(cli, tmp_path):
    over = dict(BASE, **{"optics.wavefront.w222_waves": 0.5})
    sensor = eoir.load_sensor("multimir", overrides=over)
    freq = np.linspace(0.0, 12.5, 51)
    py = eoir.mtf(sensor, freq, wavelength_um=4.0, field=1.0)
    out = subprocess.run([cli, "mtf", "--sensor", "multimir", *cli_sets(over), "--wavelength-um", "4",
                          "--field", "1", "--max-cy-per-mrad", "12.5", "--points", "51", "--csv", "-"],
                         check=True, capture_output=True, text=True).stdout
    rows = list(csv.DictReader(io.StringIO(out)))
    np.testing.assert_allclose([float(r["freq_cy_per_mrad"]) for r in rows], freq, rtol=0, atol=5e-7)
    # To the CSV's printed precision (8 decimals).
    for cli_name, py_name in (("pupil_tangential_H1", "pupil_tangential"),
                              ("pupil_sagittal_H1", "pupil_sagittal"), ("diffraction", "diffraction")):
        np.testing.assert_allclose([float(r[cli_name]) for r in rows], py[py_name], rtol=0, atol=6e-9)
    assert py["field"] == 1.0
    # Astigmatism W222 y² leaves the sagittal section diffraction-limited and lowers the
    # tangential one.
    np.testing.assert_allclose(py["pupil_sagittal"], np.abs(py["diffraction"]), rtol=0, atol=2e-3)
    assert np.max(py["pupil_sagittal"] - py["pupil_tangential"]) > 0.2
    assert "pupil_tangential" not in eoir.mtf(sensor, freq, wavelength_um=4.0)
