"""A third-party radiance cube through three sensors, with pictures.

What a scientist with a cube from another tool (CAMEO-SIM, DIRSIG, MODTRAN-driven
renderers, a Spectral Python array) does first: write or read the cube, check its field
covers each sensor, run it through a visible camera, an MWIR and an LWIR imager, and look.

The cube here is made in the script: a 300 K ground with a 318 K vehicle and a cool sky
band, emission from Planck's law plus reflected sunlight, 0.4–12 µm, stored as an ENVI
file the way AVIRIS-style tools write one (band-interleaved-by-pixel, wavelengths in
nanometres, radiance in µW cm⁻² sr⁻¹ nm⁻¹). Replace ``make_envi_cube`` with your own file.

Run: python examples/python/third_party_cube.py [OUTDIR]   (default: a temporary folder)
"""

import sys
import tempfile
from pathlib import Path

import numpy as np

import eoir

H, C, KB = 6.62607015e-34, 2.99792458e8, 1.380649e-23


def planck_um(wl_um, t_k):
    """Blackbody spectral radiance, W m-2 sr-1 µm-1 (Planck's law)."""
    wl = wl_um[:, None, None] * 1e-6
    return 2 * H * C**2 / wl**5 / np.expm1(H * C / (wl * KB * t_k)) * 1e-6


def make_envi_cube(folder: Path, field_mrad=(30.0, 22.5), samples=(240, 180)) -> Path:
    """Writes scene.hdr + scene.bip as a third-party tool would, returns the header path."""
    cols, rows = samples
    wl_um = np.round(np.arange(0.40, 12.0001, 0.10), 3)
    y, x = np.mgrid[0:rows, 0:cols]
    t = np.full((rows, cols), 300.0) + 2.0 * np.sin(x / 17.0) * np.cos(y / 23.0)
    t[y < rows * 0.25] = 260.0                       # sky band
    vehicle = (abs(x - cols * 0.55) < cols * 0.12) & (abs(y - rows * 0.6) < rows * 0.08)
    t[vehicle] = 318.0  # warm, inside the MWIR camera's range at its preset integration time
    emissivity = np.where(vehicle, 0.9, 0.95)
    # Emission plus reflected sunlight (a 5800 K blackbody diluted by the solar solid angle).
    sun = planck_um(wl_um, np.full((1, 1), 5800.0)) * 6.8e-5 / np.pi
    radiance = emissivity * planck_um(wl_um, t) + (1 - emissivity) * 0.3 * sun
    # AVIRIS units: 1 W m-2 sr-1 µm-1 = 0.1 µW cm-2 sr-1 nm-1.
    bip = np.ascontiguousarray(np.moveaxis(radiance * 0.1, 0, -1), dtype="<f4")  # [row, col, band]
    bip.tofile(folder / "scene.bip")
    h_deg, v_deg = np.degrees(np.array(field_mrad) * 1e-3)
    header = [
        "ENVI", f"samples = {cols}", f"lines = {rows}", f"bands = {len(wl_um)}",
        "header offset = 0", "data type = 4", "interleave = bip", "byte order = 0",
        "wavelength units = Nanometers",
        "wavelength = {" + ", ".join(f"{w * 1000:.1f}" for w in wl_um) + "}",
        "radiance units = uW cm-2 sr-1 nm-1",
        f"fov = {{{h_deg:.6f}, {v_deg:.6f}}}",
    ]
    (folder / "scene.hdr").write_text("\n".join(header) + "\n")
    return folder / "scene.hdr"


def sensor_covering(name, field_deg, options=None):
    """A preset with its detector cut to the pixels the cube's field covers (whole
    pixels, 4 pixels of margin each side): same optics, pitch and electronics."""
    s = eoir.load_sensor(name, options=options)
    ifov_deg = np.degrees(s.ifov_rad)
    cols = int(field_deg[0] / ifov_deg) - 8
    rows = int(field_deg[1] / ifov_deg) - 8
    return eoir.load_sensor(name, options=options,
                            overrides={"detector.cols": cols, "detector.rows": rows})


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    cube = eoir.read_cube(make_envi_cube(out))
    print("vehicle 318 K with emissivity 0.9 on 300 K ground: its apparent temperature is lower\n"
          "(emissivity, blur over the small target, the sensor's path and spectral band)")
    print(f"cube {cube.radiance.shape} bands×rows×cols, {cube.wavelength_um[0]:.2f}–"
          f"{cube.wavelength_um[-1]:.2f} µm, field {cube.fov_deg[0]:.3f}° × {cube.fov_deg[1]:.3f}°")
    results = {}
    for name, options in (("ccd", None), ("multimir", None), ("qwip", None)):
        s = sensor_covering(name, cube.fov_deg, options)
        need = s.scene_extent_deg(margin_px=0)
        assert cube.fov_deg[0] >= need[0] and cube.fov_deg[1] >= need[1]
        ds = eoir.run(s, cube, seed=1)
        results[name] = ds
        lo, hi = s.band_um
        print(f"{name:9s} {s.cols:3d}×{s.rows:3d} px, IFOV {s.ifov_rad * 1e3:.3f} mrad, band "
              f"{lo:.2f}–{hi:.2f} µm: mean {float(ds.dn.mean()):.0f} DN"
              + (f", hottest pixel {float(ds.temperature.max()):.1f} K apparent" if "temperature" in ds else ""))
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no pictures (pip install matplotlib)")
        return
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), constrained_layout=True)
    for ax, (name, ds) in zip(axes, results.items()):
        img = ds.temperature if "temperature" in ds else ds.dn
        x, y = ds.col.values, ds.row.values
        m = ax.imshow(img, cmap="inferno" if "temperature" in ds else "gray",
                      extent=(x[0], x[-1], y[-1], y[0]), interpolation="nearest")
        ax.set_title(f"{name} ({ds.attrs['sensor_options'] or 'default'})")
        ax.set_xlabel("angle (mrad)")
        ax.set_ylabel("angle (mrad)")
        label = "apparent temperature (K)" if "temperature" in ds else "signal (DN)"
        fig.colorbar(m, ax=ax, label=label, shrink=0.85)
    fig.savefig(out / "three_sensors.png", dpi=110)
    print(f"wrote {out / 'three_sensors.png'}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="eoir-cube-")))
