//! OpenEXR reading and writing on top of the `exr` crate.
//!
//! Reading goes through the crate's low-level block API rather than its image API, because the
//! image API rejects subsampled channels, and luminance-chroma files as written by OpenEXR's
//! `RgbaOutputFile` (channels Y, RY, BY with RY/BY subsampled 2×2) are common. We read the
//! headers without the crate's validation, check subsampling ourselves, validate the rest with
//! the crate, then decompress the chosen layer's blocks (any compression the crate supports) in
//! parallel and unpack the samples, honouring per-channel sampling rates.

use super::{ExrPrecision, Image};
use crate::error::{Error, Result};
use exr::block::chunk::{Chunk, CompressedBlock};
use exr::math::Vec2;
use exr::meta::MetaData;
use exr::meta::attribute::{Chromaticities, IntegerBounds, SampleType};
use exr::meta::header::Header;
use rayon::prelude::*;
use std::io::{Cursor, Seek, SeekFrom};
use std::path::Path;

pub(super) fn write(path: &Path, img: &Image, precision: ExrPrecision, zip: bool) -> Result<()> {
    use exr::prelude::{Encoding, Layer, LayerAttributes, SpecificChannels, WritableImage, f16};
    if img.width == 0 || img.height == 0 {
        return Err(Error::encode(
            path,
            "cannot write an empty (0-pixel) EXR image",
        ));
    }
    let size = (img.width, img.height);
    let encoding = if zip {
        Encoding::SMALL_LOSSLESS
    } else {
        Encoding::UNCOMPRESSED
    };
    let mut buf = Cursor::new(Vec::with_capacity(img.data.len() * 2));
    let result = match precision {
        ExrPrecision::Float => {
            let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
                let [r, g, b] = img.get(p.x(), p.y());
                (r, g, b)
            });
            let layer = Layer::new(size, LayerAttributes::default(), encoding, channels);
            exr::prelude::Image::from_layer(layer)
                .write()
                .to_buffered(&mut buf)
        }
        ExrPrecision::Half => {
            let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
                let [r, g, b] = img.get(p.x(), p.y());
                (f16::from_f32(r), f16::from_f32(g), f16::from_f32(b))
            });
            let layer = Layer::new(size, LayerAttributes::default(), encoding, channels);
            exr::prelude::Image::from_layer(layer)
                .write()
                .to_buffered(&mut buf)
        }
    };
    result.map_err(|e| Error::encode(path, e))?;
    super::atomic::write_atomic(path, &buf.into_inner())
}

/// How the chosen channels become RGB.
#[derive(Clone, Copy, Debug)]
enum Kind {
    Rgb,
    Grey,
    LumaChroma,
}

/// The layer (header) and channels picked from the file.
struct Selection {
    header: usize,
    kind: Kind,
    /// Indices into the header's channel list: [R, G, B], [Y], or [Y, RY, BY].
    channels: Vec<usize>,
}

fn exr_err(path: &Path, e: exr::error::Error) -> Error {
    match e {
        exr::error::Error::NotSupported(msg) => Error::unsupported(path, format!("EXR: {msg}")),
        other => Error::decode(path, format!("truncated or corrupt EXR ({other})")),
    }
}

