"""Sensors, radiance cubes, synthetic scenes and runs."""

import json
from typing import Any, Dict, Mapping, Optional, Sequence, Tuple

import numpy as np

from . import _checks, _eoir, _xr
from ._eoir import Sensor

SPECTRAL_UNITS = "W m-2 sr-1 um-1"
"""Spectral radiance, the default unit of a cube."""

LAYOUT_AXES = {
    "band": "band", "bands": "band", "wavelength": "band", "lambda": "band",
    "row": "row", "rows": "row", "y": "row", "line": "row", "lines": "row",
    "col": "col", "cols": "col", "column": "col", "x": "col", "sample": "col", "samples": "col",
    "frame": "frame", "frames": "frame", "time": "frame", "t": "frame",
}
"""Axis names :func:`run`'s ``layout`` understands (synonyms of band, row, col, frame)."""


def load_sensor(
    name_or_path,
    options: Optional[Mapping[str, Any]] = None,
    overrides: Optional[Mapping[str, Any]] = None,
) -> Sensor:
    """Load a sensor: a built-in preset or a sensor TOML file.

    Parameters
    ----------
    name_or_path : str or os.PathLike
        A preset name (see :func:`presets`: ``"multimir"``, ``"qwip"``, ``"ccd"``, ...) or
        the path of a sensor TOML file. An existing file wins over a preset of that name.
    options : dict, optional
        The preset's alternatives, e.g. ``{"filter": "3", "optics": "15mm"}`` (what
        ``eoir run --option`` sets). Unknown names or values raise ``ValueError`` listing
        the valid ones.
    overrides : dict, optional
        Any field by its dotted key path, e.g. ``{"detector.integration_time_s": 2e-3,
        "jitter.sigma_rad": 1e-5}`` (what ``--set`` sets). Values are Python values (bool,
        int, float, str, list, dict; NumPy scalars and arrays too), never parsed as TOML
        text; keys are dotted paths of letters, digits, ``_`` and ``-``.

    Returns
    -------
    Sensor
        The resolved sensor (spectra sampled, transfer functions built).

    Raises
    ------
    ValueError
        Unknown preset, option, key; impossible values; a malformed file.
    TypeError
        An override value of an unsupported type.
    OSError
        An unreadable file.
    """
    opts = _mapping(options, "options")
    ov = _mapping(overrides, "overrides")
    for k in list(opts) + list(ov):
        if not isinstance(k, str):
            raise TypeError(f"invalid key {k!r}: option and override names are str")
    return _eoir.load_sensor(
        str(name_or_path),
        [f"{k}={v}" for k, v in opts.items()],
        list(ov.items()),
    )


def _mapping(m, name) -> Dict[str, Any]:
    if m is None:
        return {}
    if not isinstance(m, Mapping):
        raise TypeError(
            f"invalid parameter `{name}` = {m!r}: a dict such as "
            + ("{'filter': '4'}" if name == "options" else "{'detector.integration_time_s': 2e-3}")
        )
    return dict(m)


def sensor_from_toml(text: str, base_dir=".") -> Sensor:
    """A sensor from resolved TOML text.

    Parameters
    ----------
    text : str
        A sensor description, e.g. :meth:`Sensor.to_toml` or a run's ``config.toml``.
    base_dir : str or os.PathLike, default "."
        Directory that relative file references in ``text`` resolve against.

    Returns
    -------
    Sensor
    """
    return _eoir.sensor_from_toml(str(text), str(base_dir))


def presets() -> list:
    """The built-in presets.

    Returns
    -------
    list of dict
        ``[{"name", "description", "options": {name: [values]}, "defaults": {name:
        value}}, ...]``.
    """
    return _eoir.presets_info()


