//! `eoir._eoir`: the native half of the Python package `eoir`.
//!
//! Thin bindings over the eoir library: sensors, cubes, runs and transfer functions. The
//! pure-Python package (`python/eoir/`) wraps these in friendlier objects (dict options,
//! xarray, Dask). Conventions at this boundary:
//!
//! - Radiance arrives as a float32 NumPy array and is *borrowed* (an `ndarray` view of the
//!   NumPy buffer, strided or not): the engine copies one band plane at a time, as it does
//!   when it reads a file, never the whole cube. The Python side converts other dtypes.
//! - The GIL is released (`Python::detach`) while the engine runs.
//! - Library errors become Python exceptions with the library's message (the one the CLI
//!   prints): file errors `OSError`, everything else `ValueError`. A panic inside the engine
//!   is caught here and raised as `RuntimeError`, so no input can abort the interpreter.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;

use ndarray::{s, Array2, Array3, ArrayView4, Axis, Ix4};
use numpy::{
    IntoPyArray, PyReadonlyArray2, PyReadonlyArray3, PyReadonlyArrayDyn, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

use eoir::calibration::CalibrationOptions;
use eoir::io::CubeReader;
use eoir::pipeline::{self, RunOptions};
use eoir::scene::units::{parse_radiance, RadianceScale, EXAMPLES as UNIT_EXAMPLES};
use eoir::scene::{synthetic, Cube, CubeMeta, Geometry, RadianceUnits};
use eoir::sensor::config::MAX_OVERRIDE_DEPTH;
use eoir::sensor::{presets, Override, Sensor, SensorConfig};

/// The library's messages name command-line flags where the CLI is the caller; at this
/// boundary they name the Python parameter instead.
fn python_wording(msg: String) -> String {
    msg.replace("`--sensor`", "`name_or_path`")
        .replace("`--option ", "`options[")
        .replace("`--option`", "`options`")
        .replace("`--set`", "`overrides`")
        .replace("`--radiance-units`", "`radiance_units`")
        .replace("--radiance-units", "radiance_units=")
        .replace("pass --fov-deg H,V", "pass fov_deg=(H, V)")
        .replace("--fov-deg", "fov_deg")
        .replace(
            "raise it with --max-memory",
            "raise it with eoir.set_max_memory_bytes()",
        )
}

/// Library error → Python exception, keeping the library's message (CLI flags renamed to
/// the Python parameters, [`python_wording`]).
fn to_py(e: eoir::Error) -> PyErr {
    match e {
        eoir::Error::Io { .. } => PyOSError::new_err(python_wording(e.to_string())),
        eoir::Error::InvalidParameter {
            field,
            value,
            expected,
        } => {
            let field = match field.as_str() {
                "--sensor" => "name_or_path".to_string(),
                "--option" => "options".to_string(),
                f if f.starts_with("--option ") => {
                    format!("options['{}']", f.trim_start_matches("--option ").trim())
                }
                _ => field,
            };
            PyValueError::new_err(python_wording(
                eoir::Error::InvalidParameter {
                    field,
                    value,
                    expected,
                }
                .to_string(),
            ))
        }
        other => PyValueError::new_err(python_wording(other.to_string())),
    }
}

/// Runs `f`, turning a library error into a Python exception and a panic into
/// `RuntimeError` (a panic is a bug in eoir, never the caller's fault, but it must not take
/// the interpreter down).
fn guarded<T>(f: impl FnOnce() -> eoir::Result<T>) -> PyResult<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(r) => r.map_err(to_py),
        Err(payload) => {
            let msg = payload
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "unknown panic".into());
            Err(PyRuntimeError::new_err(format!(
                "internal error in eoir (please report it): {msg}"
            )))
        }
    }
}

/// Runs `f` with the GIL released, guarded as [`guarded`].
fn detached<T: Send>(py: Python<'_>, f: impl FnOnce() -> eoir::Result<T> + Send) -> PyResult<T> {
    py.detach(|| guarded(f))
}

/// A resolved, validated sensor description (immutable). Build one with
/// `eoir.load_sensor`.
#[pyclass(frozen, name = "Sensor", module = "eoir._eoir")]
struct PySensor {
    /// Resolved once (spectra sampled, transfer functions and detector model built), then
    /// shared by every run.
    inner: Sensor,
}

#[pymethods]
impl PySensor {
    /// The fully resolved description as TOML (what `eoir run` writes as `config.toml`;
    /// `eoir run --sensor FILE` and `eoir.load_sensor(FILE)` read it back).
    fn to_toml(&self) -> PyResult<String> {
        guarded(|| self.inner.to_toml_string())
    }
    /// This sensor with every transfer function switched off (diffraction, the detector
    /// footprint, aberration, defocus, motion, jitter, turbulence, aerosol, Gaussian,
    /// measured MTF, and `[optics.wavefront]`): the unblurred reference of a run
    /// (`SensorConfig::unblurred`, `eoir run --unblurred`).
    fn unblurred(&self) -> PyResult<PySensor> {
        guarded(|| Sensor::build(&self.inner.config().unblurred())).map(|inner| PySensor { inner })
    }
    /// Short name.
    #[getter]
    fn name(&self) -> String {
        self.inner.name.clone()
    }
    /// One-line description.
    #[getter]
    fn description(&self) -> String {
        self.inner.description.clone()
    }
    /// Preset options this sensor was resolved with (`{"filter": "4", ...}`).
    #[getter]
    fn options(&self) -> std::collections::BTreeMap<String, String> {
        self.inner.selected_options.clone()
    }
    /// Detector rows.
    #[getter]
    fn rows(&self) -> usize {
        self.inner.detector.rows
    }
    /// Detector columns.
    #[getter]
    fn cols(&self) -> usize {
        self.inner.detector.cols
    }
    /// Pixel pitch, m.
    #[getter]
    fn pitch_m(&self) -> f64 {
        self.inner.detector.pitch_m
    }
    /// ADC bits.
    #[getter]
    fn bits(&self) -> u32 {
        self.inner.detector.bits
    }
    /// Integration time, s.
    #[getter]
    fn integration_time_s(&self) -> f64 {
        self.inner.detector.integration_time_s
    }
    /// Full-well capacity, electrons.
    #[getter]
    fn full_well_e(&self) -> f64 {
        self.inner.detector.full_well_e
    }
    /// Focal length, m.
    #[getter]
    fn focal_length_m(&self) -> f64 {
        self.inner.optics.focal_length_m
    }
    /// F-number.
    #[getter]
    fn f_number(&self) -> f64 {
        self.inner.optics.f_number
    }
    /// Entrance-pupil diameter, m.
    #[getter]
    fn aperture_diameter_m(&self) -> f64 {
        self.inner.aperture_diameter_m()
    }
    /// Instantaneous field of view (pitch / focal length), rad.
    #[getter]
    fn ifov_rad(&self) -> f64 {
        self.inner.ifov_rad()
    }
    /// Full field of view (horizontal, vertical), degrees.
    #[getter]
    fn fov_deg(&self) -> (f64, f64) {
        self.inner.fov_deg()
    }
    /// The paraxial field the detector covers (horizontal, vertical), degrees: `cols·IFOV`,
    /// `rows·IFOV`, the rule the engine samples with (`eoir::scene::sizing`). Slightly
    /// wider than the datasheet's `fov_deg` (flat focal plane, `2·atan(n·p/2f)`).
    #[getter]
    fn paraxial_fov_deg(&self) -> (f64, f64) {
        use eoir::scene::sizing::paraxial_extent_rad;
        let i = self.inner.ifov_rad();
        (
            paraxial_extent_rad(self.inner.detector.cols, i).to_degrees(),
            paraxial_extent_rad(self.inner.detector.rows, i).to_degrees(),
        )
    }
    /// The field a scene must cover for this sensor (horizontal, vertical), degrees: the
    /// paraxial extent of the detector plus `margin_px` detector pixels each side, as
    /// `eoir scene --sensor` sizes its scenes (default margin 4 px, so the blur at the edge
    /// pixels reaches scene content). A cube whose `fov_deg` is at least this runs.
    #[pyo3(signature = (margin_px=4))]
    fn scene_extent_deg(&self, margin_px: usize) -> PyResult<(f64, f64)> {
        use eoir::scene::sizing::{paraxial_extent_rad, MAX_MARGIN_PX};
        if margin_px > MAX_MARGIN_PX {
            return Err(PyValueError::new_err(format!(
                "invalid parameter `margin_px` = {margin_px}: at most {MAX_MARGIN_PX} detector pixels per side"
            )));
        }
        let i = self.inner.ifov_rad();
        Ok((
            paraxial_extent_rad(self.inner.detector.cols + 2 * margin_px, i).to_degrees(),
            paraxial_extent_rad(self.inner.detector.rows + 2 * margin_px, i).to_degrees(),
        ))
    }
    /// Detector Nyquist frequency, cycles/mrad.
    #[getter]
    fn nyquist_cy_per_mrad(&self) -> f64 {
        self.inner.nyquist_cy_per_rad() * 1e-3
    }
    /// Whether the response reaches beyond 3 µm (radiance/temperature products exist).
    #[getter]
    fn thermal(&self) -> bool {
        self.inner.is_thermal()
    }
    /// Response-weighted mean wavelength, µm.
    #[getter]
    fn mean_wavelength_um(&self) -> PyResult<f64> {
        guarded(|| eoir::report::mean_wavelength_um(&self.inner))
    }
    /// Support of the spectral response (lowest, highest wavelength), µm.
    #[getter]
    fn band_um(&self) -> PyResult<(f64, f64)> {
        guarded(|| Ok(self.inner.response().support_um()))
    }
    /// Whether the conversion gain comes from the imaged scene (`[detector.auto_gain]
    /// reference = "scene_mean"`): then the first frame of each run sets it.
    #[getter]
    fn gain_from_scene(&self) -> PyResult<bool> {
        guarded(|| Ok(self.inner.detector().scene_mean_gain_fraction().is_some()))
    }
    /// Whether the focal plane traps charge from frame to frame (`[detector.persistence]`):
    /// a frame then depends on every earlier frame's image, so a piece of a 4-D input
    /// cannot start after the sequence start.
    #[getter]
    fn has_persistence(&self) -> bool {
        self.inner.config().detector.persistence.is_some()
    }
    /// Problems worth knowing about (assumed values, odd combinations).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.inner.warnings().to_vec()
    }
    fn __repr__(&self) -> String {
        let (h, v) = self.inner.fov_deg();
        format!(
            "<eoir.Sensor {:?} {}x{} px, f={} mm F/{}, FOV {:.3}x{:.3} deg>",
            self.inner.name,
            self.inner.detector.cols,
            self.inner.detector.rows,
            self.inner.optics.focal_length_m * 1e3,
            self.inner.optics.f_number,
            h,
            v
        )
    }
    fn __eq__(&self, other: PyRef<'_, PySensor>) -> bool {
        self.inner.config() == other.inner.config()
    }
    /// Pickling (Dask workers): the resolved TOML and the directory relative paths in it
    /// are resolved against.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, (String, String))> {
        let f = py.import("eoir._eoir")?.getattr("sensor_from_toml")?;
        Ok((
            f,
            (
                self.to_toml()?,
                self.inner.base_dir.to_string_lossy().into_owned(),
            ),
        ))
    }
}

