//! Spectral OpenEXR cubes in the layout of Fichet, Pacanowski and Wilkie, "An OpenEXR
//! Layout for Spectral Images", *Journal of Computer Graphics Techniques* 10(3), 2021
//! (<http://jcgt.org/published/0010/03/01/>), as implemented by the authors' reference
//! library (<https://github.com/afichet/spectral-exr>).
//!
//! # What the layout says (and what eoir does with it)
//!
//! - **Emissive channels** are named `S<k>.<value><unit>`: `k` is the Stokes component
//!   (`S0` = total radiance, `S1`–`S3` = polarisation), `<value>` a positive decimal number
//!   whose decimal separator is a **comma** (the dot is OpenEXR's layer separator), with an
//!   optional power-of-ten exponent (`E`/`e`, optional sign, digits), and `<unit>` an
//!   optional SI prefix (`Y Z E P T G M k h da d c m u n p`) followed by `m` (wavelength)
//!   or `Hz` (frequency). The paper's pattern is
//!   `^S[0-3]\.(\d*,?\d*([Ee][+-]?\d+)?)(Y|Z|E|P|T|G|M|k|h|da|d|c|m|u|n|p)?(m|Hz)$`;
//!   eoir also accepts `µ`/`μ` for the micro prefix. Examples: `S0.550,000000nm`,
//!   `S0.4,5um`, `S0.5E-7m`, `S0.600THz`.
//! - **Reflective channels** are `T.<value><unit>`, bi-spectral re-radiation
//!   `T.<value><unit>.<value><unit>`. eoir reads radiance only: reflective, polarised
//!   (`S1`–`S3`) and any other channel (RGB previews, depth…) are ignored and listed in
//!   [`CubeReader::warnings`](super::CubeReader::warnings).
//! - OpenEXR stores channels **sorted by name**, so the band order is recovered by sorting
//!   the parsed wavelengths, never assumed (`S0.1000,000000nm` sorts before
//!   `S0.950,000000nm` as a string).
//! - Header attributes of the layout: `spectralLayoutVersion` (string, `"1.0"`) and
//!   `emissiveUnits` (string, `"W.m^-2.sr^-1"` in the reference library).
//!
//! # What the layout leaves open, and the eoir attributes that close it
//!
//! The layout does not say per which spectral unit a spectral density is given. eoir
//! writes, next to the layout's attributes:
//!
//! | attribute | OpenEXR type | meaning |
//! |---|---|---|
//! | `eoirRadianceUnits` | string | [`RadianceUnits::as_str`]: spectral per µm or band-integrated |
//! | `eoirSpectralDensityUnit` | string | `"um"`: values are per µm (spectral cubes only) |
//! | `eoirWavelengthUm` | string | exact band centres, µm, space separated (the channel names carry 6 decimals in nm) |
//! | `eoirFwhmUm` | string | band widths, µm, space separated, band order (if known) |
//! | `eoirFovDeg` | `v2d` | full field of view `[horizontal, vertical]`, degrees (if known) |
//! | `eoirRangeM` | `double` | range to the scene, m (if known) |
//!
//! Reading a file, the units come from, in this order: `--radiance-units`
//! ([`ReadOptions`]); eoir's attributes above; a `radianceUnits` or `units` string
//! attribute in any spelling of [`crate::scene::units`] (e.g. `W m-2 sr-1 um-1` on a file
//! whose channels are named in nm: the values are per µm whatever the channel names
//! say); the density unit of `emissiveUnits` if it names one (e.g.
//! `W.m^-2.sr^-1.nm^-1`). **Without any unit statement, eoir assumes the values are per
//! the unit of the channel names** (nm channels ⇒ values per nm, multiplied by 1000 to
//! give per µm), says so in [`CubeReader::warnings`](super::CubeReader::warnings) and
//! records the rule in [`CubeReader::units_source`](super::CubeReader::units_source)
//! (`report.json`: `input.units_source`).
//!
//! The field of view comes from `eoirFovDeg`, else from a `fov_deg` or `fov` attribute
//! (`[horizontal, vertical]` degrees or the horizontal alone). A density per frequency unit is converted with
//! `L_λ = L_ν · |dν/dλ| = L_ν · c / λ²`.
//!
//! # Memory
//!
//! OpenEXR stores all channels of a scan-line block (1–32 lines, by compression) or tile
//! together, so one band cannot be read without decoding every block of the image.
//! [`ExrReader::open`] therefore decodes the file once, block by block, and writes the
//! spectral channels (as f32) into a band-order scratch file in the temporary directory
//! (unlinked at creation; see `spill`); each band read is then one sequential read, and
//! the imaging engine maps the planes of bands stored in the cube's units from that file
//! instead (`CubeReader::read_planes_deferred`, as for a band-sequential input). The
//! peak memory of reading is one compressed chunk + one decompressed block + one
//! channel's share of it (for 1024 columns × 256 f32 channels with ZIP, 16 lines: 16 MiB
//! per block), plus the offset tables (8 bytes per block) and the band planes the
//! caller asks for. It does not grow with the number of bands beyond the block size
//! (bands × columns × lines per block), and no whole-image buffer is ever allocated.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use exr::meta::attribute::AttributeValue;
use exr::prelude::{
    f16, AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, SmallVec,
    Text, WritableImage,
};
use ndarray::{Array2, Axis};

