//! `eoir nuc fit` / `eoir nuc apply`: per-pixel polynomial non-uniformity correction from
//! recorded blackbody frames (FOI report §4.1, eq. 4.1–4.3), for real cameras.
//!
//! `fit` groups the frames by temperature (N frames and T temperatures: N/T consecutive
//! frames per temperature, in the order of `--temperatures-k`), averages each group per
//! pixel, finds the bad pixels from the coldest and warmest averages
//! (`processing::bad_pixels::detect`, median/MAD tests: dead, hot, stuck, unresponsive),
//! and fits each pixel's polynomial onto the reference ⟨Y_k⟩, the mean of the *good*
//! pixels at temperature k (FOI eq. 4.1–4.2 with the defects left out of the mean: the
//! correction maps every pixel onto the mean response of the working array). The bad
//! pixels are stored with the coefficients. It then prints, per temperature, the residual
//! non-uniformity σ_s/μ of the first frame of the group after correction (good pixels;
//! that frame is one of those averaged for the fit), and at the middle temperature the
//! NETD from the temporal noise alone and including that spatial noise
//! (`processing::netd::netd_with_spatial_noise`; temporal noise needs ≥ 2 frames per
//! temperature).
//! `apply` evaluates the polynomials and replaces the bad pixels by the median of their
//! valid neighbours.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use ndarray::{Array2, Array3, Axis};

use eoir::io::raster;
use eoir::processing::bad_pixels::{self, BadPixelCriteria};
use eoir::processing::netd::netd_with_spatial_noise;
use eoir::processing::nuc::{good_pixel_mean, residual_nonuniformity, NucCoefficients};
use eoir::processing::{mean_frame, to_f64};

/// Arguments of `eoir nuc`.
#[derive(Debug, clap::Args)]
pub struct NucArgs {
    #[command(subcommand)]
    pub command: NucCommand,
}

/// The `nuc` subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum NucCommand {
    /// Fit per-pixel NUC polynomials and a bad-pixel map from blackbody frames.
    Fit(FitArgs),
    /// Correct an image with fitted coefficients.
    Apply(ApplyArgs),
}

/// Arguments of `eoir nuc fit`.
#[derive(Debug, clap::Args)]
pub struct FitArgs {
    /// Frames (16-bit PNG or TIFF DN): N/T consecutive frames per temperature.
    #[arg(required = true)]
    pub frames: Vec<PathBuf>,
    /// Blackbody temperatures, K, comma separated, in the order of the frames.
    #[arg(long, value_delimiter = ',', required = true)]
    pub temperatures_k: Vec<f64>,
    /// Polynomial degree (1 = two-point gain/offset).
    #[arg(long, default_value_t = 1)]
    pub degree: usize,
    /// Output: `NAME.json` (sidecar) and `NAME.npy` (coefficients) are written.
    #[arg(short, long)]
    pub output: PathBuf,
}

/// Arguments of `eoir nuc apply`.
#[derive(Debug, clap::Args)]
pub struct ApplyArgs {
    /// Image to correct (16-bit PNG or TIFF DN).
    pub image: PathBuf,
    /// Coefficients written by `eoir nuc fit` (the .json or the .npy).
    #[arg(long)]
    pub nuc: PathBuf,
    /// Output: `.tif`/`.tiff` (32-bit float) or `.png` (16-bit, rounded and clipped).
    #[arg(short, long)]
    pub output: PathBuf,
}

/// Runs `eoir nuc`.
pub fn nuc(args: NucArgs) -> Result<()> {
    match args.command {
        NucCommand::Fit(a) => fit(a),
        NucCommand::Apply(a) => apply(a),
    }
}

/// The size `(rows, cols)` of a DN image (PNG or TIFF) from its header alone, so that a
/// frame of the wrong (or a huge) size is refused before it is decoded.
fn dn_dimensions(path: &Path) -> Result<(usize, usize)> {
    dn_extension(path)?;
    Ok(raster::image_dimensions(path)?)
}

/// The lower-case extension of a DN image path, if it is one `read_dn` reads.
fn dn_extension(path: &Path) -> Result<String> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if !matches!(ext.as_str(), "png" | "tif" | "tiff") {
        bail!(
            "{}: unsupported image type `.{ext}`; expected a 16-bit greyscale .png or .tif/.tiff",
            path.display()
        );
    }
    Ok(ext)
}

/// Reads a 16-bit DN image (PNG or TIFF) as f64.
pub fn read_dn(path: &Path) -> Result<Array2<f64>> {
    let ext = dn_extension(path)?;
    let img = match ext.as_str() {
        "png" => raster::read_png_u16(path)?,
        _ => raster::read_tiff_u16(path)?,
    };
    Ok(to_f64(img.view()))
}

/// The `.npy` coefficient path for an output/nuc argument ending in `.json` or `.npy`.
fn npy_path(path: &Path) -> Result<PathBuf> {
    match path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .as_deref()
    {
        Some("json") | Some("npy") => Ok(path.with_extension("npy")),
        _ => bail!(
            "{}: the NUC file name must end in .json (the .npy coefficients are written beside it)",
            path.display()
        ),
    }
}