/// A Python override value as a TOML value: bool, int (64-bit), float, str, list/tuple,
/// dict with str keys; NumPy scalars and arrays through `.item()` / `.tolist()`. Nesting
/// deeper than [`MAX_OVERRIDE_DEPTH`] (a self-containing list included) is a `ValueError`,
/// a value of another type a `TypeError`, both naming the key.
fn py_to_toml(v: &Bound<'_, PyAny>, key: &str, depth: usize) -> PyResult<toml::Value> {
    if depth > MAX_OVERRIDE_DEPTH {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `overrides[{key:?}]`: a value nested deeper than {MAX_OVERRIDE_DEPTH} levels of lists and dicts"
        )));
    }
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        return v.extract::<i64>().map(toml::Value::Integer).map_err(|_| {
            PyValueError::new_err(format!(
                "invalid parameter `overrides[{key:?}]` = {}: an integer from -2**63 to 2**63 - 1",
                v.str().map(|s| s.to_string()).unwrap_or_default()
            ))
        });
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        let mut t = toml::Table::new();
        for (k, x) in d.iter() {
            let k: String = k.extract().map_err(|_| {
                PyTypeError::new_err(format!(
                    "invalid parameter `overrides[{key:?}]`: dict keys must be str"
                ))
            })?;
            let sub = format!("{key}.{k}");
            t.insert(k, py_to_toml(&x, &sub, depth + 1)?);
        }
        return Ok(toml::Value::Table(t));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let mut a = Vec::new();
        for x in v.try_iter()? {
            a.push(py_to_toml(&x?, key, depth + 1)?);
        }
        return Ok(toml::Value::Array(a));
    }
    // NumPy: scalars (np.float64, np.int32, np.bool_) and arrays.
    let module = v
        .get_type()
        .module()
        .map(|m| m.to_string())
        .unwrap_or_default();
    if module == "numpy" {
        if v.hasattr("ndim")? && v.getattr("ndim")?.extract::<usize>()? > 0 {
            return py_to_toml(&v.call_method0("tolist")?, key, depth);
        }
        if v.hasattr("item")? {
            let item = v.call_method0("item")?;
            if item
                .get_type()
                .module()
                .map(|m| m.to_string())
                .unwrap_or_default()
                != "numpy"
            {
                return py_to_toml(&item, key, depth);
            }
        }
    }
    Err(PyTypeError::new_err(format!(
        "invalid parameter `overrides[{key:?}]` of type {}: a bool, int, float, str, list or dict",
        v.get_type()
            .name()
            .map(|n| n.to_string())
            .unwrap_or_default()
    )))
}

/// Loads a sensor: a preset name or a TOML file, with `name=value` option choices and
/// overrides given as `(key path, value)` pairs: the key is split at its dots, each part a
/// bare key, and the value converted from its Python type, so neither is ever read as
/// TOML text (`eoir::sensor::Override::new`).
#[pyfunction]
#[pyo3(signature = (name_or_path, options=Vec::new(), overrides=Vec::new()))]
fn load_sensor<'py>(
    name_or_path: &str,
    options: Vec<String>,
    overrides: Vec<(String, Bound<'py, PyAny>)>,
) -> PyResult<PySensor> {
    let overrides = overrides
        .iter()
        .map(|(k, v)| {
            let value = py_to_toml(v, k, 0)?;
            Override::new(k, value).map_err(to_py)
        })
        .collect::<PyResult<Vec<_>>>()?;
    guarded(|| Sensor::build(&presets::load_with(name_or_path, &options, &overrides)?))
        .map(|inner| PySensor { inner })
}

/// A sensor from resolved TOML text (`Sensor.to_toml()`); `base_dir` resolves relative
/// file references.
#[pyfunction]
#[pyo3(signature = (text, base_dir=".".to_string(), source="sensor TOML".to_string()))]
fn sensor_from_toml(text: &str, base_dir: String, source: String) -> PyResult<PySensor> {
    guarded(|| {
        Sensor::build(&SensorConfig::from_toml_str(
            text,
            &source,
            PathBuf::from(base_dir),
            &[],
        )?)
    })
    .map(|inner| PySensor { inner })
}

/// The built-in presets: name, description, options `{name: [values]}` and defaults.
#[pyfunction]
fn presets_info(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    let list = PyList::empty(py);
    for p in presets::list() {
        let d = PyDict::new(py);
        d.set_item("name", p.name)?;
        d.set_item("description", p.description)?;
        let opts = PyDict::new(py);
        for (n, v) in p.options {
            opts.set_item(n, v)?;
        }
        d.set_item("options", opts)?;
        let defs = PyDict::new(py);
        for (n, v) in p.defaults {
            defs.set_item(n, v)?;
        }
        d.set_item("defaults", defs)?;
        list.append(d)?;
    }
    Ok(list)
}

/// Radiance frames `[frame, band, row, col]` borrowed from NumPy, served band by band like
/// a file. Each plane is checked for NaN, ±Inf and negative values as it is read (the same
/// check and message as every file reader).
struct ArrayReader<'a> {
    data: ArrayView4<'a, f32>,
    meta: CubeMeta,
    source: String,
    /// Factor to eoir's units of the caller's unit string (1 for eoir's own).
    to_eoir: f64,
}

impl CubeReader for ArrayReader<'_> {
    fn meta(&self) -> &CubeMeta {
        &self.meta
    }
    fn frames(&self) -> usize {
        self.data.dim().0
    }
    fn read_band(&mut self, frame: usize, band: usize) -> eoir::Result<Array2<f32>> {
        let (nf, nb, _, _) = self.data.dim();
        if frame >= nf {
            return Err(eoir::Error::param("frame", frame, format!("< {nf} frames")));
        }
        if band >= nb {
            return Err(eoir::Error::param("band", band, format!("< {nb} bands")));
        }
        let plane = self.data.slice(s![frame, band, .., ..]);
        // Scaled exactly as the file readers scale a sample (`io::binary`: the value as
        // f64 times the factor, plus 0, rounded to f32), so an array in W m-2 sr-1 nm-1
        // equals the same values read from a file that declares those units.
        let plane = if self.to_eoir != 1.0 {
            let k = self.to_eoir;
            plane.mapv(|v| (k * f64::from(v) + 0.0) as f32)
        } else {
            plane.to_owned()
        };
        eoir::scene::check_radiance_plane(
            &self.source,
            band,
            self.meta.wavelength_um[band],
            plane.view(),
        )?;
        Ok(plane)
    }
}

/// Parses a radiance unit string in any spelling the file readers accept
/// (`eoir::scene::units`), naming what is valid.
fn parse_scale(units: &str) -> PyResult<RadianceScale> {
    parse_radiance(units).ok_or_else(|| {
        PyValueError::new_err(format!(
            "invalid parameter `units` = {:?}: a radiance unit such as {UNIT_EXAMPLES}",
            eoir::limits::escape_token(units)
        ))
    })
}

/// Parses a unit string that must be one of eoir's own (what a written cube declares).
fn parse_units(units: &str) -> PyResult<RadianceUnits> {
    RadianceUnits::parse(units).ok_or_else(|| {
        PyValueError::new_err(format!(
            "invalid parameter `units` = {:?}: \"{}\" (spectral radiance) or \"{}\" (band-integrated); convert other units before writing",
            eoir::limits::escape_token(units),
            RadianceUnits::SpectralPerUm.as_str(),
            RadianceUnits::BandIntegrated.as_str()
        ))
    })
}

