"""The analysis toolbox: restoration, slanted-edge MTF, NUC, EMVA 1288.

Each function makes the library calls its CLI command makes (``eoir restore``, ``eoir
edge-mtf``, ``eoir nuc fit``/``apply``, ``eoir characterize``) on arrays instead of
files; the test suite checks the results against the CLI's files bit for bit.
"""

import json
import os
from typing import Optional, Sequence

import numpy as np

from . import _checks, _eoir, _xr
from ._eoir import Nuc, Sensor


def read_image(path) -> np.ndarray:
    """Read a single-plane image file as the CLI's analysis commands read it.

    Parameters
    ----------
    path : str or os.PathLike
        A 16-bit greyscale PNG or TIFF (DN) or a 32-bit float TIFF.

    Returns
    -------
    numpy.ndarray
        uint16 (DN) or float32 ``[row, col]``.
    """
    return _eoir.read_image(os.fspath(path))


def _image_input(image, name="image"):
    """(values, dims, is_dn, units attr, source name) of an image given as an array, a
    DataArray, a one-frame run Dataset (its ``dn``) or a file path."""
    dims, units, source = ("row", "col"), None, "numpy array"
    if isinstance(image, (str, os.PathLike)):
        source = os.fspath(image)
        image = read_image(image)
    elif _xr.is_dataset(image):
        if "dn" not in image:
            raise ValueError(f"invalid parameter `{name}`: a Dataset with a `dn` variable (a run's products)")
        image = image["dn"]
    if _xr.is_dataarray(image):
        dims = tuple(image.dims)
        units = image.attrs.get("units")
        image = image.values
    arr = np.asarray(image)
    if np.iscomplexobj(arr):
        raise TypeError(f"invalid parameter `{name}`: complex values; a real image is expected")
    if arr.dtype.kind not in "biuf":
        raise TypeError(f"invalid parameter `{name}`: an array of numbers, not dtype {arr.dtype}")
    if arr.ndim != 2:
        raise ValueError(
            f"invalid parameter `{name}` = array of shape {arr.shape}: one image [row, col] "
            "(for a sequence pick a frame, e.g. ds.dn.isel(frame=0))"
        )
    is_dn = arr.dtype.kind in "biu"
    if is_dn and arr.size and (arr.min() < 0 or arr.max() > 65535):
        raise ValueError(f"invalid parameter `{name}`: integer DN must lie in 0 to 65535")
    return np.ascontiguousarray(arr, dtype=np.float64), dims, is_dn, units, source


def restore(
    sensor: Sensor,
    image,
    *,
    noise: str = "auto",
    nsr: Optional[float] = None,
    black_level: Optional[float] = None,
    units: str = "electrons",
):
    """Wiener restoration of a recorded image with the sensor's transfer function
    (``eoir restore``).

    Parameters
    ----------
    sensor : Sensor
        The sensor that recorded the image (its size must match).
    image : numpy.ndarray, xarray.DataArray, xarray.Dataset or path
        Integer DN (e.g. a run's ``dn``, uint16) or float values (electrons or radiance,
        see ``units``); a run's Dataset gives its ``dn``; a path is read with
        :func:`read_image`.
    noise : {"auto", "model"}, default "auto"
        Noise-to-signal rule: ``auto`` (noise power from the frequencies the optics do not
        pass, FOI §3.6) or ``model`` (the sensor's shot, read and quantisation noise).
    nsr : float, optional
        A constant noise-to-signal power ratio instead of ``noise``.
    black_level : float, optional
        Black level of a DN image, DN (default: the model's offset plus dark and
        background signal).
    units : {"electrons", "radiance"}, default "electrons"
        What a float image holds (``noise="model"`` needs electrons).

    Returns
    -------
    xarray.Dataset
        ``restored`` (float32, what ``restored.tiff`` holds; units of the input) on the
        input's image dims with angular coordinates (mrad); attrs the options, the sensor,
        ``report`` (what ``restore.json`` holds).
    """
    values, dims, is_dn, _, source = _image_input(image)
    d = _eoir.restore(
        sensor, values, is_dn, str(noise), _checks.real("nsr", nsr),
        _checks.real("black_level", black_level), str(units), source,
    )
    report = json.loads(d["report_json"])
    attrs = _xr.base_attrs(sensor)
    attrs.update({
        "noise": report["noise_rule"],
        "input_units": report["units"],
        "pixels_replaced": report["pixels_replaced"],
        "report": report,
    })
    if nsr is not None:
        attrs["nsr"] = float(nsr)
    if report["black_level_dn"] is not None:
        attrs["black_level_dn"] = report["black_level_dn"]
    return _xr.image_dataset(
        {"restored": (d["restored"], report["units"], "Wiener-restored image")},
        dims, sensor.ifov_rad, attrs,
    )


