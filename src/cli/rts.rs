//! `eoir rts`: the random telegraph (RTS) pixels of a dark sequence
//! ([`eoir::characterize::rts::find_rts_pixels`]; docs/focal-plane.md).

use std::path::PathBuf;

use anyhow::{Context, Result};

use eoir::characterize::rts::{find_rts_pixels, RtsSearch};

/// Arguments of `eoir rts`.
#[derive(Debug, clap::Args)]
pub struct RtsArgs {
    /// A dark sequence as one `[frame, row, col]` .npy (a run's `dn_stack.npy`; DN or
    /// electrons, `<u2`/`<i2`/`<f4`/`<f8`).
    stack: PathBuf,
    /// The flagged pixels as CSV: `row,col,step,high_fraction,separation_sigma`.
    #[arg(short, long)]
    output: PathBuf,
    /// Minimum separation of the two levels, in pooled within-level standard deviations.
    #[arg(long, default_value_t = 4.0)]
    threshold_sigma: f64,
    /// Minimum number of frames in each level.
    #[arg(long, default_value_t = 3)]
    min_frames: usize,
    /// Keep each frame's median (by default it is subtracted, removing common-mode
    /// offsets such as a drifting bias).
    #[arg(long)]
    keep_frame_median: bool,
    /// Print nothing but errors.
    #[arg(long)]
    quiet: bool,
}

/// `eoir rts`.
pub fn rts(args: RtsArgs) -> Result<()> {
    let stack = eoir::io::npy::read_stack(&args.stack)?;
    let search = RtsSearch {
        threshold_sigma: args.threshold_sigma,
        min_frames: args.min_frames,
        remove_frame_median: !args.keep_frame_median,
    };
    let found = find_rts_pixels(stack.mapv(f64::from).view(), &search)
        .with_context(|| format!("finding RTS pixels in {}", args.stack.display()))?;
    let mut csv = String::from("row,col,step,high_fraction,separation_sigma\n");
    for d in &found {
        csv.push_str(&format!(
            "{},{},{},{},{}\n",
            d.row, d.col, d.step, d.high_fraction, d.separation_sigma
        ));
    }
    eoir::io::output::check_output_target(&args.output)?;
    eoir::io::atomic_write(&args.output, |w| {
        eoir::io::write_all(w, csv.as_bytes(), &args.output)
    })?;
    if !args.quiet {
        let (frames, rows, cols) = stack.dim();
        println!(
            "{} RTS pixel(s) of {} in {} frames ({:.3} %); wrote {}",
            found.len(),
            rows * cols,
            frames,
            100.0 * found.len() as f64 / (rows * cols).max(1) as f64,
            args.output.display()
        );
    }
    Ok(())
}
