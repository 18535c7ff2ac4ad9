//! Pictures of optics that change across the field (docs/field-optics.md): the grid of
//! PSFs at several normalised field heights (`psf_grid.png`, with the heights written
//! under the tiles) and the tangential/sagittal MTF at field heights 0, 0.7 and 1
//! (`field_mtf.png`), both from the pupil of `[optics.wavefront]`
//! ([`crate::sensor::wavefront::pupil_transfer`]). `eoir psf` writes the same grid, and
//! report.html shows both for a sensor with `[optics.wavefront]`.

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::error::{Error, Result};
use crate::plot::{ensure_font, LinePlot, Series, FONT};
use crate::sensor::wavefront::pupil_transfer;
use crate::sensor::SensorConfig;

/// Each tile is normalised to its peak and drawn with a log10 stretch over this many
/// decades.
pub const PSF_DECADES: f64 = 4.0;
/// Pixels between tiles.
const GAP: usize = 4;
/// Each PSF sample (λ/(4D)) is drawn as ZOOM × ZOOM pixels.
const ZOOM: usize = 2;
/// Height of the label band under the tiles, pixels.
const LABEL_PX: usize = 22;
/// Field heights of the report's pictures.
pub const REPORT_FIELDS: [f64; 3] = [0.0, 0.7, 1.0];

/// The PSF grid picture: one tile per field height in `fields`, left to right, each
/// `±half_width` λ/D, normalised to its peak, log10 stretch over [`PSF_DECADES`]
/// (inferno), tangential axis up, with "H = …" under each tile. Returns the PNG bytes and
/// the pupil transfers (for the caller's figures).
pub fn psf_grid_png(
    config: &SensorConfig,
    fields: &[f64],
    wavelength_um: f64,
    half_width_lambda_over_d: f64,
) -> Result<(Vec<u8>, Vec<crate::wavefront::PupilTransfer>)> {
    let mut tiles = Vec::new();
    let mut transfers = Vec::new();
    for &h in fields {
        let t = pupil_transfer(config, h, wavelength_um * 1e-6, 4)?;
        // λ/D is `padding` = 4 PSF samples.
        let psf = t.psf();
        let m = psf.nrows() as i64;
        let half = ((half_width_lambda_over_d * 4.0).round() as i64).min(m / 2 - 1);
        let peak = psf.iter().cloned().fold(0.0, f64::max);
        let side = (2 * half + 1) as usize;
        let mut tile = vec![[0u8; 3]; side * side];
        for (i, row) in (-half..=half).rev().enumerate() {
            for (j, col) in (-half..=half).enumerate() {
                let v = psf[((m / 2 + row) as usize, (m / 2 + col) as usize)] / peak;
                let s = (v.max(10f64.powf(-PSF_DECADES)).log10() + PSF_DECADES) / PSF_DECADES;
                tile[i * side + j] = crate::display::inferno(s);
            }
        }
        tiles.push((side, tile));
        transfers.push(t);
    }
    let side = tiles
        .first()
        .map(|t| t.0)
        .ok_or_else(|| Error::param("field heights", "none", "at least one field height"))?;
    let zside = side * ZOOM;
    let width = tiles.len() * zside + (tiles.len() - 1) * GAP;
    let height = zside + LABEL_PX;
    let mut buf = vec![255u8; width * height * 3];
    {
        ensure_font();
        let root =
            BitMapBackend::with_buffer(&mut buf, (width as u32, height as u32)).into_drawing_area();
        let draw_err = |e: String| {
            Error::param(
                "psf grid",
                format!("cannot draw: {e}"),
                "a drawable picture",
            )
        };
        for (k, (_, tile)) in tiles.iter().enumerate() {
            let x0 = k * (zside + GAP);
            for r in 0..zside {
                for c in 0..zside {
                    let [red, g, b] = tile[(r / ZOOM) * side + c / ZOOM];
                    root.draw_pixel(((x0 + c) as i32, r as i32), &RGBColor(red, g, b))
                        .map_err(|e| draw_err(e.to_string()))?;
                }
            }
            let style = TextStyle::from((FONT, 15).into_font())
                .color(&BLACK)
                .pos(Pos::new(HPos::Center, VPos::Center));
            root.draw_text(
                &format!("H = {:.2}", fields[k]),
                &style,
                ((x0 + zside / 2) as i32, (zside + LABEL_PX / 2) as i32),
            )
            .map_err(|e| draw_err(e.to_string()))?;
        }
        root.present().map_err(|e| draw_err(e.to_string()))?;
    }
    Ok((
        crate::display::encode_png(width, height, 3, &buf)?,
        transfers,
    ))
}

/// The tangential and sagittal MTF of the pupil at each of `transfers` (field heights
/// `fields`) from 0 to the cutoff D/λ, in cycles/mrad, as a PNG line plot.
pub fn field_mtf_png(
    transfers: &[crate::wavefront::PupilTransfer],
    fields: &[f64],
    wavelength_um: f64,
) -> Result<Vec<u8>> {
    let fc = transfers.first().map_or(0.0, |t| t.cutoff_cy_per_rad());
    let points = 200;
    let f: Vec<f64> = (0..=points)
        .map(|i| fc * i as f64 / points as f64)
        .collect();
    let x: Vec<f64> = f.iter().map(|v| v * 1e-3).collect();
    let curves: Vec<(String, Vec<f64>)> = transfers
        .iter()
        .zip(fields)
        .flat_map(|(t, h)| {
            let (tan, sag) = t.tangential_sagittal_cy_per_rad(&f);
            [
                (format!("T, H = {h:.1}"), tan),
                (format!("S, H = {h:.1}"), sag),
            ]
        })
        .collect();
    let title = format!("pupil MTF across the field at {wavelength_um:.2} µm");
    crate::plot::render_line_plot(&LinePlot {
        title: &title,
        x_label: "spatial frequency (cy/mrad)",
        y_label: "MTF",
        series: curves
            .iter()
            .map(|(label, y)| Series { label, x: &x, y })
            .collect(),
        markers: Vec::new(),
        y_range: Some((0.0, 1.0)),
        size_px: (640, 400),
    })
}
