//! ENVI cubes: a plain-text `.hdr` header next to a raw binary data file.
//!
//! # Reading
//!
//! [`EnviReader::open`] accepts either file of the pair. Given a header `X.hdr` it looks
//! for the data in `X`, `X.img`, `X.dat`, `X.raw`, `X.bsq`, `X.bil`, `X.bip` (in that
//! order, any letter case); given a data file `X.ext` it looks for `X.ext.hdr`, then
//! `X.hdr`. The header's first line is `ENVI`; every other line is `key = value`, where a
//! value in `{…}` may run over several lines and lines starting with `;` are comments.
//! Keys are matched case-insensitively with runs of white space treated as one space;
//! keys eoir does not use are ignored.
//!
//! | key | meaning |
//! |---|---|
//! | `samples`, `lines`, `bands` | columns, rows, bands (required) |
//! | `header offset` | bytes to skip at the start of the data file (default 0) |
//! | `data type` | 2 int16, 3 int32, 4 float32, 5 float64, 12 uint16 (required) |
//! | `interleave` | `bsq`, `bil` or `bip` |
//! | `byte order` | 0 little-endian, 1 big-endian |
//! | `wavelength` | band centres, one per band (required) |
//! | `wavelength units` | `Micrometers` (`micron`, `um`, `µm`), `Nanometers` (`nm`), `Millimeters`, `Meters`, `Wavenumber` (`cm-1`) |
//! | `fwhm` | band widths, same units as `wavelength` |
//! | `data gain values`, `data offset values` | per band: value = gain · stored + offset |
//! | `eoir radiance units`, `radiance units`, `data units`, `units` | radiance unit, first present wins: `W m-2 sr-1 um-1`, `W/(m2 sr nm)`, `uW cm-2 sr-1 nm-1`… ([`crate::scene::units`]); values are converted to W m-2 sr-1 µm-1 |
//! | `eoir fov deg` | `{horizontal, vertical}` full field of view, degrees |
//! | `eoir ifov rad` | `{x, y}` angular pixel spacing, rad (instead of `eoir fov deg`) |
//! | `fov`, `field of view` | `{horizontal, vertical}` (or horizontal only) full field of view, degrees, as SPy writes it; used when eoir's keys are absent |
//! | `eoir range m` | range to the scene, m |
//! | `data ignore value` | stored value marking pixels without data: they are read as 0 radiance and counted in the warnings |
//!
//! Without `wavelength units` (or with `wavelength units = Unknown`) eoir assumes µm when
//! every wavelength is below 30 and nm when every wavelength is above 200 (and says so in
//! the reader's warnings); anything else is an error. Wavenumbers ν (cm⁻¹) become λ = 10⁴/ν µm and their widths
//! Δλ = 10⁴ Δν / ν² µm. Bands stored in strictly decreasing wavelength order (usual for
//! wavenumber grids) are handed out in increasing order; any other order is an error.
//! Without any unit key the values are taken to be spectral radiance per µm (with a
//! warning); `--radiance-units` ([`ReadOptions`]) overrides every key. Without a field of view the cube has no geometry and the caller
//! (the CLI) has to supply one.
//!
//! The minimal header a user writes by hand for a float32 cube of 2 bands, 480 rows and
//! 640 columns stored band after band in `scene.img`:
//!
//! ```text
//! ENVI
//! samples = 640
//! lines = 480
//! bands = 2
//! data type = 4
//! interleave = bsq
//! byte order = 0
//! wavelength units = Micrometers
//! wavelength = {8.5, 10.5}
//! eoir radiance units = W m-2 sr-1 um-1
//! eoir fov deg = {10.0, 7.5}
//! ```
//!
//! (`fwhm`, `eoir fov deg` and `eoir range m` are optional.)
//!
//! # Writing
//!
//! [`write()`] stores float32, little-endian, band-sequential data. The header is always
//! `<stem>.hdr`; the data file is the path given, or `<stem>.img` when the path given is
//! the header itself. Examples: `write("out/cube.img")` and `write("out/cube.hdr")` both
//! produce `out/cube.img` + `out/cube.hdr`; `write("out/cube.bsq")` produces
//! `out/cube.bsq` + `out/cube.hdr`. The data file is written first and the header last,
//! each atomically; if the header cannot be written the new data file is removed again.

use std::fs::File;
use std::path::{Path, PathBuf};

use ndarray::Array2;

use crate::error::{Error, Result};
use crate::scene::{check_radiance_plane, Cube, CubeMeta};