class Cube:
    """A spectral radiance cube and its metadata.

    Parameters
    ----------
    radiance : numpy.ndarray
        float32 ``[band, row, col]`` (one frame) or ``[frame, band, row, col]``.
    wavelength_um : sequence of float
        Band centres, µm, strictly increasing.
    fov_deg : (float, float), optional
        Angular extent (horizontal, vertical), degrees, by the paraxial rule: ``n``
        samples spaced ``s`` rad cover ``n·s`` (see :attr:`Sensor.scene_extent_deg`).
    units : str, default "W m-2 sr-1 um-1"
        ``"W m-2 sr-1 um-1"`` (spectral) or ``"W m-2 sr-1"`` (band-integrated).
    range_m : float, optional
        Range to the scene, m.
    fwhm_um : sequence of float, optional
        Band widths, µm.
    frame_time_s : float, optional
        Time between frames, s.
    warnings : sequence of str
        What the reader assumed.
    """

    def __init__(
        self,
        radiance: np.ndarray,
        wavelength_um: Sequence[float],
        fov_deg: Optional[Tuple[float, float]] = None,
        units: str = SPECTRAL_UNITS,
        range_m: Optional[float] = None,
        fwhm_um: Optional[Sequence[float]] = None,
        frame_time_s: Optional[float] = None,
        warnings: Sequence[str] = (),
    ):
        self.radiance = radiance
        self.wavelength_um = np.asarray(wavelength_um, dtype=np.float64)
        self.fov_deg = None if fov_deg is None else (float(fov_deg[0]), float(fov_deg[1]))
        self.units = units
        self.range_m = range_m
        self.fwhm_um = None if fwhm_um is None else np.asarray(fwhm_um, dtype=np.float64)
        self.frame_time_s = frame_time_s
        self.warnings = list(warnings)

    @property
    def frames(self) -> int:
        """Number of frames (1 for a 3-D cube)."""
        return 1 if self.radiance.ndim == 3 else self.radiance.shape[0]

    def to_xarray(self):
        """The cube as an ``xarray.DataArray`` ``(frame?, wavelength, y, x)``.

        Returns
        -------
        xarray.DataArray
            ``wavelength`` coordinate in µm (``units`` attribute), ``y``/``x`` angular
            coordinates in mrad (sample ``j`` of ``n`` at ``(j − (n − 1)/2)·fov/n``) when
            the field of view is known; attrs ``units``, ``fov_deg``, ``range_m``.
            :func:`run` takes it back as it is.
        """
        xr = _xr.xarray()
        dims = (("frame",) if self.radiance.ndim == 4 else ()) + ("wavelength", "y", "x")
        coords = {"wavelength": xr.Variable("wavelength", self.wavelength_um,
                                            attrs={"units": "µm", "long_name": "wavelength"})}
        rows, cols = self.radiance.shape[-2:]
        if self.fov_deg is not None:
            coords.update(_xr.image_coords(("y", "x"), (rows, cols), np.radians(self.fov_deg[0]) / cols))
            coords["y"] = xr.Variable("y", _xr.angles_mrad(rows, np.radians(self.fov_deg[1]) / rows),
                                      attrs=coords["y"].attrs)
        attrs = {"units": self.units, "long_name": "spectral radiance"}
        if self.fov_deg is not None:
            attrs["fov_deg"] = list(self.fov_deg)
        if self.range_m is not None:
            attrs["range_m"] = float(self.range_m)
        return xr.DataArray(self.radiance, dims=dims, coords=coords, attrs=attrs, name="radiance")

    def __repr__(self) -> str:
        return (
            f"<eoir.Cube {tuple(self.radiance.shape)} {self.wavelength_um[0]:.3f}–"
            f"{self.wavelength_um[-1]:.3f} µm, fov {self.fov_deg}, {self.units}>"
        )

    @classmethod
    def _from_dict(cls, d: Dict[str, Any]) -> "Cube":
        return cls(d["radiance"], d["wavelength_um"], d["fov_deg"], d["units"], d["range_m"],
                   d["fwhm_um"], d["frame_time_s"], d["warnings"])


def read_cube(path, radiance_units: Optional[str] = None) -> Cube:
    """Read a radiance cube file, every frame.

    Parameters
    ----------
    path : str or os.PathLike
        ENVI ``.hdr`` (with its data file), spectral OpenEXR ``.exr``, ``.npy`` with its
        ``.json`` sidecar, ``.h5`` (when built with HDF5). Units are converted to eoir's
        (any spelling of docs/importing.md).
    radiance_units : str, optional
        Units to use instead of what the file states (the CLI's ``--radiance-units``),
        e.g. ``"W m-2 sr-1 nm-1"``; needed for a file that states none.

    Returns
    -------
    Cube

    Raises
    ------
    OSError
        A missing or unreadable file.
    ValueError
        A malformed file (the message names the file, field and what is valid).
    """
    return Cube._from_dict(_eoir.read_cube(str(path), None if radiance_units is None else str(radiance_units)))