pub(super) fn decode(path: &Path, bytes: &[u8]) -> Result<Image> {
    let mut cursor = Cursor::new(bytes);
    // Unvalidated: the crate's validation rejects any subsampled channel.
    let meta = MetaData::read_from_buffered(&mut cursor, false).map_err(|e| exr_err(path, e))?;
    // PeekRead leaves no byte buffered after the header sequence, so the cursor now sits on the
    // offset tables.
    let sel = select(path, &meta)?;
    let header = &meta.headers[sel.header];
    // Before the offset tables or any pixel buffer are allocated (decompression bombs).
    super::limits::check(
        path,
        "EXR",
        header.layer_size.width() as u64,
        header.layer_size.height() as u64,
    )?;
    check_sampling(path, header)?;
    validate(path, &meta)?;

    let offsets = {
        let mut peek = exr::io::PeekRead::new(&mut cursor);
        MetaData::read_offset_tables(&mut peek, &meta.headers).map_err(|e| exr_err(path, e))?
    };
    let width = header.layer_size.width();
    let height = header.layer_size.height();
    if width == 0 || height == 0 {
        return Ok(Image::new(width, height));
    }

    // Read the compressed chunks of the chosen layer, full resolution level only.
    let mut chunks = Vec::with_capacity(offsets[sel.header].len());
    for &offset in &offsets[sel.header] {
        let offset = offset as usize;
        if offset >= bytes.len() {
            return Err(Error::decode(
                path,
                format!(
                    "truncated or corrupt EXR: chunk offset {offset} beyond end of file ({} bytes)",
                    bytes.len()
                ),
            ));
        }
        cursor
            .seek(SeekFrom::Start(offset as u64))
            .map_err(|e| Error::decode(path, e))?;
        let chunk = Chunk::read(&mut cursor, &meta).map_err(|e| exr_err(path, e))?;
        if chunk.layer_index != sel.header {
            return Err(Error::decode(
                path,
                "corrupt EXR: chunk belongs to a different part than its offset table",
            ));
        }
        let tile = header
            .get_block_data_indices(&chunk.compressed_block)
            .map_err(|e| exr_err(path, e))?;
        if tile.level_index == Vec2(0, 0) {
            chunks.push(chunk);
        }
    }

    let planes = decode_planes(path, header, &sel.channels, chunks)?;
    Ok(assemble(header, &sel, planes))
}

/// Pick the first usable channel group: headers in file order; within a header the group
/// without a layer prefix first, then prefixed groups ("diffuse.R") in channel-list order.
fn select(path: &Path, meta: &MetaData) -> Result<Selection> {
    for (hi, header) in meta.headers.iter().enumerate() {
        if header.deep {
            continue;
        }
        let names: Vec<String> = header
            .channels
            .list
            .iter()
            .map(|c| c.name.to_string())
            .collect();
        let split = |n: &str| -> (String, String) {
            match n.rfind('.') {
                Some(i) => (n[..i].to_string(), n[i + 1..].to_ascii_uppercase()),
                None => (String::new(), n.to_ascii_uppercase()),
            }
        };
        let mut prefixes: Vec<String> = Vec::new();
        for n in &names {
            let (p, _) = split(n);
            if !prefixes.contains(&p) {
                prefixes.push(p);
            }
        }
        if let Some(i) = prefixes.iter().position(|p| p.is_empty()) {
            let p = prefixes.remove(i);
            prefixes.insert(0, p);
        }
        for prefix in &prefixes {
            let find = |base: &str| {
                names.iter().position(|n| {
                    let (p, b) = split(n);
                    &p == prefix && b == base
                })
            };
            if let (Some(r), Some(g), Some(b)) = (find("R"), find("G"), find("B")) {
                return Ok(Selection {
                    header: hi,
                    kind: Kind::Rgb,
                    channels: vec![r, g, b],
                });
            }
            if let Some(y) = find("Y") {
                if let (Some(ry), Some(by)) = (find("RY"), find("BY")) {
                    return Ok(Selection {
                        header: hi,
                        kind: Kind::LumaChroma,
                        channels: vec![y, ry, by],
                    });
                }
                return Ok(Selection {
                    header: hi,
                    kind: Kind::Grey,
                    channels: vec![y],
                });
            }
        }
    }
    let mut found: Vec<String> = Vec::new();
    for header in &meta.headers {
        let part = header
            .own_attributes
            .layer_name
            .as_ref()
            .map(|n| format!("{n}:"))
            .unwrap_or_default();
        let deep = if header.deep { " (deep)" } else { "" };
        for c in &header.channels.list {
            found.push(format!("{part}{}{deep}", c.name));
        }
    }
    Err(Error::unsupported(
        path,
        format!(
            "channels found: [{}]; need R,G,B or Y[,RY,BY]",
            found.join(", ")
        ),
    ))
}

