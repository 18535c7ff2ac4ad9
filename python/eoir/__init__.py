"""eoir — electro-optical / infrared sensor model, on NumPy.

Turns synthetic hyperspectral radiance cubes (W m-2 sr-1 µm-1 per pixel over a wavelength
grid) into the imagery a real IR/EO camera records: optics, atmosphere and motion as
cascaded transfer functions, the camera equation, detector noise / fixed pattern / ADC,
then calibration back to in-band radiance and apparent temperature.

>>> import eoir
>>> sensor = eoir.load_sensor("multimir", options={"filter": "4"},
...                           overrides={"detector.integration_time_s": 2e-3})
>>> cube = eoir.read_cube("scene.hdr")                       # doctest: +SKIP
>>> result = eoir.run(sensor, cube, seed=7)                   # doctest: +SKIP
>>> result.dn.shape == (sensor.rows, sensor.cols)             # doctest: +SKIP
True

Every function raises ``ValueError`` for bad values and ``OSError`` for files, with the
same message the command-line tool prints. The engine runs with the GIL released.
Scale-out on Dask: :mod:`eoir.dask`.
"""

from __future__ import annotations

import json
import math
from typing import Any, Dict, Iterable, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _eoir
from ._eoir import Sensor, __version__

__all__ = [
    "Sensor",
    "Cube",
    "RunResult",
    "load_sensor",
    "presets",
    "read_cube",
    "write_cube",
    "run",
    "mtf",
    "scene",
    "__version__",
]

SPECTRAL_UNITS = "W m-2 sr-1 um-1"
"""Spectral radiance, the default unit of a cube."""


def _toml_value(value: Any) -> str:
    """A Python value as the TOML text ``--set key=value`` expects."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        v = float(value)
        if not math.isfinite(v):
            # TOML spells these nan / inf; validation then names the field.
            return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")
        return repr(v)
    if isinstance(value, str):
        return json.dumps(value)  # a TOML basic string
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, Mapping):
        return "{ " + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + " }"
    raise ValueError(
        f"invalid override value {value!r} of type {type(value).__name__}: "
        "a bool, number, string, list or dict"
    )


def _pairs(mapping: Optional[Union[Mapping[str, Any], Iterable[str]]], what: str, toml: bool):
    if mapping is None:
        return []
    if isinstance(mapping, str):
        raise ValueError(f"invalid parameter `{what}` = {mapping!r}: a dict (or a list of 'key=value')")
    if isinstance(mapping, Mapping):
        return [f"{k}={_toml_value(v) if toml else v}" for k, v in mapping.items()]
    return [str(m) for m in mapping]


def load_sensor(
    name_or_path: str,
    options: Optional[Mapping[str, Any]] = None,
    overrides: Optional[Mapping[str, Any]] = None,
) -> Sensor:
    """Loads a sensor: a built-in preset name (see :func:`presets`) or a TOML file.

    ``options`` choose a preset's alternatives, e.g. ``{"filter": "3", "optics": "15mm"}``
    (``eoir run --option``); ``overrides`` set any field by its dotted path, e.g.
    ``{"detector.integration_time_s": 2e-3, "jitter.sigma_rad": 1e-5}`` (``--set``).
    Unknown options, keys and impossible values raise ``ValueError``; an unreadable file
    ``OSError``.
    """
    return _eoir.load_sensor(
        str(name_or_path),
        _pairs(options, "options", toml=False),
        _pairs(overrides, "overrides", toml=True),
    )


def sensor_from_toml(text: str, base_dir: str = ".") -> Sensor:
    """A sensor from resolved TOML text (:meth:`Sensor.to_toml`); relative file references
    resolve against ``base_dir``."""
    return _eoir.sensor_from_toml(text, str(base_dir))


def presets() -> list:
    """The built-in presets: ``[{"name", "description", "options": {name: [values]},
    "defaults": {name: value}}, ...]``."""
    return _eoir.presets_info()


class Cube:
    """A spectral radiance cube and its metadata.

    ``radiance`` is float32 ``[band, row, col]`` (one frame) or ``[frame, band, row, col]``;
    ``wavelength_um`` the band centres (µm, increasing); ``fov_deg`` (horizontal, vertical)
    or None; ``units`` ``"W m-2 sr-1 um-1"`` (spectral) or ``"W m-2 sr-1"`` (band-integrated).
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

    def __repr__(self) -> str:
        return (
            f"<eoir.Cube {tuple(self.radiance.shape)} {self.wavelength_um[0]:.3f}–"
            f"{self.wavelength_um[-1]:.3f} µm, fov {self.fov_deg}, {self.units}>"
        )

    @classmethod
    def _from_dict(cls, d: Dict[str, Any]) -> "Cube":
        return cls(
            d["radiance"],
            d["wavelength_um"],
            d["fov_deg"],
            d["units"],
            d["range_m"],
            d["fwhm_um"],
            d["frame_time_s"],
            d["warnings"],
        )