use crate::error::{Error, Result};
use crate::scene::{check_radiance_plane, Cube, CubeMeta, RadianceUnits};

use super::mapped::{BandPlanes, DeferredCheck};
use super::metadata::{resolve_geometry, resolve_units, ReadOptions};
use super::spill::BandSpill;

mod channels;
pub use channels::channel_name;
use channels::*;

/// Common attributes stating the radiance units (strings, any spelling of
/// [`crate::scene::units`]), in precedence order.
pub const UNIT_ATTRIBUTES: [&str; 2] = ["radianceUnits", "units"];
/// Common attributes holding the full field of view in degrees (`v2f`, `v2d`, `float`,
/// `double` or a string of numbers), in precedence order.
pub const FOV_ATTRIBUTES: [&str; 2] = ["fov_deg", "fov"];

/// Layout version eoir writes into `spectralLayoutVersion`.
pub const LAYOUT_VERSION: &str = "1.0";
/// Attribute naming the layout version (Fichet et al. 2021).
pub const ATTR_LAYOUT_VERSION: &str = "spectralLayoutVersion";
/// Attribute naming the radiometric unit of emissive channels (Fichet et al. 2021).
pub const ATTR_EMISSIVE_UNITS: &str = "emissiveUnits";
/// The `emissiveUnits` value eoir writes (the reference library's spelling).
pub const EMISSIVE_UNITS: &str = "W.m^-2.sr^-1";
/// eoir attribute: [`RadianceUnits::as_str`] of the values.
pub const ATTR_RADIANCE_UNITS: &str = "eoirRadianceUnits";
/// eoir attribute: the spectral unit a spectral density is given per (`"um"`).
pub const ATTR_SPECTRAL_DENSITY_UNIT: &str = "eoirSpectralDensityUnit";
/// eoir attribute: exact band centres, µm, space separated, in band order.
pub const ATTR_WAVELENGTH_UM: &str = "eoirWavelengthUm";
/// eoir attribute: band full widths at half maximum, µm, space separated, in band order.
pub const ATTR_FWHM_UM: &str = "eoirFwhmUm";
/// eoir attribute: full field of view `[horizontal, vertical]`, degrees (`v2d`).
pub const ATTR_FOV_DEG: &str = "eoirFovDeg";
/// eoir attribute: range from the sensor to the scene, m (`double`).
pub const ATTR_RANGE_M: &str = "eoirRangeM";

/// OpenEXR type name of a vector of two doubles (Imath `V2d`).
const V2D: &str = "v2d";
/// How many ignored channel names a warning lists before summarising.
const MAX_LISTED: usize = 12;

/// One spectral channel found in the file.
struct Found {
    wavelength_um: f64,
    name: String,
    unit: SpectralUnit,
    unit_text: String,
    /// Index of the channel in the part's (name-sorted) channel list.
    channel: usize,
}

/// Reads a spectral OpenEXR cube (one frame); see the [module documentation](self).
pub struct ExrReader {
    path: PathBuf,
    meta: CubeMeta,
    /// The spectral planes in band order, as stored in the file (f16 widened to f32),
    /// decoded once at opening into a band-order scratch file.
    spill: BandSpill,
    /// Per band: factor turning stored values into the cube's units.
    scale: Vec<f64>,
    units_source: String,
    warnings: Vec<String>,
    /// Whether the engine's planes may be mapped from the scratch file (mapping not
    /// turned off, and not failed yet).
    map: bool,
}

/// Hands the heap memory the decode freed back to the system (glibc keeps large freed
/// blocks resident once its mmap threshold has risen): otherwise the decompressed
/// blocks of all channels stay in the resident set for the whole run, under the planes
/// the engine maps from the scratch file. Nothing elsewhere (other allocators return
/// such memory themselves or not at all).
fn release_freed_heap() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free heap memory to the system; it takes no
    // pointers and leaves every live allocation as it is.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Maps an OpenEXR decoder error to eoir's, naming the file.
fn exr_error(path: &Path, e: exr::error::Error) -> Error {
    match e {
        exr::error::Error::Io(io) => Error::io(path, io),
        other => Error::format(path, format!("not a readable OpenEXR file: {other}")),
    }
}