/// Calibration options as `eoir run --nuc-degree N [--calibration-temperatures ...]`
/// builds them: `temperatures_k` empty means the sensor file's `[calibration]` section,
/// else `max(3, degree + 2)` levels from 10 % to 90 % of the sensor's range. A degree
/// outside 0 to `MAX_DEGREE` is an error before anything is built (`nuc_degree=10**9`).
fn calibration_options(degree: usize, temperatures_k: Vec<f64>) -> PyResult<CalibrationOptions> {
    let max = eoir::processing::nuc::MAX_DEGREE;
    if degree > max {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `nuc_degree` = {degree}: a NUC degree from 0 to {max}"
        )));
    }
    Ok(CalibrationOptions {
        temperatures_k,
        degree,
        ..Default::default()
    })
}

/// Stacks per-frame planes into `[frame, row, col]`.
fn stack<T: Clone + num_zero::Zero>(planes: &[&Array2<T>]) -> Array3<T> {
    let (r, c) = planes.first().map(|p| p.dim()).unwrap_or((0, 0));
    let mut out = Array3::<T>::from_elem((planes.len(), r, c), T::zero());
    for (i, p) in planes.iter().enumerate() {
        out.index_axis_mut(Axis(0), i).assign(*p);
    }
    out
}

/// Zero values for [`stack`] without another dependency.
mod num_zero {
    /// A type with a zero.
    pub trait Zero {
        /// The zero.
        fn zero() -> Self;
    }
    impl Zero for f32 {
        fn zero() -> Self {
            0.0
        }
    }
    impl Zero for u16 {
        fn zero() -> Self {
            0
        }
    }
}

/// Runs radiance through a sensor. `radiance` is float32 `[band, row, col]` or
/// `[frame, band, row, col]`. Returns a dict of NumPy arrays `[frame, row, col]`
/// (`dn`, `electrons_mean`, `radiance`/`temperature` or None), `report_json`,
/// `config_toml` and `warnings`.
#[pyfunction]
#[pyo3(signature = (sensor, radiance, wavelength_um, fov_deg, seed=1, frames=1,
    calibrate=true, nuc_degree=1, first_frame=0, range_m=None, units="W m-2 sr-1 um-1",
    fwhm_um=None, input_name="numpy array", calibration_temperatures_k=None,
    sequence_frames=None, assess=false, time_varying=false))]
#[allow(clippy::too_many_arguments)]
fn run<'py>(
    py: Python<'py>,
    sensor: &PySensor,
    radiance: PyReadonlyArrayDyn<'py, f32>,
    wavelength_um: Vec<f64>,
    fov_deg: (f64, f64),
    seed: u64,
    frames: usize,
    calibrate: bool,
    nuc_degree: usize,
    first_frame: u64,
    range_m: Option<f64>,
    units: &str,
    fwhm_um: Option<Vec<f64>>,
    input_name: &str,
    calibration_temperatures_k: Option<Vec<f64>>,
    sequence_frames: Option<u64>,
    assess: bool,
    time_varying: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let scale = parse_scale(units)?;
    let units = scale.units;
    let view = radiance.as_array();
    let data: ArrayView4<'_, f32> = match view.ndim() {
        3 => view.insert_axis(Axis(0)).into_dimensionality::<Ix4>(),
        4 => view.into_dimensionality::<Ix4>(),
        n => {
            return Err(PyValueError::new_err(format!(
                "invalid parameter `radiance` = array of {n} dimensions: [band, row, col] or [frame, band, row, col]"
            )))
        }
    }
    .map_err(|e| PyValueError::new_err(format!("radiance: {e}")))?;
    let (nf, nb, rows, cols) = data.dim();
    if nf == 0 {
        return Err(PyValueError::new_err(
            "invalid parameter `radiance` = 0 frames: at least one frame",
        ));
    }
    if wavelength_um.len() != nb {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `wavelength_um` = {} values: one per band of radiance ({nb})",
            wavelength_um.len()
        )));
    }
    let meta = CubeMeta {
        wavelength_um,
        fwhm_um,
        units,
        geometry: Some(Geometry {
            fov_x_deg: fov_deg.0,
            fov_y_deg: fov_deg.1,
            range_m,
        }),
        rows,
        cols,
    };
    let source = input_name.to_string();
    guarded(|| meta.validate(&source))?;
    let options = RunOptions {
        seed,
        frames,
        first_frame,
        sequence_frames,
        time_varying: time_varying || nf > 1,
        input_name: source.clone(),
        calibration: calibrate
            .then(|| {
                if calibration_temperatures_k.as_ref().is_some_and(Vec::is_empty) {
                    return Err(PyValueError::new_err(
                        "invalid parameter `calibration_temperatures_k` = []: at least two blackbody temperatures, K (or None for the default levels)",
                    ));
                }
                calibration_options(nuc_degree, calibration_temperatures_k.unwrap_or_default())
            })
            .transpose()?,
        ..Default::default()
    };
    let sensor = &sensor.inner;
    let out = detached(py, move || {
        if let Some(c) = &options.calibration {
            c.validate()?;
        }
        let mut reader = ArrayReader {
            data,
            meta,
            source,
            to_eoir: scale.to_eoir,
        };
        let mut out = pipeline::run(sensor, &mut reader, &options, |_, _| {})?;
        if assess {
            eoir::merit::run_report::attach(&mut out, &Default::default())?;
        }
        Ok(out)
    })?;
    let d = PyDict::new(py);
    let f = &out.frames;
    d.set_item(
        "dn",
        stack(&f.iter().map(|p| &p.dn).collect::<Vec<_>>()).into_pyarray(py),
    )?;
    d.set_item(
        "electrons_mean",
        stack(&f.iter().map(|p| &p.electrons_mean).collect::<Vec<_>>()).into_pyarray(py),
    )?;
    for (name, pick) in [
        (
            "radiance",
            (|p: &pipeline::FrameProducts| p.radiance.as_ref()) as fn(_) -> _,
        ),
        ("temperature", |p: &pipeline::FrameProducts| {
            p.temperature.as_ref()
        }),
    ] {
        let planes: Option<Vec<&Array2<f32>>> = f.iter().map(pick).collect();
        match planes {
            Some(p) => d.set_item(name, stack(&p).into_pyarray(py))?,
            None => d.set_item(name, py.None())?,
        }
    }
    let report = serde_json::to_string(&out.report)
        .map_err(|e| PyValueError::new_err(format!("report: {e}")))?;
    d.set_item("report_json", report)?;
    d.set_item("config_toml", guarded(|| out.sensor.to_toml_string())?)?;
    d.set_item("warnings", out.warnings)?;
    // A moving camera's truth table (`los.csv`): one column per field.
    let los = match &out.line_of_sight {
        Some(rows) => {
            let t = PyDict::new(py);
            let col = |f: &dyn Fn(&eoir::pipeline::motion::TruthRow) -> f64| -> Vec<f64> {
                rows.iter().map(f).collect()
            };
            t.set_item("frame", rows.iter().map(|r| r.frame).collect::<Vec<u64>>())?;
            t.set_item(
                "row_first",
                rows.iter().map(|r| r.rows.0).collect::<Vec<usize>>(),
            )?;
            t.set_item(
                "row_last",
                rows.iter().map(|r| r.rows.1).collect::<Vec<usize>>(),
            )?;
            t.set_item("t_start_s", col(&|r| r.window_s.0))?;
            t.set_item("t_end_s", col(&|r| r.window_s.1))?;
            t.set_item("dx_px", col(&|r| r.displacement_px[0]))?;
            t.set_item("dy_px", col(&|r| r.displacement_px[1]))?;
            t.set_item("smear_px", col(&|r| r.smear_px))?;
            Some(t)
        }
        None => None,
    };
    d.set_item("line_of_sight", los)?;
    d.set_item(
        "focal_plane",
        focal_plane_dict(py, out.focal_plane.as_ref())?,
    )?;
    Ok(d)
}

/// The focal plane's truth (`rts.csv`, `trapped_e.npy`, `drift_*.npy`) as NumPy arrays:
/// `rts_row`, `rts_col` `[pixel]`, `rts_high_fraction` `[frame, pixel]`,
/// `rts_high_at_readout` `[frame, pixel]` (bool), `trapped_e`, `drift_gain`,
/// `drift_offset_e` `[frame, row, col]`; each only when its effect is on. `None` without a
/// focal-plane memory.
fn focal_plane_dict<'py>(
    py: Python<'py>,
    truth: Option<&eoir::pipeline::focal_plane::FocalPlaneTruth>,
) -> PyResult<Option<Bound<'py, PyDict>>> {
    let Some(t) = truth else { return Ok(None) };
    let d = PyDict::new(py);
    let n = t.frames.len();
    let px = t.rts_pixels.len();
    if t.frames.iter().all(|f| f.rts.is_some()) && n > 0 {
        d.set_item(
            "rts_row",
            t.rts_pixels.iter().map(|p| p / t.cols).collect::<Vec<_>>(),
        )?;
        d.set_item(
            "rts_col",
            t.rts_pixels.iter().map(|p| p % t.cols).collect::<Vec<_>>(),
        )?;
        let frac = Array2::from_shape_fn((n, px), |(k, i)| {
            t.frames[k].rts.as_ref().map_or(0.0, |r| r.high_fraction[i])
        });
        let high = Array2::from_shape_fn((n, px), |(k, i)| {
            t.frames[k]
                .rts
                .as_ref()
                .is_some_and(|r| r.high_at_readout[i])
        });
        d.set_item("rts_high_fraction", frac.into_pyarray(py))?;
        d.set_item("rts_high_at_readout", high.into_pyarray(py))?;
    }
    let trapped: Option<Vec<&Array2<f32>>> =
        t.frames.iter().map(|f| f.trapped_e.as_ref()).collect();
    if let Some(p) = trapped.filter(|p| !p.is_empty()) {
        d.set_item("trapped_e", stack(&p).into_pyarray(py))?;
    }
    let drift: Option<Vec<&(Array2<f32>, Array2<f32>)>> =
        t.frames.iter().map(|f| f.drift.as_ref()).collect();
    if let Some(p) = drift.filter(|p| !p.is_empty()) {
        let gains: Vec<&Array2<f32>> = p.iter().map(|(g, _)| g).collect();
        let offsets: Vec<&Array2<f32>> = p.iter().map(|(_, o)| o).collect();
        d.set_item("drift_gain", stack(&gains).into_pyarray(py))?;
        d.set_item("drift_offset_e", stack(&offsets).into_pyarray(py))?;
    }
    Ok(Some(d))
}

