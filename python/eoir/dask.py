"""Scale-out on Dask: sequences chunked along frames, and many cube files, on any Dask
scheduler (threads, processes, a ``dask.distributed`` cluster).

Determinism: temporal noise is drawn per *sequence frame index* (the run's ``first_frame``
plus the frame's index in the chunk) and the fixed pattern from the sensor instance's seed
alone, so the result equals one :func:`eoir.run` over the same frames with the same seed
bit for bit, whatever the chunking or the number of workers. Sensors travel to workers as
their resolved TOML (pickling a :class:`eoir.Sensor`), so every worker builds the same
instance.

Needs ``dask[array]`` (and ``distributed`` for clusters, ``zarr`` for :func:`run_files`).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

import numpy as np

import eoir

try:
    import dask
    import dask.array as da
except ImportError as e:  # pragma: no cover - import guard
    raise ImportError("eoir.dask needs dask: pip install 'dask[array]' distributed zarr") from e

__all__ = ["run_frames", "run_files", "sweep", "PRODUCTS"]

PRODUCTS = {
    "dn": np.uint16,
    "electrons_mean": np.float32,
    "radiance": np.float32,
    "temperature": np.float32,
}
"""Products :func:`run_frames` can return, with their dtypes."""


def _check_product(product: str) -> None:
    if product not in PRODUCTS:
        raise ValueError(
            f"invalid parameter `product` = {product!r}: one of {', '.join(PRODUCTS)}"
        )


def _run_block(block, sensor, wavelength_um, fov_deg, seed, product, range_m, units,
               nuc_degree, block_info=None):
    """One chunk of frames: ``first_frame`` is the chunk's offset in the whole sequence."""
    first = block_info[0]["array-location"][0][0] if block_info else 0
    # The whole sequence's length: a moving camera's wander is drawn over all of it.
    total = block_info[0]["shape"][0] if block_info else None
    calibrate = product in ("radiance", "temperature")
    r = eoir.run(
        sensor,
        np.ascontiguousarray(block, dtype=np.float32),
        wavelength_um,
        fov_deg,
        seed=seed,
        calibrate=calibrate,
        first_frame=int(first),
        sequence_frames=None if total is None else int(total),
        range_m=range_m,
        units=units,
        nuc_degree=nuc_degree,
        as_dataset=False,
    )
    out = getattr(r, product)
    if out is None:
        raise ValueError(
            f"sensor `{sensor.name}` gives no `{product}` product "
            "(radiance and temperature need a thermal sensor, response beyond 3 µm)"
        )
    return out


def run_frames(
    sensor: "eoir.Sensor",
    radiance,
    wavelength_um,
    fov_deg,
    seed: int = 1,
    product: str = "dn",
    *,
    range_m: Optional[float] = None,
    units: Optional[str] = None,
    nuc_degree: int = 1,
):
    """Runs a Dask array ``[frame, band, row, col]`` (chunked along frames) through
    ``sensor``, lazily: returns a Dask array ``[frame, row, col]`` of ``product`` (``"dn"``
    uint16, ``"electrons_mean"``, ``"radiance"``, ``"temperature"`` float32) with the same
    frame chunks. Band, row and column axes are gathered into one chunk each.

    Equals ``eoir.run(sensor, radiance.compute(), wavelength_um, fov_deg, seed=seed)`` bit
    for bit (same product), whatever the chunking and the scheduler. A sensor whose gain
    comes from the scene (``sensor.gain_from_scene``) sets it from the first frame of each
    run, so it is accepted only as one chunk.
    """
    _check_product(product)
    radiance = da.asarray(radiance)
    if radiance.ndim != 4:
        raise ValueError(
            f"invalid parameter `radiance` = Dask array of {radiance.ndim} dimensions: "
            "[frame, band, row, col]"
        )
    radiance = radiance.rechunk({1: -1, 2: -1, 3: -1})
    if sensor.gain_from_scene and len(radiance.chunks[0]) > 1:
        raise ValueError(
            f"sensor `{sensor.name}` sets its gain from the first frame's mean signal "
            "([detector.auto_gain] reference = \"scene_mean\"): chunks would each set their own; "
            "fix the gain (overrides={'detector.gain_dn_per_e': K}, without auto_gain) or use one chunk"
        )
    wl = [float(w) for w in np.asarray(wavelength_um, dtype=np.float64).ravel()]
    fov = (float(fov_deg[0]), float(fov_deg[1]))
    dtype = PRODUCTS[product]
    return da.map_blocks(
        _run_block,
        radiance,
        sensor,
        wl,
        fov,
        int(seed),
        product,
        range_m,
        units,
        int(nuc_degree),
        dtype=dtype,
        drop_axis=1,
        chunks=(radiance.chunks[0], (sensor.rows,), (sensor.cols,)),
        meta=np.empty((0, 0, 0), dtype=dtype),
    )