/// Checks, from the headers alone and before anything of their size is allocated, that
/// the file can hold what they claim and that decoding fits the memory budget
/// ([`crate::limits`]): the offset tables (8 bytes per chunk, stored in the file, so
/// they cannot exceed it) and the largest block, counted three times (the compressed
/// chunk, the decompressed block and one channel's share of it on its way to the scratch
/// file, rounded up).
fn check_exr_size(path: &Path, headers: &[exr::meta::header::Header], file_len: u64) -> Result<()> {
    let what = format!("reading {}", path.display());
    let mut chunks: u64 = 0;
    let mut block: u64 = 0;
    for h in headers {
        chunks = chunks.saturating_add(h.chunk_count as u64);
        let pixels = match h.blocks {
            exr::meta::BlockDescription::Tiles(t) => crate::limits::checked_count(
                &what,
                &[
                    ("tile columns", t.tile_size.x() as u64),
                    ("tile rows", t.tile_size.y() as u64),
                ],
            )?,
            exr::meta::BlockDescription::ScanLines => crate::limits::checked_count(
                &what,
                &[
                    (
                        "scan lines per block",
                        h.compression.scan_lines_per_block() as u64,
                    ),
                    ("columns", h.layer_size.x() as u64),
                ],
            )?,
        };
        let bytes = crate::limits::checked_count(
            &what,
            &[
                ("block pixels", pixels),
                ("bytes per pixel", h.channels.bytes_per_pixel as u64),
            ],
        )?;
        block = block.max(bytes);
    }
    if chunks.saturating_mul(8) > file_len {
        return Err(Error::format(
            path,
            format!(
                "the headers describe {chunks} pixel blocks, whose offset table alone needs {} bytes, but the file has {file_len} bytes (truncated, or a corrupt data window)",
                chunks.saturating_mul(8)
            ),
        ));
    }
    crate::limits::check_bytes(
        &what,
        &format!("3 × the largest block ({block} bytes) + offset tables ({chunks} × 8 bytes)"),
        block
            .saturating_mul(3)
            .saturating_add(chunks.saturating_mul(8)),
    )?;
    Ok(())
}

/// Reads the headers only and checks, before any pixel is decoded, that every part's data
/// window × channels (as f32, the decoder's flat samples, plus this reader's band planes:
/// 8 bytes per sample) fits the memory budget of a whole-image decode (a single-channel image read in full, as `eoir restore` does) ([`crate::limits`]); rewinds `file`.
pub fn check_exr_image_size(
    path: &Path,
    file: &mut std::io::BufReader<std::fs::File>,
) -> Result<()> {
    use std::io::{Seek, SeekFrom};
    let meta = exr::meta::MetaData::read_from_buffered(&mut *file, false).map_err(|e| match e {
        exr::error::Error::Io(io) => Error::io(path, io),
        other => Error::format(path, format!("not a readable OpenEXR file: {other}")),
    })?;
    let mut total: u64 = 0;
    for h in meta.headers.iter() {
        let dims = [
            ("columns", h.layer_size.0 as u64),
            ("rows", h.layer_size.1 as u64),
            ("channels", h.channels.list.len() as u64),
        ];
        let n = crate::limits::checked_count(&format!("reading {}", path.display()), &dims)?;
        total = n
            .checked_mul(8)
            .and_then(|b| b.checked_add(total))
            .ok_or_else(|| Error::TooLarge {
                what: "the OpenEXR image".into(),
                needed: "more than 2^64 bytes".into(),
                limit: crate::limits::max_memory_bytes(),
            })?;
    }
    crate::limits::check_bytes(
        &format!("reading {}", path.display()),
        &format!(
            "{} part(s): data windows × channels × 8 bytes",
            meta.headers.len()
        ),
        total,
    )?;
    file.seek(SeekFrom::Start(0))
        .map_err(|e| Error::io(path, e))?;
    Ok(())
}