def write_cube(path, cube, wavelength_um=None, fov_deg=None, units: str = SPECTRAL_UNITS,
               range_m=None, fwhm_um=None) -> None:
    """Write a one-frame cube ``[band, row, col]``, atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; the extension picks the format (``.hdr`` ENVI, ``.exr``, ``.npy``).
    cube : Cube or numpy.ndarray
        A :class:`Cube`, or a real array ``[band, row, col]`` with ``wavelength_um``.
    wavelength_um : sequence of float, optional
        Band centres, µm (with an array).
    fov_deg : (float, float), optional
        Angular extent (horizontal, vertical), degrees.
    units : str, default "W m-2 sr-1 um-1"
        ``"W m-2 sr-1 um-1"`` or ``"W m-2 sr-1"``.
    range_m : float, optional
        Range to the scene, m.
    fwhm_um : sequence of float, optional
        Band widths, µm.
    """
    if isinstance(cube, Cube):
        radiance, wavelength_um = cube.radiance, cube.wavelength_um
        fov_deg, units, range_m, fwhm_um = cube.fov_deg, cube.units, cube.range_m, cube.fwhm_um
    else:
        radiance = cube
        if wavelength_um is None:
            raise ValueError("invalid parameter `wavelength_um` = None: one wavelength (µm) per band")
    _eoir.write_cube(
        str(path),
        _checks.real_array(radiance, "cube"),
        _checks.float_list(wavelength_um, "wavelength_um"),
        None if fov_deg is None else _checks.pair("fov_deg", fov_deg, "(horizontal, vertical) degrees"),
        str(units),
        _checks.real("range_m", range_m),
        None if fwhm_um is None else _checks.float_list(fwhm_um, "fwhm_um"),
    )


class RunResult:
    """The products of ``run(..., as_dataset=False)``: NumPy arrays.

    Attributes
    ----------
    dn : numpy.ndarray
        uint16 ``[row, col]`` (``[frame, row, col]`` for a sequence).
    electrons_mean : numpy.ndarray
        float32, noise-free expected photo-electrons.
    radiance, temperature : numpy.ndarray or None
        In-band radiance (W m-2 sr-1) and apparent temperature (K) for thermal sensors with
        ``calibrate=True``, else None.
    report : dict
        The run report (what ``report.json`` holds).
    config_toml : str
        The resolved sensor.
    warnings : list of str
    line_of_sight : dict of numpy.ndarray or None
        A moving camera's truth table (``los.csv``): ``frame``, ``row_first``, ``row_last``,
        ``t_start_s``, ``t_end_s``, ``dx_px``, ``dy_px``, ``smear_px``; None for a still
        camera.
    focal_plane : dict of numpy.ndarray or None
        The focal plane's truth (docs/focal-plane.md): ``rts_row``, ``rts_col``
        ``[pixel]``, ``rts_high_fraction`` and ``rts_high_at_readout`` ``[frame, pixel]``,
        ``trapped_e``, ``drift_gain``, ``drift_offset_e`` ``[frame, row, col]`` — each only
        when its effect is on; None when the detector has no memory.
    """

    UNITS = {
        "dn": ("DN", "digital numbers"),
        "electrons_mean": ("e-", "expected photo-electrons (mean, noise-free)"),
        "radiance": ("W m-2 sr-1", "in-band radiance (normalised to peak response)"),
        "temperature": ("K", "apparent temperature (blackbody-equivalent)"),
    }

    def __init__(self, d: Dict[str, Any], squeeze: bool):
        def prod(name):
            a = d[name]
            return None if a is None else (a[0] if squeeze else a)

        self.dn = prod("dn")
        self.electrons_mean = prod("electrons_mean")
        self.radiance = prod("radiance")
        self.temperature = prod("temperature")
        self.report = json.loads(d["report_json"])
        self.config_toml = d["config_toml"]
        self.warnings = list(d["warnings"])
        los = d.get("line_of_sight")
        self.line_of_sight = (
            None if los is None else {k: np.asarray(v) for k, v in los.items()}
        )
        fp = d.get("focal_plane")
        self.focal_plane = None if fp is None else {k: np.asarray(v) for k, v in fp.items()}

    def __repr__(self) -> str:
        return f"<eoir.RunResult dn {tuple(self.dn.shape)}, {len(self.warnings)} warnings>"


