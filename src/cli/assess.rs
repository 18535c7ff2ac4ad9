//! `eoir assess`: a sensor's figures of merit, analytic and measured on simulated frames,
//! side by side (docs/figures-of-merit.md).

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};

use eoir::merit::assess::{self, AssessOptions, Assessment, TargetSpec};
use eoir::merit::plots;
use eoir::plot::{self, LinePlot, Marker, Series};

use super::sensor_args::SensorArgs;

/// Arguments of `eoir assess`.
#[derive(Debug, clap::Args)]
pub struct AssessArgs {
    #[command(flatten)]
    pub sensor: SensorArgs,
    /// The target and the ranges.
    #[command(flatten)]
    pub task: TaskArgs,
    /// Frames of the simulated uniform sequence (3-D noise, NETD).
    #[arg(long, default_value_t = 32)]
    pub frames: usize,
    /// Side of the square detector window the measurements simulate, pixels (16–1024).
    #[arg(long, default_value_t = 64)]
    pub window: usize,
    /// Reference blackbody temperature, K.
    #[arg(long = "temperature-k", default_value_t = 300.0)]
    pub temperature_k: f64,
    /// Line-of-sight elevation above the ground for GIQE's GSD, degrees (90 = nadir).
    #[arg(long = "elevation-deg", default_value_t = 90.0)]
    pub elevation_deg: f64,
    /// Seed of the simulated frames.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Analytic figures only (no simulation).
    #[arg(long)]
    pub analytic_only: bool,
    /// Output directory (assess.json, CSV tables, PNG plots, assess.html).
    #[arg(short, long)]
    pub output: PathBuf,
}

/// The target and the range grid of the range performance (`eoir assess`, `eoir sweep`).
#[derive(Debug, clap::Args)]
pub struct TaskArgs {
    /// Target: comma-separated `key=value` of `size_m` (√area, default 2.3), `delta_t_k`
    /// (thermal ΔT, 2), `contrast` (reflective, 0.3), `sct_k` (scene contrast temperature,
    /// 4), `extinction_per_km` (default: the sensor's [aerosol], else 0).
    #[arg(long, value_name = "KEY=VALUE,…")]
    pub target: Option<String>,
    /// Ranges `START:STOP:N` in km (N ≥ 2 evenly spaced values, 0 < START < STOP).
    #[arg(
        long = "range-km",
        value_name = "START:STOP:N",
        default_value = "0.5:20:40"
    )]
    pub range_km: String,
}

impl TaskArgs {
    /// The target (defaults where not given) and the ranges in m.
    pub fn parse(&self) -> Result<(TargetSpec, Vec<f64>)> {
        let target = match &self.target {
            Some(t) => parse_target(t)?,
            None => TargetSpec::default(),
        };
        let ranges_km = parse_grid(&self.range_km, "--range-km")?;
        if ranges_km[0] <= 0.0 {
            bail!("--range-km `{}`: ranges must be > 0 km", self.range_km);
        }
        Ok((target, ranges_km.iter().map(|r| r * 1e3).collect()))
    }
}

/// Parses `--target key=value,…` onto the defaults.
pub fn parse_target(text: &str) -> Result<TargetSpec> {
    let mut t = TargetSpec::default();
    for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let Some((k, v)) = part.split_once('=') else {
            bail!("--target `{part}`: expected key=value (keys: size_m, delta_t_k, contrast, sct_k, extinction_per_km)");
        };
        let x: f64 = v
            .trim()
            .parse()
            .with_context(|| format!("--target {}: `{}` is not a number", k.trim(), v.trim()))?;
        match k.trim() {
            "size_m" => t.size_m = x,
            "delta_t_k" => t.delta_t_k = x,
            "contrast" => t.contrast = x,
            "sct_k" => t.sct_k = x,
            "extinction_per_km" => t.extinction_per_km = Some(x),
            other => bail!(
                "--target: unknown key `{other}` (valid: size_m, delta_t_k, contrast, sct_k, extinction_per_km)"
            ),
        }
    }
    t.validate().context("--target")?;
    Ok(t)
}