use super::binary::{
    check_size, decode_interleaved, decode_into, read_at, read_samples, PlanePool, SampleType,
    READ_BLOCK_BYTES,
};
use super::mapped::{map_plane, BandPlanes, DeferredCheck};
use super::metadata::{
    default_units, order_bands, resolve_geometry, resolve_units, BandOrder, ReadOptions,
};
use super::spill::BandSpill;
use super::{atomic_write, write_all, CubeReader};

mod header;
use header::{find_pair, Header, Interleave, SpectralUnits, FOV_KEYS, UNIT_KEYS};

/// Reads an ENVI cube band by band or a chunk of bands at a time.
///
/// Opening parses and checks the header and the data file's size. Reading converts the
/// stored samples to f32 with the header's gain and offset, sets `data ignore value`
/// samples to 0, and checks every plane is physical radiance (finite, non-negative; the
/// error names the file, band and pixel). Only the requested bands are decoded and
/// checked, and the I/O follows the interleave:
///
/// - **BSQ**: one sequential read per band (in 4 MiB pieces for larger planes).
/// - **BIL**: one read per image row spanning the lines of the requested bands (several
///   rows per read when every band is requested), so a chunk of adjacent bands costs its
///   own bytes and nothing more.
/// - **BIP**: every band's samples are spread over the whole frame. Frames up to
///   [`BIP_DIRECT_FRAME_BYTES`] (or a request for every band) are read whole, in 4 MiB
///   row blocks, picking the requested samples out of each pixel. Larger frames are
///   transposed once, on the first read, into a band-order scratch file in the temporary
///   directory (unlinked at creation; see `spill`), and each band is then one sequential
///   read: one pass over the file, memory of one block, instead of one pass per chunk.
#[derive(Debug)]
pub struct EnviReader {
    meta: CubeMeta,
    header_path: PathBuf,
    data_path: PathBuf,
    file: File,
    header_offset: u64,
    ty: SampleType,
    big_endian: bool,
    interleave: Interleave,
    /// Bands as stored in the file.
    file_bands: usize,
    /// Output band index → stored band index.
    band_map: Vec<usize>,
    /// Per stored band `(gain, offset)`, if the header scales the data.
    scale: Option<Vec<(f64, f64)>>,
    /// `data ignore value`, and per output band the samples found equal to it.
    ignore: Option<f64>,
    masked: Vec<Option<usize>>,
    units_source: String,
    warnings: Vec<String>,
    /// BIP frames above this size go through the scratch file.
    bip_direct_frame_bytes: u64,
    /// The band-order scratch file of a large BIP frame, once created.
    spill: Option<BandSpill>,
    /// The reading options it was opened with (for [`CubeReader::reopen`]).
    options: ReadOptions,
    /// Band-sequential plane buffers handed back by the engine.
    pool: PlanePool,
    /// Set once mapping the file failed (e.g. a file system without `mmap`): later reads
    /// go straight to `read()`.
    map_failed: bool,
}

impl EnviReader {
    /// Opens an ENVI cube from its header (`.hdr`) or its data file, parses the header and
    /// checks the data file has exactly the size the header implies.
    pub fn open(path: &Path) -> Result<Self> {
        Self::open_with(path, &ReadOptions::default())
    }