/// A cube's arrays and metadata as a dict (`radiance` `[band, row, col]`, or
/// `[frame, band, row, col]` when there is more than one frame).
fn cube_dict<'py>(
    py: Python<'py>,
    radiance: ndarray::ArrayD<f32>,
    meta: &CubeMeta,
    frame_time_s: Option<f64>,
    warnings: Vec<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("radiance", radiance.into_pyarray(py))?;
    d.set_item("wavelength_um", meta.wavelength_um.clone())?;
    d.set_item("fwhm_um", meta.fwhm_um.clone())?;
    d.set_item("units", meta.units.as_str())?;
    d.set_item("fov_deg", meta.geometry.map(|g| (g.fov_x_deg, g.fov_y_deg)))?;
    d.set_item("range_m", meta.geometry.and_then(|g| g.range_m))?;
    d.set_item("frame_time_s", frame_time_s)?;
    d.set_item("warnings", warnings)?;
    Ok(d)
}

/// Reads a cube file (ENVI, spectral EXR, NPY, HDF5 with the feature), every frame;
/// `radiance_units` replaces the units the file states (the CLI's `--radiance-units`).
#[pyfunction]
#[pyo3(signature = (path, radiance_units=None))]
fn read_cube<'py>(
    py: Python<'py>,
    path: PathBuf,
    radiance_units: Option<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let options = eoir::io::ReadOptions {
        radiance_units,
        ..Default::default()
    };
    let (data, meta, ft, warnings) = detached(py, || {
        let mut r = eoir::io::open_with(&path, &options)?;
        let meta = r.meta().clone();
        let nf = r.frames();
        let mut data = ndarray::Array4::<f32>::zeros((nf, meta.bands(), meta.rows, meta.cols));
        for f in 0..nf {
            for b in 0..meta.bands() {
                let plane = r.read_band(f, b)?;
                data.slice_mut(s![f, b, .., ..]).assign(&plane);
            }
        }
        let data = if nf == 1 {
            data.index_axis_move(Axis(0), 0).into_dyn()
        } else {
            data.into_dyn()
        };
        Ok((data, meta, r.frame_time_s(), r.warnings()))
    })?;
    cube_dict(py, data, &meta, ft, warnings)
}

/// Writes a `[band, row, col]` cube, format from the extension, atomically.
#[pyfunction]
#[pyo3(signature = (path, radiance, wavelength_um, fov_deg=None, units="W m-2 sr-1 um-1",
    range_m=None, fwhm_um=None))]
#[allow(clippy::too_many_arguments)]
fn write_cube(
    py: Python<'_>,
    path: PathBuf,
    radiance: PyReadonlyArrayDyn<'_, f32>,
    wavelength_um: Vec<f64>,
    fov_deg: Option<(f64, f64)>,
    units: &str,
    range_m: Option<f64>,
    fwhm_um: Option<Vec<f64>>,
) -> PyResult<()> {
    let units = parse_units(units)?;
    if radiance.ndim() != 3 {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `radiance` = array of {} dimensions: [band, row, col] (one frame per file)",
            radiance.ndim()
        )));
    }
    let data = radiance
        .as_array()
        .into_dimensionality::<ndarray::Ix3>()
        .map_err(|e| PyValueError::new_err(format!("radiance: {e}")))?
        .to_owned();
    let (_, rows, cols) = data.dim();
    let meta = CubeMeta {
        wavelength_um,
        fwhm_um,
        units,
        geometry: fov_deg.map(|(h, v)| Geometry {
            fov_x_deg: h,
            fov_y_deg: v,
            range_m,
        }),
        rows,
        cols,
    };
    detached(py, move || {
        let cube = Cube::new(data, meta)?;
        cube.check(&path.display().to_string())?;
        eoir::io::write_cube(&path, &cube)
    })
}

/// The sensor's transfer functions along one frequency axis: each enabled component and
/// their product `system` (signed), at `wavelength_um` (default: the response-weighted mean
/// wavelength). Frequencies are angular, cycles/mrad in object space. With `field` (a
/// normalised field height in [0, 1]), also the pupil MTF of `[optics.wavefront]` along the
/// field direction (`pupil_tangential`) and across it (`pupil_sagittal`), as the columns
/// `eoir mtf --field` adds (docs/wavefront.md).
#[pyfunction]
#[pyo3(signature = (sensor, freq_cy_per_mrad, wavelength_um=None, field=None))]
fn mtf<'py>(
    py: Python<'py>,
    sensor: &PySensor,
    freq_cy_per_mrad: Vec<f64>,
    wavelength_um: Option<f64>,
    field: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let s = &sensor.inner;
    let (lambda, columns) = guarded(|| {
        let lambda = match wavelength_um {
            Some(w) => eoir::error::require_positive("wavelength_um", w)?,
            None => eoir::report::mean_wavelength_um(s)?,
        };
        if let Some(f) = freq_cy_per_mrad.iter().find(|f| !f.is_finite()) {
            return Err(eoir::Error::param(
                "freq_cy_per_mrad",
                f,
                "finite frequencies",
            ));
        }
        let otf = s.otf();
        let mut columns: Vec<(String, Vec<f64>)> = otf
            .components()
            .iter()
            .map(|c| {
                let v = freq_cy_per_mrad
                    .iter()
                    .map(|f| otf.component(*c, f * 1e3, 0.0, lambda))
                    .collect();
                (c.name().to_string(), v)
            })
            .collect();
        columns.push((
            "system".into(),
            freq_cy_per_mrad
                .iter()
                .map(|f| otf.evaluate(f * 1e3, 0.0, lambda))
                .collect(),
        ));
        if let Some(h) = field {
            // As `eoir mtf --field`: padding 2, frequency along y (the field direction) for
            // the tangential curve, along x for the sagittal one.
            let t = eoir::sensor::wavefront::pupil_transfer(s, h, lambda * 1e-6, 2)?;
            let f_cy_per_rad: Vec<f64> = freq_cy_per_mrad.iter().map(|f| f * 1e3).collect();
            let (tan, sag) = t.tangential_sagittal_cy_per_rad(&f_cy_per_rad);
            columns.push(("pupil_tangential".into(), tan));
            columns.push(("pupil_sagittal".into(), sag));
        }
        Ok((lambda, columns))
    })?;
    let d = PyDict::new(py);
    d.set_item("wavelength_um", lambda)?;
    d.set_item("freq_cy_per_mrad", freq_cy_per_mrad.into_pyarray(py))?;
    if let Some(h) = field {
        d.set_item("field", h)?;
    }
    for (n, v) in columns {
        d.set_item(n, v.into_pyarray(py))?;
    }
    Ok(d)
}

/// What `psf` computes: wavelength (µm), PSF sample (rad), the cropped PSFs (field, y, x),
/// centroid x and y (µrad), FWHM (µrad) and Strehl per field point, pupil samples across.
type PsfTable = (f64, f64, Array3<f64>, [Vec<f64>; 4], Vec<u64>);