def _layout_perm(layout, ndim):
    """The transpose taking an array in ``layout`` to ``[frame?, band, row, col]``."""
    names = [p.strip().lower() for p in str(layout).replace("[", "").replace("]", "").split(",")]
    try:
        axes = [LAYOUT_AXES[n] for n in names]
    except KeyError:
        raise ValueError(
            f"invalid parameter `layout` = {layout!r}: axis names separated by commas, e.g. "
            "\"band,row,col\" (the default), \"row,col,band\" (Spectral Python, BIP) or "
            "\"frame,band,row,col\""
        ) from None
    want = (["frame"] if ndim == 4 else []) + ["band", "row", "col"]
    if sorted(axes) != sorted(want):
        raise ValueError(
            f"invalid parameter `layout` = {layout!r}: a {ndim}-D array needs the axes "
            f"{', '.join(want)} each once"
        )
    return [axes.index(a) for a in want]


def _band_hint(shape, nwl):
    """A hint when the wavelengths match another axis than the band axis."""
    if len(shape) >= 3 and shape[-1] == nwl:
        lay = ("frame," if len(shape) == 4 else "") + "row,col,band"
        return (f"; the last axis has {nwl} values: for a [row, col, band] array (Spectral "
                f"Python's layout) pass layout=\"{lay}\"")
    return ""