/// Decodes the spectral channels `channels` (indices in part `layer`'s channel list, in
/// band order) of the full-resolution level into a band-order scratch file, one block at
/// a time: each decompressed block is split into its channels' line runs, converted to
/// f32 and written at their place. Peak memory: one compressed chunk, one decompressed
/// block and one channel's share of it.
fn decode_to_spill(
    path: &Path,
    blocks: exr::block::reader::Reader<std::io::BufReader<std::fs::File>>,
    layer: usize,
    channels: &[usize],
    rows: usize,
    cols: usize,
) -> Result<BandSpill> {
    use exr::block::reader::ChunksReader;
    let mut spill = BandSpill::create(path, channels.len(), rows, cols)?;
    let header = blocks.headers()[layer].clone();
    let list = &header.channels.list;
    let sizes: Vec<usize> = list
        .iter()
        .map(|c| c.sample_type.bytes_per_sample())
        .collect();
    let half: Vec<bool> = list
        .iter()
        .map(|c| c.sample_type == exr::meta::attribute::SampleType::F16)
        .collect();
    let bytes_per_pixel: usize = sizes.iter().sum();
    let mut failure: Option<Error> = None;
    let reader = blocks
        .filter_chunks(false, |_, _, b| {
            b.layer == layer && b.level == exr::math::Vec2(0, 0)
        })
        .map_err(|e| exr_error(path, e))?;
    let mut values: Vec<f32> = Vec::new();
    let result = reader.decompress_sequential(false, |_, block| {
        let exr::math::Vec2(x0, y0) = block.index.pixel_position;
        let exr::math::Vec2(w, h) = block.index.pixel_size;
        let inside = x0.checked_add(w).is_some_and(|e| e <= cols)
            && y0.checked_add(h).is_some_and(|e| e <= rows);
        if !inside || block.data.len() != w * h * bytes_per_pixel {
            failure = Some(Error::format(
                path,
                format!(
                    "a pixel block at ({x0}, {y0}) of {w} x {h} pixels and {} bytes does not fit the {cols} x {rows} data window with {bytes_per_pixel} bytes per pixel",
                    block.data.len()
                ),
            ));
            return Err(exr::error::Error::Aborted);
        }
        // Within one scan line of the block: every channel's w samples, in list order.
        for (band, &c) in channels.iter().enumerate() {
            let before: usize = sizes[..c].iter().sum::<usize>() * w;
            let n = sizes[c] * w;
            values.clear();
            for y in 0..h {
                let at = y * w * bytes_per_pixel + before;
                let line = &block.data[at..at + n];
                if half[c] {
                    values.extend(
                        line.chunks_exact(2)
                            .map(|b| f16::from_ne_bytes([b[0], b[1]]).to_f32()),
                    );
                } else {
                    values.extend(
                        line.chunks_exact(4)
                            .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]])),
                    );
                }
            }
            let written = if w == cols {
                spill.write(path, band, y0, 0, &values)
            } else {
                (0..h).try_for_each(|y| {
                    spill.write(path, band, y0 + y, x0, &values[y * w..(y + 1) * w])
                })
            };
            if let Err(e) = written {
                failure = Some(e);
                return Err(exr::error::Error::Aborted);
            }
        }
        Ok(())
    });
    match (failure, result) {
        (Some(e), _) => Err(e),
        (None, Err(e)) => Err(exr_error(path, e)),
        (None, Ok(())) => Ok(spill),
    }
}

impl ExrReader {
    /// Opens and reads a spectral OpenEXR file, parsing the band order from the channel
    /// names and the units and geometry from the attributes.
    pub fn open(path: &Path) -> Result<Self> {
        Self::open_with(path, &ReadOptions::default())
    }