/// The pupil PSF at each normalised field height, as `eoir psf` computes it
/// (docs/wavefront.md): `[optics.wavefront]` and the `[optics]` aperture, at `wavelength_um`
/// (default: the response-weighted mean wavelength), sampled at λ/(4D). Returns the PSF
/// pictures (field, y, x) cropped to ±`half_width_lambda_over_d` λ/D around the grid centre
/// (unit sum over the full grid; y is the tangential axis, increasing with the row), the
/// sample in rad, and the centroid (µrad), FWHM (µrad), Strehl ratio and pupil samples per
/// field point, the numbers `psf.json` holds.
#[pyfunction]
#[pyo3(signature = (sensor, field, wavelength_um=None, half_width_lambda_over_d=12.0))]
fn psf<'py>(
    py: Python<'py>,
    sensor: &PySensor,
    field: Vec<f64>,
    wavelength_um: Option<f64>,
    half_width_lambda_over_d: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let s = &sensor.inner;
    let hw = half_width_lambda_over_d;
    let (lambda, sample_rad, images, stats, samples_across) =
        detached(py, || -> eoir::Result<PsfTable> {
            let lambda = match wavelength_um {
                Some(w) => eoir::error::require_positive("wavelength_um", w)?,
                None => eoir::report::mean_wavelength_um(s)?,
            };
            if !(hw.is_finite() && (1.0..=64.0).contains(&hw)) {
                return Err(eoir::Error::param(
                    "half_width_lambda_over_d",
                    hw,
                    "a number in [1, 64]",
                ));
            }
            if field.is_empty() || field.len() > 16 {
                return Err(eoir::Error::param(
                    "field",
                    field.len(),
                    "1 to 16 field heights",
                ));
            }
            let mut transfers = Vec::with_capacity(field.len());
            for &h in &field {
                transfers.push(eoir::sensor::wavefront::pupil_transfer(
                    s,
                    h,
                    lambda * 1e-6,
                    4,
                )?);
            }
            // λ/D is `padding` = 4 PSF samples; one crop for every field point.
            let half = transfers
                .iter()
                .map(|t| t.psf().nrows() as i64 / 2 - 1)
                .fold((hw * 4.0).round() as i64, i64::min);
            let side = (2 * half + 1) as usize;
            let mut images = Array3::<f64>::zeros((field.len(), side, side));
            let mut stats: [Vec<f64>; 4] = Default::default();
            let mut samples_across = Vec::with_capacity(field.len());
            for (k, t) in transfers.iter().enumerate() {
                let p = t.psf();
                let m = p.nrows() as i64;
                let lo = (m / 2 - half) as usize;
                images
                    .slice_mut(s![k, .., ..])
                    .assign(&p.slice(s![lo..lo + side, lo..lo + side]));
                let (cx, cy) = t.centroid_rad();
                stats[0].push(cx * 1e6);
                stats[1].push(cy * 1e6);
                stats[2].push(t.fwhm_rad() * 1e6);
                stats[3].push(t.strehl());
                samples_across.push(t.sampling().samples_across as u64);
            }
            let sample_rad = transfers[0].psf_sample_rad();
            Ok((lambda, sample_rad, images, stats, samples_across))
        })?;
    let d = PyDict::new(py);
    d.set_item("wavelength_um", lambda)?;
    d.set_item("psf_sample_rad", sample_rad)?;
    d.set_item("field", field.into_pyarray(py))?;
    d.set_item("psf", images.into_pyarray(py))?;
    let names = ["centroid_x_urad", "centroid_y_urad", "fwhm_urad", "strehl"];
    for (n, v) in names.into_iter().zip(stats) {
        d.set_item(n, v.into_pyarray(py))?;
    }
    d.set_item("samples_across_pupil", samples_across.into_pyarray(py))?;
    Ok(d)
}

/// A built-in synthetic scene (as `eoir scene KIND`): `thermal`, `bars`, `edge`,
/// `blackbody`, `ramp`. Returns the same dict as `read_cube`.
#[pyfunction]
#[pyo3(signature = (kind, rows=288, cols=384, oversampling=1, lo_um=3.0, hi_um=5.5, bands=51,
    fov_deg=5.28, range_m=None, seed=1, night=false, temperature_k=300.0, emissivity=1.0,
    t_low_k=295.0, t_high_k=305.0, angle_deg=5.0, wavelength_um=None))]
#[allow(clippy::too_many_arguments)]
fn scene<'py>(
    py: Python<'py>,
    kind: &str,
    rows: usize,
    cols: usize,
    oversampling: usize,
    lo_um: f64,
    hi_um: f64,
    bands: usize,
    fov_deg: f64,
    range_m: Option<f64>,
    seed: u64,
    night: bool,
    temperature_k: f64,
    emissivity: f64,
    t_low_k: f64,
    t_high_k: f64,
    angle_deg: f64,
    wavelength_um: Option<Vec<f64>>,
) -> PyResult<Bound<'py, PyDict>> {
    let kind = kind.to_string();
    let cube = detached(py, move || {
        let wavelength_um = match wavelength_um {
            Some(w) => w,
            None => synthetic::SceneParams::uniform_grid(lo_um, hi_um, bands)?,
        };
        let params = synthetic::SceneParams {
            rows,
            cols,
            oversampling,
            wavelength_um,
            fov_x_deg: fov_deg,
            range_m,
            seed,
            sun: !night,
        };
        match kind.as_str() {
            "thermal" => synthetic::thermal(&params),
            "bars" => synthetic::bars(&params, t_high_k, t_low_k),
            "edge" => synthetic::edge(&params, t_low_k, t_high_k, angle_deg),
            "blackbody" => synthetic::blackbody(&params, temperature_k, emissivity),
            "ramp" => synthetic::ramp(&params, t_low_k, t_high_k),
            other => Err(eoir::Error::param(
                "kind",
                other,
                format!(
                    "one of: {}",
                    synthetic::KINDS
                        .iter()
                        .map(|(n, _)| *n)
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )),
        }
    })?;
    let meta = cube.meta.clone();
    cube_dict(py, cube.data.into_dyn(), &meta, None, Vec::new())
}

/// The scene size that covers `sensor` (as `eoir scene --sensor` and `eoir demo` size it,
/// `eoir::scene::sizing`): `{rows, cols, oversampling, fov_deg, wavelength_um}` with
/// `oversampling` scene samples per detector pixel, `margin_px` detector pixels of scene
/// beyond each edge, and the wavelength grid across the sensor's response.
#[pyfunction]
#[pyo3(signature = (sensor, oversampling=2, margin_px=4))]
fn covering_params<'py>(
    py: Python<'py>,
    sensor: &PySensor,
    oversampling: usize,
    margin_px: usize,
) -> PyResult<Bound<'py, PyDict>> {
    use eoir::scene::sizing;
    let s = &sensor.inner;
    let (params, wavelength_um) = guarded(|| {
        let (lo, hi) = s.response().support_um();
        let wavelength_um = sizing::response_grid_um(lo, hi)?;
        let grid = sizing::DetectorGrid {
            rows: s.detector.rows,
            cols: s.detector.cols,
            ifov_rad: s.ifov_rad(),
        };
        Ok((
            sizing::covering(&grid, oversampling, margin_px)?,
            wavelength_um,
        ))
    })?;
    let d = PyDict::new(py);
    d.set_item("rows", params.rows)?;
    d.set_item("cols", params.cols)?;
    d.set_item("oversampling", params.oversampling)?;
    d.set_item("fov_deg", params.fov_x_deg)?;
    d.set_item("wavelength_um", wavelength_um)?;
    Ok(d)
}

// ---- the toolbox: restore, edge MTF, NUC, EMVA 1288 (the CLI commands' library calls) ----
//
// Each function below performs the same library calls, in the same order and with the same
// arithmetic, as its command in `src/cli/` (restore.rs, edge_mtf.rs, nuc.rs,
// characterize.rs), on arrays instead of files; python/tests/test_toolbox.py checks the
// results against the CLI's files bit for bit.

/// Peak memory of a restoration per image pixel, bytes (the CLI's
/// `RESTORE_BYTES_PER_PIXEL`, measured there).
const RESTORE_BYTES_PER_PIXEL: u64 = 192;
/// Peak memory of an edge-MTF measurement per image pixel, bytes (the CLI's).
const EDGE_MTF_BYTES_PER_PIXEL: u64 = 64;

/// Wiener restoration of a recorded image with the sensor's transfer function (as `eoir
/// restore`). `image` is f64 `[row, col]`; `is_dn` says it holds DN (else f32 values in
/// `units`, "electrons" or "radiance"). Returns `{restored (f32, what restored.tiff
/// holds), report_json (restore.json)}`.
#[pyfunction]
#[pyo3(signature = (sensor, image, is_dn, noise="auto", nsr=None, black_level=None,
    units="electrons", input_name="numpy array"))]