    /// Like [`open`](Self::open), with reading options (a radiance-unit override).
    pub fn open_with(path: &Path, options: &ReadOptions) -> Result<Self> {
        let (header_path, data_path) = find_pair(path)?;
        let bytes = crate::io::input::read_regular(&header_path, crate::io::input::MAX_TEXT_BYTES)?;
        let text = String::from_utf8_lossy(&bytes);
        let mut warnings = Vec::new();
        let h = Header::parse(&header_path, &text, &mut warnings)?;

        let cols = h.count("samples", "640")?;
        let rows = h.count("lines", "480")?;
        let bands = h.count("bands", "3")?;
        let header_offset = h.opt_u64("header offset")?.unwrap_or(0);

        let ty = match h.get("data type") {
            None => return Err(h.missing("data type", "4")),
            Some(e) => match e.value.parse::<u32>() {
                Ok(2) => SampleType::I16,
                Ok(3) => SampleType::I32,
                Ok(4) => SampleType::F32,
                Ok(5) => SampleType::F64,
                Ok(12) => SampleType::U16,
                Ok(n) => {
                    let name = match n {
                        1 => "uint8",
                        6 => "complex float32",
                        9 => "complex float64",
                        13 => "uint32",
                        14 => "int64",
                        15 => "uint64",
                        _ => "unknown",
                    };
                    return Err(h.error(
                        "data type",
                        e,
                        &format!("one of 2 (int16), 3 (int32), 4 (float32), 5 (float64), 12 (uint16); data type {n} ({name}) is not supported"),
                    ));
                }
                Err(_) => {
                    return Err(h.error(
                        "data type",
                        e,
                        "one of 2 (int16), 3 (int32), 4 (float32), 5 (float64), 12 (uint16)",
                    ))
                }
            },
        };

        let interleave = match h.get("interleave") {
            None => {
                warnings.push(format!(
                    "{}: no `interleave`; assuming bsq (band sequential)",
                    header_path.display()
                ));
                Interleave::Bsq
            }
            Some(e) => match e.value.to_ascii_lowercase().as_str() {
                "bsq" => Interleave::Bsq,
                "bil" => Interleave::Bil,
                "bip" => Interleave::Bip,
                _ => return Err(h.error("interleave", e, "bsq, bil or bip")),
            },
        };

        let big_endian = match h.get("byte order") {
            None => {
                if ty.size() > 1 {
                    warnings.push(format!(
                        "{}: no `byte order`; assuming 0 (little-endian)",
                        header_path.display()
                    ));
                }
                false
            }
            Some(e) => match e.value.as_str() {
                "0" => false,
                "1" => true,
                _ => return Err(h.error("byte order", e, "0 (little-endian) or 1 (big-endian)")),
            },
        };

        // Spectral axis.
        let wl_raw = h.opt_list("wavelength", Some(bands))?.ok_or_else(|| {
            h.missing(
                "wavelength",
                "{8.5, 9.5, 10.5}` with `wavelength units = Micrometers",
            )
        })?;
        let fwhm_raw = h.opt_list("fwhm", Some(bands))?;
        let units = match h.get("wavelength units") {
            Some(e) if !e.value.eq_ignore_ascii_case("unknown") => SpectralUnits::parse(&e.value)
                .ok_or_else(|| {
                h.error(
                    "wavelength units",
                    e,
                    "Micrometers, Nanometers, Millimeters, Meters or Wavenumber (cm-1)",
                )
            })?,
            _ => {
                if wl_raw.iter().all(|w| *w < 30.0) {
                    warnings.push(format!(
                        "{}: no `wavelength units`; the wavelengths are all below 30, so they are taken as micrometers",
                        header_path.display()
                    ));
                    SpectralUnits::Length(1.0)
                } else if wl_raw.iter().all(|w| *w > 200.0) {
                    warnings.push(format!(
                        "{}: no `wavelength units`; the wavelengths are all above 200, so they are taken as nanometers",
                        header_path.display()
                    ));
                    SpectralUnits::Length(1e-3)
                } else {
                    return Err(Error::format(
                        &header_path,
                        format!(
                            "no `wavelength units` and the wavelengths ({} … {}) are neither all below 30 (micrometers) nor all above 200 (nanometers); add `wavelength units = Micrometers`, `Nanometers` or `Wavenumber`",
                            wl_raw.iter().cloned().fold(f64::INFINITY, f64::min),
                            wl_raw.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
                        ),
                    ));
                }
            }
        };
        if let Some((i, w)) = wl_raw.iter().enumerate().find(|(_, w)| **w <= 0.0) {
            return Err(Error::format(
                &header_path,
                format!("wavelength[{i}] = {w} is not a positive number"),
            ));
        }
        let wl_um = units.centres_um(&wl_raw);
        let fwhm_um = fwhm_raw.map(|f| units.widths_um(&f, &wl_raw));
        let BandOrder {
            wavelength_um,
            fwhm_um,
            band_map,
            reversed,
        } = order_bands(&header_path, wl_um, fwhm_um)?;
        if reversed {
            warnings.push(format!(
                "{}: wavelengths are stored in decreasing order; bands are handed out in increasing wavelength (band 0 = stored band {})",
                header_path.display(),
                bands - 1
            ));
        }

        // Scaling.
        let gains = h.opt_list("data gain values", Some(bands))?;
        let offsets = h.opt_list("data offset values", Some(bands))?;
        let scale: Option<Vec<(f64, f64)>> = match (gains, offsets) {
            (None, None) => None,
            (g, o) => Some(
                (0..bands)
                    .map(|b| {
                        (
                            g.as_ref().map_or(1.0, |g| g[b]),
                            o.as_ref().map_or(0.0, |o| o[b]),
                        )
                    })
                    .collect(),
            ),
        };

        // Radiance units and geometry: eoir's keys, then the common ones.
        let statements: Vec<(String, String)> = UNIT_KEYS
            .iter()
            .filter_map(|k| h.get(k).map(|e| (k.to_string(), e.value.clone())))
            .collect();
        let resolved = match resolve_units(&header_path, &statements, options, &mut warnings)? {
            Some(r) => r,
            None => default_units(
                &header_path,
                "`eoir radiance units`, `radiance units`, `data units` or `units`",
                &mut warnings,
            ),
        };
        let units_rad = resolved.scale.units;
        let k = resolved.scale.to_eoir;
        let scale = match scale {
            Some(v) if k != 1.0 => Some(v.into_iter().map(|(g, o)| (g * k, o * k)).collect()),
            None if k != 1.0 => Some(vec![(k, 0.0); bands]),
            other => other,
        };
        let mut common = Vec::new();
        for key in FOV_KEYS {
            if let Some(v) = h.opt_list(key, None)? {
                common.push((key.to_string(), v));
            }
        }
        let geometry = resolve_geometry(
            &header_path,
            ["`eoir fov deg`", "`eoir ifov rad`", "`eoir range m`"],
            h.opt_pair("eoir fov deg")?,
            h.opt_pair("eoir ifov rad")?,
            &common,
            h.opt_f64("eoir range m")?,
            rows,
            cols,
            &mut warnings,
        )?;
        let ignore = h.opt_f64("data ignore value")?;

        let meta = CubeMeta {
            wavelength_um,
            fwhm_um,
            units: units_rad,
            geometry,
            rows,
            cols,
        };
        meta.validate(&header_path.display().to_string())?;

        // Size check.
        let expected = (cols as u64)
            .checked_mul(rows as u64)
            .and_then(|n| n.checked_mul(bands as u64))
            .and_then(|n| n.checked_mul(ty.size() as u64))
            .and_then(|n| n.checked_add(header_offset))
            .ok_or_else(|| Error::format(&header_path, "samples × lines × bands is too large"))?;
        let file = crate::io::input::open_regular(&data_path)?;
        let actual = file.metadata().map_err(|e| Error::io(&data_path, e))?.len();
        let layout = format!(
            "header offset {header_offset} + {cols} samples × {rows} lines × {bands} bands × {} bytes",
            ty.size()
        );
        check_size(&data_path, actual, expected, &layout)?;
        crate::limits::check_alloc(
            &format!("reading one band of {}", header_path.display()),
            &[("lines", rows as u64), ("samples", cols as u64)],
            4 + ty.size() as u64,
        )?;

        Ok(EnviReader {
            meta,
            header_path,
            data_path,
            file,
            header_offset,
            ty,
            big_endian,
            interleave,
            file_bands: bands,
            masked: vec![None; band_map.len()],
            band_map,
            scale,
            ignore,
            units_source: resolved.source,
            warnings,
            bip_direct_frame_bytes: BIP_DIRECT_FRAME_BYTES,
            spill: None,
            pool: PlanePool::default(),
            map_failed: false,
            options: options.clone(),
        })
    }