def run(
    sensor: Sensor,
    radiance,
    wavelength_um=None,
    fov_deg=None,
    seed: int = 1,
    frames: int = 1,
    calibrate: bool = True,
    *,
    layout: Optional[str] = None,
    units: Optional[str] = None,
    range_m: Optional[float] = None,
    nuc_degree: int = 1,
    calibration_temperatures_k=None,
    first_frame: int = 0,
    sequence_frames: Optional[int] = None,
    time_varying: bool = False,
    assess: bool = False,
    unblurred: bool = False,
    as_dataset: bool = True,
):
    """Run radiance through a sensor: what ``eoir run`` computes, without files.

    Parameters
    ----------
    sensor : Sensor
        From :func:`load_sensor`.
    radiance : numpy.ndarray, Cube or xarray.DataArray
        Spectral radiance. A NumPy array is ``[band, row, col]`` or ``[frame, band, row,
        col]`` unless ``layout`` says otherwise (float32 is borrowed, other real dtypes
        converted; complex is refused). A :class:`Cube` brings its wavelengths, field of
        view, units and range. A DataArray needs a ``wavelength`` dimension (or ``band``
        with a ``wavelength`` coordinate; its ``units`` attribute may say nm), two image
        dimensions in any order and optionally ``frame``; its ``fov_deg``, ``range_m`` and
        ``units`` attributes are used; the output keeps its image dimension names.
    wavelength_um : sequence of float, optional
        Band centres, µm, strictly increasing (taken from a Cube or DataArray otherwise).
    fov_deg : (float, float), optional
        The scene's angular extent (horizontal, vertical), degrees, paraxial: at least
        ``sensor.paraxial_fov_deg``; :meth:`Sensor.scene_extent_deg` gives the extent
        with the margin ``eoir scene`` adds. Not the datasheet angle ``sensor.fov_deg``.
    seed : int, default 1
        Seed of every random effect (0 to 2**64 − 1); the same seed gives bit-identical
        products, the CLI's ``eoir run --seed`` included.
    frames : int, default 1
        Expose a one-frame scene this many times (a sequence with independent noise).
    calibrate : bool, default True
        Thermal sensors also return ``radiance`` and ``temperature`` (a simulated
        blackbody calibration and NUC, as ``eoir run``).
    layout : str, optional
        Axis order of a NumPy ``radiance``, e.g. ``"row,col,band"`` for a Spectral Python
        ``[row, col, band]`` array or ``"frame,row,col,band"``; default ``"band,row,col"``
        (``"frame,band,row,col"`` for 4-D). Reordered as a view, not copied.
    units : str, optional
        Units of ``radiance`` in any spelling the file readers accept:
        ``"W m-2 sr-1 um-1"`` (default), ``"W m-2 sr-1 nm-1"``, ``"uW cm-2 sr-1 nm-1"``,
        ``"W/(m2 sr um)"``, ``"W m-2 sr-1"`` (band-integrated); values are scaled to eoir's
        units exactly as a file reader scales them.
    range_m : float, optional
        Range to the scene, m (motion smear and path effects).
    nuc_degree : int, default 1
        Degree of the simulated calibration's NUC polynomial (0 to 8).
    calibration_temperatures_k : sequence of float, optional
        Blackbody levels of the calibration, K (at least two, distinct). Default: the
        sensor file's ``[calibration]`` section, else 10/50/90 % of the sensor's range
        (``eoir run --calibration-temperatures``).
    first_frame : int, default 0
        Index in the whole sequence of this call's first frame: temporal noise is drawn per
        sequence frame, so a sequence run in pieces equals one run.
    sequence_frames : int, optional
        Frames of the whole sequence this call is a piece of (default
        ``first_frame + frames``): a moving camera's random wander is drawn over the whole
        sequence, so pieces agree with one run when each is told the total
        (:func:`eoir.dask.run_frames` does). A moving camera is a sensor with a
        ``[clock]`` and motion (``docs/motion.md``; MultimIR's
        ``sequence="aircraft"`` option drifts 2 px per frame).
    time_varying : bool, default False
        The input is a time-varying (rendered) sequence even when it holds one frame: a
        one-frame piece of a 4-D sequence (:func:`eoir.dask.run_frames` passes it). A
        one-frame input is otherwise a static scene, which a moving camera sweeps over
        frame after frame; a rendered frame already shows the platform's motion.
    assess : bool, default False
        Add the sensor's analytic figures of merit (``eoir run --assess``) to the report
        as ``report["figures_of_merit"]``: the same dict as ``eoir.assess(sensor,
        analytic_only=True)["analytic"]``.
    unblurred : bool, default False
        The unblurred reference ("truth image") of the run (``eoir run --unblurred``):
        the run through :meth:`Sensor.unblurred`, every transfer function off (the
        detector footprint and ``[optics.wavefront]`` included), so each pixel samples
        the scene at its centre; ``report["unblurred"]`` is True.
    as_dataset : bool, default True
        Return an ``xarray.Dataset``; False returns a :class:`RunResult` of NumPy arrays.

    Returns
    -------
    xarray.Dataset
        Variables ``dn`` (uint16), ``electrons_mean`` (float32), and for calibrated thermal
        sensors ``radiance`` and ``temperature``; dims ``(frame?, row, col)`` or the input's
        image dim names, angular coordinates in mrad; attrs ``sensor``,
        ``sensor_options``, ``seed``, ``first_frame``, ``frames``, ``calibrate``,
        ``nuc_degree``, ``input_units``, ``ifov_mrad``, ``eoir_version``, ``config_toml``
        (resolved sensor), ``report`` (dict, ``report.json``), ``warnings``. A moving
        camera adds its truth table (``los.csv``) as variables ``los_frame``,
        ``los_row_first``, ``los_row_last``, ``los_t_start_s``, ``los_t_end_s``,
        ``los_dx_px``, ``los_dy_px``, ``los_smear_px`` over dim ``los_window`` (one per frame,
        or per row of each frame for a rolling shutter); :class:`RunResult` has it as
        ``line_of_sight``, a dict of NumPy arrays (``None`` for a still camera).

    Raises
    ------
    ValueError
        Bad values (shape, wavelengths, field of view smaller than the sensor's, units,
        integers out of range); the message names the parameter.
    TypeError
        Complex or non-numeric radiance; a non-integer seed.
    """
    if unblurred:
        sensor = sensor.unblurred()
    dims, frame_dim, attrs_in = ("row", "col"), None, {}
    if isinstance(radiance, Cube):
        cube = radiance
        radiance = cube.radiance
        wavelength_um = cube.wavelength_um if wavelength_um is None else wavelength_um
        fov_deg = cube.fov_deg if fov_deg is None else fov_deg
        range_m = cube.range_m if range_m is None else range_m
        units = cube.units if units is None else units
    elif _xr.is_dataarray(radiance):
        if layout is not None:
            raise ValueError("invalid parameter `layout`: a DataArray's axes are read from its dims")
        values, wl, dims, frame_dim, attrs_in = _xr.dataarray_input(radiance)
        radiance = values
        wavelength_um = wl if wavelength_um is None else wavelength_um
        fov_deg = attrs_in.get("fov_deg") if fov_deg is None else fov_deg
        range_m = attrs_in.get("range_m") if range_m is None else range_m
        units = attrs_in.get("units") if units is None else units
    data = _checks.real_array(radiance, "radiance")
    if layout is not None:
        if data.ndim not in (3, 4):
            raise ValueError(f"invalid parameter `radiance` = array of {data.ndim} dimensions: 3 or 4")
        data = data.transpose(_layout_perm(layout, data.ndim))
    if wavelength_um is None:
        raise ValueError("invalid parameter `wavelength_um` = None: one wavelength (µm) per band")
    wl = _checks.float_list(wavelength_um, "wavelength_um")
    if data.ndim in (3, 4):
        nb = data.shape[-3]
        if len(wl) != nb:
            raise ValueError(
                f"invalid parameter `wavelength_um` = {len(wl)} values: one per band of "
                f"`radiance`, whose band axis (axis {data.ndim - 3} of shape {tuple(data.shape)}) "
                f"has {nb}{_band_hint(data.shape, len(wl)) if layout is None else ''}"
            )
    if fov_deg is None:
        raise ValueError(
            "invalid parameter `fov_deg` = None: the scene's (horizontal, vertical) angular "
            "extent, degrees (sensor.scene_extent_deg() gives what a scene must cover)"
        )
    fov = _checks.pair("fov_deg", fov_deg, "(horizontal, vertical) degrees")
    seed = _checks.uint("seed", seed)
    frames = _checks.uint("frames", frames)
    first_frame = _checks.uint("first_frame", first_frame)
    if sequence_frames is not None:
        sequence_frames = _checks.uint("sequence_frames", sequence_frames)
    nuc_degree = _checks.uint("nuc_degree", nuc_degree)
    temps = None
    if calibration_temperatures_k is not None:
        temps = _checks.float_list(calibration_temperatures_k, "calibration_temperatures_k")
        if not temps:
            raise ValueError(
                "invalid parameter `calibration_temperatures_k` = []: at least two blackbody "
                "temperatures, K (or None for the default levels)"
            )
    units_text = SPECTRAL_UNITS if units is None else str(units)
    d = _checks.native(
        _eoir.run,
        sensor,
        data,
        wl,
        fov,
        seed,
        frames,
        bool(calibrate),
        nuc_degree,
        first_frame,
        _checks.real("range_m", range_m),
        units_text,
        calibration_temperatures_k=temps,
        sequence_frames=sequence_frames,
        assess=bool(assess),
        time_varying=bool(time_varying),
    )
    squeeze = data.ndim == 3 and frames <= 1
    result = RunResult(d, squeeze)
    if not as_dataset:
        return result
    attrs = _xr.base_attrs(sensor)
    attrs.update({
        "seed": seed,
        "first_frame": first_frame,
        "frames": frames,
        "calibrate": int(bool(calibrate)),
        "nuc_degree": nuc_degree,
        "input_units": units_text,
        "fov_deg": list(fov),
        "config_toml": result.config_toml,
        "report": result.report,
        "warnings": result.warnings,
    })
    if range_m is not None:
        attrs["range_m"] = float(range_m)
    if calibration_temperatures_k is not None:
        attrs["calibration_temperatures_k"] = temps
    variables = {
        name: (getattr(result, name),) + RunResult.UNITS[name]
        for name in ("dn", "electrons_mean", "radiance", "temperature")
    }
    ds = _xr.image_dataset(variables, dims, sensor.ifov_rad, attrs, frame_dim, first_frame)
    if result.line_of_sight is not None:
        units = {"t_start_s": "s", "t_end_s": "s", "dx_px": "px", "dy_px": "px", "smear_px": "px"}
        for k, v in result.line_of_sight.items():
            ds["los_" + k] = _xr.xarray().Variable(
                "los_window", v, attrs={"units": units.get(k, "1")}
            )
    if result.focal_plane is not None:
        fp = result.focal_plane
        frame = frame_dim or "frame"
        for k, v in fp.items():
            if k in ("rts_row", "rts_col"):
                ds[k] = _xr.xarray().Variable("rts_pixel", v)
            elif k.startswith("rts_"):
                ds[k] = _xr.xarray().Variable((frame, "rts_pixel"), v)
            else:
                units = {"trapped_e": "e-", "drift_offset_e": "e-", "drift_gain": "1"}[k]
                ds[k] = _xr.xarray().Variable((frame,) + tuple(dims), v, attrs={"units": units})
    return ds