fn fit(a: FitArgs) -> Result<()> {
    let npy = npy_path(&a.output)?;
    let t = &a.temperatures_k;
    let max = eoir::processing::nuc::MAX_DEGREE;
    if a.degree > max {
        bail!(
            "--degree {}: the NUC polynomial degree must be 0 to {max}",
            a.degree
        );
    }
    // The blackbody range the calibration searches (the coldest and hottest sources a
    // laboratory sets): 1e30 K or 0.001 K is a typing error, not a blackbody.
    let (t_lo, t_hi) = eoir::calibration::levels::SEARCH_RANGE_K;
    if let Some(v) = t
        .iter()
        .find(|v| !(v.is_finite() && (t_lo..=t_hi).contains(*v)))
    {
        // Scientific notation for the absurd ones (1e30, not thirty-one digits).
        let shown = if (1e-3..1e6).contains(&v.abs()) {
            format!("{v}")
        } else {
            format!("{v:e}")
        };
        bail!("--temperatures-k: {shown} K is not a blackbody temperature; give values from {t_lo} to {t_hi} K");
    }
    for (i, x) in t.iter().enumerate() {
        if t[..i].contains(x) {
            bail!("--temperatures-k: {x} K appears twice; give each blackbody temperature once");
        }
    }
    if t.len() < a.degree + 1 {
        bail!(
            "--temperatures-k: {} temperature(s) cannot determine a degree-{} polynomial; give at least {}",
            t.len(),
            a.degree,
            a.degree + 1
        );
    }
    if a.frames.len() % t.len() != 0 {
        bail!(
            "{} frames for {} temperatures: give the same number of frames for every temperature (N/T consecutive frames each)",
            a.frames.len(),
            t.len()
        );
    }
    let per = a.frames.len() / t.len();
    // Checked from the headers before any frame is decoded: every frame has the first
    // one's size, and one group's f64 stack, the T mean frames and the fit's per-pixel
    // working set (coefficients and normal equations, about 2·(degree + 1) + 4 values)
    // fit the memory budget.
    let first = &a.frames[0];
    let (rows, cols) = dn_dimensions(first)?;
    for p in &a.frames[1..] {
        let dim = dn_dimensions(p)?;
        if dim != (rows, cols) {
            bail!(
                "{}: the frame is {} x {} pixels (rows x cols) but {} is {rows} x {cols}; all frames must have one size",
                p.display(), dim.0, dim.1, first.display()
            );
        }
    }
    let planes = (per + 3 * t.len() + 2 * (a.degree + 1) + 4) as u64;
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
    let mut firsts: Vec<Array2<f64>> = Vec::with_capacity(t.len());
    let mut variances: Vec<Option<Array2<f64>>> = Vec::with_capacity(t.len());
    for group in a.frames.chunks(per) {
        let mut stack: Option<Array3<f64>> = None;
        for (i, p) in group.iter().enumerate() {
            let img = read_dn(p)?;
            let dim = img.dim();
            if dim != (rows, cols) {
                bail!("{}: the decoded frame is {} x {} pixels, not the {rows} x {cols} its header states", p.display(), dim.0, dim.1);
            }
            let st = stack.get_or_insert_with(|| Array3::zeros((group.len(), dim.0, dim.1)));
            st.index_axis_mut(Axis(0), i).assign(&img);
        }
        let st = stack.context("no frames")?;
        firsts.push(st.index_axis(Axis(0), 0).to_owned());
        variances.push((per >= 2).then(|| st.var_axis(Axis(0), 1.0)));
        means.push(mean_frame(st.view())?);
    }
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
    )
    .context("finding bad pixels from the coldest and warmest frames")?;
    // FOI eq. 4.1 on the good pixels: the reference of level k is their mean ⟨Y_k⟩.
    let references: Vec<f64> = means
        .iter()
        .map(|m| good_pixel_mean(m.view(), &det.map))
        .collect::<eoir::error::Result<_>>()
        .context("the good-pixel mean of a level")?;
    let levels: Vec<(f64, ndarray::ArrayView2<f64>)> = references
        .iter()
        .zip(&means)
        .map(|(r, m)| (*r, m.view()))
        .collect();
    let mut coeffs =
        NucCoefficients::fit(&levels, a.degree).context("fitting the NUC polynomials")?;
    coeffs.set_bad_pixels(&det.map)?;
    coeffs.save(&npy)?;
    let (r, c) = coeffs.dim();
    println!(
        "NUC degree {} from {} temperatures x {per} frame(s), {r} x {c} px; {} bad pixel(s), {} rank-deficient; wrote {} and {}",
        a.degree,
        t.len(),
        det.map.count(),
        coeffs.rank_deficient().len(),
        npy.with_extension("json").display(),
        npy.display()
    );
    // Quality after correction, on the good pixels.
    let bad = coeffs.bad_pixel_map();
    let mut order: Vec<usize> = (0..t.len()).collect();
    order.sort_by(|x, y| t[*x].total_cmp(&t[*y]));
    let mut residual = Vec::with_capacity(t.len());
    for &k in &order {
        let corrected = coeffs.apply(firsts[k].view())?;
        let nu = residual_nonuniformity(corrected.view(), Some(&bad))?;
        residual.push(format!("{} K {:.4} %", t[k], 100.0 * nu));
    }
    println!(
        "residual non-uniformity after correction (good pixels, one frame of each level, σ/mean): {}",
        residual.join(", ")
    );
    let mid = order.len() / 2;
    let (lo, hi) = (
        order[mid.saturating_sub(1)],
        order[(mid + 1).min(order.len() - 1)],
    );
    let (lo, hi) = if lo == hi {
        (order[0], order[order.len() - 1])
    } else {
        (lo, hi)
    };
    let k = order[mid];
    let responsivity = (references[hi] - references[lo]) / (t[hi] - t[lo]);
    let corrected = coeffs.apply(firsts[k].view())?;
    let nu = residual_nonuniformity(corrected.view(), Some(&bad))?;
    let spatial_dn = nu * good_pixel_mean(corrected.view(), &bad)?.abs();
    match &variances[k] {
        Some(var) => {
            let temporal_dn = good_pixel_mean(var.view(), &bad)?.sqrt();
            let n = netd_with_spatial_noise(temporal_dn, spatial_dn, responsivity)?;
            println!(
                "NETD at {} K: {:.2} mK temporal ({:.3} DN rms), {:.2} mK including the spatial noise after correction ({:.3} DN rms); responsivity {:.4} DN/K",
                t[k],
                1e3 * n.temporal_netd_k,
                n.temporal_noise_dn,
                1e3 * n.total_netd_k,
                n.spatial_noise_dn,
                n.responsivity_dn_per_k
            );
        }
        None => println!(
            "NETD at {} K including the spatial noise after correction: {:.2} mK ({:.3} DN rms; responsivity {:.4} DN/K); give ≥ 2 frames per temperature for the temporal NETD",
            t[k],
            1e3 * spatial_dn / responsivity.abs(),
            spatial_dn,
            responsivity
        ),
    }
    Ok(())
}