    /// The header file in use.
    pub fn header_path(&self) -> &Path {
        &self.header_path
    }

    /// The data file in use.
    pub fn data_path(&self) -> &Path {
        &self.data_path
    }
}

/// Frames up to this size (bytes of the data file) are read pixel-interleaved directly,
/// whole, for every chunk of bands; larger BIP frames go through a `BandSpill` (64 MiB).
pub const BIP_DIRECT_FRAME_BYTES: u64 = 64 << 20;

impl EnviReader {
    /// BIP frames larger than `bytes` are transposed once into a band-order scratch file
    /// ([`BIP_DIRECT_FRAME_BYTES`] by default); smaller ones are re-read whole for every
    /// call. Both give identical planes; the setting trades temporary disk space against
    /// repeated reads (tests use it to exercise both paths on small cubes).
    pub fn set_bip_direct_frame_bytes(&mut self, bytes: u64) {
        self.bip_direct_frame_bytes = bytes;
    }

    /// Whether a band-order scratch file is in use (BIP frames above the direct size, once
    /// a band was read).
    pub fn uses_scratch_file(&self) -> bool {
        self.spill.is_some()
    }

    /// Checks a request names frame 0 and existing bands.
    fn check_request(&self, frame: usize, bands: &[usize]) -> Result<()> {
        if frame != 0 {
            return Err(Error::OutOfRange(format!(
                "{}: frame {frame} requested but an ENVI cube has one frame (0)",
                self.data_path.display()
            )));
        }
        if let Some(band) = bands.iter().find(|&&b| b >= self.meta.bands()) {
            return Err(Error::OutOfRange(format!(
                "{}: band {band} requested but the cube has bands 0..{}",
                self.data_path.display(),
                self.meta.bands()
            )));
        }
        Ok(())
    }

    /// The `(gain, offset)` of stored band `fb`, if the header scales the data.
    fn scale_of(&self, fb: usize) -> Option<(f64, f64)> {
        self.scale.as_ref().map(|s| s[fb])
    }