    /// Like [`open`](Self::open), with reading options (a radiance-unit override).
    pub fn open_with(path: &Path, options: &ReadOptions) -> Result<Self> {
        let file = crate::io::input::open_regular(path)?;
        let file_len = file.metadata().map_err(|e| Error::io(path, e))?.len();
        let blocks = exr::block::read(std::io::BufReader::new(file), false)
            .map_err(|e| exr_error(path, e))?;
        check_exr_size(path, blocks.headers(), file_len)?;
        let mut warnings = Vec::new();

        let has_s0 = |header: &exr::meta::header::Header| {
            header.channels.list.iter().any(|c| {
                parse_channel_name(&c.name.to_string())
                    .is_some_and(|n| n.kind == ChannelKind::Emissive(0))
            })
        };
        let n_layers = blocks.headers().len();
        let Some(layer_index) = blocks.headers().iter().position(has_s0) else {
            let names: Vec<String> = blocks
                .headers()
                .iter()
                .flat_map(|h| h.channels.list.iter().map(|c| c.name.to_string()))
                .collect();
            return Err(Error::format(
                path,
                format!(
                    "no spectral radiance channels: expected channels named like `S0.550,000000nm` (Fichet et al. 2021 spectral OpenEXR layout), found {}",
                    list_names(&names)
                ),
            ));
        };
        if n_layers > 1 {
            warnings.push(format!(
                "the file has {n_layers} parts; read part {layer_index}, the first with spectral channels, and ignored the others"
            ));
        }
        let header = blocks.headers()[layer_index].clone();
        if header.deep {
            return Err(Error::format(
                path,
                format!("part {layer_index} holds deep data, which eoir does not read; store the spectral channels as flat (non-deep) samples"),
            ));
        }
        let rows = header.layer_size.y();
        let cols = header.layer_size.x();
        let attrs = header.own_attributes.other.clone();

        // Channels: keep S0, list the rest.
        let mut found = Vec::new();
        let mut ignored = Vec::new();
        for (index, channel) in header.channels.list.iter().enumerate() {
            let name = channel.name.to_string();
            match parse_channel_name(&name) {
                Some(n) if n.kind == ChannelKind::Emissive(0) => {
                    if channel.sampling.x() != 1 || channel.sampling.y() != 1 {
                        return Err(Error::format(
                            path,
                            format!(
                                "channel `{name}` is subsampled ({} x {}); spectral channels must have one sample per pixel",
                                channel.sampling.x(),
                                channel.sampling.y()
                            ),
                        ));
                    }
                    if channel.sample_type == exr::meta::attribute::SampleType::U32 {
                        return Err(Error::format(
                            path,
                            format!("channel `{name}` holds u32 integers; spectral radiance must be f16 or f32"),
                        ));
                    }
                    found.push(Found {
                        wavelength_um: n.unit.wavelength_um(n.value),
                        name,
                        unit: n.unit,
                        unit_text: n.unit_text,
                        channel: index,
                    });
                }
                _ => ignored.push(name),
            }
        }
        if !ignored.is_empty() {
            warnings.push(format!(
                "ignored {} channel(s) that are not spectral radiance (eoir reads only the emissive S0.* channels): {}",
                ignored.len(),
                list_names(&ignored)
            ));
        }
        found.sort_by(|a, b| a.wavelength_um.total_cmp(&b.wavelength_um));
        for pair in found.windows(2) {
            let rel = (pair[1].wavelength_um - pair[0].wavelength_um) / pair[1].wavelength_um;
            if rel < 1e-12 {
                return Err(Error::format(
                    path,
                    format!(
                        "channels `{}` and `{}` name the same wavelength ({} µm); each band needs its own wavelength",
                        pair[0].name, pair[1].name, pair[1].wavelength_um
                    ),
                ));
            }
        }
        let mut wavelength_um: Vec<f64> = found.iter().map(|f| f.wavelength_um).collect();

        // Layout attributes.
        match text_attr(path, &attrs, ATTR_LAYOUT_VERSION)? {
            Some(v) if v == LAYOUT_VERSION => {}
            Some(v) => warnings.push(format!(
                "{ATTR_LAYOUT_VERSION} = `{v}`; eoir knows version {LAYOUT_VERSION} and read the file as such"
            )),
            None => warnings.push(format!(
                "no {ATTR_LAYOUT_VERSION} attribute; read the file as spectral layout version {LAYOUT_VERSION}"
            )),
        }
        let emissive_density = match text_attr(path, &attrs, ATTR_EMISSIVE_UNITS)? {
            Some(u) => match parse_emissive_units(&u) {
                Ok(d) => d,
                Err(()) => {
                    warnings.push(format!(
                        "{ATTR_EMISSIVE_UNITS} = `{u}` is not a radiance unit eoir understands; read the values as radiance in W m-2 sr-1 (per spectral unit)"
                    ));
                    None
                }
            },
            None => None,
        };

        // Units: band-integrated or spectral, and per which spectral unit.
        let eoir_units = match text_attr(path, &attrs, ATTR_RADIANCE_UNITS)? {
            Some(u) => Some(RadianceUnits::parse(&u).ok_or_else(|| {
                Error::format(
                    path,
                    format!(
                        "attribute `{ATTR_RADIANCE_UNITS}` = `{u}`: expected `{}` or `{}`",
                        RadianceUnits::SpectralPerUm.as_str(),
                        RadianceUnits::BandIntegrated.as_str()
                    ),
                )
            })?),
            None => None,
        };
        let eoir_density = match text_attr(path, &attrs, ATTR_SPECTRAL_DENSITY_UNIT)? {
            Some(u) => Some(SpectralUnit::parse(u.trim()).ok_or_else(|| {
                Error::format(
                    path,
                    format!(
                        "attribute `{ATTR_SPECTRAL_DENSITY_UNIT}` = `{u}`: expected a wavelength or frequency unit such as `um`, `nm` or `THz`"
                    ),
                )
            })?),
            None => None,
        };
        let mut statements = Vec::new();
        for name in UNIT_ATTRIBUTES {
            if let Some(u) = text_attr(path, &attrs, name)? {
                statements.push((name.to_string(), u));
            }
        }
        let eoir_stated = eoir_units.is_some() || eoir_density.is_some();
        let common = if options.radiance_units.is_some() || !eoir_stated {
            resolve_units(path, &statements, options, &mut warnings)?
        } else {
            None
        };
        let (units, scale, units_source) = match (common, eoir_units, eoir_density) {
            (Some(r), _, _) => (r.scale.units, vec![r.scale.to_eoir; found.len()], r.source),
            (None, eoir_units, eoir_density) => match (eoir_units, eoir_density) {
            (Some(RadianceUnits::BandIntegrated), Some(_)) => {
                return Err(Error::format(
                    path,
                    format!(
                        "attribute `{ATTR_RADIANCE_UNITS}` says band-integrated but `{ATTR_SPECTRAL_DENSITY_UNIT}` gives a spectral density unit; remove one of them"
                    ),
                ))
            }
            (Some(RadianceUnits::BandIntegrated), None) => (
                RadianceUnits::BandIntegrated,
                vec![1.0; found.len()],
                format!("stated: `{ATTR_RADIANCE_UNITS}` (band-integrated)"),
            ),
            (_, Some(d)) => {
                let s = wavelength_um.iter().map(|&w| d.per_um_factor(w)).collect();
                (
                    RadianceUnits::SpectralPerUm,
                    s,
                    format!("stated: `{ATTR_SPECTRAL_DENSITY_UNIT}` = {d:?}"),
                )
            }
            (Some(RadianceUnits::SpectralPerUm), None) => (
                RadianceUnits::SpectralPerUm,
                vec![1.0; found.len()],
                format!("stated: `{ATTR_RADIANCE_UNITS}` (per um)"),
            ),
            (None, None) => {
                let (s, source) = if let Some((d, text)) = &emissive_density {
                    (
                        wavelength_um.iter().map(|&w| d.per_um_factor(w)).collect(),
                        format!("stated: `{ATTR_EMISSIVE_UNITS}` density per {text}"),
                    )
                } else {
                    let mut units: Vec<&str> = found.iter().map(|f| f.unit_text.as_str()).collect();
                    units.sort_unstable();
                    units.dedup();
                    warnings.push(format!(
                        "the file does not say per which spectral unit its radiance is given (no `{ATTR_SPECTRAL_DENSITY_UNIT}` attribute, `{ATTR_EMISSIVE_UNITS}` names none); assumed the unit of the channel names ({}) and converted to W m-2 sr-1 um-1",
                        units.join(", ")
                    ));
                    (
                        found
                            .iter()
                            .map(|f| f.unit.per_um_factor(f.wavelength_um))
                            .collect(),
                        format!(
                            "assumed: no unit statement, values per the unit of the channel names ({}), converted to W m-2 sr-1 um-1",
                            units.join(", ")
                        ),
                    )
                };
                (RadianceUnits::SpectralPerUm, s, source)
            }
        },
        };

        // Exact wavelengths written by eoir (names carry 1e-6 nm).
        if let Some(text) = text_attr(path, &attrs, ATTR_WAVELENGTH_UM)? {
            let exact = parse_list(path, ATTR_WAVELENGTH_UM, &text)?;
            let agrees = exact.len() == wavelength_um.len()
                && exact
                    .iter()
                    .zip(&wavelength_um)
                    .all(|(e, n)| (e - n).abs() <= 1e-9 + 1e-12 * n.abs());
            if agrees {
                wavelength_um = exact;
            } else {
                warnings.push(format!(
                    "attribute `{ATTR_WAVELENGTH_UM}` does not match the channel names ({} values for {} channels); used the wavelengths in the channel names",
                    exact.len(),
                    wavelength_um.len()
                ));
            }
        }
        let fwhm_um = match text_attr(path, &attrs, ATTR_FWHM_UM)? {
            Some(text) => Some(parse_list(path, ATTR_FWHM_UM, &text)?),
            None => None,
        };

        // Geometry.
        let fov = match attrs.get(ATTR_FOV_DEG.as_bytes()) {
            None => None,
            Some(AttributeValue::Custom { kind, bytes }) if kind == V2D && bytes.len() == 16 => {
                let mut x = [0u8; 8];
                let mut y = [0u8; 8];
                x.copy_from_slice(&bytes[..8]);
                y.copy_from_slice(&bytes[8..]);
                Some((f64::from_le_bytes(x), f64::from_le_bytes(y)))
            }
            Some(AttributeValue::FloatVec2(v)) => Some((f64::from(v.x()), f64::from(v.y()))),
            Some(other) => {
                return Err(Error::format(
                    path,
                    format!(
                        "attribute `{ATTR_FOV_DEG}` has type `{}`; expected v2d or v2f [horizontal, vertical] degrees",
                        String::from_utf8_lossy(other.kind_name())
                    ),
                ))
            }
        };
        let range_m = match attrs.get(ATTR_RANGE_M.as_bytes()) {
            None => None,
            Some(AttributeValue::F64(v)) => Some(*v),
            Some(AttributeValue::F32(v)) => Some(f64::from(*v)),
            Some(other) => {
                return Err(Error::format(
                    path,
                    format!(
                        "attribute `{ATTR_RANGE_M}` has type `{}`; expected double (metres)",
                        String::from_utf8_lossy(other.kind_name())
                    ),
                ))
            }
        };
        let mut common = Vec::new();
        for name in FOV_ATTRIBUTES {
            if let Some(v) = attrs.get(name.as_bytes()) {
                common.push((name.to_string(), fov_values(path, name, v)?));
            }
        }
        let geometry = if fov.is_none() && common.is_empty() {
            if range_m.is_some() {
                warnings.push(format!(
                    "attribute `{ATTR_RANGE_M}` ignored: without `{ATTR_FOV_DEG}` the file has no geometry"
                ));
            }
            None
        } else {
            resolve_geometry(
                path,
                ["`eoirFovDeg`", "`eoirIfovRad`", "`eoirRangeM`"],
                fov.map(|(h, v)| [h, v]),
                None,
                &common,
                range_m,
                rows,
                cols,
                &mut warnings,
            )?
        };

        let meta = CubeMeta {
            wavelength_um,
            fwhm_um,
            units,
            geometry,
            rows,
            cols,
        };
        meta.validate(&path.display().to_string())?;

        let channels: Vec<usize> = found.iter().map(|f| f.channel).collect();
        let spill = decode_to_spill(path, blocks, layer_index, &channels, rows, cols)?;
        release_freed_heap();
        Ok(ExrReader {
            path: path.to_path_buf(),
            meta,
            spill,
            scale,
            units_source,
            warnings,
            map: !options.no_memory_map,
        })
    }
}