#[allow(clippy::too_many_arguments)]
fn restore<'py>(
    py: Python<'py>,
    sensor: &PySensor,
    image: PyReadonlyArray2<'py, f64>,
    is_dn: bool,
    noise: &str,
    nsr: Option<f64>,
    black_level: Option<f64>,
    units: &str,
    input_name: &str,
) -> PyResult<Bound<'py, PyDict>> {
    use eoir::processing::bad_pixels::{find_image_defects, replace};
    use eoir::processing::wiener::{
        self, Method, NoiseRule, RestoreMasks, SensorTransfer, IMPULSE_K_SIGMA,
    };
    let sensor = &sensor.inner;
    let image = image.as_array().to_owned();
    let (rows, cols) = image.dim();
    if (rows, cols) != (sensor.detector.rows, sensor.detector.cols) {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `image` = {rows} x {cols} pixels (rows x cols): sensor `{}` records {} x {}; restore an image with the sensor that recorded it",
            sensor.name, sensor.detector.rows, sensor.detector.cols
        )));
    }
    if !matches!(noise, "auto" | "model") {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `noise` = {:?}: \"auto\" or \"model\"",
            eoir::limits::escape_token(noise)
        )));
    }
    if !matches!(units, "electrons" | "radiance") {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `units` = {:?}: \"electrons\" or \"radiance\" (of a float image)",
            eoir::limits::escape_token(units)
        )));
    }
    if nsr.is_some() && noise != "auto" {
        return Err(PyValueError::new_err(
            "invalid parameters: give `nsr` (a constant noise-to-signal ratio) or `noise`, not both",
        ));
    }
    let noise = noise.to_string();
    let units = if is_dn {
        "DN".to_string()
    } else {
        units.to_string()
    };
    let input_name = input_name.to_string();
    let (restored, report) = detached(py, move || {
        eoir::limits::check_alloc(
            "restoring the image",
            &[("rows", rows as u64), ("columns", cols as u64)],
            RESTORE_BYTES_PER_PIXEL,
        )?;
        let model = sensor.detector();
        let black = if is_dn {
            let b = black_level.unwrap_or_else(|| model.expected_dn(0.0));
            if !b.is_finite() || b < 0.0 {
                return Err(eoir::Error::param("black_level", b, "a finite DN >= 0"));
            }
            b
        } else {
            if black_level.is_some() {
                return Err(eoir::Error::param(
                    "black_level",
                    black_level.unwrap_or_default(),
                    "None for a float image (a black level applies to DN)",
                ));
            }
            0.0
        };
        // As `eoir restore` on an image without its run's instance.json: the defect
        // clusters and saturated regions found in the image.
        let found =
            find_image_defects(image.view(), IMPULSE_K_SIGMA, is_dn.then(|| model.max_dn()))?;
        let replaced = found.defects.count();
        let clean = if replaced > 0 {
            replace(image.view(), &found.defects)?
        } else {
            image.clone()
        };
        let signal = clean.mapv(|v| v - black);
        let rule = match (nsr, noise.as_str()) {
            (Some(x), _) => NoiseRule::Constant(x),
            (None, "model") => {
                let mean = signal.mean().unwrap_or(0.0);
                let variance = if is_dn {
                    let k = model.gain_dn_per_e();
                    let mean_e = (mean / k).max(0.0);
                    model.temporal_noise_dn(mean_e).powi(2) + model.quantisation_noise_dn().powi(2)
                } else if units == "electrons" {
                    model.temporal_noise_e(mean.max(0.0)).powi(2)
                } else {
                    return Err(eoir::Error::param(
                        "noise",
                        "model",
                        "\"auto\" or a constant `nsr` for a radiance image (the model needs DN or electrons to know the noise level)",
                    ));
                };
                NoiseRule::Model {
                    noise_variance: variance,
                }
            }
            (None, _) => NoiseRule::Auto,
        };
        let transfer = SensorTransfer::new(sensor)?;
        let noise_mask = found.defects.union(&found.saturated)?;
        let masks = RestoreMasks {
            noise: Some(&noise_mask),
            saturated: (found.saturated.count() > 0).then_some(&found.saturated),
        };
        let r = wiener::restore(signal.view(), &transfer, rule, Method::Auto, masks)?;
        let restored = r.image.mapv(|v| v + black);
        let report = serde_json::json!({
            "input": input_name,
            "sensor": sensor.name,
            "options": sensor.selected_options,
            "units": units,
            "black_level_dn": if is_dn { Some(black) } else { None },
            "pixels_replaced": replaced,
            "noise_rule": r.rule,
            "nsr": match rule { NoiseRule::Constant(x) => serde_json::json!(x), _ => serde_json::json!(null) },
            "nsr_median": r.nsr_median,
            "noise_power": r.noise_power,
            "noise_sigma": r.noise_sigma,
            "defects": {
                "source": "image",
                "replaced": replaced,
                "clusters": found.clusters,
                "largest_cluster_px": found.largest_cluster,
                "saturated_px": found.saturated.count(),
                "saturated_raised_px": r.saturated_raised,
                "saturated_filled_px": r.saturated_filled,
            },
            "method": r.method,
            "method_requested": if nsr.is_some() { "constant" } else { "auto" },
            "candidates": r.candidates.iter().map(|c| serde_json::json!({"method": c.name, "parameter": c.parameter, "relative_error": c.relative_risk})).collect::<Vec<_>>(),
            "sharpness_guard_bins": r.guarded_bins,
            "noise_sigma_measured": r.noise_sigma_measured,
            "object_spectrum_exponent": r.spectrum_exponent,
            "transfer_function": {
                "mtf_at_nyquist_x": transfer.eval(0.5, 0.0),
                "mtf_at_nyquist_y": transfer.eval(0.0, 0.5),
                "spectral_weighting_temperature_k": transfer.reference_temperature_k(),
                "components": sensor.otf().components().iter().map(|c| c.name()).collect::<Vec<_>>(),
            },
            "padded_shape": [r.padded_shape.0, r.padded_shape.1],
            "input_stats": eoir::processing::wiener::ImageStats::of(&image),
            "output_stats": eoir::processing::wiener::ImageStats::of(&restored),
        });
        let text = serde_json::to_string(&report)
            .map_err(|e| eoir::Error::param("report", "restore", e.to_string()))?;
        let restored = restored.mapv(|v| v as f32);
        if let Some(v) = restored.iter().find(|v| !v.is_finite()) {
            return Err(eoir::Error::OutOfRange(format!(
                "the restored image holds a value float32 cannot hold ({v}); check the input for extreme pixels"
            )));
        }
        Ok((restored, text))
    })?;
    let d = PyDict::new(py);
    d.set_item("restored", restored.into_pyarray(py))?;
    d.set_item("report_json", report)?;
    Ok(d)
}

/// ISO 12233 slanted-edge MTF of an image (as `eoir edge-mtf`): `image` f64 `[row, col]`,
/// `roi` `(x, y, width, height)` or None, `sensor` (adds cycles/mrad) or None. Returns
/// `{freq_cy_per_px, mtf, esf, report_json}` (report_json: edge_mtf.json's fields).
#[pyfunction]
#[pyo3(signature = (image, roi=None, sensor=None, input_name="numpy array"))]
fn edge_mtf<'py>(
    py: Python<'py>,
    image: PyReadonlyArray2<'py, f64>,
    roi: Option<(usize, usize, usize, usize)>,
    sensor: Option<PyRef<'py, PySensor>>,
    input_name: &str,
) -> PyResult<Bound<'py, PyDict>> {
    use eoir::processing::edge_mtf::{interpolate, slanted_edge_mtf, Roi, OVERSAMPLING};
    use eoir::processing::wiener::IMPULSE_K_SIGMA;
    let image = image.as_array().to_owned();
    let (rows, cols) = image.dim();
    let full_scale = sensor.as_ref().map(|s| s.inner.detector().max_dn());
    let sensor_info = sensor.as_ref().map(|s| {
        (
            s.inner.name.clone(),
            s.inner.ifov_rad() * 1e3,
            (s.inner.detector.rows, s.inner.detector.cols),
        )
    });
    if let Some((name, _, dim)) = &sensor_info {
        if (rows, cols) != *dim {
            return Err(PyValueError::new_err(format!(
                "invalid parameter `image` = {rows} x {cols} pixels (rows x cols): sensor `{name}` records {} x {}",
                dim.0, dim.1
            )));
        }
    }
    let input_name = input_name.to_string();
    let (m, report) = detached(py, move || {
        eoir::limits::check_alloc(
            "measuring the edge",
            &[("rows", rows as u64), ("columns", cols as u64)],
            EDGE_MTF_BYTES_PER_PIXEL,
        )?;
        let roi = roi.map(|(x, y, width, height)| Roi {
            x,
            y,
            width,
            height,
        });
        // As `eoir edge-mtf` on an image without its run's instance: the clusters of
        // dead, hot and stuck pixels found in the image, replaced by good neighbours.
        let found = eoir::processing::bad_pixels::find_image_defects(
            image.view(),
            IMPULSE_K_SIGMA,
            full_scale,
        )?;
        let replaced = found.defects.count();
        let clean = if replaced > 0 {
            eoir::processing::bad_pixels::replace(image.view(), &found.defects)?
        } else {
            image.clone()
        };
        let m = slanted_edge_mtf(clean.view(), roi)?;
        let ifov_mrad = sensor_info.as_ref().map(|s| s.1);
        let report = serde_json::json!({
            "image": input_name,
            "roi": { "x": m.roi.x, "y": m.roi.y, "width": m.roi.width, "height": m.roi.height },
            "edge_angle_deg": m.angle_deg,
            "edge_orientation": if m.vertical { "near-vertical" } else { "near-horizontal" },
            "mtf50_cy_per_px": m.mtf50_cy_per_px,
            "mtf50_cy_per_mrad": match (m.mtf50_cy_per_px, ifov_mrad) { (Some(f), Some(i)) => Some(f / i), _ => None },
            "mtf_at_nyquist": interpolate(&m.freq_cy_per_px, &m.mtf, 0.5),
            "edge_contrast": m.contrast,
            "noise_rms": m.noise_rms,
            "pixels_replaced": replaced,
            "sensor": sensor_info.as_ref().map(|s| s.0.clone()),
            "oversampling": OVERSAMPLING,
        });
        let text = serde_json::to_string(&report)
            .map_err(|e| eoir::Error::param("report", "edge_mtf", e.to_string()))?;
        Ok((m, text))
    })?;
    let d = PyDict::new(py);
    d.set_item("freq_cy_per_px", m.freq_cy_per_px.into_pyarray(py))?;
    d.set_item("mtf", m.mtf.into_pyarray(py))?;
    d.set_item("esf", m.esf.into_pyarray(py))?;
    d.set_item("report_json", report)?;
    Ok(d)
}

/// Per-pixel NUC polynomials and their bad-pixel map, fitted by `eoir.nuc_fit` or
/// loaded from the files `eoir nuc fit` writes (`Nuc.load`).
#[pyclass(frozen, name = "Nuc", module = "eoir._eoir")]
struct PyNuc {
    inner: eoir::processing::nuc::NucCoefficients,
}