def restore_sequence(
    path_or_array,
    sensor: Optional[Sensor] = None,
    *,
    upsample: int = 2,
    register: str = "phase",
    noise: str = "auto",
    nsr: Optional[float] = None,
    black_level: Optional[float] = None,
):
    """Multi-frame restoration of a sequence (``eoir restore DIR``): register the frames,
    shift-and-add them onto a grid ``upsample`` times finer, Wiener-restore with the
    sensor's transfer function on that grid (docs/multi-frame.md).

    Parameters
    ----------
    path_or_array : str, os.PathLike, numpy.ndarray or sequence of 2-D arrays
        An eoir sequence output folder (its ``dn_stack.npy``, ``config.toml`` and
        ``los.csv``), a ``.npy`` stack, or frames of DN ``[frame, row, col]``.
    sensor : Sensor, optional
        The recording sensor (default: a folder's own ``config.toml``).
    upsample : int, default 2
        The fine grid's factor R (1 to 8).
    register : {"phase", "truth"}, default "phase"
        Phase correlation, or the folder's ``los.csv`` truth table.
    noise : {"auto", "model"}, default "auto"
        ``auto``: the scatter of the samples within the fine cells; ``model``: the
        sensor's temporal noise. ``nsr`` gives a constant instead.
    nsr : float, optional
        A constant noise-to-signal power ratio instead of ``noise``.
    black_level : float, optional
        The DN of zero signal (default: the sensor model's dark level).

    Returns
    -------
    dict
        ``restored`` (float32 ``[R·rows, R·cols]``, DN) and ``report`` (restore.json's
        fields).
    """
    truth = None
    if isinstance(path_or_array, (str, os.PathLike)):
        path = os.fspath(path_or_array)
        folder = path if os.path.isdir(path) else os.path.dirname(path) or "."
        stack_path = os.path.join(path, "dn_stack.npy") if os.path.isdir(path) else path
        if not os.path.isfile(stack_path):
            raise ValueError(f"{path}: no dn_stack.npy (not an eoir sequence output folder)")
        frames = np.load(stack_path)
        if sensor is None:
            config = os.path.join(folder, "config.toml")
            if not os.path.isfile(config):
                raise ValueError(f"{path}: no config.toml beside the stack; give `sensor`")
            from ._core import load_sensor
            sensor = load_sensor(config)
        los = os.path.join(folder, "los.csv")
        if os.path.isfile(los):
            table = np.genfromtxt(los, delimiter=",", names=True)
            table = np.atleast_1d(table)
            truth = [(float(x - table["dx_px"][0]), float(y - table["dy_px"][0]))
                     for x, y in zip(table["dx_px"], table["dy_px"])]
    else:
        if isinstance(path_or_array, np.ndarray):
            frames = path_or_array
        else:
            shapes = {np.shape(f) for f in path_or_array}
            if len(shapes) > 1:
                raise ValueError(
                    f"invalid parameter `frames`: frames of different sizes {sorted(shapes)}; "
                    "a sequence needs frames of one size"
                )
            frames = np.stack([np.asarray(f) for f in path_or_array]) if shapes else np.zeros((0, 0, 0))
    if sensor is None:
        raise ValueError("invalid parameter `sensor`: None; give the sensor that recorded the frames")
    frames = np.asarray(frames)
    if frames.ndim != 3:
        raise ValueError(f"invalid parameter `frames` = array of shape {frames.shape}: [frame, row, col]")
    if register not in ("phase", "truth"):
        raise ValueError(f"invalid parameter `register` = {register!r}: \"phase\" or \"truth\"")
    shifts = None
    if register == "truth":
        if truth is None:
            raise ValueError("register=\"truth\" needs an eoir sequence folder with los.csv")
        if len(truth) != frames.shape[0]:
            raise ValueError(
                f"los.csv: {len(truth)} lines for {frames.shape[0]} frames; register=\"truth\" "
                "needs one line per frame (a global shutter)"
            )
        shifts = truth
    if isinstance(upsample, bool) or int(upsample) != upsample or upsample < 0:
        raise ValueError(f"invalid parameter `upsample` = {upsample!r}: an integer from 1 to 8")
    d = _eoir.restore_sequence(
        sensor, np.ascontiguousarray(frames, dtype=np.float64), shifts, int(upsample),
        str(noise), _checks.real("nsr", nsr), _checks.real("black_level", black_level),
    )
    report = json.loads(d["report_json"])
    if truth is not None and len(truth) == len(report["shifts_px"]):
        res = [max(abs(e[0] - t[0]), abs(e[1] - t[1])) for e, t in zip(report["shifts_px"], truth)]
        report["shift_residual_vs_truth_max_px"] = max(res)
    return {"restored": d["restored"], "report": report}