def _write_array(group, name: str, data: np.ndarray) -> None:
    """Writes one array into a Zarr group (zarr 3 ``create_array``, zarr 2 ``array``)."""
    if hasattr(group, "create_array"):
        group.create_array(name=name, data=data, overwrite=True)
    else:  # zarr 2
        group.array(name, data, overwrite=True)


def _run_file(sensor, path: str, store: str, name: str, seed: int, frames: int,
              calibrate: bool, fov_deg, nuc_degree: int) -> Dict[str, Any]:
    """Worker task: one cube file → one Zarr group ``name`` under ``store``."""
    import zarr

    cube = eoir.read_cube(path)
    r = eoir.run(sensor, cube, fov_deg=fov_deg, seed=seed, frames=frames,
                 calibrate=calibrate, nuc_degree=nuc_degree, as_dataset=False)
    root = zarr.open_group(store, mode="a")
    g = root.require_group(name)
    for product in PRODUCTS:
        a = getattr(r, product)
        if a is not None:
            _write_array(g, product, np.asarray(a))
    g.attrs.update({
        "source": str(path),
        "seed": int(seed),
        "sensor_toml": r.config_toml,
        "report": r.report,
    })
    return {"name": name, "source": str(path), "mean_dn": float(np.mean(r.dn))}


def run_files(
    sensor: "eoir.Sensor",
    paths: Sequence,
    out,
    seed: int = 1,
    frames: int = 1,
    calibrate: bool = True,
    *,
    fov_deg=None,
    nuc_degree: int = 1,
    client=None,
    compute: bool = True,
):
    """Runs many cube files through ``sensor`` as one Dask task each, writing a Zarr store
    ``out`` with one group per file (named ``NNNN_<file stem>``) holding ``dn``,
    ``electrons_mean`` (and ``radiance``/``temperature`` for thermal sensors) and the
    report and resolved sensor as attributes. Workers write their own groups, so the
    store must be on a file system every worker sees.

    ``client``: a ``dask.distributed.Client`` (default: the current one if any, else the
    default scheduler). Returns one summary dict per file, or the delayed tasks if
    ``compute=False``.
    """
    import zarr

    paths = [os.fspath(p) for p in paths]
    store = os.fspath(out)
    zarr.open_group(store, mode="a")  # the root exists before workers add groups
    fov = None if fov_deg is None else (float(fov_deg[0]), float(fov_deg[1]))
    tasks = []
    for i, p in enumerate(paths):
        name = f"{i:04d}_{Path(p).stem}"
        tasks.append(
            dask.delayed(_run_file, pure=False)(
                sensor, p, store, name, int(seed), int(frames), bool(calibrate), fov,
                int(nuc_degree), dask_key_name=f"eoir-run-file-{name}-{seed}",
            )
        )
    if not compute:
        return tasks
    if client is not None:
        return list(client.gather(client.compute(tasks)))
    return list(dask.compute(*tasks))


def _sweep_point(sensor, options, overrides, point, assess_kwargs):
    """The figures of merit at one grid point: ``point`` maps varied keys to values."""
    ov = dict(overrides)
    ov.update(point)
    s = eoir.load_sensor(sensor, options, ov)
    try:
        a = eoir.assess(s, **assess_kwargs)
    except ValueError as e:
        # A valid sensor without figures at this point (e.g. its reference saturates): a
        # NaN row with a note, as `eoir sweep` does, not the end of the trade study.
        return {"_note": str(e)}
    an = a["analytic"]
    out = {
        "netd_k": an.get("netd_k"),
        "mtf50_cy_per_px": an.get("mtf50_cy_per_px"),
        "mtf_nyquist": an.get("mtf_nyquist"),
        "rer": an.get("rer"),
    }
    for t in an.get("tasks", []):
        out[f"{t['task']}_p50_m"] = t.get("range_p50_m")
        out[f"{t['task']}_p80_m"] = t.get("range_p80_m")
    m = a.get("measured")
    if m:
        out["netd_measured_k"] = m.get("netd_k")
        out["mtf50_measured_cy_per_px"] = m.get("mtf50_cy_per_px")
    return {k: (np.nan if v is None else float(v)) for k, v in out.items()}