    /// Output bands `bands` of a band-sequential file as views of memory maps of their
    /// stored planes, each checked as `read_band` checks it if `check` (else the caller
    /// owes the check, see `CubeReader::read_planes_deferred`); `None` when the file's data
    /// cannot be served as it lies (not BSQ f32 in the machine's byte order, scaled or
    /// with a `data ignore value`, mapping turned off or failing): the caller reads.
    fn map_bsq(&mut self, bands: &[usize], check: bool) -> Result<Option<BandPlanes>> {
        let native = self.big_endian == cfg!(target_endian = "big");
        if self.options.no_memory_map
            || self.map_failed
            || self.interleave != Interleave::Bsq
            || self.ty != SampleType::F32
            || !native
            || self.ignore.is_some()
        {
            return Ok(None);
        }
        let (rows, cols) = (self.meta.rows, self.meta.cols);
        let n = rows * cols;
        let mut planes = Vec::with_capacity(bands.len());
        for &b in bands {
            let fb = self.band_map[b];
            if self.scale_of(fb).is_some() {
                return Ok(None);
            }
            let offset = self.header_offset + (fb * n * 4) as u64;
            let Some(plane) = map_plane(&self.file, offset, rows, cols) else {
                self.map_failed = true;
                return Ok(None);
            };
            planes.push(plane);
        }
        let planes = BandPlanes::Mapped(planes);
        if check {
            planes.check(&self.data_path, bands, &self.meta.wavelength_um)?;
        }
        Ok(Some(planes))
    }

    /// Stored band `fb` of a band-sequential file: one sequential read.
    fn read_bsq(&mut self, fb: usize) -> Result<Vec<f32>> {
        let n = self.meta.rows * self.meta.cols;
        let offset = self.header_offset + (fb * n * self.ty.size()) as u64;
        let mut values = self.pool.take(n);
        let scale = self.scale_of(fb);
        read_samples(
            &mut self.file,
            &self.data_path,
            offset,
            n,
            self.ty,
            self.big_endian,
            scale,
            &mut values,
        )?;
        Ok(values)
    }

    /// Stored bands `fbs` of a band-interleaved-by-line file. Each image row holds one
    /// line per band, so per row the span of lines from the lowest to the highest
    /// requested band is read in one piece (several rows per read when the span is the
    /// whole row) and the requested lines are decoded out of it.
    fn read_bil(&mut self, fbs: &[usize]) -> Result<Vec<Vec<f32>>> {
        let (rows, cols, nb) = (self.meta.rows, self.meta.cols, self.file_bands);
        let (Some(&lo), Some(&hi)) = (fbs.iter().min(), fbs.iter().max()) else {
            return Ok(Vec::new());
        };
        let bps = self.ty.size();
        let line = cols * bps;
        let span = hi - lo + 1;
        // Rows per read: consecutive rows are contiguous only when the span is the row.
        let group = if span == nb {
            (READ_BLOCK_BYTES / (nb * line)).clamp(1, rows)
        } else {
            1
        };
        let scales: Vec<Option<(f64, f64)>> = fbs.iter().map(|&fb| self.scale_of(fb)).collect();
        let mut out: Vec<Vec<f32>> = fbs
            .iter()
            .map(|_| Vec::with_capacity(rows * cols))
            .collect();
        let mut buf = vec![0u8; group * span * line];
        let mut r0 = 0;
        while r0 < rows {
            let g = group.min(rows - r0);
            let bytes = &mut buf[..g * span * line];
            let offset = self.header_offset + ((r0 * nb + lo) * line) as u64;
            read_at(&mut self.file, &self.data_path, offset, bytes)?;
            for r in 0..g {
                let row = &bytes[r * span * line..(r + 1) * span * line];
                for ((fb, scale), values) in fbs.iter().zip(&scales).zip(out.iter_mut()) {
                    let at = (fb - lo) * line;
                    decode_into(
                        &row[at..at + line],
                        self.ty,
                        self.big_endian,
                        *scale,
                        values,
                    );
                }
            }
            r0 += g;
        }
        Ok(out)
    }

    /// Stored bands `fbs` of a band-interleaved-by-pixel file: from the band-order scratch
    /// file (created on first use) when the frame is larger than the direct size and the
    /// request is not every band; otherwise by reading the frame's rows and picking the
    /// requested samples out of every pixel.
    fn read_bip(&mut self, fbs: &[usize]) -> Result<Vec<Vec<f32>>> {
        if !self.bip_through_spill(fbs) {
            return self.read_bip_direct(fbs);
        }
        let path = self.data_path.clone();
        let spill = self.bip_spill()?;
        fbs.iter().map(|&fb| spill.read(&path, fb)).collect()
    }

