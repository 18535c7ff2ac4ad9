"""A characterisation walk: simulate an EMVA 1288 acquisition set for a camera model,
analyse it as a lab would analyse a real camera's, and compare with what was configured.

The same analysis reads a real camera's set (a folder with the reference
implementation's ``descriptor.txt``): replace the simulated folder with yours.

Run: python examples/python/characterization.py [OUTDIR]   (default: a temporary folder)
"""

import sys
import tempfile
from pathlib import Path

import eoir


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    # The CCD preset with a read noise, offset pattern and gain pattern of a few DN, so
    # that every line of the datasheet has something to measure.
    sensor = eoir.load_sensor("ccd", overrides={
        "detector.read_noise_e": 60.0, "detector.fpn.dsnu_sigma_e": 40.0,
        "detector.fpn.prnu_sigma_rel": 0.01, "detector.offset_dn": 40})
    acquisition = Path(tempfile.mkdtemp(dir=out, prefix="acquisition-"))  # a new, empty folder
    truth = eoir.simulate_acquisition_set(sensor, acquisition, seed=1, window=64)
    c = eoir.characterize(acquisition, output=out / "datasheet")
    print(f"{sensor.name}: EMVA 1288 set of {truth['window'][0]}×{truth['window'][1]} px at "
          f"λ0 = {truth['wavelength_um']:.3f} µm")
    print(f"{'':22s}{'configured':>12s}{'measured':>12s}")
    rows = [
        ("gain K (DN/e⁻)", "K_DN_per_e", "K_DN_per_e", "{:.4f}"),
        ("QE (%)", "QE_percent", "QE_percent", "{:.1f}"),
        ("dark noise σd (e⁻)", "sigma_d_e", "sigma_d_e", "{:.2f}"),
        ("DSNU (e⁻)", "DSNU1288_e", "DSNU1288_e", "{:.2f}"),
        ("PRNU (%)", "PRNU1288_percent", "PRNU1288_percent", "{:.2f}"),
        ("saturation (e⁻)", "u_e_sat_e", "u_e_sat_e", "{:.0f}"),
    ]
    for label, t_key, c_key, fmt in rows:
        measured = c.get(c_key)
        print(f"{label:22s}{fmt.format(truth[t_key]):>12s}"
              f"{(fmt.format(measured) if measured is not None else '—'):>12s}")
    print(f"dynamic range {c['DR_dB']:.1f} dB; datasheet in {out / 'datasheet'}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="eoir-emva-")))