/// Field-of-view values of a common attribute: a 2-vector, one number, or a string of
/// numbers.
fn fov_values(path: &Path, name: &str, v: &AttributeValue) -> Result<Vec<f64>> {
    let bad = |what: String| {
        Error::format(
            path,
            format!("attribute `{name}` {what}; expected the field of view in degrees as v2f/v2d [horizontal, vertical], a float/double, or a string of numbers"),
        )
    };
    Ok(match v {
        AttributeValue::FloatVec2(v) => vec![f64::from(v.x()), f64::from(v.y())],
        AttributeValue::F32(x) => vec![f64::from(*x)],
        AttributeValue::F64(x) => vec![*x],
        AttributeValue::Custom { kind, bytes } if kind == V2D && bytes.len() == 16 => {
            let mut x = [0u8; 8];
            let mut y = [0u8; 8];
            x.copy_from_slice(&bytes[..8]);
            y.copy_from_slice(&bytes[8..]);
            vec![f64::from_le_bytes(x), f64::from_le_bytes(y)]
        }
        AttributeValue::Text(t) => t
            .to_string()
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
            .map(|t| {
                t.parse::<f64>()
                    .map_err(|_| bad(format!("= `{t}` is not a number")))
            })
            .collect::<Result<_>>()?,
        other => {
            return Err(bad(format!(
                "has type `{}`",
                String::from_utf8_lossy(other.kind_name())
            )))
        }
    })
}