def read_cube(path) -> Cube:
    """Reads a cube file (ENVI ``.hdr``, spectral ``.exr``, ``.npy`` + ``.json`` sidecar;
    ``.h5`` when built with HDF5), every frame. A missing or unreadable file raises
    ``OSError``, a malformed one ``ValueError``."""
    return Cube._from_dict(_eoir.read_cube(str(path)))


def write_cube(path, cube: Union[Cube, np.ndarray], wavelength_um=None, fov_deg=None,
               units: str = SPECTRAL_UNITS, range_m=None, fwhm_um=None) -> None:
    """Writes a one-frame cube ``[band, row, col]`` (a :class:`Cube`, or an array plus its
    wavelengths) in the format given by the extension, atomically."""
    if isinstance(cube, Cube):
        radiance, wavelength_um = cube.radiance, cube.wavelength_um
        fov_deg, units, range_m, fwhm_um = cube.fov_deg, cube.units, cube.range_m, cube.fwhm_um
    else:
        radiance = cube
        if wavelength_um is None:
            raise ValueError("invalid parameter `wavelength_um` = None: one wavelength (µm) per band")
    _eoir.write_cube(
        str(path),
        _as_f32(radiance),
        _float_list(wavelength_um, "wavelength_um"),
        None if fov_deg is None else (float(fov_deg[0]), float(fov_deg[1])),
        units,
        range_m,
        None if fwhm_um is None else _float_list(fwhm_um, "fwhm_um"),
    )


def _as_f32(a) -> np.ndarray:
    """float32 without a copy when it already is (strided views are borrowed as they are)."""
    if isinstance(a, np.ndarray) and a.dtype == np.float32:
        return a
    return np.asarray(a, dtype=np.float32)


def _float_list(v, what: str) -> list:
    try:
        return [float(x) for x in np.asarray(v, dtype=np.float64).ravel()]
    except (TypeError, ValueError) as e:
        raise ValueError(f"invalid parameter `{what}` = {v!r}: numbers ({e})") from None


class RunResult:
    """The products of :func:`run`.

    ``dn`` uint16 ``[row, col]`` (``[frame, row, col]`` for a sequence), ``electrons_mean``
    float32 (noise-free expected photo-electrons), ``radiance`` (in-band, W m-2 sr-1) and
    ``temperature`` (apparent, K) for thermal sensors with ``calibrate=True``, else None;
    ``report`` the run report (the dict ``report.json`` holds); ``config_toml`` the resolved
    sensor; ``warnings``.
    """

    UNITS = {
        "dn": "DN",
        "electrons_mean": "electrons (mean, noise-free)",
        "radiance": "W m-2 sr-1 (in-band, normalised to peak response)",
        "temperature": "K (apparent, blackbody-equivalent)",
    }

    def __init__(self, d: Dict[str, Any], squeeze: bool, wrap=None):
        def prod(name):
            a = d[name]
            if a is None:
                return None
            a = a[0] if squeeze else a
            return wrap(a, name, self.UNITS[name]) if wrap is not None else a

        self.dn = prod("dn")
        self.electrons_mean = prod("electrons_mean")
        self.radiance = prod("radiance")
        self.temperature = prod("temperature")
        self.report = json.loads(d["report_json"])
        self.config_toml = d["config_toml"]
        self.warnings = list(d["warnings"])

    def __repr__(self) -> str:
        return f"<eoir.RunResult dn {tuple(self.dn.shape)}, {len(self.warnings)} warnings>"