def edge_mtf(image, *, roi: Optional[Sequence[int]] = None, sensor: Optional[Sensor] = None):
    """ISO 12233 slanted-edge MTF of an image (``eoir edge-mtf``).

    Parameters
    ----------
    image : numpy.ndarray, xarray.DataArray, xarray.Dataset or path
        An image with a straight edge tilted 2–45° from the rows or columns (DN or float;
        a run's Dataset gives its ``dn``, a restore's Dataset its ``restored``).
    roi : (x, y, width, height), optional
        Region of interest, pixels (top-left corner and size); default the whole image.
    sensor : Sensor, optional
        The sensor that recorded it: adds frequencies in cycles/mrad.

    Returns
    -------
    xarray.Dataset
        ``mtf`` over ``freq`` (coordinate ``freq`` in cycles/pixel, and
        ``freq_cy_per_mrad`` with a sensor), ``esf`` (edge spread function, 4× oversampled,
        over ``esf_sample``); attrs ``mtf50_cy_per_px``, ``mtf50_cy_per_mrad``,
        ``mtf_at_nyquist``, ``edge_angle_deg``, ``edge_orientation``, ``report`` (what
        ``edge_mtf.json`` holds).
    """
    if _xr.is_dataset(image) and "restored" in image:
        image = image["restored"]
    values, _, _, _, source = _image_input(image)
    r = None
    if roi is not None:
        try:
            r = tuple(_checks.uint("roi", v) for v in roi)
        except TypeError:
            raise TypeError(f"invalid parameter `roi` = {roi!r}: (x, y, width, height) integers") from None
        if len(r) != 4:
            raise ValueError(f"invalid parameter `roi` = {roi!r}: (x, y, width, height)")
    d = _checks.native(_eoir.edge_mtf, values, r, sensor, source)
    report = json.loads(d["report_json"])
    xr = _xr.xarray()
    coords = {"freq": xr.Variable("freq", d["freq_cy_per_px"],
                                  attrs={"units": "cycles/pixel", "long_name": "spatial frequency along the edge normal"})}
    if sensor is not None:
        coords["freq_cy_per_mrad"] = xr.Variable(
            "freq", d["freq_cy_per_px"] / (sensor.ifov_rad * 1e3),
            attrs={"units": "cycles/mrad", "long_name": "angular frequency in object space"})
    attrs = {k: v for k, v in report.items() if v is not None and not isinstance(v, dict)}
    attrs.update({"eoir_version": _eoir.__version__, "report": report})
    if sensor is not None:
        attrs.update(_xr.base_attrs(sensor))
    return xr.Dataset(
        {
            "mtf": xr.Variable("freq", d["mtf"], attrs={"units": "1", "long_name": "modulation transfer function"}),
            "esf": xr.Variable("esf_sample", d["esf"], attrs={"long_name": "edge spread function (4x oversampled)"}),
        },
        coords=coords,
        attrs=attrs,
    )