/// Subsampling is legal only in flat scan-line parts, with sampling rates dividing the data
/// window's origin and size (as OpenEXR itself requires).
fn check_sampling(path: &Path, header: &Header) -> Result<()> {
    let pos = header.own_attributes.layer_position;
    let size = header.layer_size;
    for c in &header.channels.list {
        let (sx, sy) = (c.sampling.x(), c.sampling.y());
        if sx == 0 || sy == 0 {
            return Err(Error::decode(
                path,
                format!("corrupt EXR: channel {} has a zero sampling rate", c.name),
            ));
        }
        if (sx, sy) == (1, 1) {
            continue;
        }
        if !matches!(header.blocks, exr::meta::BlockDescription::ScanLines) {
            return Err(Error::decode(
                path,
                format!("corrupt EXR: subsampled channel {} in a tiled part", c.name),
            ));
        }
        if pos.x().rem_euclid(sx as i32) != 0
            || pos.y().rem_euclid(sy as i32) != 0
            || !size.width().is_multiple_of(sx)
            || !size.height().is_multiple_of(sy)
        {
            return Err(Error::decode(
                path,
                format!(
                    "corrupt EXR: sampling {sx}x{sy} of channel {} does not divide the data window",
                    c.name
                ),
            ));
        }
    }
    Ok(())
}

/// Run the crate's header validation on a copy with sampling rates set to 1 (we checked them).
fn validate(path: &Path, meta: &MetaData) -> Result<()> {
    let mut headers = meta.headers.clone();
    for h in headers.iter_mut() {
        for c in h.channels.list.iter_mut() {
            c.sampling = Vec2(1, 1);
        }
    }
    MetaData::validate(&headers, false)
        .map(|_| ())
        .map_err(|e| exr_err(path, e))
}

/// One selected channel at its own (possibly subsampled) resolution.
struct Plane {
    width: usize,
    height: usize,
    sampling: (usize, usize),
    data: Vec<f32>,
}

/// A decoded block: its origin in the data window and the selected channels' samples.
struct Block {
    x: usize,
    y: usize,
    /// Per selected channel: (samples per row, rows, samples).
    samples: Vec<(usize, usize, Vec<f32>)>,
}

/// Bytes per pixel that makes the crate's uncompressed-size check (`area × bytes_per_pixel`)
/// match a block with subsampled channels. None if the block's byte count is not a multiple
/// of its area (cannot happen for the usual 2×2 chroma subsampling).
fn subsampled_bytes_per_pixel(header: &Header, y0: usize, w: usize, h: usize) -> Option<usize> {
    let total: usize = header
        .channels
        .list
        .iter()
        .map(|c| {
            let (sx, sy) = (c.sampling.x(), c.sampling.y());
            let rows = (y0..y0 + h).filter(|y| y.is_multiple_of(sy)).count();
            (w / sx) * rows * c.sample_type.bytes_per_sample()
        })
        .sum();
    let area = w * h;
    (area > 0 && total.is_multiple_of(area)).then_some(total / area)
}

fn decode_planes(
    path: &Path,
    header: &Header,
    selected: &[usize],
    chunks: Vec<Chunk>,
) -> Result<Vec<Plane>> {
    let subsampled = header
        .channels
        .list
        .iter()
        .any(|c| c.sampling != Vec2(1, 1));
    if subsampled
        && matches!(
            header.compression,
            exr::compression::Compression::B44 | exr::compression::Compression::B44A
        )
    {
        // exr 1.74's B44 decoder sizes subsampled channels as if they were full resolution
        // (and panics); every other compression is checked against OpenEXR's own reader.
        return Err(Error::unsupported(
            path,
            format!(
                "EXR: {} with subsampled channels (e.g. luminance-chroma) is not supported by the exr crate",
                header.compression
            ),
        ));
    }

    let (geometry, patched) = block_geometry(path, header, subsampled, &chunks)?;
    let blocks = decode_blocks(path, header, selected, chunks, geometry, &patched)?;
    assemble_planes(path, header, selected, blocks)
}