/// Parses `START:STOP:N` into N evenly spaced values (`flag` names the option in errors).
pub fn parse_grid(text: &str, flag: &str) -> Result<Vec<f64>> {
    let parts: Vec<&str> = text.split(':').map(str::trim).collect();
    if parts.len() != 3 {
        bail!("{flag} `{text}`: expected START:STOP:N, e.g. 0.5:20:40");
    }
    let a: f64 = parts[0]
        .parse()
        .with_context(|| format!("{flag} `{text}`: START is not a number"))?;
    let b: f64 = parts[1]
        .parse()
        .with_context(|| format!("{flag} `{text}`: STOP is not a number"))?;
    let n: usize = parts[2]
        .parse()
        .with_context(|| format!("{flag} `{text}`: N is not a whole number"))?;
    if !(a.is_finite() && b.is_finite()) {
        bail!("{flag} `{text}`: START and STOP must be finite");
    }
    if !(2..=10_000).contains(&n) {
        bail!("{flag} `{text}`: N must be 2 to 10000");
    }
    if b <= a {
        bail!("{flag} `{text}`: STOP must exceed START");
    }
    Ok((0..n)
        .map(|i| decimal(a + (b - a) * i as f64 / (n - 1) as f64))
        .collect())
}

/// `v` rounded to 12 significant digits: a grid step's rounding error dropped, so
/// `0.05:0.25:5` gives 0.15 (printed as `0.15`), not 0.15000000000000002.
fn decimal(v: f64) -> f64 {
    format!("{v:.11e}").parse().unwrap_or(v)
}

/// `eoir assess`.
pub fn assess(args: AssessArgs) -> Result<()> {
    let sensor = args.sensor.load()?;
    let (target, ranges_m) = args.task.parse()?;
    let opts = AssessOptions {
        seed: args.seed,
        temperature_k: args.temperature_k,
        frames: args.frames,
        window_px: args.window,
        target,
        ranges_m,
        elevation_deg: args.elevation_deg,
        display: None,
        analytic_only: args.analytic_only,
    };
    let a = assess::assess(&sensor, &opts)
        .with_context(|| format!("assessing sensor `{}`", sensor.name))?;
    let set = eoir::io::output::ProductSet::begin(&args.output)?;
    write_products(&set, &a)?;
    let written = set.commit()?;
    print_summary(&a);
    for p in written {
        println!("wrote {}", p.display());
    }
    Ok(())
}

fn opt(v: Option<f64>) -> String {
    v.map_or(String::new(), |x| format!("{x:.6e}"))
}