def _axis(key, spec):
    """The values of one varied key: ``(start, stop, n)`` (inclusive, like ``eoir sweep
    --vary key=start:stop:n``) or an explicit sequence of numbers."""
    if not isinstance(key, str) or not key:
        raise ValueError(f"invalid parameter `vary`: key {key!r} is not a dotted key path")
    if isinstance(spec, tuple) and len(spec) == 3:
        start, stop, n = spec
        if not (isinstance(n, (int, np.integer)) and n >= 1):
            raise ValueError(
                f"invalid parameter `vary[{key!r}]`: n = {n!r}; an integer >= 1")
        values = np.linspace(float(start), float(stop), int(n))
    else:
        values = np.asarray(spec, dtype=float).ravel()
    if values.size == 0 or not np.all(np.isfinite(values)):
        raise ValueError(
            f"invalid parameter `vary[{key!r}]`: {spec!r}; (start, stop, n) or finite numbers")
    return values


def sweep(
    sensor: str,
    vary: Dict[str, Any],
    *,
    options: Optional[Dict[str, Any]] = None,
    overrides: Optional[Dict[str, Any]] = None,
    analytic_only: bool = True,
    target: Optional[Dict[str, Any]] = None,
    ranges_km: Optional[Sequence[float]] = None,
    seed: int = 1,
    client=None,
    store=None,
):
    """A trade study: the figures of merit of ``sensor`` (a preset name or TOML path) over
    the grid of every combination of the ``vary`` values, one Dask task per grid point
    (``eoir sweep`` in Python).

    ``vary`` maps dotted keys (as ``overrides``/``--set``) to ``(start, stop, n)`` or a
    sequence of values. Each task loads the sensor with the point's values and runs
    :func:`eoir.assess` (analytic figures only unless ``analytic_only=False``, which also
    simulates and measures). ``client``: a ``dask.distributed.Client`` (default: the
    current one if any, else the default scheduler). The result is the same whatever the
    scheduler or the number of workers.

    Returns an ``xarray.Dataset`` with one dimension per varied key (in the order given)
    and one variable per figure (``netd_k``, ``mtf50_cy_per_px``, ``mtf_nyquist``, ``rer``,
    ``<task>_p50_m``, ``<task>_p80_m``; NaN where a figure does not apply); written to the
    Zarr store ``store`` too when given. A point whose sensor is valid but has no figures
    (e.g. its reference level saturates) is NaN throughout and explained in the attribute
    ``notes`` (one string per such point); if no point has figures, ``ValueError``.
    """
    import itertools

    import xarray as xr

    if not isinstance(vary, dict) or not vary:
        raise ValueError("invalid parameter `vary`: a dict of at least one dotted key")
    keys = list(vary)
    axes = [_axis(k, vary[k]) for k in keys]
    opts = dict(options or {})
    ov = dict(overrides or {})
    kw = {"analytic_only": bool(analytic_only), "seed": int(seed)}
    if target is not None:
        kw["target"] = dict(target)
    if ranges_km is not None:
        kw["ranges_km"] = [float(r) for r in ranges_km]
    # The first point in this process: a bad sensor, key or target fails here, once.
    points = [dict(zip(keys, (float(v) for v in p))) for p in itertools.product(*axes)]
    first = _sweep_point(sensor, opts, ov, points[0], kw)
    tasks = [
        dask.delayed(_sweep_point, pure=True)(sensor, opts, ov, p, kw)
        for p in points[1:]
    ]
    if client is not None:
        rest = list(client.gather(client.compute(tasks)))
    else:
        rest = list(dask.compute(*tasks))
    results = [first] + rest
    notes = [
        ", ".join(f"{k}={v}" for k, v in p.items()) + ": " + r["_note"]
        for p, r in zip(points, results) if "_note" in r
    ]
    if len(notes) == len(points):
        raise ValueError(f"no sweep point has figures of merit; the first: {notes[0]}")
    shape = tuple(len(a) for a in axes)
    names = next(list(r) for r in results if "_note" not in r)
    data = {
        n: (keys, np.array([r.get(n, np.nan) for r in results], dtype=float).reshape(shape))
        for n in names
    }
    ds = xr.Dataset(data, coords={k: a for k, a in zip(keys, axes)},
                    attrs={"sensor": str(sensor), "analytic_only": int(bool(analytic_only)),
                           "notes": notes})
    if store is not None:
        ds.to_zarr(os.fspath(store), mode="w")
    return ds