def mtf(sensor: Sensor, freq_cy_per_mrad, wavelength_um: Optional[float] = None,
        field: Optional[float] = None) -> Dict[str, Any]:
    """The sensor's transfer functions at angular frequencies (``eoir mtf``).

    Parameters
    ----------
    sensor : Sensor
    freq_cy_per_mrad : sequence of float
        Frequencies, cycles/mrad in object space.
    wavelength_um : float, optional
        Wavelength, µm; default the response-weighted mean.
    field : float, optional
        A normalised field height in [0, 1] (``eoir mtf --field``): adds the pupil MTF of
        ``[optics.wavefront]`` (aperture and wavefront only; diffraction-limited without
        the section) at that field height.

    Returns
    -------
    dict
        ``{"wavelength_um", "freq_cy_per_mrad", <component>..., "system"}``: one array per
        enabled component (``diffraction``, ``detector``, ``jitter``, ...; signed values)
        and their product. With ``field``, also ``"field"`` and the arrays
        ``"pupil_tangential"`` (frequency along the field direction) and
        ``"pupil_sagittal"`` (across it): the CLI's ``pupil_tangential_H…`` and
        ``pupil_sagittal_H…`` columns.

    See Also
    --------
    psf : the pupil PSF across the field.
    """
    f = _checks.float_list(freq_cy_per_mrad, "freq_cy_per_mrad")
    return _eoir.mtf(sensor, f, _checks.real("wavelength_um", wavelength_um),
                     _checks.real("field", field))