/// The CSV tables, plots, assess.json and assess.html of one assessment into `set`.
pub fn write_products(set: &eoir::io::output::ProductSet, a: &Assessment) -> Result<()> {
    let an = &a.analytic;
    let me = a.measured.as_ref();
    set.write_json("assess.json", a)?;

    // 3-D noise: predicted and measured in every unit.
    let mut csv = String::from(
        "component,predicted_dn,measured_dn,predicted_e,measured_e,predicted_k,measured_k\n",
    );
    for (k, (name, p_dn)) in an.noise3d.dn.named().iter().enumerate() {
        let m =
            |u: fn(&assess::Noise3dUnits) -> Option<eoir::merit::noise3d::Noise3dComponents>| {
                me.and_then(|m| u(&m.noise3d)).map(|c| c.named()[k].1)
            };
        let _ = writeln!(
            csv,
            "{name},{p_dn:.6e},{},{:.6e},{},{},{}",
            opt(m(|n| Some(n.dn))),
            an.noise3d.electrons.named()[k].1,
            opt(m(|n| Some(n.electrons))),
            opt(an.noise3d.kelvin.map(|c| c.named()[k].1)),
            opt(m(|n| n.kelvin)),
        );
    }
    set.write_bytes("noise3d.csv", csv.as_bytes())?;

    // Range curves.
    let mut csv = String::from("range_m,contrast,ttp_v");
    for t in &an.tasks {
        let _ = write!(csv, ",p_{}", t.task);
    }
    if an.niirs.is_some() {
        csv.push_str(",giqe_snr,niirs");
    }
    csv.push('\n');
    for (k, r) in an.ranges_m.iter().enumerate() {
        let _ = write!(csv, "{r:.3},{:.6e},{:.6e}", an.contrast[k], an.ttp_v[k]);
        for t in &an.tasks {
            let _ = write!(csv, ",{:.6}", t.probability[k]);
        }
        if let (Some(n), Some(s)) = (&an.niirs, &an.giqe_snr) {
            let _ = write!(csv, ",{:.6e},{:.4}", s[k], n[k]);
        }
        csv.push('\n');
    }
    set.write_bytes("ranges.csv", csv.as_bytes())?;

    // CTF_sys tables (anyone can recompute V from them).
    let mut csv =
        String::from("freq_cy_per_mrad,mtf_h,ctf_eye,noise_factor,ctf_sys_h,mtf_v,ctf_sys_v\n");
    for (h, v) in an.ctf_sys_h.iter().zip(&an.ctf_sys_v) {
        let _ = writeln!(
            csv,
            "{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e}",
            h.freq_cy_per_mrad, h.mtf, h.ctf_eye, h.noise_factor, h.ctf_sys, v.mtf, v.ctf_sys
        );
    }
    set.write_bytes("ctf_sys.csv", csv.as_bytes())?;

    // Plots.
    set.write_bytes("probability.png", &plots::probability_png(an)?)?;
    if let Some(mrtd) = &an.mrtd {
        let mut csv = String::from("freq_cy_per_px,freq_cy_per_mrad,mtf,mrtd_k\n");
        for p in mrtd {
            let _ = writeln!(
                csv,
                "{:.6},{:.6},{:.6e},{:.6e}",
                p.freq_cy_per_px,
                p.freq_cy_per_px / (an.ifov_rad * 1e3),
                p.mtf,
                p.mrtd_k
            );
        }
        set.write_bytes("mrtd.csv", csv.as_bytes())?;
    }
    if let Some(png) = plots::mrtd_png(an)? {
        set.write_bytes("mrtd.png", &png)?;
    }
    if let Some(png) = plots::niirs_png(an)? {
        set.write_bytes("niirs.png", &png)?;
    }
    if let Some((f, m)) = me.and_then(|m| m.edge_mtf.as_ref()) {
        let analytic: Vec<f64> = f
            .iter()
            .map(|x| {
                an.ctf_sys_h
                    .iter()
                    .find(|s| s.freq_cy_per_mrad * an.ifov_rad * 1e3 >= *x - 1e-12)
                    .map_or(f64::NAN, |s| s.mtf)
            })
            .collect();
        let (fa, ma): (Vec<f64>, Vec<f64>) = f
            .iter()
            .zip(&analytic)
            .filter(|(_, v)| v.is_finite())
            .map(|(a, b)| (*a, *b))
            .unzip();
        set.write("mtf.png", |p| {
            plot::write_line_plot(
                p,
                &LinePlot {
                    title: "system MTF: analytic (x) and slanted edge",
                    x_label: "spatial frequency (cycles/pixel)",
                    y_label: "MTF",
                    series: vec![
                        Series {
                            label: "slanted edge (simulated)",
                            x: f,
                            y: m,
                        },
                        Series {
                            label: "analytic",
                            x: &fa,
                            y: &ma,
                        },
                    ],
                    markers: vec![Marker {
                        label: "Nyquist",
                        x: 0.5,
                    }],
                    y_range: Some((0.0, 1.1)),
                    size_px: (900, 600),
                },
            )
        })?;
    }
    set.write_bytes("assess.html", html(a).as_bytes())?;
    Ok(())
}

/// Escapes text for HTML.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn cell(v: Option<f64>, digits: usize) -> String {
    v.map_or("—".to_string(), |x| plot::significant(x, digits))
}

