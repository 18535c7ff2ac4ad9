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
use numpy::{IntoPyArray, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use eoir::calibration::CalibrationOptions;
use eoir::io::CubeReader;
use eoir::pipeline::{self, RunOptions};
use eoir::scene::{synthetic, Cube, CubeMeta, Geometry, RadianceUnits};
use eoir::sensor::{presets, Sensor, SensorConfig};

/// Library error → Python exception, keeping the library's message.
fn to_py(e: eoir::Error) -> PyErr {
    match e {
        eoir::Error::Io { .. } => PyOSError::new_err(e.to_string()),
        other => PyValueError::new_err(other.to_string()),
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

/// Loads a sensor: a preset name or a TOML file, with `name=value` option choices and
/// `key.path=value` overrides (as `eoir run --option/--set`).
#[pyfunction]
#[pyo3(signature = (name_or_path, options=Vec::new(), overrides=Vec::new()))]
fn load_sensor(
    name_or_path: &str,
    options: Vec<String>,
    overrides: Vec<String>,
) -> PyResult<PySensor> {
    guarded(|| Sensor::build(&presets::load(name_or_path, &options, &overrides)?))
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
        eoir::scene::check_radiance_plane(
            &self.source,
            band,
            self.meta.wavelength_um[band],
            plane,
        )?;
        Ok(plane.to_owned())
    }
}

/// Parses a unit string, naming what is valid.
fn parse_units(units: &str) -> PyResult<RadianceUnits> {
    RadianceUnits::parse(units).ok_or_else(|| {
        PyValueError::new_err(format!(
            "invalid parameter `units` = {units}: \"{}\" (spectral radiance) or \"{}\" (band-integrated)",
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
    fwhm_um=None, input_name="numpy array", calibration_temperatures_k=None))]
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
) -> PyResult<Bound<'py, PyDict>> {
    let units = parse_units(units)?;
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
        input_name: source.clone(),
        calibration: calibrate
            .then(|| {
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
        let mut reader = ArrayReader { data, meta, source };
        pipeline::run(sensor, &mut reader, &options, |_, _| {})
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
    Ok(d)
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

/// Reads a cube file (ENVI, spectral EXR, NPY, HDF5 with the feature), every frame.
#[pyfunction]
fn read_cube<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let (data, meta, ft, warnings) = detached(py, || {
        let mut r = eoir::io::open(&path)?;
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
/// wavelength). Frequencies are angular, cycles/mrad in object space.
#[pyfunction]
#[pyo3(signature = (sensor, freq_cy_per_mrad, wavelength_um=None))]
fn mtf<'py>(
    py: Python<'py>,
    sensor: &PySensor,
    freq_cy_per_mrad: Vec<f64>,
    wavelength_um: Option<f64>,
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
        Ok((lambda, columns))
    })?;
    let d = PyDict::new(py);
    d.set_item("wavelength_um", lambda)?;
    d.set_item("freq_cy_per_mrad", freq_cy_per_mrad.into_pyarray(py))?;
    for (n, v) in columns {
        d.set_item(n, v.into_pyarray(py))?;
    }
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

/// The native module.
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
    m.add_function(wrap_pyfunction!(scene, m)?)?;
    m.add_function(wrap_pyfunction!(covering_params, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
