//! Helpers shared by the benchmark examples (not an example itself: Cargo only builds
//! `examples/*.rs` and `examples/*/main.rs`).

#![allow(dead_code)] // each example uses the part it needs

/// Median of the finite values (NaN if none).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// A numeric field of `/usr/bin/time -v`'s report (`key` including its `": "`), NaN if
/// absent.
pub fn time_v_field(stderr: &str, key: &str) -> f64 {
    stderr
        .lines()
        .find_map(|l| l.trim().strip_prefix(key))
        .and_then(|v| v.trim().parse::<f64>().ok())
        .unwrap_or(f64::NAN)
}

/// Peak resident set size, MiB, from `/usr/bin/time -v`'s report.
pub fn peak_rss_mib(stderr: &str) -> f64 {
    time_v_field(stderr, "Maximum resident set size (kbytes): ") / 1024.0
}

/// The every-component SWIR sensor of the performance issue
/// (`benches/swir_all_components.toml`) with a `det × det` detector.
pub fn swir_sensor_config(det: usize) -> eoir::Result<eoir::sensor::SensorConfig> {
    swir_sensor_config_with(det, &[])
}

/// [`swir_sensor_config`] with further `key=value` overrides (as `--set` takes them).
pub fn swir_sensor_config_with(
    det: usize,
    extra: &[String],
) -> eoir::Result<eoir::sensor::SensorConfig> {
    const SENSOR: &str = include_str!("../../benches/swir_all_components.toml");
    let mut overrides = vec![
        format!("detector.rows={det}"),
        format!("detector.cols={det}"),
    ];
    overrides.extend(extra.iter().cloned());
    eoir::sensor::SensorConfig::from_toml_str(SENSOR, "bench", ".".into(), &overrides)
}

/// Metadata of an `n × n` cube of 50 µrad pixels in W m⁻² sr⁻¹ µm⁻¹ with the given
/// wavelengths.
pub fn swir_meta(n: usize, wavelength_um: Vec<f64>) -> eoir::scene::CubeMeta {
    eoir::scene::CubeMeta {
        wavelength_um,
        fwhm_um: None,
        units: eoir::scene::RadianceUnits::SpectralPerUm,
        geometry: Some(eoir::scene::Geometry::from_ifov(50e-6, 50e-6, n, n)),
        rows: n,
        cols: n,
    }
}