def psf(sensor: Sensor, field=(0.0, 0.5, 0.7, 1.0), wavelength_um: Optional[float] = None,
        half_width_lambda_over_d: float = 12.0):
    """The pupil PSF across the field (``eoir psf``).

    The PSF of the ``[optics]`` aperture (diameter ``focal_length_m / f_number``, central
    obscuration) and the ``[optics.wavefront]`` wavefront and spider vanes at each field
    height, sampled at λ/(4D); diffraction-limited when the sensor has no
    ``[optics.wavefront]``. The numbers are those of the CLI's ``psf.json``. Guide:
    docs/wavefront.md.

    Parameters
    ----------
    sensor : Sensor
    field : float or sequence of float, default (0, 0.5, 0.7, 1)
        Normalised field heights H in [0, 1] (1 to 16); the field lies along ``y``.
    wavelength_um : float, optional
        Wavelength, µm; default the response-weighted mean.
    half_width_lambda_over_d : float, default 12
        Half-width of each picture, λ/D, in [1, 64].

    Returns
    -------
    xarray.Dataset
        ``psf`` (``field``, ``y``, ``x``): the PSF samples, unit sum over the engine's full
        grid (the crop holds slightly less), ``y`` the tangential axis (towards larger
        field heights), ``x`` the sagittal one. Coordinates ``field`` (H), ``y`` and ``x``
        (mrad from the chief ray's paraxial image point, the grid centre) and
        ``y_lambda_over_d``, ``x_lambda_over_d``. Per field point: ``centroid_x_urad``,
        ``centroid_y_urad``, ``fwhm_urad`` (area-equivalent: the diameter of the disc whose
        area is the area above half maximum), ``strehl`` (peak over the unaberrated peak on
        the grid, a lower bound) and ``samples_across_pupil``. ``attrs``: the sensor,
        ``wavelength_um``, ``psf_sample_urad``, ``half_width_lambda_over_d``.

    See Also
    --------
    mtf : with ``field``, the tangential and sagittal pupil MTF.
    """
    h = _checks.float_list(field, "field")
    d = _eoir.psf(sensor, h, _checks.real("wavelength_um", wavelength_um),
                  _checks.real("half_width_lambda_over_d", half_width_lambda_over_d, optional=False))
    xr = _xr.xarray()
    sample_rad = d["psf_sample_rad"]
    side = d["psf"].shape[-1]
    k = np.arange(side, dtype=np.float64) - (side - 1) / 2.0
    coords = {"field": xr.Variable("field", d["field"], attrs={
        "units": "1", "long_name": "normalised field height H"})}
    for ax, name in (("y", "tangential (along the field direction)"), ("x", "sagittal")):
        coords[ax] = xr.Variable(ax, k * sample_rad * 1e3, attrs={
            "units": "mrad", "long_name": f"angle from the grid centre, {name}"})
        coords[ax + "_lambda_over_d"] = xr.Variable(ax, k / 4.0, attrs={
            "units": "lambda/D", "long_name": f"angle from the grid centre, {name}, in λ/D"})
    per_field = {
        "centroid_x_urad": ("urad", "PSF centroid, sagittal"),
        "centroid_y_urad": ("urad", "PSF centroid, tangential"),
        "fwhm_urad": ("urad", "area-equivalent full width at half maximum"),
        "strehl": ("1", "Strehl ratio (grid peak over the unaberrated grid peak)"),
        "samples_across_pupil": ("1", "pupil samples across the diameter"),
    }
    data_vars = {"psf": xr.Variable(("field", "y", "x"), d["psf"], attrs={
        "units": "1", "long_name": "pupil PSF, unit sum over the full grid"})}
    for name, (units, long_name) in per_field.items():
        data_vars[name] = xr.Variable("field", d[name], attrs={"units": units, "long_name": long_name})
    attrs = _xr.base_attrs(sensor)
    attrs.update(wavelength_um=d["wavelength_um"], psf_sample_urad=sample_rad * 1e6,
                 half_width_lambda_over_d=float(half_width_lambda_over_d))
    return xr.Dataset(data_vars, coords=coords, attrs=attrs)