def nuc_fit(frames, temperatures_k: Sequence[float], degree: int = 1) -> Nuc:
    """Fit per-pixel NUC polynomials and a bad-pixel map from blackbody frames
    (``eoir nuc fit``; FOI report §4.1, eq. 4.1–4.3).

    Parameters
    ----------
    frames : array-like or sequence of paths
        DN frames ``[N, row, col]`` (integers), or N image files (16-bit PNG/TIFF): N/T
        consecutive frames per temperature, in the order of ``temperatures_k``.
    temperatures_k : sequence of float
        Blackbody temperatures, K, distinct, finite, > 0; at least ``degree + 1``.
    degree : int, default 1
        Polynomial degree (1 = two-point gain/offset; 0 to 8).

    Returns
    -------
    Nuc
        Coefficients and bad-pixel map; :meth:`Nuc.save` writes the files ``eoir nuc
        fit`` writes, :func:`nuc_apply` corrects an image.
    """
    if isinstance(frames, (list, tuple)) and frames and isinstance(frames[0], (str, os.PathLike)):
        frames = np.stack([read_image(p) for p in frames])
    if _xr.is_dataarray(frames):
        frames = frames.values
    arr = np.asarray(frames)
    if np.iscomplexobj(arr) or arr.dtype.kind not in "biuf":
        raise TypeError(f"invalid parameter `frames`: real DN frames, not dtype {arr.dtype}")
    if arr.ndim != 3:
        raise ValueError(f"invalid parameter `frames` = array of shape {arr.shape}: [N, row, col]")
    temps = _checks.float_list(temperatures_k, "temperatures_k")
    return _checks.native(
        _eoir.nuc_fit, np.ascontiguousarray(arr, dtype=np.float64), temps, _checks.uint("degree", degree)
    )


def find_rts_pixels(stack, threshold_sigma: float = 4.0, min_frames: int = 3,
                    remove_frame_median: bool = True) -> dict:
    """The random telegraph (RTS) pixels of a dark sequence (``eoir rts``;
    docs/focal-plane.md).

    Parameters
    ----------
    stack : array-like
        ``[frame, row, col]`` DN or electrons (e.g. a run's ``dn_stack.npy``).
    threshold_sigma : float, default 4
        Minimum separation of the two levels in pooled within-level standard deviations.
    min_frames : int, default 3
        Minimum number of frames in each level.
    remove_frame_median : bool, default True
        Subtract each frame's median first (removes common-mode offsets).

    Returns
    -------
    dict of numpy.ndarray
        ``row``, ``col``, ``step`` (high minus low level, the stack's unit),
        ``high_fraction`` and ``separation_sigma``, one entry per pixel found.
    """
    arr = np.asarray(stack.values if _xr.is_dataarray(stack) else stack)
    if np.iscomplexobj(arr) or arr.dtype.kind not in "biuf":
        raise TypeError(f"invalid parameter `stack`: real values, not dtype {arr.dtype}")
    if arr.ndim != 3:
        raise ValueError(f"invalid parameter `stack` = array of shape {arr.shape}: [frame, row, col]")
    d = _checks.native(
        _eoir.find_rts_pixels, np.ascontiguousarray(arr, dtype=np.float64),
        float(threshold_sigma), _checks.uint("min_frames", min_frames), bool(remove_frame_median),
    )
    return {k: np.asarray(v) for k, v in d.items()}


def nuc_apply(nuc, image):
    """Correct an image with NUC coefficients (``eoir nuc apply``).

    Parameters
    ----------
    nuc : Nuc or path
        From :func:`nuc_fit`, or the ``.json``/``.npy`` ``eoir nuc fit`` wrote.
    image : numpy.ndarray, xarray.DataArray, xarray.Dataset or path
        DN image of the NUC's size.

    Returns
    -------
    xarray.Dataset
        ``corrected`` (float64; ``eoir nuc apply`` writes it to a .tiff as float32) on the
        input's image dims; attrs ``degree``, ``bad_pixels_replaced``.
    """
    if not isinstance(nuc, Nuc):
        nuc = Nuc.load(os.fspath(nuc))
    values, dims, _, _, _ = _image_input(image)
    out = _eoir.nuc_apply(nuc, values)
    xr = _xr.xarray()
    return xr.Dataset(
        {"corrected": xr.Variable(dims, out, attrs={"units": "DN", "long_name": "NUC-corrected image"})},
        attrs={"degree": nuc.degree, "bad_pixels_replaced": int(nuc.bad_pixels.sum()),
               "eoir_version": _eoir.__version__},
    )