/// A block's pixel bounds and, with subsampled channels, the `bytes_per_pixel` its decoder
/// is told.
type BlockGeometry = (IntegerBounds, Option<usize>);
/// A header whose `bytes_per_pixel` is patched to the value beside it.
type PatchedHeader = (usize, Header);

/// Each block's pixel bounds in the data window (checked to lie inside it) and, when channels
/// are subsampled, the `bytes_per_pixel` its decoder must be told; plus the headers whose
/// `bytes_per_pixel` is patched so the crate accepts subsampled blocks, one per distinct value
/// (at most a few: full blocks, the last block, odd/even single lines).
fn block_geometry(
    path: &Path,
    header: &Header,
    subsampled: bool,
    chunks: &[Chunk],
) -> Result<(Vec<BlockGeometry>, Vec<PatchedHeader>)> {
    let mut patched: Vec<PatchedHeader> = Vec::new();
    let mut geometry = Vec::with_capacity(chunks.len());
    for chunk in chunks {
        let tile = header
            .get_block_data_indices(&chunk.compressed_block)
            .map_err(|e| exr_err(path, e))?;
        let bounds = header
            .get_absolute_block_pixel_coordinates(tile)
            .map_err(|e| exr_err(path, e))?;
        bounds
            .validate(Some(header.layer_size))
            .map_err(|e| exr_err(path, e))?;
        let (x0, y0) = (bounds.position.x(), bounds.position.y());
        if x0 < 0
            || y0 < 0
            || x0 as usize + bounds.size.width() > header.layer_size.width()
            || y0 as usize + bounds.size.height() > header.layer_size.height()
        {
            return Err(Error::decode(
                path,
                "corrupt EXR: block outside the data window",
            ));
        }
        let bpp = if subsampled {
            let bpp = subsampled_bytes_per_pixel(
                header,
                y0 as usize,
                bounds.size.width(),
                bounds.size.height(),
            )
            .ok_or_else(|| {
                Error::unsupported(
                    path,
                    "EXR: subsampled channels with a block size the decoder cannot handle",
                )
            })?;
            if !patched.iter().any(|(b, _)| *b == bpp) {
                let mut h = header.clone();
                h.channels.bytes_per_pixel = bpp;
                patched.push((bpp, h));
            }
            Some(bpp)
        } else {
            None
        };
        geometry.push((bounds, bpp));
    }
    Ok((geometry, patched))
}

/// The selected channels' samples of every block, decoded in parallel.
fn decode_blocks(
    path: &Path,
    header: &Header,
    selected: &[usize],
    chunks: Vec<Chunk>,
    geometry: Vec<BlockGeometry>,
    patched: &[PatchedHeader],
) -> Result<Vec<Block>> {
    chunks
        .into_par_iter()
        .zip(geometry.into_par_iter())
        .map(|(chunk, (bounds, bpp))| {
            let hdr = match bpp {
                Some(bpp) => {
                    &patched
                        .iter()
                        .find(|(b, _)| *b == bpp)
                        .expect("patched header prepared above")
                        .1
                }
                None => header,
            };
            // The crate's decompressors are meant to return errors on corrupt input; guard
            // against a panic anyway so a bad file cannot take the process down.
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                decode_block(path, header, hdr, selected, chunk, bounds)
            }))
            .unwrap_or_else(|_| {
                Err(Error::decode(
                    path,
                    "corrupt EXR: the decompressor failed on a block",
                ))
            })
        })
        .collect()
}

