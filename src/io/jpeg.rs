//! What a JPEG file says of its own compression: its quantisation tables (DQT segments, read
//! up to the first scan) and the IJG quality (libjpeg's `jpeg_set_quality`) whose scaled
//! ITU-T T.81 Annex K tables are nearest to them.

use crate::error::{Error, Result};
use std::path::Path;

/// ITU-T T.81 Annex K, table K.1 (luminance), natural order.
const LUMA: [u16; 64] = [
    16, 11, 10, 16, 24, 40, 51, 61, 12, 12, 14, 19, 26, 58, 60, 55, 14, 13, 16, 24, 40, 57, 69, 56,
    14, 17, 22, 29, 51, 87, 80, 62, 18, 22, 37, 56, 68, 109, 103, 77, 24, 35, 55, 64, 81, 104, 113,
    92, 49, 64, 78, 87, 103, 121, 120, 101, 72, 92, 95, 98, 112, 100, 103, 99,
];

/// Table K.2 (chrominance), natural order.
const CHROMA: [u16; 64] = [
    17, 18, 24, 47, 99, 99, 99, 99, 18, 21, 26, 66, 99, 99, 99, 99, 24, 26, 56, 99, 99, 99, 99, 99,
    47, 66, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99,
    99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99,
];

/// Natural-order index of each zig-zag position (T.81 figure A.6; libjpeg's
/// `jpeg_natural_order`): DQT stores its entries in zig-zag order.
const NATURAL: [usize; 64] = [
    0, 1, 8, 16, 9, 2, 3, 10, 17, 24, 32, 25, 18, 11, 4, 5, 12, 19, 26, 33, 40, 48, 41, 34, 27, 20,
    13, 6, 7, 14, 21, 28, 35, 42, 49, 56, 57, 50, 43, 36, 29, 22, 15, 23, 30, 37, 44, 51, 58, 59,
    52, 45, 38, 31, 39, 46, 53, 60, 61, 54, 47, 55, 62, 63,
];

/// One quantisation table: its destination id and its 64 entries in natural order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct QuantTable {
    pub id: u8,
    pub values: [u16; 64],
}

/// The quantisation tables of a JPEG stream (`path` names it in errors).
pub fn quant_tables(bytes: &[u8], path: &Path) -> Result<Vec<QuantTable>> {
    let bad = |msg: &str| Error::decode(path, format!("JPEG: {msg}"));
    if bytes.get(..2) != Some(&[0xFF, 0xD8]) {
        return Err(bad("no start-of-image marker"));
    }
    let mut tables = Vec::new();
    let mut at = 2;
    loop {
        // Fill bytes (0xFF) may pad before a marker.
        while bytes.get(at) == Some(&0xFF) && bytes.get(at + 1) == Some(&0xFF) {
            at += 1;
        }
        let (Some(&0xFF), Some(&marker)) = (bytes.get(at), bytes.get(at + 1)) else {
            return Err(bad("a segment does not start with a marker"));
        };
        at += 2;
        // Markers without a length: TEM and RSTn; the scan or the image's end stops the read.
        if marker == 0x01 || (0xD0..=0xD7).contains(&marker) {
            continue;
        }
        if marker == 0xDA || marker == 0xD9 {
            break;
        }
        let len = match bytes.get(at..at + 2) {
            Some(l) => usize::from(u16::from_be_bytes([l[0], l[1]])),
            None => return Err(bad("truncated before a segment's length")),
        };
        let body = bytes
            .get(at + 2..at + len.max(2))
            .ok_or_else(|| bad("a segment runs past the end of the file"))?;
        if marker == 0xDB {
            read_dqt(body, &mut tables).map_err(|m| bad(&m))?;
        }
        at += len;
    }
    Ok(tables)
}

fn read_dqt(mut body: &[u8], tables: &mut Vec<QuantTable>) -> std::result::Result<(), String> {
    while let Some((&pq_tq, rest)) = body.split_first() {
        let (wide, id) = (pq_tq >> 4 != 0, pq_tq & 0x0F);
        let size = if wide { 128 } else { 64 };
        let entries = rest
            .get(..size)
            .ok_or("a quantisation table is cut short")?;
        let mut values = [0u16; 64];
        for (k, &n) in NATURAL.iter().enumerate() {
            values[n] = if wide {
                u16::from_be_bytes([entries[2 * k], entries[2 * k + 1]])
            } else {
                u16::from(entries[k])
            };
        }
        if values.contains(&0) {
            return Err(format!("quantisation table {id} holds a zero step"));
        }
        tables.retain(|t| t.id != id);
        tables.push(QuantTable { id, values });
        body = &rest[size..];
    }
    Ok(())
}

/// libjpeg's tables at `quality` (1–100): Annex K scaled by 5000/q below 50, 200 − 2q above,
/// rounded, limited to 1–255 (`jpeg_set_quality` with baseline tables).
pub fn ijg_table(base: &[u16; 64], quality: u32) -> [u16; 64] {
    let q = quality.clamp(1, 100);
    let scale = if q < 50 { 5000 / q } else { 200 - 2 * q };
    base.map(|v| ((u32::from(v) * scale + 50) / 100).clamp(1, 255) as u16)
}

/// The IJG quality whose tables are nearest to `tables` (table 0 against the luminance table,
/// every other against the chrominance one), and the mean absolute difference of the entries
/// there (0: the file holds exactly libjpeg's tables at that quality). None without tables.
pub fn ijg_quality(tables: &[QuantTable]) -> Option<(u32, f64)> {
    if tables.is_empty() {
        return None;
    }
    let n = 64.0 * tables.len() as f64;
    (1..=100u32)
        .map(|q| {
            let err: u32 = tables
                .iter()
                .map(|t| {
                    let base = if t.id == 0 { &LUMA } else { &CHROMA };
                    let want = ijg_table(base, q);
                    t.values
                        .iter()
                        .zip(&want)
                        .map(|(a, b)| u32::from(a.abs_diff(*b)))
                        .sum::<u32>()
                })
                .sum();
            (q, f64::from(err) / n)
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// [`ijg_quality`] of the JPEG file at `path`.
pub fn file_quality(path: &Path) -> Result<Option<(u32, f64)>> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    Ok(ijg_quality(&quant_tables(&bytes, path)?))
}