    /// The band-order scratch file of a BIP frame, made on first use
    /// ([`EnviReader::transpose_bip`]).
    fn bip_spill(&mut self) -> Result<&mut BandSpill> {
        if self.spill.is_none() {
            self.spill = Some(self.transpose_bip()?);
        }
        let path = &self.data_path;
        self.spill
            .as_mut()
            .ok_or_else(|| Error::format(path, "scratch file missing"))
    }

    /// Whether stored bands `fbs` of a BIP file are read from the band-order scratch file:
    /// once it exists, or when the frame is larger than the direct size and the request
    /// is not every band (for every band, one pass over the rows is the cheaper way).
    fn bip_through_spill(&self, fbs: &[usize]) -> bool {
        let all_bands = {
            let mut seen = vec![false; self.file_bands];
            fbs.iter().for_each(|&fb| seen[fb] = true);
            seen.iter().all(|s| *s)
        };
        self.spill.is_some() || (self.frame_bytes() > self.bip_direct_frame_bytes && !all_bands)
    }

    /// Bands `bands` of a BIP file mapped from the band-order scratch file (created here
    /// if it is due, [`EnviReader::bip_through_spill`]), unchecked: the values `read_bip`
    /// would read, without the copy. `None` where they are read instead: mapping off or
    /// failed, a `data ignore value` to replace, bands read directly.
    fn map_bip_spill(&mut self, bands: &[usize]) -> Result<Option<BandPlanes>> {
        if self.options.no_memory_map
            || self.map_failed
            || self.interleave != Interleave::Bip
            || self.ignore.is_some()
        {
            return Ok(None);
        }
        let fbs: Vec<usize> = bands.iter().map(|&b| self.band_map[b]).collect();
        if !self.bip_through_spill(&fbs) {
            return Ok(None);
        }
        let planes = self.bip_spill()?.map_bands(&fbs);
        self.map_failed = planes.is_none();
        Ok(planes)
    }

    /// Bytes of one frame in the data file.
    fn frame_bytes(&self) -> u64 {
        (self.meta.rows * self.meta.cols * self.file_bands * self.ty.size()) as u64
    }

    /// Rows of a BIP file per read (≥ 1, at most [`READ_BLOCK_BYTES`] unless one row is
    /// larger).
    fn bip_rows_per_read(&self) -> usize {
        let row = self.meta.cols * self.file_bands * self.ty.size();
        (READ_BLOCK_BYTES / row).clamp(1, self.meta.rows)
    }

    /// BIP, direct: sequential reads of whole rows, the requested samples decoded out of
    /// each pixel.
    fn read_bip_direct(&mut self, fbs: &[usize]) -> Result<Vec<Vec<f32>>> {
        let (rows, cols, nb) = (self.meta.rows, self.meta.cols, self.file_bands);
        let group = self.bip_rows_per_read();
        let row_bytes = cols * nb * self.ty.size();
        let scales: Vec<Option<(f64, f64)>> = fbs.iter().map(|&fb| self.scale_of(fb)).collect();
        let mut out: Vec<Vec<f32>> = fbs
            .iter()
            .map(|_| Vec::with_capacity(rows * cols))
            .collect();
        // Whole f32 words, so that native f32 samples are read in place (4-byte aligned).
        let mut words = vec![0u32; (group * row_bytes).div_ceil(4)];
        let buf: &mut [u8] = bytemuck::cast_slice_mut(&mut words);
        let mut r0 = 0;
        while r0 < rows {
            let g = group.min(rows - r0);
            let bytes = &mut buf[..g * row_bytes];
            let offset = self.header_offset + (r0 * row_bytes) as u64;
            read_at(&mut self.file, &self.data_path, offset, bytes)?;
            decode_interleaved(
                bytes,
                self.ty,
                self.big_endian,
                &scales,
                fbs,
                nb,
                g * cols,
                &mut out,
            );
            r0 += g;
        }
        Ok(out)
    }