#[pymethods]
impl PyNuc {
    /// Reads coefficients written by `eoir nuc fit` or `Nuc.save` (the .json or the .npy).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let npy = path.with_extension("npy");
        detached(py, move || {
            eoir::processing::nuc::NucCoefficients::load(&npy)
        })
        .map(|inner| PyNuc { inner })
    }
    /// Writes `NAME.npy` (coefficients) and `NAME.json` (sidecar) as `eoir nuc fit` does;
    /// `path` ends in .json or .npy.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let npy = nuc_npy_path(&path)?;
        detached(py, || self.inner.save(&npy))
    }
    /// Polynomial degree.
    #[getter]
    fn degree(&self) -> usize {
        self.inner.degree()
    }
    /// Frame size (rows, cols).
    #[getter]
    fn shape(&self) -> (usize, usize) {
        self.inner.dim()
    }
    /// Bad-pixel map, bool `[row, col]` (True: replaced by its neighbours' median).
    #[getter]
    fn bad_pixels<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray2<bool>> {
        self.inner.bad_pixel_map().mask().clone().into_pyarray(py)
    }
    /// Coefficients `[degree + 1, row, col]` of the polynomial in the normalised signal
    /// (see `signal_normalisation`).
    #[getter]
    fn coefficients<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray3<f64>> {
        self.inner.coefficients().clone().into_pyarray(py)
    }
    /// (centre, scale) of the signal normalisation the polynomials are evaluated in.
    #[getter]
    fn signal_normalisation(&self) -> (f64, f64) {
        self.inner.signal_normalisation()
    }
    /// Pixels whose fit was rank-deficient, `[(row, col), ...]`.
    #[getter]
    fn rank_deficient(&self) -> Vec<(usize, usize)> {
        self.inner.rank_deficient().to_vec()
    }
    fn __repr__(&self) -> String {
        let (r, c) = self.inner.dim();
        format!(
            "<eoir.Nuc degree {} {r}x{c} px, {} bad pixel(s)>",
            self.inner.degree(),
            self.inner.bad_pixel_map().count()
        )
    }
}

/// The `.npy` path of a NUC file name ending in .json or .npy.
fn nuc_npy_path(path: &std::path::Path) -> PyResult<PathBuf> {
    match path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .as_deref()
    {
        Some("json") | Some("npy") => Ok(path.with_extension("npy")),
        _ => Err(PyValueError::new_err(format!(
            "invalid parameter `path` = {:?}: a file name ending in .json (the .npy coefficients are written beside it)",
            eoir::limits::escape_token(&path.display().to_string())
        ))),
    }
}

/// The RTS pixels of a dark sequence (as `eoir rts`): `stack` f64 `[frame, row, col]`.
/// Returns a dict of arrays `row`, `col`, `step`, `high_fraction`, `separation_sigma`.
#[pyfunction]
#[pyo3(signature = (stack, threshold_sigma=4.0, min_frames=3, remove_frame_median=true))]
fn find_rts_pixels<'py>(
    py: Python<'py>,
    stack: PyReadonlyArray3<'py, f64>,
    threshold_sigma: f64,
    min_frames: usize,
    remove_frame_median: bool,
) -> PyResult<Bound<'py, PyDict>> {
    use eoir::characterize::rts::{find_rts_pixels as find, RtsSearch};
    let stack = stack.as_array().to_owned();
    let search = RtsSearch {
        threshold_sigma,
        min_frames,
        remove_frame_median,
    };
    let found = detached(py, move || find(stack.view(), &search))?;
    let d = PyDict::new(py);
    d.set_item("row", found.iter().map(|f| f.row).collect::<Vec<_>>())?;
    d.set_item("col", found.iter().map(|f| f.col).collect::<Vec<_>>())?;
    d.set_item("step", found.iter().map(|f| f.step).collect::<Vec<_>>())?;
    d.set_item(
        "high_fraction",
        found.iter().map(|f| f.high_fraction).collect::<Vec<_>>(),
    )?;
    d.set_item(
        "separation_sigma",
        found.iter().map(|f| f.separation_sigma).collect::<Vec<_>>(),
    )?;
    Ok(d)
}

/// Fits per-pixel NUC polynomials (as `eoir nuc fit`): `frames` f64 `[N, row, col]`, N/T
/// consecutive frames per temperature in the order of `temperatures_k`.
#[pyfunction]
#[pyo3(signature = (frames, temperatures_k, degree=1))]
fn nuc_fit(
    py: Python<'_>,
    frames: PyReadonlyArray3<'_, f64>,
    temperatures_k: Vec<f64>,
    degree: usize,
) -> PyResult<PyNuc> {
    use eoir::processing::bad_pixels::{self, BadPixelCriteria};
    use eoir::processing::nuc::{NucCoefficients, MAX_DEGREE};
    let t = temperatures_k;
    if degree > MAX_DEGREE {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `degree` = {degree}: a NUC polynomial degree from 0 to {MAX_DEGREE}"
        )));
    }
    if let Some(v) = t.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `temperatures_k`: {v} is not a temperature; give finite values > 0 K"
        )));
    }
    for (i, x) in t.iter().enumerate() {
        if t[..i].contains(x) {
            return Err(PyValueError::new_err(format!(
                "invalid parameter `temperatures_k`: {x} K appears twice; give each blackbody temperature once"
            )));
        }
    }
    if t.len() < degree + 1 {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `temperatures_k`: {} temperature(s) cannot determine a degree-{degree} polynomial; give at least {}",
            t.len(),
            degree + 1
        )));
    }
    let stack = frames.as_array();
    let (n, rows, cols) = stack.dim();
    if n == 0 || n % t.len() != 0 {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `frames` = {n} frames for {} temperatures: the same number of frames (at least one) for every temperature, N/T consecutive frames each",
            t.len()
        )));
    }
    let per = n / t.len();
    let stack = stack.to_owned();
    let inner = detached(py, move || {
        let planes = (per + t.len() + 2 * (degree + 1) + 4) as u64;
        eoir::limits::check_alloc(
            "nuc fit",
            &[
                ("planes", planes),
                ("rows", rows as u64),
                ("columns", cols as u64),
            ],
            8,
        )?;
        let mut means: Vec<Array2<f64>> = Vec::with_capacity(t.len());
        for k in 0..t.len() {
            let group = stack.slice(s![k * per..(k + 1) * per, .., ..]).to_owned();
            means.push(eoir::processing::mean_frame(group.view())?);
        }
        // As `eoir nuc fit`: bad pixels first, then FOI eq. 4.1 on the good pixels (the
        // reference of level k is their mean ⟨Y_k⟩).
        let cold = t
            .iter()
            .enumerate()
            .min_by(|x, y| x.1.total_cmp(y.1))
            .map_or(0, |v| v.0);
        let warm = t
            .iter()
            .enumerate()
            .max_by(|x, y| x.1.total_cmp(y.1))
            .map_or(0, |v| v.0);
        let det = bad_pixels::detect(
            means[cold].view(),
            means[warm].view(),
            &BadPixelCriteria::default(),
        )?;
        let references: Vec<f64> = means
            .iter()
            .map(|m| eoir::processing::nuc::good_pixel_mean(m.view(), &det.map))
            .collect::<eoir::error::Result<_>>()?;
        let levels: Vec<(f64, ndarray::ArrayView2<f64>)> = references
            .iter()
            .zip(&means)
            .map(|(r, m)| (*r, m.view()))
            .collect();
        let mut coeffs = NucCoefficients::fit(&levels, degree)?;
        coeffs.set_bad_pixels(&det.map)?;
        Ok(coeffs)
    })?;
    Ok(PyNuc { inner })
}

/// Corrects an image with NUC coefficients (as `eoir nuc apply`): f64 `[row, col]` →
/// corrected f64, bad pixels replaced by the median of their valid neighbours.
#[pyfunction]
fn nuc_apply<'py>(
    py: Python<'py>,
    nuc: &PyNuc,
    image: PyReadonlyArray2<'py, f64>,
) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
    let img = image.as_array().to_owned();
    let (rows, cols) = img.dim();
    if (rows, cols) != nuc.inner.dim() {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `image` = {rows} x {cols} pixels (rows x cols): the NUC is for {} x {}",
            nuc.inner.dim().0,
            nuc.inner.dim().1
        )));
    }
    let coeffs = &nuc.inner;
    let out = detached(py, move || {
        let corrected = coeffs.apply(img.view())?;
        let bad = coeffs.bad_pixel_map();
        if bad.count() > 0 {
            eoir::processing::bad_pixels::replace(corrected.view(), &bad)
        } else {
            Ok(corrected)
        }
    })?;
    Ok(out.into_pyarray(py))
}

/// EMVA 1288 analysis of an acquisition set (as `eoir characterize SET`): the
/// characterisation as JSON (`characterization.json`); with `output`, also the datasheet
/// files the CLI writes there.
#[pyfunction]
#[pyo3(signature = (acquisition_set, output=None))]
fn characterize(
    py: Python<'_>,
    acquisition_set: PathBuf,
    output: Option<PathBuf>,
) -> PyResult<String> {
    detached(py, move || {
        let descriptor = eoir::characterize::descriptor_path(&acquisition_set);
        let c = eoir::characterize::characterize(&descriptor)?;
        if let Some(out) = &output {
            let title = acquisition_set.display().to_string();
            eoir::characterize::write_outputs(&c, out, &title)?;
        }
        serde_json::to_string(&c)
            .map_err(|e| eoir::Error::param("characterization", "json", e.to_string()))
    })
}

