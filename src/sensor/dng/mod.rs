//! DNG reading: the raw image of an uncompressed CFA DNG (`image`), and the tags that describe
//! the sensor (`tags`) with the DNG specification's colour model (`colour`), from which a
//! sensor profile is built (`profile`, `hdrsynth calibrate dng`).
//!
//! The raw image: the CFA mosaic, black-subtracted and normalised, demosaiced bilinearly to
//! linear camera RGB (not white balanced), plus the tags that say where it came from
//! (ColorMatrix1/2, AsShotNeutral, levels, CFA pattern).
//!
//! No permissively licensed Rust crate decodes these files: the `tiff` crate (MIT) refuses an
//! IFD whose PhotometricInterpretation is CFA (32803) before any tag can be read, the `dng` crate
//! is AGPL-3.0, and rawloader/rawler are LGPL. So this module carries a small TIFF/DNG IFD reader
//! of its own (`tiff`: classic TIFF, either byte order) that handles what DNG writers such as
//! Magic Lantern, smartphones and most converters produce *uncompressed*:
//! - the raw image in IFD 0 or in a SubIFD (NewSubfileType 0, PhotometricInterpretation 32803);
//! - Compression 1 (none), strips or tiles, 8–16 bits per sample, packed MSB-first without row
//!   padding as the DNG specification requires for depths other than 8/16 (16-bit samples in the
//!   file's byte order);
//! - a 2 × 2 Bayer CFAPattern (RGGB, BGGR, GRBG, GBRG), taken relative to the ActiveArea origin;
//! - LinearizationTable, BlackLevel (one value or one per CFA position via BlackLevelRepeatDim),
//!   BlackLevelDeltaH/V, WhiteLevel, ActiveArea, DefaultCropOrigin/Size.
//!
//! Lossless-JPEG (Compression 7), lossy JPEG (34892) and JPEG XL DNGs, LinearRaw (demosaiced)
//! DNGs and non-Bayer CFAs are refused with an error naming the file; convert such files to an
//! uncompressed DNG first (e.g. Adobe DNG Converter with compression off, or
//! `dng_validate -dng out.dng in.dng` from the DNG SDK).
//!
//! Output: values (DN − black) / (white − black) per photosite, not clipped (noise below black
//! stays negative, so patch means stay unbiased); then the ActiveArea, then the DefaultCrop.
//! Orientation is not applied.
//!
//! The tags, by contrast, are read from any raw DNG, CFA or LinearRaw, compressed or not, even
//! one whose image data was pruned: only the IFDs are read.

pub mod colour;
mod image;
pub mod profile;
pub mod tags;
mod tiff;

pub use image::{
    Dng, DngInfo, Mosaic, demosaic_bilinear, read_dng, read_dng_bytes, read_dng_info,
    read_dng_mosaic,
};
pub use tags::{DngTags, RawLayout, read_dng_tags, read_dng_tags_bytes};