_SCENE_INTS = ("rows", "cols", "oversampling", "bands", "seed")


def scene(kind: str = "thermal", sensor: Optional[Sensor] = None, oversampling: Optional[int] = None,
          margin_px: int = 4, **params) -> Cube:
    """A built-in synthetic scene (``eoir scene KIND``).

    Parameters
    ----------
    kind : {"thermal", "bars", "edge", "blackbody", "ramp"}, default "thermal"
    sensor : Sensor, optional
        Size the scene to this sensor (as ``eoir scene --sensor``): ``oversampling``
        samples per detector pixel over its paraxial field plus ``margin_px`` pixels each
        side, wavelengths across its response. Used when given, or when none of ``rows``,
        ``cols``, ``fov_deg`` is (then the default sensor ``multimir``).
    oversampling : int, optional
        Scene samples per detector pixel (default 2 with a sensor, 1 without).
    margin_px : int, default 4
        Detector pixels of scene beyond each edge (with a sensor).
    **params
        ``rows``, ``cols``, ``lo_um``, ``hi_um``, ``bands``, ``fov_deg`` (explicit size;
        defaults 288, 384, 3.0, 5.5, 51, 5.28), ``range_m``, ``seed``, ``night``,
        ``temperature_k``, ``emissivity``, ``t_low_k``, ``t_high_k``, ``angle_deg``.

    Returns
    -------
    Cube
    """
    for k in _SCENE_INTS:
        if k in params:
            params[k] = _checks.uint(k, params[k])
    margin_px = _checks.uint("margin_px", margin_px)
    if oversampling is not None:
        oversampling = _checks.uint("oversampling", oversampling)
    explicit = any(k in params for k in ("rows", "cols", "fov_deg"))
    if sensor is not None and explicit:
        raise ValueError("invalid parameters: give either `sensor` (sized to it) or `rows`, `cols`, `fov_deg`, not both")
    if sensor is None and not explicit:
        sensor = load_sensor("multimir")
    if sensor is not None:
        for k in ("lo_um", "hi_um", "bands"):
            if k in params:
                raise ValueError(f"invalid parameter `{k}` with `sensor`: the wavelengths follow the sensor's response")
        g = _checks.native(_eoir.covering_params, sensor, 2 if oversampling is None else oversampling, margin_px)
        params.update(rows=g["rows"], cols=g["cols"], oversampling=g["oversampling"], fov_deg=g["fov_deg"],
                      wavelength_um=list(g["wavelength_um"]))
    elif oversampling is not None:
        params["oversampling"] = oversampling
    return Cube._from_dict(_checks.native(_eoir.scene, str(kind), **params))


def demo_scene(sensor: Sensor, oversampling: int = 2, seed: int = 1) -> Cube:
    """The scene ``eoir demo`` writes for ``sensor``.

    Parameters
    ----------
    sensor : Sensor
    oversampling : int, default 2
        Scene samples per detector pixel.
    seed : int, default 1

    Returns
    -------
    Cube
        The thermal scene sized to the sensor (4 detector pixels of margin each side, bands
        every ~0.02 µm, at least 24, across its response), daylight, 1900 m range.
    """
    return scene("thermal", sensor=sensor, oversampling=oversampling, seed=seed, range_m=1900.0)


def set_max_memory_bytes(bytes: int) -> None:
    """Set the memory budget every size is checked against before allocating.

    Parameters
    ----------
    bytes : int
        Budget, bytes (the CLI's ``--max-memory``); the default is a share of the
        machine's memory.
    """
    _eoir.set_max_memory_bytes(_checks.uint("bytes", bytes))