def _xarray_input(radiance):
    """(values, wavelength_um, dims of the non-spectral axes) of an xarray.DataArray with a
    ``wavelength`` dimension (µm), or None if ``radiance`` is not a DataArray."""
    try:
        import xarray as xr  # optional
    except ImportError:
        return None
    if not isinstance(radiance, xr.DataArray):
        return None
    if "wavelength" not in radiance.dims:
        raise ValueError(
            f"invalid parameter `radiance` = DataArray with dims {radiance.dims}: "
            "a `wavelength` dimension (µm) with a coordinate"
        )
    lead = [d for d in ("frame",) if d in radiance.dims]
    rest = [d for d in radiance.dims if d not in lead and d != "wavelength"]
    if len(rest) != 2:
        raise ValueError(
            f"invalid parameter `radiance` = DataArray with dims {radiance.dims}: "
            "(wavelength, row, col) or (frame, wavelength, row, col)"
        )
    da = radiance.transpose(*lead, "wavelength", *rest)
    return da.values, da["wavelength"].values, lead


def run(
    sensor: Sensor,
    radiance,
    wavelength_um=None,
    fov_deg=None,
    seed: int = 1,
    frames: int = 1,
    calibrate: bool = True,
    *,
    nuc_degree: int = 1,
    first_frame: int = 0,
    range_m: Optional[float] = None,
    units: Optional[str] = None,
    calibration_temperatures_k=None,
) -> RunResult:
    """Runs radiance through a sensor (what ``eoir run`` does, without files).

    ``radiance``: float32 ``[band, row, col]`` or ``[frame, band, row, col]`` (other dtypes
    are converted; contiguous float32 is borrowed, not copied), or a :class:`Cube` (its
    wavelengths, field of view, units and range are used), or an ``xarray.DataArray`` with
    a ``wavelength`` dimension in µm (then the products are DataArrays too).
    ``fov_deg``: the cube's (horizontal, vertical) field of view, degrees. ``seed``: every
    random effect (same seed ⇒ bit-identical DN). ``frames``: expose a one-frame scene
    this many times. ``first_frame``: index in the whole sequence of this call's first frame
    (temporal noise is drawn per sequence frame index, so a sequence run in pieces equals
    one run). ``calibrate``: thermal sensors also return radiance and temperature.
    ``calibration_temperatures_k``: the blackbody levels of the calibration, K (default: the
    sensor file's ``[calibration]`` section, else 10/50/90 % of the sensor's range, as
    ``eoir run --calibration-temperatures``).
    """
    wrap = None
    if isinstance(radiance, Cube):
        cube = radiance
        radiance = cube.radiance
        wavelength_um = cube.wavelength_um if wavelength_um is None else wavelength_um
        fov_deg = cube.fov_deg if fov_deg is None else fov_deg
        range_m = cube.range_m if range_m is None else range_m
        units = cube.units if units is None else units
    else:
        x = _xarray_input(radiance)
        if x is not None:
            import xarray as xr

            attrs = dict(radiance.attrs)
            radiance, wl, lead = x
            wavelength_um = wl if wavelength_um is None else wavelength_um
            fov_deg = attrs.get("fov_deg") if fov_deg is None else fov_deg
            range_m = attrs.get("range_m") if range_m is None else range_m
            units = attrs.get("units") if units is None else units

            def wrap(a, name, unit):
                dims = (["frame"] if a.ndim == 3 else []) + ["row", "col"]
                return xr.DataArray(a, dims=dims, name=name, attrs={"units": unit})

    if wavelength_um is None:
        raise ValueError("invalid parameter `wavelength_um` = None: one wavelength (µm) per band")
    if fov_deg is None:
        raise ValueError(
            "invalid parameter `fov_deg` = None: the input's (horizontal, vertical) field of view in degrees"
        )
    try:
        fov = (float(fov_deg[0]), float(fov_deg[1]))
    except (TypeError, ValueError, IndexError):
        raise ValueError(f"invalid parameter `fov_deg` = {fov_deg!r}: (horizontal, vertical) degrees") from None
    for name, v in (("seed", seed), ("frames", frames), ("first_frame", first_frame), ("nuc_degree", nuc_degree)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
            raise ValueError(f"invalid parameter `{name}` = {v!r}: an integer >= 0")
    data = _as_f32(radiance)
    d = _eoir.run(
        sensor,
        data,
        _float_list(wavelength_um, "wavelength_um"),
        fov,
        int(seed),
        int(frames),
        bool(calibrate),
        int(nuc_degree),
        int(first_frame),
        None if range_m is None else float(range_m),
        units or SPECTRAL_UNITS,
        calibration_temperatures_k=None
        if calibration_temperatures_k is None
        else _float_list(calibration_temperatures_k, "calibration_temperatures_k"),
    )
    squeeze = data.ndim == 3 and int(frames) <= 1
    return RunResult(d, squeeze, wrap)


def mtf(sensor: Sensor, freq_cy_per_mrad, wavelength_um: Optional[float] = None) -> Dict[str, Any]:
    """The sensor's transfer functions at the given angular frequencies (cycles/mrad, object
    space): ``{"wavelength_um", "freq_cy_per_mrad", <component>..., "system"}``, one array
    per enabled component (``diffraction``, ``detector``, ``jitter``, ...; signed values)
    and their product. ``wavelength_um`` defaults to the response-weighted mean."""
    f = _float_list(freq_cy_per_mrad, "freq_cy_per_mrad")
    return _eoir.mtf(sensor, f, None if wavelength_um is None else float(wavelength_um))


def scene(kind: str = "thermal", sensor: Optional[Sensor] = None, oversampling: Optional[int] = None,
          margin_px: int = 4, **params) -> Cube:
    """A built-in synthetic scene (as ``eoir scene KIND``): ``thermal``, ``bars``, ``edge``,
    ``blackbody``, ``ramp``.

    Sized to a sensor (as ``eoir scene --sensor``) when ``sensor`` is given or when none of
    ``rows, cols, fov_deg`` is: ``oversampling`` (default 2) scene samples per detector
    pixel over the sensor's field of view plus ``margin_px`` detector pixels each side,
    wavelengths across its response; the default sensor is ``multimir``, so
    ``eoir.run(eoir.load_sensor("multimir"), eoir.scene())`` works as it is. Otherwise the
    explicit keywords ``rows, cols, oversampling, lo_um, hi_um, bands, fov_deg`` (defaults
    288, 384, 1, 3.0, 5.5, 51, 5.28). Other keywords: ``range_m, seed, night,
    temperature_k, emissivity, t_low_k, t_high_k, angle_deg``."""
    explicit = any(k in params for k in ("rows", "cols", "fov_deg"))
    if sensor is not None and explicit:
        raise ValueError("invalid parameters: give either `sensor` (sized to it) or `rows`, `cols`, `fov_deg`, not both")
    if sensor is None and not explicit:
        sensor = load_sensor("multimir")
    if sensor is not None:
        for k in ("lo_um", "hi_um", "bands"):
            if k in params:
                raise ValueError(f"invalid parameter `{k}` with `sensor`: the wavelengths follow the sensor's response")
        g = _eoir.covering_params(sensor, 2 if oversampling is None else int(oversampling), int(margin_px))
        params.update(rows=g["rows"], cols=g["cols"], oversampling=g["oversampling"], fov_deg=g["fov_deg"],
                      wavelength_um=list(g["wavelength_um"]))
    elif oversampling is not None:
        params["oversampling"] = oversampling
    return Cube._from_dict(_eoir.scene(kind, **params))


def demo_scene(sensor: Sensor, oversampling: int = 2, seed: int = 1) -> Cube:
    """The scene ``eoir demo`` writes for ``sensor``: the thermal scene sized to the sensor
    (``oversampling`` samples per pixel, 4 detector pixels of margin each side, bands every
    ~0.02 µm, at least 24, across its response), daylight, 1900 m range."""
    return scene("thermal", sensor=sensor, oversampling=oversampling, seed=seed, range_m=1900.0)