fn apply(a: ApplyArgs) -> Result<()> {
    let npy = npy_path(&a.nuc)?;
    let out_ext = a
        .output
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if !matches!(out_ext.as_str(), "tif" | "tiff" | "png") {
        bail!(
            "{}: the output must end in .tif/.tiff (32-bit float) or .png (16-bit)",
            a.output.display()
        );
    }
    let coeffs = NucCoefficients::load(&npy)?;
    let (rows, cols) = dn_dimensions(&a.image)?;
    if (rows, cols) != coeffs.dim() {
        bail!(
            "{}: the image is {} x {} pixels (rows x cols) but the NUC {} is for {} x {}",
            a.image.display(),
            rows,
            cols,
            a.nuc.display(),
            coeffs.dim().0,
            coeffs.dim().1
        );
    }
    let img = read_dn(&a.image)?;
    if img.dim() != (rows, cols) {
        bail!(
            "{}: the decoded image is {} x {} pixels, not the {rows} x {cols} its header states",
            a.image.display(),
            img.nrows(),
            img.ncols()
        );
    }
    let corrected = coeffs.apply(img.view())?;
    // The calibration's bad pixels, and every pixel the correction leaves non-finite (a
    // NaN coefficient of a rank-deficient pixel): all replaced, all counted.
    let mut mask = coeffs.bad_pixel_map().mask().clone();
    let from_map = mask.iter().filter(|b| **b).count();
    let mut non_finite = 0usize;
    ndarray::Zip::from(&mut mask)
        .and(&corrected)
        .for_each(|m, v| {
            if !*m && !v.is_finite() {
                *m = true;
                non_finite += 1;
            }
        });
    let bad = bad_pixels::BadPixelMap::from_mask(mask);
    let corrected = if bad.count() > 0 {
        bad_pixels::replace(corrected.view(), &bad)?
    } else {
        corrected
    };
    if out_ext == "png" {
        let u = corrected.mapv(|v| v.round().clamp(0.0, u16::MAX as f64) as u16);
        raster::write_png_u16(&a.output, u.view())?;
    } else {
        let f = corrected.mapv(|v| v as f32);
        eoir::io::output::check_finite(
            &a.output,
            f.iter().map(|&v| v as f64),
            "the corrected image must fit 32-bit floats; check the NUC's coefficients against the image",
        )?;
        raster::write_tiff_f32(&a.output, f.view())?;
    }
    if non_finite > 0 {
        eprintln!(
            "warning: {non_finite} pixel(s) came out of the correction non-finite (NaN coefficients of rank-deficient pixels) and were replaced like bad pixels"
        );
    }
    println!(
        "corrected {} ({} bad pixel(s) replaced: {from_map} from the calibration's map, {non_finite} non-finite after correction); wrote {}",
        a.image.display(),
        bad.count(),
        a.output.display()
    );
    Ok(())
}