/// The selected channels as planes at their own resolution, each block's samples copied to
/// its place (an error when a block's samples overrun the plane).
fn assemble_planes(
    path: &Path,
    header: &Header,
    selected: &[usize],
    blocks: Vec<Block>,
) -> Result<Vec<Plane>> {
    let mut planes: Vec<Plane> = selected
        .iter()
        .map(|&ci| {
            let c = &header.channels.list[ci];
            let (sx, sy) = (c.sampling.x(), c.sampling.y());
            let (w, h) = (
                header.layer_size.width() / sx,
                header.layer_size.height() / sy,
            );
            Plane {
                width: w,
                height: h,
                sampling: (sx, sy),
                data: vec![0.0; w * h],
            }
        })
        .collect();
    for block in blocks {
        for (plane, (nx, ny, samples)) in planes.iter_mut().zip(block.samples) {
            let (sx, sy) = plane.sampling;
            let px = block.x / sx;
            let py = block.y.div_ceil(sy);
            if px + nx > plane.width || py + ny > plane.height {
                return Err(Error::decode(
                    path,
                    "corrupt EXR: block outside the data window",
                ));
            }
            for (row, src) in samples.chunks_exact(nx.max(1)).take(ny).enumerate() {
                let start = (py + row) * plane.width + px;
                plane.data[start..start + nx].copy_from_slice(&src[..nx]);
            }
        }
    }
    Ok(planes)
}

fn decode_block(
    path: &Path,
    header: &Header,
    decomp_header: &Header,
    selected: &[usize],
    chunk: Chunk,
    bounds: exr::meta::attribute::IntegerBounds,
) -> Result<Block> {
    let compressed = match chunk.compressed_block {
        CompressedBlock::ScanLine(b) => b.compressed_pixels_le,
        CompressedBlock::Tile(t) => t.compressed_pixels_le,
        _ => return Err(Error::unsupported(path, "EXR: deep data")),
    };
    let data = header
        .compression
        .decompress_image_section_from_le(decomp_header, compressed, bounds, false)
        .map_err(|e| exr_err(path, e))?;

    let (x0, y0) = (bounds.position.x() as usize, bounds.position.y() as usize);
    let (w, h) = (bounds.size.width(), bounds.size.height());
    let list = &header.channels.list;
    // Slot of each channel among the selected ones.
    let slot: Vec<Option<usize>> = (0..list.len())
        .map(|ci| selected.iter().position(|&s| s == ci))
        .collect();
    let mut out: Vec<(usize, usize, Vec<f32>)> = selected
        .iter()
        .map(|&ci| {
            let c = &list[ci];
            let nx = w / c.sampling.x();
            let ny = (y0..y0 + h)
                .filter(|y| y.is_multiple_of(c.sampling.y()))
                .count();
            (nx, ny, Vec::with_capacity(nx * ny))
        })
        .collect();

    // Uncompressed layout: for each row, for each channel present on that row, its samples.
    let mut off = 0usize;
    for y in y0..y0 + h {
        for (ci, c) in list.iter().enumerate() {
            if !y.is_multiple_of(c.sampling.y()) {
                continue;
            }
            let n = w / c.sampling.x();
            let nbytes = n * c.sample_type.bytes_per_sample();
            let line = data.get(off..off + nbytes).ok_or_else(|| {
                Error::decode(path, "corrupt EXR: decompressed block is too short")
            })?;
            off += nbytes;
            if let Some(s) = slot[ci] {
                let dst = &mut out[s].2;
                match c.sample_type {
                    SampleType::F16 => {
                        dst.extend(line.chunks_exact(2).map(|b| {
                            half::f16::from_bits(u16::from_ne_bytes([b[0], b[1]])).to_f32()
                        }))
                    }
                    SampleType::F32 => dst.extend(
                        line.chunks_exact(4)
                            .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]])),
                    ),
                    SampleType::U32 => dst.extend(
                        line.chunks_exact(4)
                            .map(|b| u32::from_ne_bytes([b[0], b[1], b[2], b[3]]) as f32),
                    ),
                }
            }
        }
    }
    if off != data.len() {
        return Err(Error::decode(
            path,
            "corrupt EXR: decompressed block size does not match its channels",
        ));
    }
    Ok(Block {
        x: x0,
        y: y0,
        samples: out,
    })
}

