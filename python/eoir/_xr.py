"""xarray at the boundary: reading DataArrays in, building Datasets out.

Conventions of every Dataset eoir returns:

- Image axes keep the input's dimension names (``("y", "x")`` in, ``("y", "x")`` out);
  NumPy inputs give ``("row", "col")``. A sequence adds ``frame`` in front.
- Each image axis carries an angular coordinate, mrad from the boresight, in the engine's
  paraxial convention: pixel ``j`` of ``n`` looks at ``(j − (n − 1)/2)·IFOV``.
- ``attrs`` hold the sensor's name and options, the seed and the other options of the
  call, the units of the input, the eoir version; each variable has ``units`` and
  ``long_name``.
"""

import numpy as np

from . import _eoir

WAVELENGTH_UNITS_TO_UM = {
    "um": 1.0, "µm": 1.0, "μm": 1.0, "micrometer": 1.0, "micrometers": 1.0, "micrometre": 1.0,
    "micrometres": 1.0, "micron": 1.0, "microns": 1.0,
    "nm": 1e-3, "nanometer": 1e-3, "nanometers": 1e-3, "nanometre": 1e-3, "nanometres": 1e-3,
    "m": 1e6, "meter": 1e6, "meters": 1e6, "metre": 1e6, "metres": 1e6,
    "mm": 1e3, "cm": 1e4,
}
"""Wavelength unit spellings a DataArray's ``wavelength`` coordinate may declare."""

BAND_DIMS = ("wavelength", "band", "bands")
"""Dimension names read as the spectral axis (``band`` needs a ``wavelength`` coordinate)."""


def xarray():
    """The xarray module (a dependency of the package)."""
    import xarray as xr

    return xr


def is_dataarray(a):
    try:
        import xarray as xr
    except ImportError:  # pragma: no cover - xarray is a dependency
        return False
    return isinstance(a, xr.DataArray)


def is_dataset(a):
    try:
        import xarray as xr
    except ImportError:  # pragma: no cover
        return False
    return isinstance(a, xr.Dataset)


def wavelength_um_of(coord, name="radiance"):
    """A wavelength coordinate's values in µm, from its ``units`` attribute (µm when it
    declares none)."""
    units = str(coord.attrs.get("units", "um")).strip()
    key = units.lower() if units.lower() in WAVELENGTH_UNITS_TO_UM else units
    if key not in WAVELENGTH_UNITS_TO_UM:
        raise ValueError(
            f"invalid parameter `{name}`: wavelength coordinate in units {units!r}: one of "
            "µm (um, micrometer, micron), nm, mm, cm, m"
        )
    return np.asarray(coord.values, dtype=np.float64) * WAVELENGTH_UNITS_TO_UM[key]


def dataarray_input(radiance):
    """(values ``[frame?, band, row, col]``, wavelength µm, image dim names, frame dim name
    or None, attrs) of a DataArray with a spectral dimension."""
    band = next((d for d in BAND_DIMS if d in radiance.dims), None)
    if band is None:
        raise ValueError(
            f"invalid parameter `radiance` = DataArray with dims {radiance.dims}: a spectral "
            "dimension named `wavelength` (or `band` with a `wavelength` coordinate), in µm "
            "or with a `units` attribute"
        )
    coord_name = "wavelength" if "wavelength" in radiance.coords else band
    if coord_name not in radiance.coords:
        raise ValueError(
            f"invalid parameter `radiance`: dimension `{band}` has no wavelength coordinate"
        )
    lead = [d for d in ("frame", "time") if d in radiance.dims]
    rest = [d for d in radiance.dims if d not in lead and d != band]
    if len(lead) > 1 or len(rest) != 2:
        raise ValueError(
            f"invalid parameter `radiance` = DataArray with dims {radiance.dims}: two image "
            f"dimensions and `{band}`, optionally `frame` first"
        )
    da = radiance.transpose(*lead, band, *rest)
    wl = wavelength_um_of(da[coord_name])
    return da.values, wl, tuple(rest), (lead[0] if lead else None), dict(radiance.attrs)


def angles_mrad(n, ifov_rad):
    """Angular coordinate of ``n`` samples spaced ``ifov_rad``, mrad:
    ``(j − (n − 1)/2)·IFOV`` (the engine's paraxial convention)."""
    return (np.arange(n, dtype=np.float64) - (n - 1) / 2.0) * ifov_rad * 1e3


def image_coords(dims, shape, ifov_rad):
    """Angular coordinates of the image axes ``dims`` (sizes ``shape``)."""
    xr = xarray()
    axis = {0: "rows (down the image)", 1: "columns (across the image)"}
    coords = {}
    for k, (d, n) in enumerate(zip(dims, shape)):
        coords[d] = xr.Variable(
            d,
            angles_mrad(n, ifov_rad),
            attrs={
                "units": "mrad",
                "long_name": f"angle from the boresight along the {axis[k]}",
                "convention": "pixel j of n at (j - (n - 1)/2) * IFOV (paraxial)",
            },
        )
    return coords


def options_text(options):
    """``{"filter": "4"}`` → ``"filter=4"`` (attrs hold strings, so the Dataset writes to
    netCDF and Zarr alike)."""
    return ", ".join(f"{k}={v}" for k, v in sorted(options.items()))


def base_attrs(sensor):
    return {
        "sensor": sensor.name,
        "sensor_options": options_text(sensor.options),
        "ifov_mrad": sensor.ifov_rad * 1e3,
        "eoir_version": _eoir.__version__,
    }


def image_dataset(variables, dims, ifov_rad, attrs, frame_dim=None, first_frame=0):
    """A Dataset of image variables ``{name: (array, units, long_name)}`` over ``dims``
    (plus ``frame_dim`` first for 3-D arrays) with angular coordinates."""
    xr = xarray()
    data_vars = {}
    shape = None
    nframes = None
    for name, (a, units, long_name) in variables.items():
        if a is None:
            continue
        a = np.asarray(a)
        if a.ndim == 3:
            vdims = (frame_dim or "frame",) + tuple(dims)
            nframes = a.shape[0]
        else:
            vdims = tuple(dims)
        shape = a.shape[-2:]
        data_vars[name] = xr.Variable(vdims, a, attrs={"units": units, "long_name": long_name})
    coords = image_coords(dims, shape, ifov_rad)
    if nframes is not None:
        f = frame_dim or "frame"
        coords[f] = xr.Variable(
            f, np.arange(first_frame, first_frame + nframes, dtype=np.int64),
            attrs={"long_name": "frame index in the sequence"},
        )
    return xr.Dataset(data_vars, coords=coords, attrs=attrs)
