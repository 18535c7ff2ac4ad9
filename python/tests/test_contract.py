"""The Python API's type contract (issue 39) and its namespace and docs (issue 40):
ValueError / TypeError / OSError only, overrides taken as key paths, messages in Python
terms."""

import inspect
import re

import numpy as np
import pytest

import eoir


def test_complex_radiance_refused_not_truncated(small_sensor, small_scene):
    c = small_scene
    z = c.radiance.astype(np.complex64) * (1 + 1j)
    with pytest.raises(TypeError, match="complex"):
        eoir.run(small_sensor, z, c.wavelength_um, c.fov_deg)
    with pytest.raises(TypeError, match="complex"):
        eoir.write_cube("never.npy", z, c.wavelength_um)
    with pytest.raises(TypeError, match="complex"):
        eoir.run(small_sensor, c, wavelength_um=c.wavelength_um + 0j)


@pytest.mark.parametrize("kw", [{"seed": 2**64}, {"first_frame": 2**64}, {"seed": -1},
                                {"frames": 2**64}, {"nuc_degree": 2**70}])
def test_big_and_negative_integers_are_value_errors(small_sensor, small_scene, kw):
    with pytest.raises(ValueError, match=next(iter(kw))):
        eoir.run(small_sensor, small_scene, **kw)


def test_largest_seed_runs(small_sensor, small_scene):
    a = eoir.run(small_sensor, small_scene, seed=2**64 - 1, calibrate=False)
    assert a.attrs["seed"] == 2**64 - 1


@pytest.mark.parametrize("kw", [{"rows": -1}, {"cols": 2**64}, {"bands": -3}, {"seed": 2**65}])
def test_scene_integers_are_value_errors(kw):
    with pytest.raises(ValueError, match=next(iter(kw))):
        eoir.scene("bars", **({"rows": 8, "cols": 8, "fov_deg": 1.0} | kw))


def test_deep_override_value_is_value_error():
    v = 1.0
    for _ in range(100_000):
        v = [v]
    with pytest.raises(ValueError, match="nested deeper"):
        eoir.load_sensor("multimir", overrides={"optics.f_number": v})
    loop = []
    loop.append(loop)
    with pytest.raises(ValueError, match="nested deeper"):
        eoir.load_sensor("multimir", overrides={"optics.f_number": loop})
    with pytest.raises(ValueError, match="overrides"):
        eoir.load_sensor("multimir", overrides={"optics.f_number": 2**70})
    with pytest.raises(TypeError, match="overrides"):
        eoir.load_sensor("multimir", overrides={"optics.f_number": object()})


def test_empty_calibration_temperatures_is_value_error(small_sensor, small_scene):
    with pytest.raises(ValueError, match="calibration_temperatures_k"):
        eoir.run(small_sensor, small_scene, calibration_temperatures_k=[])


def test_override_keys_are_key_paths_never_toml_text():
    base = eoir.load_sensor("multimir")
    # The old string path turned this key into `detector.integration_time_s=1e-3` plus text.
    hostile = "detector.integration_time_s=1e-3\n[optics]\nf_number"
    with pytest.raises(ValueError, match="dotted key"):
        eoir.load_sensor("multimir", overrides={hostile: 9.0})
    for key in ("optics.f_number\n[detector]\nrows", 'optics."f_number"', "optics..f_number", ""):
        with pytest.raises(ValueError, match="dotted key"):
            eoir.load_sensor("multimir", overrides={key: 2.0})
    # A string value holding TOML text stays a string: it sets nothing else.
    with pytest.raises(ValueError, match="f_number"):
        eoir.load_sensor("multimir", overrides={"optics.f_number": '2.0\n[detector]\nrows = 4'})
    # Typed values: NumPy scalars, bools, dicts as tables.
    s = eoir.load_sensor("multimir", overrides={
        "optics.f_number": np.float64(2.5), "detector.rows": np.int32(24),
        "optics.transmission": {"kind": "constant", "value": 0.5}})
    assert s.f_number == 2.5 and s.rows == 24 and base.rows != 24
    with pytest.raises(TypeError):
        eoir.load_sensor("multimir", overrides=["optics.f_number=2"])


def test_errors_speak_python(small_sensor):
    with pytest.raises(ValueError) as e:
        eoir.load_sensor("no-such-sensor")
    assert "--sensor" not in str(e.value) and "name_or_path" in str(e.value)
    with pytest.raises(ValueError) as e:
        eoir.load_sensor("multimir", options={"filter": "9"})
    assert "--option" not in str(e.value) and "options" in str(e.value)
    with pytest.raises(ValueError) as e:
        eoir.load_sensor("multimir", overrides={"detector.no_such_key": 1})
    assert "--set" not in str(e.value) and "no_such_key" in str(e.value)


def test_namespace_is_clean_and_documented():
    public = [n for n in dir(eoir) if not n.startswith("_")]
    for leaked in ("np", "json", "math", "Any", "Optional", "annotations", "os"):
        assert leaked not in public
    assert set(eoir.__all__) <= set(dir(eoir))
    for name in eoir.__all__:
        obj = getattr(eoir, name)
        if callable(obj) and not isinstance(obj, type):
            doc = inspect.getdoc(obj) or ""
            assert doc, name
            # numpydoc: every parameter named in a Parameters section.
            try:
                params = [p for p in inspect.signature(obj).parameters if p not in ("params",)]
            except (TypeError, ValueError):
                continue
            if params:
                assert "Parameters\n----------" in doc, name
                for p in params:
                    assert re.search(rf"^\**{p}\b", doc, re.M), f"{name}: `{p}` undocumented"
    assert "units" in eoir.run.__doc__ and "range_m" in eoir.run.__doc__