/// The assessment page: the side-by-side table and the plots beside it.
fn html(a: &Assessment) -> String {
    let an = &a.analytic;
    let me = a.measured.as_ref();
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>eoir assess: {}</title>\
         <style>body{{font-family:sans-serif;max-width:1000px;margin:auto}}td,th{{padding:2px 10px;text-align:right}}\
         th:first-child,td:first-child{{text-align:left}}img{{max-width:100%}}</style></head><body>\
         <h1>Figures of merit: {}</h1><h2>Analytic and measured</h2><table><tr><th>figure</th><th>analytic</th><th>measured</th></tr>",
        esc(&a.sensor),
        esc(&a.sensor)
    );
    let rows: Vec<(&str, Option<f64>, Option<f64>)> = vec![
        ("NETD (K)", an.netd_k, me.and_then(|m| m.netd_k)),
        (
            "MTF50 (cycles/pixel)",
            an.mtf50_cy_per_px,
            me.and_then(|m| m.mtf50_cy_per_px),
        ),
        (
            "MTF at Nyquist",
            Some(an.mtf_nyquist),
            me.and_then(|m| m.mtf_nyquist),
        ),
        (
            "RER (edge normal)",
            me.and_then(|m| m.rer_analytic_along_normal),
            me.and_then(|m| m.rer),
        ),
        ("RER √(x·y)", Some(an.rer), None),
    ];
    for (name, x, y) in rows {
        let _ = write!(
            h,
            "<tr><td>{name}</td><td>{}</td><td>{}</td></tr>",
            cell(x, 4),
            cell(y, 4)
        );
    }
    for (k, (name, p)) in an.noise3d.dn.named().iter().enumerate() {
        let m = me.map(|m| m.noise3d.dn.named()[k].1);
        let _ = write!(
            h,
            "<tr><td>3-D noise {name} (DN)</td><td>{}</td><td>{}</td></tr>",
            cell(Some(*p), 4),
            cell(m, 4)
        );
    }
    h.push_str("</table><h2>Range performance (TTP)</h2><table><tr><th>task</th><th>V50</th><th>range P = 0.5 (km)</th><th>range P = 0.8 (km)</th></tr>");
    for t in &an.tasks {
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{:.1}</td><td>{}</td><td>{}</td></tr>",
            esc(&t.task),
            t.v50,
            cell(t.range_p50_m.map(|r| r * 1e-3), 4),
            cell(t.range_p80_m.map(|r| r * 1e-3), 4)
        );
    }
    h.push_str("</table><p><img src=\"probability.png\" alt=\"task probability vs range\"></p>");
    if an.mrtd.is_some() {
        h.push_str("<p><img src=\"mrtd.png\" alt=\"MRTD\"></p>");
    }
    if an.niirs.is_some() {
        h.push_str("<p><img src=\"niirs.png\" alt=\"GIQE 5 NIIRS vs range\"></p>");
    }
    if me.and_then(|m| m.edge_mtf.as_ref()).is_some() {
        h.push_str("<p><img src=\"mtf.png\" alt=\"MTF\"></p>");
    }
    if let Some(m) = me {
        for n in &m.notes {
            let _ = write!(h, "<p>note: {}</p>", esc(n));
        }
    }
    h.push_str("<p>Tables: assess.json, noise3d.csv, ranges.csv, ctf_sys.csv, mrtd.csv. Methods: docs/figures-of-merit.md.</p></body></html>\n");
    h
}

/// One line per headline figure.
fn print_summary(a: &Assessment) {
    let an = &a.analytic;
    let me = a.measured.as_ref();
    if let Some(n) = an.netd_k {
        println!(
            "NETD {:.4} K analytic, {} measured",
            n,
            me.and_then(|m| m.netd_k)
                .map_or("not".to_string(), |x| format!("{x:.4} K"))
        );
    }
    println!(
        "MTF50 {} cy/px analytic, {} measured; RER {:.3}",
        cell(an.mtf50_cy_per_px, 4),
        cell(me.and_then(|m| m.mtf50_cy_per_px), 4),
        an.rer
    );
    for t in &an.tasks {
        println!(
            "{}: P50 at {} km, P80 at {} km",
            t.task,
            cell(t.range_p50_m.map(|r| r * 1e-3), 4),
            cell(t.range_p80_m.map(|r| r * 1e-3), 4)
        );
    }
}
