#!/usr/bin/env python3
"""The plain NumPy/SciPy imaging script eoir is benchmarked against (BENCHMARKS.md).

Per band: mirror-pad, scipy.fft.rfft2 (all workers), multiply by the system OTF times the
band's spectral weight, irfft2, crop, sum; float64. The OTF is the same cascade as the
engine's (obscured aperture, Shannon aberration, defocus, detector footprint, jitter,
linear smear, horizontal turbulence, aerosol, Gaussian), evaluated directly with NumPy;
its parameters, the spectral weights and the padded frame size come from the JSON file
written by `cargo run --release --example bench_run`.

usage: baseline.py PARAMS.json CUBE.img   (prints wall seconds and peak RSS in MiB)
       baseline.py rfft2 ROWS COLS REPEATS  (median seconds of one scipy.fft.rfft2 of a
                                             ROWS x COLS frame, all workers, in float32
                                             and float64)
"""
import json
import resource
import sys
import time

import numpy as np
import scipy.fft
from scipy.special import j1


def obscured(x, r):
    x = np.minimum(np.abs(x), 1.0)
    a = 2 / np.pi * (np.arccos(x) - x * np.sqrt(1 - x * x))
    if r <= 0:
        return a
    y = np.minimum(x / r, 1.0)
    b = np.where(x <= r, 2 * r * r / np.pi * (np.arccos(y) - y * np.sqrt(1 - y * y)), 0.0)
    arg = np.clip((1 + r * r - 4 * x * x) / (2 * r), -1, 1)
    al = np.arccos(arg)
    cm = (2 * r / np.pi * np.sin(al) + (1 + r * r) / np.pi * al
          - 2 * (1 - r * r) / np.pi * np.arctan((1 + r) / (1 - r) * np.tan(al / 2)) - 2 * r * r)
    c = np.where(x <= (1 - r) / 2, -2 * r * r, np.where(x < (1 + r) / 2, cm, 0.0))
    return (a + b + c) / (1 - r * r)


def otf(p, fy, fx, lam_um):
    lam = lam_um * 1e-6
    rho = np.hypot(fy, fx)
    x = rho * lam / p["aperture_m"]
    inside = x < 1
    xc = np.minimum(x, 1.0)
    t = obscured(xc, p["obscuration"]) * inside
    k = p["w_rms_waves"] / 0.18
    t *= np.maximum(1 - k * k * (1 - 4 * (xc - 0.5) ** 2), 0)
    a = 8 * np.pi * p["w020_waves"] * xc * (1 - xc)
    with np.errstate(invalid="ignore", divide="ignore"):
        t *= np.where(np.abs(a) < 1e-6, 1 - a * a / 8, 2 * j1(a) / a)
    t *= np.sinc(fx * p["active_m"] / p["focal_m"]) * np.sinc(fy * p["active_m"] / p["focal_m"])
    d = p["smear_rad"]
    th = np.radians(p["smear_direction_deg"])
    t *= np.sinc((fx * np.cos(th) + fy * np.sin(th)) * d)
    t *= np.exp(-2 * np.pi ** 2 * (p["jitter_rad"] ** 2 + p["gaussian_rad"] ** 2) * rho ** 2)
    kw = 2 * np.pi / lam
    r0 = (0.423 * kw * kw * p["cn2"] * p["turb_range_m"] * 3 / 8) ** -0.6
    t *= np.exp(-3.44 * (lam * rho / r0) ** (5 / 3))
    fa = p["particle_m"] / lam
    s = np.minimum(rho / fa, 1.0)
    t *= np.exp(-p["absorb_per_m"] * p["aer_range_m"] - p["scatter_per_m"] * p["aer_range_m"] * s * s)
    return t


def time_rfft2(ny, nx, repeats):
    out = {}
    for name, dtype in (("f32", np.float32), ("f64", np.float64)):
        x = (np.arange(ny * nx, dtype=np.int64).reshape(ny, nx) % 101).astype(dtype)
        scipy.fft.rfft2(x, workers=-1)  # plan / warm up
        ts = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            scipy.fft.rfft2(x, workers=-1)
            ts.append(time.perf_counter() - t0)
        out[name] = float(np.median(ts))
    print(json.dumps(out))


def main():
    if sys.argv[1] == "rfft2":
        time_rfft2(int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]))
        return
    p = json.load(open(sys.argv[1]))
    bands, rows, cols = p["bands"], p["rows"], p["cols"]
    cube = np.memmap(sys.argv[2], dtype="<f4", mode="r", shape=(bands, rows, cols))
    ny, nx = p["padded_rows"], p["padded_cols"]
    py, px = p["pad_rows"], p["pad_cols"]
    dy = dx = p["scene_ifov_rad"]
    fy = scipy.fft.fftfreq(ny, dy)[:, None]
    fx = scipy.fft.rfftfreq(nx, dx)[None, :]
    t0 = time.perf_counter()
    img = np.zeros((rows, cols))
    for b in range(bands):
        w = p["weights"][b]
        if w == 0:
            continue
        band = np.asarray(cube[b], dtype=np.float64)
        pad = np.pad(band, ((py, ny - rows - py), (px, nx - cols - px)), mode="symmetric")
        spec = scipy.fft.rfft2(pad, workers=-1)
        spec *= w * otf(p, fy, fx, p["wavelength_um"][b])
        out = scipy.fft.irfft2(spec, s=(ny, nx), workers=-1)
        img += out[py:py + rows, px:px + cols]
    k = p["k"]
    det = img[k // 2::k, k // 2::k]
    wall = time.perf_counter() - t0
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps({"wall_s": wall, "peak_rss_mib": rss, "mean_electrons": float(det.mean())}))


if __name__ == "__main__":
    main()