/// Writes a simulated EMVA 1288 acquisition set for `sensor` into `output` (as `eoir
/// characterize --simulate`); returns the configured truth as JSON (`truth.json`).
#[pyfunction]
#[pyo3(signature = (sensor, output, seed=1, window=eoir::characterize::simulate::DEFAULT_WINDOW))]
fn simulate_acquisition_set(
    py: Python<'_>,
    sensor: &PySensor,
    output: PathBuf,
    seed: u64,
    window: usize,
) -> PyResult<String> {
    let config = sensor.inner.config();
    detached(py, move || {
        let truth = eoir::characterize::simulate(
            config,
            &output,
            &eoir::characterize::SimulateOptions { seed, window },
        )?;
        serde_json::to_string(&truth)
            .map_err(|e| eoir::Error::param("truth", "json", e.to_string()))
    })
}

/// The figures of merit of a sensor (as `eoir assess`): `assess.json` as JSON. `target` is
/// `(size_m, delta_t_k, contrast, sct_k or None, extinction_per_km or None)`; `ranges_m` the
/// ranges of the range curves; `analytic_only` skips the simulated measurements.
#[pyfunction]
#[pyo3(signature = (sensor, seed=1, temperature_k=300.0, frames=32, window=64, target=None, ranges_m=None, elevation_deg=90.0, analytic_only=false))]
#[allow(clippy::too_many_arguments)]
fn assess(
    py: Python<'_>,
    sensor: &PySensor,
    seed: u64,
    temperature_k: f64,
    frames: usize,
    window: usize,
    target: Option<(f64, f64, f64, Option<f64>, Option<f64>)>,
    ranges_m: Option<Vec<f64>>,
    elevation_deg: f64,
    analytic_only: bool,
) -> PyResult<String> {
    use eoir::merit::assess::{AssessOptions, TargetSpec};
    let defaults = AssessOptions::default();
    let target = match target {
        Some((size_m, delta_t_k, contrast, sct_k, extinction_per_km)) => TargetSpec {
            size_m,
            delta_t_k,
            contrast,
            sct_k: sct_k.unwrap_or(TargetSpec::default().sct_k),
            extinction_per_km,
        },
        None => TargetSpec::default(),
    };
    let opts = AssessOptions {
        seed,
        temperature_k,
        frames,
        window_px: window,
        target,
        ranges_m: ranges_m.unwrap_or(defaults.ranges_m),
        elevation_deg,
        display: None,
        analytic_only,
    };
    let sensor = sensor.inner.clone();
    detached(py, move || {
        opts.validate()?;
        let a = eoir::merit::assess::assess(&sensor, &opts)?;
        serde_json::to_string(&a)
            .map_err(|e| eoir::Error::param("assessment", "json", e.to_string()))
    })
}

/// Reads a single-plane image file: a 16-bit greyscale PNG or TIFF (DN, uint16) or a
/// 32-bit float TIFF (float32), with the library's readers (as `eoir restore` reads them).
#[pyfunction]
fn read_image<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyAny>> {
    use eoir::io::raster;
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "png" => Ok(detached(py, || raster::read_png_u16(&path))?
            .into_pyarray(py)
            .into_any()),
        "tif" | "tiff" => {
            let (u16s, f32s) = detached(py, || match raster::read_tiff_u16(&path) {
                Ok(a) => Ok((Some(a), None)),
                Err(_) => raster::read_tiff_f32(&path).map(|a| (None, Some(a))),
            })?;
            match (u16s, f32s) {
                (Some(a), _) => Ok(a.into_pyarray(py).into_any()),
                (_, Some(a)) => Ok(a.into_pyarray(py).into_any()),
                _ => Err(PyValueError::new_err("unreachable")),
            }
        }
        other => Err(PyValueError::new_err(format!(
            "invalid parameter `path` = {:?}: unsupported image type `.{}`; a 16-bit PNG/TIFF (DN) or a 32-bit float TIFF",
            eoir::limits::escape_token(&path.display().to_string()),
            eoir::limits::escape_token(other)
        ))),
    }
}

/// Sets the memory budget every size is checked against before allocating, bytes (the
/// CLI's `--max-memory`).
#[pyfunction]
fn set_max_memory_bytes(bytes: u64) -> PyResult<()> {
    guarded(|| eoir::limits::set_max_memory_bytes(bytes))
}

/// The native module.
/// Multi-frame restoration of a sequence (as `eoir restore DIR`): `stack` f64
/// `[frame, row, col]` of DN (NaN marks a pixel to skip), `shifts` `[(dx, dy)]` per frame
/// relative to frame 0 or None (phase correlation), `upsample` the fine grid's factor,
/// `noise` "auto" (the in-cell sample scatter) or "model" (the sensor's temporal noise),
/// or a constant `nsr`. Returns `{restored (f32, [R·rows, R·cols], DN), report_json}`.
#[pyfunction]
#[pyo3(signature = (sensor, stack, shifts=None, upsample=2, noise="auto", nsr=None, black_level=None))]
#[allow(clippy::too_many_arguments)]
fn restore_sequence<'py>(
    py: Python<'py>,
    sensor: &PySensor,
    stack: PyReadonlyArray3<'py, f64>,
    shifts: Option<Vec<(f64, f64)>>,
    upsample: usize,
    noise: &str,
    nsr: Option<f64>,
    black_level: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    use eoir::processing::multi_frame::{restore_sequence as restore_stack, SequenceNoise};
    use eoir::processing::wiener::SensorTransfer;
    let sensor = &sensor.inner;
    let stack = stack.as_array().to_owned();
    let (frames, rows, cols) = stack.dim();
    if (rows, cols) != (sensor.detector.rows, sensor.detector.cols) {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `stack` = frames of {rows} x {cols} pixels (rows x cols): sensor `{}` records {} x {}; restore a sequence with the sensor that recorded it",
            sensor.name, sensor.detector.rows, sensor.detector.cols
        )));
    }
    if !matches!(noise, "auto" | "model") {
        return Err(PyValueError::new_err(format!(
            "invalid parameter `noise` = {:?}: \"auto\" or \"model\"",
            eoir::limits::escape_token(noise)
        )));
    }
    let noise = noise.to_string();
    let (restored, report) = detached(py, move || {
        eoir::limits::check_alloc(
            "restoring the sequence",
            &[
                ("rows", (rows * upsample.max(1)) as u64),
                ("columns", (cols * upsample.max(1)) as u64),
            ],
            RESTORE_BYTES_PER_PIXEL,
        )?;
        let model = sensor.detector();
        let black = black_level.unwrap_or_else(|| model.expected_dn(0.0));
        if !black.is_finite() || black < 0.0 {
            return Err(eoir::Error::param("black_level", black, "a finite DN >= 0"));
        }
        let signal = stack.mapv(|v| v - black);
        let rule = SequenceNoise::from_rule(nsr, &noise, signal.view(), model)?;
        let transfer = SensorTransfer::new(sensor)?;
        let r = restore_stack(signal.view(), shifts.as_deref(), upsample, &transfer, rule)?;
        let restored = r.restoration.image.mapv(|v| (v + black) as f32);
        let report = serde_json::json!({
            "sensor": sensor.name,
            "frames": frames,
            "upsample": upsample,
            "registration": if shifts.is_some() { "given" } else { "phase" },
            "shifts_px": r.shifts.iter().map(|t| [t.dx_px, t.dy_px]).collect::<Vec<_>>(),
            "black_level_dn": black,
            "holes_filled": r.fine.holes_filled,
            "noise_rule": rule.name(),
            "fine_noise_variance_dn2": r.fine_noise_variance,
            "sample_variance_dn2": r.fine.sample_variance,
            "nsr_median": r.restoration.nsr_median,
        });
        let text = serde_json::to_string(&report)
            .map_err(|e| eoir::Error::param("report", "restore_sequence", e.to_string()))?;
        Ok((restored, text))
    })?;
    let d = PyDict::new(py);
    d.set_item("restored", restored.into_pyarray(py))?;
    d.set_item("report_json", report)?;
    Ok(d)
}

#[pymodule]
fn _eoir(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySensor>()?;
    m.add_function(wrap_pyfunction!(load_sensor, m)?)?;
    m.add_function(wrap_pyfunction!(sensor_from_toml, m)?)?;
    m.add_function(wrap_pyfunction!(presets_info, m)?)?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(read_cube, m)?)?;
    m.add_function(wrap_pyfunction!(write_cube, m)?)?;
    m.add_function(wrap_pyfunction!(mtf, m)?)?;
    m.add_function(wrap_pyfunction!(psf, m)?)?;
    m.add_function(wrap_pyfunction!(scene, m)?)?;
    m.add_function(wrap_pyfunction!(covering_params, m)?)?;
    m.add_class::<PyNuc>()?;
    m.add_function(wrap_pyfunction!(restore, m)?)?;
    m.add_function(wrap_pyfunction!(restore_sequence, m)?)?;
    m.add_function(wrap_pyfunction!(assess, m)?)?;
    m.add_function(wrap_pyfunction!(edge_mtf, m)?)?;
    m.add_function(wrap_pyfunction!(nuc_fit, m)?)?;
    m.add_function(wrap_pyfunction!(find_rts_pixels, m)?)?;
    m.add_function(wrap_pyfunction!(nuc_apply, m)?)?;
    m.add_function(wrap_pyfunction!(characterize, m)?)?;
    m.add_function(wrap_pyfunction!(simulate_acquisition_set, m)?)?;
    m.add_function(wrap_pyfunction!(read_image, m)?)?;
    m.add_function(wrap_pyfunction!(set_max_memory_bytes, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