/// Lists channel names for a message, at most [`MAX_LISTED`] of them.
fn list_names(names: &[String]) -> String {
    if names.is_empty() {
        return "no channels".into();
    }
    let shown = names
        .iter()
        .take(MAX_LISTED)
        .map(|n| format!("`{n}`"))
        .collect::<Vec<_>>()
        .join(", ");
    if names.len() > MAX_LISTED {
        format!("{shown} and {} more", names.len() - MAX_LISTED)
    } else {
        shown
    }
}

/// A string attribute, `None` if absent, an error if present with another type.
fn text_attr(
    path: &Path,
    attrs: &HashMap<Text, AttributeValue>,
    name: &str,
) -> Result<Option<String>> {
    match attrs.get(name.as_bytes()) {
        None => Ok(None),
        Some(AttributeValue::Text(t)) => Ok(Some(t.to_string())),
        Some(other) => Err(Error::format(
            path,
            format!(
                "attribute `{name}` has type `{}`; expected string",
                String::from_utf8_lossy(other.kind_name())
            ),
        )),
    }
}

impl super::CubeReader for ExrReader {
    fn meta(&self) -> &CubeMeta {
        &self.meta
    }

    fn read_band(&mut self, frame: usize, band: usize) -> Result<Array2<f32>> {
        if frame != 0 {
            return Err(Error::param(
                "frame",
                frame,
                "0 (an OpenEXR cube holds one frame)",
            ));
        }
        let bands = self.meta.bands();
        if band >= bands {
            return Err(Error::param(
                "band",
                band,
                format!("an index below {bands} (bands in {})", self.path.display()),
            ));
        }
        let scale = self.scale[band];
        let mut values = self.spill.read(&self.path, band)?;
        if scale != 1.0 {
            values
                .iter_mut()
                .for_each(|v| *v = (f64::from(*v) * scale) as f32);
        }
        let plane =
            Array2::from_shape_vec((self.meta.rows, self.meta.cols), values).map_err(|_| {
                Error::format(
                    &self.path,
                    format!(
                        "band {band}: channel size does not match the image size {} x {}",
                        self.meta.rows, self.meta.cols
                    ),
                )
            })?;
        check_radiance_plane(
            &self.path.display().to_string(),
            band,
            self.meta.wavelength_um[band],
            plane.view(),
        )?;
        Ok(plane)
    }