    /// BIP → band order, once: reads the frame's rows sequentially, a block at a time,
    /// decodes every stored band of the block (scaled as the planes are; a tile of pixels
    /// at a time, [`decode_interleaved`]) and writes each band's part to the scratch file.
    /// Memory: one read block and its decoded copy.
    fn transpose_bip(&mut self) -> Result<BandSpill> {
        let (rows, cols, nb) = (self.meta.rows, self.meta.cols, self.file_bands);
        let mut spill = BandSpill::create(&self.data_path, nb, rows, cols)?;
        let group = self.bip_rows_per_read();
        let row_bytes = cols * nb * self.ty.size();
        // Whole f32 words, so that native f32 samples are read in place (4-byte aligned).
        let mut words = vec![0u32; (group * row_bytes).div_ceil(4)];
        let buf: &mut [u8] = bytemuck::cast_slice_mut(&mut words);
        let bands: Vec<usize> = (0..nb).collect();
        let scales: Vec<Option<(f64, f64)>> = bands.iter().map(|&fb| self.scale_of(fb)).collect();
        let mut values: Vec<Vec<f32>> = bands
            .iter()
            .map(|_| Vec::with_capacity(group * cols))
            .collect();
        let mut r0 = 0;
        while r0 < rows {
            let g = group.min(rows - r0);
            let bytes = &mut buf[..g * row_bytes];
            let offset = self.header_offset + (r0 * row_bytes) as u64;
            read_at(&mut self.file, &self.data_path, offset, bytes)?;
            values.iter_mut().for_each(Vec::clear);
            decode_interleaved(
                bytes,
                self.ty,
                self.big_endian,
                &scales,
                &bands,
                nb,
                g * cols,
                &mut values,
            );
            for (fb, v) in values.iter().enumerate() {
                spill.write(&self.data_path, fb, r0, 0, v)?;
            }
            r0 += g;
        }
        Ok(spill)
    }

    /// Output band `band` from its decoded values: `data ignore value` samples to 0
    /// (counted), then the radiance check.
    fn finish_plane(&mut self, band: usize, mut values: Vec<f32>) -> Result<Array2<f32>> {
        if let Some(ignore) = self.ignore {
            // The marker after the same scaling as the data, so the comparison is exact.
            let marker = match self.scale_of(self.band_map[band]) {
                Some((g, o)) => (g * ignore + o) as f32,
                None => ignore as f32,
            };
            let mut n = 0;
            for v in values.iter_mut().filter(|v| **v == marker) {
                *v = 0.0;
                n += 1;
            }
            self.masked[band] = Some(n);
        }
        let plane = Array2::from_shape_vec((self.meta.rows, self.meta.cols), values)
            .map_err(|e| Error::format(&self.data_path, e.to_string()))?;
        check_radiance_plane(
            &self.data_path.display().to_string(),
            band,
            self.meta.wavelength_um[band],
            plane.view(),
        )?;
        Ok(plane)
    }
}

impl CubeReader for EnviReader {
    fn meta(&self) -> &CubeMeta {
        &self.meta
    }

    fn read_band(&mut self, frame: usize, band: usize) -> Result<Array2<f32>> {
        let mut planes = self.read_bands(frame, &[band])?;
        planes.pop().ok_or_else(|| {
            Error::OutOfRange(format!(
                "{}: band {band} was requested but not read",
                self.data_path.display()
            ))
        })
    }

    /// Reads the requested bands with I/O proportional to what they occupy (see
    /// [`EnviReader`]): BSQ one sequential read per band, BIL one read per image row
    /// covering the rows of the requested bands, BIP through the band-order scratch file
    /// (or whole-row reads for small frames). Every value is checked as in `read_band`.
    fn read_bands(&mut self, frame: usize, bands: &[usize]) -> Result<Vec<Array2<f32>>> {
        self.check_request(frame, bands)?;
        if bands.is_empty() {
            return Ok(Vec::new());
        }
        let file_bands: Vec<usize> = bands.iter().map(|&b| self.band_map[b]).collect();
        let raw = match self.interleave {
            Interleave::Bsq => file_bands
                .iter()
                .map(|&fb| self.read_bsq(fb))
                .collect::<Result<Vec<_>>>()?,
            Interleave::Bil => self.read_bil(&file_bands)?,
            Interleave::Bip => self.read_bip(&file_bands)?,
        };
        bands
            .iter()
            .zip(raw)
            .map(|(&b, values)| self.finish_plane(b, values))
            .collect()
    }

    /// Band-sequential f32 data in the machine's byte order comes zero-copy from memory
    /// maps of the file (see [`super::mapped`]); everything else as
    /// [`CubeReader::read_bands`] reads it.
    fn read_planes(&mut self, frame: usize, bands: &[usize]) -> Result<BandPlanes> {
        self.check_request(frame, bands)?;
        if bands.is_empty() {
            return Ok(BandPlanes::Owned(Vec::new()));
        }
        match self.map_bsq(bands, true)? {
            Some(planes) => Ok(planes),
            None => self.read_bands(frame, bands).map(BandPlanes::Owned),
        }
    }

