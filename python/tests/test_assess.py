"""Figures of merit from Python: eoir.assess (as `eoir assess`) and the Dask trade study
eoir.dask.sweep (as `eoir sweep`)."""

import math

import numpy as np
import pytest

import eoir


def test_assess_analytic_and_measured_thermal():
    s = eoir.load_sensor("multimir")
    a = eoir.assess(s, frames=8, window=32, ranges_km=[0.5, 1, 2, 4, 8])
    an, m = a["analytic"], a["measured"]
    assert an["thermal"] and an["netd_k"] > 0
    assert 0 < an["mtf_nyquist"] < 1 and 0 < an["rer"] <= 1
    # TTP: probabilities fall with range and the P50 range falls from detection to identification.
    tasks = {t["task"]: t for t in an["tasks"]}
    p = tasks["detection"]["probability"]
    assert all(b <= a_ + 1e-12 for a_, b in zip(p, p[1:]))
    # The measured NETD uses the same noise as the analytic one.
    assert m is not None and abs(m["netd_k"] / an["netd_k"] - 1) < 0.2


def test_assess_target_shrinks_range_and_bad_input_is_refused():
    s = eoir.load_sensor("multimir")
    big = eoir.assess(s, analytic_only=True, target={"size_m": 4.0})
    small = eoir.assess(s, analytic_only=True, target={"size_m": 1.0})
    r = lambda a: {t["task"]: t["range_p50_m"] for t in a["analytic"]["tasks"]}["identification"]
    assert r(small) < r(big)
    with pytest.raises(ValueError, match="target"):
        eoir.assess(s, analytic_only=True, target={"size": 2.0})
    with pytest.raises(ValueError, match="size_m"):
        eoir.assess(s, analytic_only=True, target={"size_m": -1.0})
    with pytest.raises(ValueError, match="ranges"):
        eoir.assess(s, analytic_only=True, ranges_km=[2.0, 1.0])


def test_sweep_on_a_two_worker_cluster_equals_sequential(tmp_path):
    distributed = pytest.importorskip("distributed")
    pytest.importorskip("xarray")
    edask = pytest.importorskip("eoir.dask")
    vary = {"detector.integration_time_s": (1e-3, 2.6e-3, 3), "optics.focal_length_m": [0.05, 0.1]}
    seq = edask.sweep("multimir", vary)
    assert seq["netd_k"].dims == ("detector.integration_time_s", "optics.focal_length_m")
    # Longer integration lowers NETD; a longer focal length lengthens the identification range.
    netd = seq["netd_k"].values
    assert np.all(np.diff(netd[:, 0]) < 0)
    ident = seq["identification_p50_m"].values
    assert np.all(ident[:, 1] > ident[:, 0])
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        par = edask.sweep("multimir", vary, client=client, store=tmp_path / "sweep.zarr")
    for name in seq.data_vars:
        np.testing.assert_array_equal(seq[name].values, par[name].values)
    with pytest.raises(ValueError, match="vary"):
        edask.sweep("multimir", {"detector.integration_time_s": (1e-3, 2e-3, 0)})
    # A saturating point is a NaN row with a note; the others keep their figures.
    sat = edask.sweep("multimir", {"detector.integration_time_s": [1e-3, 0.04]})
    assert np.isfinite(sat["netd_k"].values[0]) and np.isnan(sat["netd_k"].values[1])
    assert len(sat.attrs["notes"]) == 1 and "saturated" in sat.attrs["notes"][0]
    with pytest.raises(ValueError, match="no sweep point"):
        edask.sweep("multimir", {"detector.integration_time_s": [0.04]})


def test_run_with_assess_reports_the_analytic_figures(small_sensor, small_scene):
    ds = eoir.run(small_sensor, small_scene, assess=True)
    fom = ds.attrs["report"]["figures_of_merit"]
    an = eoir.assess(small_sensor, analytic_only=True)["analytic"]
    assert fom["netd_k"] == an["netd_k"]
    assert [t["range_p50_m"] for t in fom["tasks"]] == [t["range_p50_m"] for t in an["tasks"]]
    assert "figures_of_merit" not in eoir.run(small_sensor, small_scene).attrs["report"]