    /// The planes mapped from the band-order scratch file, unchecked (see the trait
    /// method), when every requested band is stored in the cube's units (no scaling, as
    /// the scratch file then holds the values `read_band` returns); otherwise read.
    fn read_planes_deferred(
        &mut self,
        frame: usize,
        bands: &[usize],
    ) -> Result<(BandPlanes, Option<DeferredCheck>)> {
        let unscaled = |b: usize| self.scale.get(b).is_some_and(|s| *s == 1.0);
        if self.map && frame == 0 && !bands.is_empty() && bands.iter().all(|&b| unscaled(b)) {
            if let Some(planes) = self.spill.map_bands(bands) {
                let check = DeferredCheck::new(&self.path, bands, &self.meta.wavelength_um);
                return Ok((planes, Some(check)));
            }
            self.map = false;
        }
        Ok((self.read_planes(frame, bands)?, None))
    }

    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    fn units_source(&self) -> String {
        self.units_source.clone()
    }
}

/// Makes an OpenEXR text value, naming the attribute if a character cannot be stored.
fn text(path: &Path, what: &str, s: &str) -> Result<Text> {
    Text::new_or_none(s).ok_or_else(|| {
        Error::format(
            path,
            format!("{what} `{s}` has characters OpenEXR text cannot hold (Latin-1 only)"),
        )
    })
}

/// Writes `cube` as a spectral OpenEXR file (f32, ZIP-compressed scan lines) with the
/// layout's and eoir's attributes (see the [module documentation](self)), atomically.
///
/// Channels are `S0.<nm with 6 decimals>nm`; the exact wavelengths go into
/// `eoirWavelengthUm`. Fails, writing nothing, if any value is NaN, infinite or negative,
/// or if two bands would get the same channel name.
pub fn write(path: &Path, cube: &Cube) -> Result<()> {
    let meta = &cube.meta;
    let source = path.display().to_string();
    cube.check(&source)?;
    let (bands, rows, cols) = cube.data.dim();

    let mut channels: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    let mut names: Vec<String> = Vec::with_capacity(bands);
    for (b, plane) in cube.data.axis_iter(Axis(0)).enumerate() {
        let wl = meta.wavelength_um[b];
        check_radiance_plane(&source, b, wl, plane)?;
        let name = channel_name(wl);
        if let Some(prev) = names.iter().position(|n| *n == name) {
            return Err(Error::format(
                path,
                format!(
                    "bands {prev} ({} µm) and {b} ({wl} µm) both round to channel `{name}`; spectral OpenEXR names carry 1e-6 nm",
                    meta.wavelength_um[prev]
                ),
            ));
        }
        let samples: Vec<f32> = plane.iter().copied().collect();
        channels.push(AnyChannel::new(
            text(path, "channel name", &name)?,
            FlatSamples::F32(samples),
        ));
        names.push(name);
    }

    let mut attributes = LayerAttributes {
        software_name: Some(text(path, "software", "eoir")?),
        ..LayerAttributes::default()
    };
    let other = &mut attributes.other;
    let mut put_text = |name: &str, value: &str| -> Result<()> {
        other.insert(
            text(path, "attribute name", name)?,
            AttributeValue::Text(text(path, name, value)?),
        );
        Ok(())
    };
    put_text(ATTR_LAYOUT_VERSION, LAYOUT_VERSION)?;
    put_text(ATTR_EMISSIVE_UNITS, EMISSIVE_UNITS)?;
    put_text(ATTR_RADIANCE_UNITS, meta.units.as_str())?;
    if meta.units == RadianceUnits::SpectralPerUm {
        put_text(ATTR_SPECTRAL_DENSITY_UNIT, "um")?;
    }
    put_text(ATTR_WAVELENGTH_UM, &format_list(&meta.wavelength_um))?;
    if let Some(f) = &meta.fwhm_um {
        put_text(ATTR_FWHM_UM, &format_list(f))?;
    }
    if let Some(g) = &meta.geometry {
        let mut bytes: SmallVec<[u8; 16]> = SmallVec::new();
        bytes.extend_from_slice(&g.fov_x_deg.to_le_bytes());
        bytes.extend_from_slice(&g.fov_y_deg.to_le_bytes());
        other.insert(
            text(path, "attribute name", ATTR_FOV_DEG)?,
            AttributeValue::Custom {
                kind: text(path, "attribute type", V2D)?,
                bytes,
            },
        );
        if let Some(r) = g.range_m {
            other.insert(
                text(path, "attribute name", ATTR_RANGE_M)?,
                AttributeValue::F64(r),
            );
        }
    }

    let layer = Layer::new(
        (cols, rows),
        attributes,
        super::raster::deterministic(Encoding::SMALL_LOSSLESS),
        AnyChannels::sort(channels),
    );
    let image = Image::from_layer(layer);
    super::atomic_write(path, |w| {
        image.write().to_buffered(&mut *w).map_err(|e| match e {
            exr::error::Error::Io(io) => Error::io(path, io),
            other => Error::format(path, format!("could not write OpenEXR: {other}")),
        })?;
        super::raster::sort_exr_header(w, path)
    })
}
