"""eoir — electro-optical / infrared sensor model, on NumPy and xarray.

Turns hyperspectral radiance cubes (W m-2 sr-1 µm-1 per pixel over a wavelength grid)
into the imagery a real IR/EO camera records: optics, atmosphere and motion as cascaded
transfer functions, the camera equation, detector noise, fixed pattern and ADC, then
calibration back to in-band radiance and apparent temperature. The analysis tools of the
command line work on the results: Wiener restoration, slanted-edge MTF, NUC, EMVA 1288.

>>> import eoir
>>> sensor = eoir.load_sensor("multimir", options={"filter": "4"},
...                           overrides={"detector.integration_time_s": 2e-3})
>>> cube = eoir.scene("edge", sensor=sensor)                 # or eoir.read_cube("x.hdr")
>>> ds = eoir.run(sensor, cube, seed=7)                       # doctest: +SKIP
>>> ds.dn.shape == (sensor.rows, sensor.cols)                 # doctest: +SKIP
True
>>> eoir.edge_mtf(ds, sensor=sensor).attrs["mtf50_cy_per_px"] # doctest: +SKIP

Functions raise ``ValueError`` for bad values, ``TypeError`` for values of the wrong kind
and ``OSError`` for files, with the message the command-line tool prints (naming the
Python parameter). The engine runs with the GIL released. Scale-out on Dask:
:mod:`eoir.dask`. Guide: docs/python.md in the repository.
"""

from ._core import (
    SPECTRAL_UNITS,
    Cube,
    RunResult,
    demo_scene,
    load_sensor,
    mtf,
    presets,
    psf,
    read_cube,
    run,
    scene,
    sensor_from_toml,
    set_max_memory_bytes,
    write_cube,
)
from ._eoir import Nuc, Sensor, __version__
from ._toolbox import (
    assess,
    characterize,
    edge_mtf,
    find_rts_pixels,
    nuc_apply,
    nuc_fit,
    read_image,
    restore,
    restore_sequence,
    simulate_acquisition_set,
)

__all__ = [
    "Sensor",
    "Cube",
    "Nuc",
    "RunResult",
    "SPECTRAL_UNITS",
    "load_sensor",
    "sensor_from_toml",
    "presets",
    "read_cube",
    "write_cube",
    "read_image",
    "scene",
    "demo_scene",
    "run",
    "mtf",
    "psf",
    "restore",
    "restore_sequence",
    "edge_mtf",
    "nuc_fit",
    "find_rts_pixels",
    "nuc_apply",
    "assess",
    "characterize",
    "simulate_acquisition_set",
    "set_max_memory_bytes",
    "__version__",
]