    /// As `read_planes`, the mapped planes unchecked (see the trait method).
    fn read_planes_deferred(
        &mut self,
        frame: usize,
        bands: &[usize],
    ) -> Result<(BandPlanes, Option<DeferredCheck>)> {
        self.check_request(frame, bands)?;
        if bands.is_empty() {
            return Ok((BandPlanes::Owned(Vec::new()), None));
        }
        let mapped = match self.map_bsq(bands, false)? {
            Some(planes) => Some(planes),
            None => self.map_bip_spill(bands)?,
        };
        match mapped {
            Some(planes) => {
                let check = DeferredCheck::new(&self.data_path, bands, &self.meta.wavelength_um);
                Ok((planes, Some(check)))
            }
            None => Ok((self.read_bands(frame, bands).map(BandPlanes::Owned)?, None)),
        }
    }

    fn warnings(&self) -> Vec<String> {
        let mut w = self.warnings.clone();
        let read: Vec<usize> = self.masked.iter().flatten().copied().collect();
        let n: usize = read.iter().sum();
        if let (Some(ignore), true) = (self.ignore, n > 0) {
            w.push(format!(
                "{}: {n} samples (pixel × band, in the {} bands read) equal `data ignore value = {ignore}` and were read as 0 radiance",
                self.header_path.display(),
                read.len()
            ));
        }
        w
    }

    fn units_source(&self) -> String {
        self.units_source.clone()
    }

    /// The same cube opened again from its header with the same options (an own file
    /// handle, no scratch file yet, the same BIP direct-read size).
    fn reopen(&self) -> Option<Result<Box<dyn CubeReader + Send>>> {
        Some(
            Self::open_with(&self.header_path, &self.options).map(|mut r| {
                r.bip_direct_frame_bytes = self.bip_direct_frame_bytes;
                Box::new(r) as _
            }),
        )
    }

    /// Keeps band-sequential plane buffers for the next reads (BIL/BIP planes are
    /// assembled elsewhere and are simply dropped).
    fn recycle(&mut self, planes: Vec<Array2<f32>>) {
        if self.interleave == Interleave::Bsq {
            self.pool.give(planes, self.meta.rows * self.meta.cols);
        }
    }
}

/// The `(header, data)` paths [`write()`] uses for `path`: the header is `<stem>.hdr`, the
/// data file is `path` itself, or `<stem>.img` when `path` is the header.
pub fn output_paths(path: &Path) -> (PathBuf, PathBuf) {
    let is_header = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("hdr"));
    if is_header {
        (path.to_path_buf(), path.with_extension("img"))
    } else {
        (path.with_extension("hdr"), path.to_path_buf())
    }
}

/// Formats numbers as an ENVI `{…}` list (shortest text that reads back to the same f64).
fn list(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{x}")).collect();
    format!("{{{}}}", items.join(", "))
}

/// Writes a cube as ENVI: float32, little-endian, band sequential, header with
/// wavelengths in µm, fwhm and eoir's keys (see the module documentation for file names).
pub fn write(path: &Path, cube: &Cube) -> Result<()> {
    let (header_path, data_path) = output_paths(path);
    cube.check(&path.display().to_string())?;
    let meta = &cube.meta;
    let (b, r, c) = cube.data.dim();

    let mut h = String::from("ENVI\n");
    h.push_str("description = {eoir spectral radiance cube}\n");
    h.push_str(&format!("samples = {c}\nlines = {r}\nbands = {b}\n"));
    h.push_str("header offset = 0\nfile type = ENVI Standard\ndata type = 4\n");
    h.push_str("interleave = bsq\nbyte order = 0\n");
    h.push_str("wavelength units = Micrometers\n");
    h.push_str(&format!("wavelength = {}\n", list(&meta.wavelength_um)));
    if let Some(f) = &meta.fwhm_um {
        h.push_str(&format!("fwhm = {}\n", list(f)));
    }
    h.push_str(&format!("eoir radiance units = {}\n", meta.units.as_str()));
    if let Some(g) = &meta.geometry {
        h.push_str(&format!(
            "eoir fov deg = {}\n",
            list(&[g.fov_x_deg, g.fov_y_deg])
        ));
        if let Some(rm) = g.range_m {
            h.push_str(&format!("eoir range m = {rm}\n"));
        }
    }

    atomic_write(&data_path, |w| {
        let mut buf = Vec::with_capacity(r * c * 4);
        for plane in cube.data.outer_iter() {
            buf.clear();
            for v in plane.iter() {
                buf.extend_from_slice(&v.to_le_bytes());
            }
            write_all(w, &buf, &data_path)?;
        }
        Ok(())
    })?;
    let res = atomic_write(&header_path, |w| write_all(w, h.as_bytes(), &header_path));
    if res.is_err() {
        // A data file without its header is useless; do not leave it behind.
        let _ = std::fs::remove_file(&data_path);
    }
    res
}