/// OpenEXR's chroma reconstruction filter (`RgbaYca::reconstructChromaHoriz/Vert`): a
/// symmetric 14-tap interpolator over the co-sited samples at odd offsets ±1, ±3, …, ±13.
/// Weights for offsets ±13, ±11, …, ±1 (they sum to 1 over both sides).
const CHROMA_TAPS: [f32; 7] = [
    0.002128, -0.007540, 0.019597, -0.043159, 0.087929, -0.186077, 0.627123,
];

/// One output sample of OpenEXR's reconstruction along a line: `src` holds the co-sited
/// samples (full-resolution positions 0, 2, 4, …); even positions copy, odd ones filter, with
/// the first and last samples repeated beyond the edges (as OpenEXR pads its line buffers).
#[inline]
fn chroma_at(src: impl Fn(usize) -> f32, n: usize, pos: usize) -> f32 {
    if pos.is_multiple_of(2) {
        return src((pos / 2).min(n - 1));
    }
    let at = |p: isize| src(((p / 2).max(0) as usize).min(n - 1));
    let c = pos as isize;
    CHROMA_TAPS
        .iter()
        .enumerate()
        .map(|(k, &t)| {
            let off = 13 - 2 * k as isize;
            t * (at(c - off) + at(c + off))
        })
        .sum()
}

/// 2×2-subsampled RY or BY to full resolution exactly as OpenEXR's `RgbaInputFile` does it
/// (horizontal pass on the sample rows, then vertical), so luminance-chroma files read the same
/// as with the reference library; only its half-float rounding of intermediates differs.
fn reconstruct_chroma(plane: &Plane, width: usize, height: usize) -> Vec<f32> {
    let (pw, ph) = (plane.width, plane.height);
    let mut rows = vec![0.0f32; ph * width];
    rows.par_chunks_mut(width).enumerate().for_each(|(j, row)| {
        let src = &plane.data[j * pw..(j + 1) * pw];
        for (x, o) in row.iter_mut().enumerate() {
            *o = chroma_at(|i| src[i], pw, x);
        }
    });
    let mut out = vec![0.0f32; width * height];
    out.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            *o = chroma_at(|j| rows[j * width + x], ph, y);
        }
    });
    out
}

/// Bring a plane to full resolution. Subsampled samples are co-sited with the full-resolution
/// pixels whose coordinates are multiples of the sampling rate (OpenEXR's convention), so
/// pixel x maps to plane coordinate x / sx; bilinear in between, clamped at the far edge.
fn upsample(plane: Plane, width: usize, height: usize) -> Vec<f32> {
    let (sx, sy) = plane.sampling;
    if (sx, sy) == (1, 1) {
        return plane.data;
    }
    let (pw, ph) = (plane.width, plane.height);
    let taps = |x: usize, s: usize, n: usize| -> (usize, usize, f32) {
        let i0 = (x / s).min(n - 1);
        let i1 = (i0 + 1).min(n - 1);
        let t = (x % s) as f32 / s as f32;
        (i0, i1, if i1 == i0 { 0.0 } else { t })
    };
    let xt: Vec<(usize, usize, f32)> = (0..width).map(|x| taps(x, sx, pw)).collect();
    let mut out = vec![0.0f32; width * height];
    out.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        let (j0, j1, v) = taps(y, sy, ph);
        let r0 = &plane.data[j0 * pw..(j0 + 1) * pw];
        let r1 = &plane.data[j1 * pw..(j1 + 1) * pw];
        for (o, &(i0, i1, u)) in row.iter_mut().zip(&xt) {
            let a = r0[i0] + (r0[i1] - r0[i0]) * u;
            let b = r1[i0] + (r1[i1] - r1[i0]) * u;
            *o = a + (b - a) * v;
        }
    });
    out
}