def characterize(acquisition_set, output=None) -> dict:
    """EMVA 1288 analysis of an acquisition set (``eoir characterize SET``).

    Parameters
    ----------
    acquisition_set : str or os.PathLike
        A directory holding ``descriptor.txt``, or the descriptor file (EMVA 1288
        reference-implementation format), e.g. one :func:`simulate_acquisition_set` wrote.
    output : str or os.PathLike, optional
        Also write the datasheet there (``characterization.json``, the HTML datasheet and
        its plots), as the CLI does.

    Returns
    -------
    dict
        The characterisation (``characterization.json``'s fields: ``K_DN_per_e``,
        ``QE_percent``, ``sigma_d_e``, ``DSNU1288_e``, ``PRNU1288_percent``,
        ``u_e_sat_e``, ``DR_dB``, ...).
    """
    return json.loads(_eoir.characterize(os.fspath(acquisition_set),
                                         None if output is None else os.fspath(output)))


def simulate_acquisition_set(sensor: Sensor, output, seed: int = 1, window: int = 128) -> dict:
    """Write a simulated EMVA 1288 acquisition set for a sensor
    (``eoir characterize --simulate``).

    Parameters
    ----------
    sensor : Sensor
    output : str or os.PathLike
        Directory to write (``descriptor.txt``, the images, ``truth.json``).
    seed : int, default 1
        Seed of the simulated sensor instance and its temporal noise.
    window : int, default 128
        Side of the simulated pixel window.

    Returns
    -------
    dict
        The configured truth (``truth.json``): ``K_DN_per_e``, ``QE_percent``,
        ``sigma_d_e``, ...
    """
    return json.loads(_checks.native(
        _eoir.simulate_acquisition_set, sensor, os.fspath(output),
        _checks.uint("seed", seed), _checks.uint("window", window),
    ))


def assess(sensor: Sensor, *, seed: int = 1, temperature_k: float = 300.0, frames: int = 32,
           window: int = 64, target=None, ranges_km=None, elevation_deg: float = 90.0,
           analytic_only: bool = False) -> dict:
    """The figures of merit of a sensor (``eoir assess``): NETD, MTF50, MTF at Nyquist, RER,
    3-D noise, MRTD (thermal), GIQE 5 NIIRS (reflective) and TTP range performance,
    analytic and, unless ``analytic_only``, measured on frames the same model simulates.

    Parameters
    ----------
    sensor : Sensor
    seed : int, default 1
        Seed of the simulated frames.
    temperature_k : float, default 300
        Blackbody temperature of the noise measurements.
    frames : int, default 32
        Frames of the simulated 3-D noise sequence.
    window : int, default 64
        Side of the square detector window (pixels) the measurements simulate.
    target : dict, optional
        ``size_m`` (2.3), ``delta_t_k`` (2.0), ``contrast`` (0.3), ``sct_k``,
        ``extinction_per_km`` (default: the sensor's atmosphere); unknown keys raise.
    ranges_km : sequence of float, optional
        Ranges of the range curves (default 40 from 0.5 to 20 km), strictly increasing.
    elevation_deg : float, default 90
        Elevation of the line of sight for GIQE's ground sample distance.
    analytic_only : bool, default False
        Skip the simulations.

    Returns
    -------
    dict
        ``assess.json``'s fields: ``analytic`` (``netd_k``, ``mtf50_cy_per_px``, ``rer``,
        ``noise3d``, ``mrtd``, ``niirs``, ``ctf_sys_h``, ``tasks`` with ``range_p50_m`` …)
        and ``measured`` (or None).
    """
    t = None
    if target is not None:
        known = {"size_m": 2.3, "delta_t_k": 2.0, "contrast": 0.3, "sct_k": None,
                 "extinction_per_km": None}
        target = dict(target)
        unknown = set(target) - set(known)
        if unknown:
            raise ValueError(
                f"invalid parameter `target`: unknown key(s) {sorted(unknown)}; "
                f"valid: {', '.join(known)}")
        sct = target.get("sct_k")
        ext = target.get("extinction_per_km")
        t = (float(target.get("size_m", 2.3)), float(target.get("delta_t_k", 2.0)),
             float(target.get("contrast", 0.3)), None if sct is None else float(sct),
             None if ext is None else float(ext))
    ranges_m = None if ranges_km is None else [1000.0 * float(r) for r in ranges_km]
    return json.loads(_checks.native(
        _eoir.assess, sensor, _checks.uint("seed", seed), float(temperature_k),
        _checks.uint("frames", frames), _checks.uint("window", window), t, ranges_m,
        float(elevation_deg), bool(analytic_only),
    ))