fn assemble(header: &Header, sel: &Selection, planes: Vec<Plane>) -> Image {
    let (w, h) = (header.layer_size.width(), header.layer_size.height());
    let yca = matches!(sel.kind, Kind::LumaChroma);
    let full: Vec<Vec<f32>> = planes
        .into_iter()
        .enumerate()
        .map(|(i, p)| {
            if yca && i > 0 && p.sampling == (2, 2) {
                reconstruct_chroma(&p, w, h)
            } else {
                upsample(p, w, h)
            }
        })
        .collect();
    let mut img = Image::new(w, h);
    match sel.kind {
        Kind::Rgb => img.data.par_chunks_mut(3).enumerate().for_each(|(i, px)| {
            px[0] = full[0][i];
            px[1] = full[1][i];
            px[2] = full[2][i];
        }),
        Kind::Grey => img
            .data
            .par_chunks_mut(3)
            .zip(full[0].par_iter())
            .for_each(|(px, &y)| px.fill(y)),
        Kind::LumaChroma => {
            let yw = luminance_weights(header.shared_attributes.chromaticities.as_ref());
            img.data.par_chunks_mut(3).enumerate().for_each(|(i, px)| {
                px.copy_from_slice(&yca_to_rgb(full[0][i], full[1][i], full[2][i], yw));
            });
        }
    }
    img
}

/// OpenEXR's `RgbaYca::YCAtoRGBA` for one pixel.
#[inline]
fn yca_to_rgb(y: f32, ry: f32, by: f32, yw: [f32; 3]) -> [f32; 3] {
    if ry == 0.0 && by == 0.0 {
        [y, y, y]
    } else {
        let r = (ry + 1.0) * y;
        let b = (by + 1.0) * y;
        let g = (y - r * yw[0] - b * yw[2]) / yw[1];
        [r, g, b]
    }
}

/// OpenEXR's `RgbaYca::computeYw`: the Y row of the RGB→XYZ matrix of the file's primaries,
/// normalised to sum to 1. Without a chromaticities attribute OpenEXR assumes Rec. 709
/// primaries with a D65 white, giving (0.2126, 0.7152, 0.0722).
fn luminance_weights(chroma: Option<&Chromaticities>) -> [f32; 3] {
    const REC709: [[f64; 2]; 4] = [
        [0.6400, 0.3300],
        [0.3000, 0.6000],
        [0.1500, 0.0600],
        [0.3127, 0.3290],
    ];
    let c = match chroma {
        Some(c) => [c.red, c.green, c.blue, c.white].map(|v| [v.x() as f64, v.y() as f64]),
        None => REC709,
    };
    yw_from_primaries(c)
        .unwrap_or_else(|| yw_from_primaries(REC709).expect("Rec. 709 primaries are well formed"))
}

/// Columns are the primaries' chromaticities (x, y, z); solve for the scales s that map
/// (1, 1, 1) to the white point's XYZ at Y = 1. The luminance weight of primary i is s_i · y_i
/// (the Y row of the RGB→XYZ matrix). Stays finite when a primary has y = 0 (ACES AP0 blue).
/// None for degenerate chromaticities.
fn yw_from_primaries(c: [[f64; 2]; 4]) -> Option<[f32; 3]> {
    if c.iter().flatten().any(|v| !v.is_finite()) || c[3][1] == 0.0 {
        return None;
    }
    let col = |p: [f64; 2]| [p[0], p[1], 1.0 - p[0] - p[1]];
    let (r, g, b) = (col(c[0]), col(c[1]), col(c[2]));
    let w = [c[3][0] / c[3][1], 1.0, (1.0 - c[3][0] - c[3][1]) / c[3][1]];
    let m = [[r[0], g[0], b[0]], [r[1], g[1], b[1]], [r[2], g[2], b[2]]];
    let s = crate::linalg::solve3(m, w)?;
    finish([s[0] * r[1], s[1] * g[1], s[2] * b[1]])
}

fn finish(y: [f64; 3]) -> Option<[f32; 3]> {
    let sum = y[0] + y[1] + y[2];
    if !sum.is_finite() || sum.abs() < 1e-12 || y[1].abs() < 1e-12 {
        return None;
    }
    Some([
        (y[0] / sum) as f32,
        (y[1] / sum) as f32,
        (y[2] / sum) as f32,
    ])
}
