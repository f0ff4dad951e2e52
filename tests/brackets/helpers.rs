//! Fixture builders several topics share: bracket JPEGs with EXIF, a synthetic scene, PNG
//! brackets with known radiance, noisy brackets and their calibration.
//!
//! The JPEGs are written here with EXIF by a minimal APP1 writer (below, written from the EXIF
//! 2.32 / TIFF 6.0 specifications, independent of the crate's reader); the oracle values are
//! the hand-known exposure times written into them.

use crate::common::{TestNoise, srgb};
use hdrsynth::capture::linearise::ResponseChoice;
use hdrsynth::capture::scan::{self, ScanOptions};
use hdrsynth::capture::testset::{BracketOptions, EncodeSpec, GtFrames, InputChoice};
use hdrsynth::sensor::profile::Response;
use image::ExtendedColorType;
use image::codecs::jpeg::JpegEncoder;
use std::path::{Path, PathBuf};

// ---------------------------------------------------------------------------------------------
// A minimal EXIF writer (little-endian TIFF in an APP1 segment).

/// EXIF tag values the helper can write.
#[derive(Clone, Default)]
pub struct Tags {
    pub exposure_time: Option<(u32, u32)>,
    pub iso: Option<u16>,
    pub f_number: Option<(u32, u32)>,
    pub bias: Option<(i32, i32)>,
    /// "YYYY:MM:DD HH:MM:SS"
    pub date: Option<String>,
    pub subsec: Option<String>,
    /// TIFF/EXIF Orientation (tag 274, IFD0).
    pub orientation: Option<u16>,
    /// ShutterSpeedValue, APEX Tv (SRATIONAL).
    pub shutter_apex: Option<(i32, i32)>,
}

/// One IFD entry: tag, TIFF type, count, value bytes (little-endian).
pub type Entry = (u16, u16, u32, Vec<u8>);

pub fn rational(n: u32, d: u32) -> Vec<u8> {
    [n.to_le_bytes(), d.to_le_bytes()].concat()
}

/// Serialise an IFD at `at` (offset in the TIFF); values over 4 bytes follow the IFD.
pub fn ifd(at: u32, mut entries: Vec<Entry>) -> Vec<u8> {
    entries.sort_by_key(|e| e.0);
    let n = entries.len() as u32;
    let mut data_at = at + 2 + 12 * n + 4;
    let (mut head, mut data) = (Vec::new(), Vec::new());
    head.extend((n as u16).to_le_bytes());
    for (tag, ty, count, bytes) in entries {
        head.extend(tag.to_le_bytes());
        head.extend(ty.to_le_bytes());
        head.extend(count.to_le_bytes());
        if bytes.len() <= 4 {
            let mut v = bytes.clone();
            v.resize(4, 0);
            head.extend(v);
        } else {
            head.extend(data_at.to_le_bytes());
            data_at += bytes.len() as u32;
            data.extend(bytes);
        }
    }
    head.extend(0u32.to_le_bytes()); // no next IFD
    head.extend(data);
    head
}

pub fn exif_app1(t: &Tags) -> Vec<u8> {
    let mut exif: Vec<Entry> = Vec::new();
    if let Some((n, d)) = t.exposure_time {
        exif.push((0x829A, 5, 1, rational(n, d)));
    }
    if let Some((n, d)) = t.f_number {
        exif.push((0x829D, 5, 1, rational(n, d)));
    }
    if let Some(iso) = t.iso {
        exif.push((0x8827, 3, 1, iso.to_le_bytes().to_vec()));
    }
    if let Some(s) = &t.date {
        let mut b = s.as_bytes().to_vec();
        b.push(0);
        exif.push((0x9003, 2, b.len() as u32, b));
    }
    if let Some((n, d)) = t.shutter_apex {
        exif.push((0x9201, 10, 1, [n.to_le_bytes(), d.to_le_bytes()].concat()));
    }
    if let Some((n, d)) = t.bias {
        exif.push((0x9204, 10, 1, [n.to_le_bytes(), d.to_le_bytes()].concat()));
    }
    if let Some(s) = &t.subsec {
        let mut b = s.as_bytes().to_vec();
        b.push(0);
        exif.push((0x9291, 2, b.len() as u32, b));
    }
    // Header (8) + IFD0 with one entry, the Exif IFD pointer (2 + 12 + 4 = 18).
    let exif_at = 8 + 18;
    let mut tiff = b"II*\0".to_vec();
    tiff.extend(8u32.to_le_bytes());
    let mut ifd0 = vec![(0x8769, 4, 1, (exif_at as u32).to_le_bytes().to_vec())];
    let exif_at = if let Some(o) = t.orientation {
        ifd0.push((274, 3, 1, o.to_le_bytes().to_vec()));
        exif_at + 12
    } else {
        exif_at
    };
    ifd0[0].3 = (exif_at as u32).to_le_bytes().to_vec();
    tiff.extend(ifd(8, ifd0));
    assert_eq!(tiff.len(), exif_at);
    tiff.extend(ifd(exif_at as u32, exif));
    let mut seg = vec![0xFF, 0xE1];
    seg.extend(((tiff.len() + 8) as u16).to_be_bytes());
    seg.extend(b"Exif\0\0");
    seg.extend(tiff);
    seg
}

/// Write an 8-bit RGB JPEG (quality 95) with the given EXIF right after SOI.
pub fn write_jpeg(path: &Path, w: u32, h: u32, rgb: &[u8], tags: Option<&Tags>) {
    let mut jpg = Vec::new();
    JpegEncoder::new_with_quality(&mut jpg, 95)
        .encode(rgb, w, h, ExtendedColorType::Rgb8)
        .expect("encode");
    assert_eq!(&jpg[..2], &[0xFF, 0xD8]);
    let mut out = jpg[..2].to_vec();
    if let Some(t) = tags {
        out.extend(exif_app1(t));
    }
    out.extend(&jpg[2..]);
    std::fs::write(path, out).expect("write jpeg");
}

// ---------------------------------------------------------------------------------------------
// A synthetic scene and its brackets.

pub const W: usize = 40;
pub const H: usize = 32;

/// Linear radiance with ~10 stops of range (a horizontal ramp in log, colour varying by row).
pub fn radiance(x: usize, y: usize) -> [f64; 3] {
    let l = (-7.0 + 10.0 * x as f64 / (W - 1) as f64).exp2();
    let c = y as f64 / (H - 1) as f64;
    [l * (0.6 + 0.4 * c), l, l * (1.0 - 0.5 * c)]
}

/// An sRGB JPEG of the scene exposed for `t` seconds (exposure scale t · 16).
pub fn bracket_jpeg(path: &Path, t: f64, tags: Option<&Tags>) {
    noisy_bracket_jpeg(path, t, tags, None);
}

/// [`bracket_jpeg`] with white noise of σ = 2 codes drawn from `rng` where given, over flat
/// 16×16 patches of the same range on a 128×96 frame instead of the ramp (the noise
/// calibration needs flat pixels).
pub fn noisy_bracket_jpeg(path: &Path, t: f64, tags: Option<&Tags>, rng: Option<&mut TestNoise>) {
    let Some(rng) = rng else {
        let mut rgb = Vec::with_capacity(W * H * 3);
        for y in 0..H {
            for x in 0..W {
                for v in radiance(x, y) {
                    rgb.push((srgb(v * t * 16.0) * 255.0).round() as u8);
                }
            }
        }
        return write_jpeg(path, W as u32, H as u32, &rgb, tags);
    };
    let (w, h) = (128usize, 96usize);
    let patches = (w / 16) * (h / 16);
    let mut rgb = Vec::with_capacity(w * h * 3);
    for y in 0..h {
        for x in 0..w {
            let k = (x / 16) * (h / 16) + y / 16;
            let l = (-7.0 + 10.0 * k as f64 / (patches - 1) as f64).exp2();
            for v in [l * 0.8, l, l * 0.7] {
                let code = srgb(v * t * 16.0) * 255.0 + 2.0 * rng.normal();
                rgb.push(code.round().clamp(0.0, 255.0) as u8);
            }
        }
    }
    write_jpeg(path, w as u32, h as u32, &rgb, tags);
}

pub fn tags(t: (u32, u32), iso: u16, date: &str, subsec: &str) -> Tags {
    Tags {
        exposure_time: Some(t),
        iso: Some(iso),
        date: Some(date.to_string()),
        subsec: Some(subsec.to_string()),
        ..Tags::default()
    }
}

pub fn scan(dir: &Path) -> scan::BracketScan {
    scan::scan(dir, &ScanOptions::default()).expect("scan")
}

pub fn stops_rel(set: &scan::BracketSet) -> Vec<f64> {
    set.frames
        .iter()
        .map(|f| f.stop - set.frames[0].stop)
        .collect()
}

pub fn assert_close(a: &[f64], b: &[f64], tol: f64) {
    assert_eq!(a.len(), b.len(), "{a:?} vs {b:?}");
    for (x, y) in a.iter().zip(b) {
        assert!((x - y).abs() <= tol, "{a:?} vs {b:?}");
    }
}

// ---------------------------------------------------------------------------------------------
// Bracket folders, readers of what a test set holds, the OpenCV oracle's folder, and tiny
// trained checkpoints.

/// An EV −2/0/+2 bracket (1/400, 1/100, 1/25 s) in one sub-folder.
pub fn bracket_folder(root: &Path) -> PathBuf {
    let d = root.join("scene1");
    std::fs::create_dir_all(&d).expect("mkdir");
    for (i, den) in [100u32, 400, 25].iter().enumerate() {
        let t = tags((1, *den), 100, "2026:11:24 10:00:00", &format!("{i}"));
        bracket_jpeg(&d.join(format!("IMG_{i}.jpg")), 1.0 / *den as f64, Some(&t));
    }
    d
}

pub fn read_u16_tiff(path: &Path) -> (usize, usize, Vec<f64>) {
    let img = image::open(path).expect("tiff");
    let rgb = img.to_rgb16();
    let (w, h) = rgb.dimensions();
    (
        w as usize,
        h as usize,
        rgb.into_raw().iter().map(|&v| v as f64 / 65535.0).collect(),
    )
}

pub fn read_rgbe(path: &Path) -> Vec<f64> {
    let img = image::open(path).expect("hdr").to_rgb32f();
    img.into_raw().iter().map(|&v| v as f64).collect()
}

pub fn oracle_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/brackets")
}

pub fn read_csv_rows(path: &Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(path)
        .expect("csv")
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().expect("number")).collect())
        .collect()
}

/// Linear per code and channel from a written crf_debevec.csv (exp g(z), OpenCV's convention),
/// by hand (the rule of `crf::linearisation_table`): per channel, W from the least-squares line
/// ln r(z) = ln W + γ·ln(z/255) over codes 128–224, running maximum of r/W over codes; one
/// common divisor, the largest value of any channel up to code 249 where above 1; capped at 1,
/// and 1 at code 255.
pub fn debevec_tables(path: &Path) -> Vec<Vec<f64>> {
    let rows = read_csv_rows(path);
    assert_eq!(rows.len(), 256);
    let over_white: Vec<Vec<f64>> = (1..4)
        .map(|c| {
            let (x, y): (Vec<f64>, Vec<f64>) = (128..=224)
                .map(|z: usize| ((z as f64 / 255.0).ln(), rows[z][c].ln()))
                .unzip();
            let n = x.len() as f64;
            let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
            let sxy: f64 = x.iter().zip(&y).map(|(a, b)| (a - mx) * (b - my)).sum();
            let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
            let white = (my - sxy / sxx * mx).exp();
            let mut run = 0.0f64;
            rows.iter()
                .map(|r| {
                    run = run.max(r[c] / white);
                    run
                })
                .collect()
        })
        .collect();
    let brightest = over_white
        .iter()
        .flat_map(|t| &t[..=249])
        .copied()
        .fold(1.0, f64::max);
    over_white
        .iter()
        .map(|t| {
            (0..256)
                .map(|z| {
                    if z == 255 {
                        1.0
                    } else {
                        (t[z] / brightest).min(1.0)
                    }
                })
                .collect()
        })
        .collect()
}

pub fn train_tiny(run: &Path, model: &str, evs: &str) {
    train_tiny_with(run, model, evs, "profile = \"pure\"");
}

/// [`train_tiny`] with `realism` as the `[data]` lines of the sensor model.
pub fn train_tiny_with(run: &Path, model: &str, evs: &str, realism: &str) {
    use hdrsynth::config::parse_toml;
    use hdrsynth::data::generate::GenerateConfig;
    use hdrsynth::train::TrainOptions;
    use hdrsynth::train::config::TrainConfig;
    let data = run.with_extension("data");
    let text = format!(
        "seed = 8\ncount = 2\nwidth = 48\nheight = 40\nevs = {evs}\n[camera]\ncandidates = 2\n"
    );
    let mut c: GenerateConfig = parse_toml(&text, Path::new("gen.toml")).expect("config");
    c.source = None;
    hdrsynth::data::generate::generate(&c, &data, false).expect("generate");
    let text = format!(
        "[run]\nout = {run:?}\nseed = 4\nsteps = 2\ncheckpoint_every = 2\nlog_every = 1\n\
         [model]\n{model}\n\
         [data]\ndataset = {data:?}\npatch = 32\nbatch_size = 2\nworkers = 1\n{realism}\n\
         [optim]\nlr = 1e-3\n"
    );
    let cfg: TrainConfig = parse_toml(&text, Path::new("train.toml")).expect("config");
    hdrsynth::train::run(&cfg, &TrainOptions::default()).expect("train");
}

// ---------------------------------------------------------------------------------------------
// Brackets of PNGs with exposure.txt, drawn by hand from a known linear scene.

/// A bracket of 8-bit sRGB PNGs `f0.png`, `f1.png`, … (ascending exposure) of the linear
/// `scene` at `stops`, with Kalantari's exposure.txt sidecar (log2 stops in file-name order).
pub fn png_bracket(
    dir: &Path,
    w: usize,
    h: usize,
    scene: &dyn Fn(usize, usize) -> f64,
    stops: &[f64],
) {
    std::fs::create_dir_all(dir).expect("mkdir");
    for (i, s) in stops.iter().enumerate() {
        let mut img = image::RgbImage::new(w as u32, h as u32);
        for y in 0..h {
            for x in 0..w {
                let v = (srgb(scene(x, y) * s.exp2()) * 255.0).round() as u8;
                img.put_pixel(x as u32, y as u32, image::Rgb([v, v, v]));
            }
        }
        img.save(dir.join(format!("f{i}.png"))).expect("png");
    }
    let text: String = stops.iter().map(|s| format!("{s}\n")).collect();
    std::fs::write(dir.join("exposure.txt"), text).expect("exposure.txt");
}

pub fn srgb_opts(inputs: InputChoice, gt_frames: GtFrames) -> BracketOptions {
    BracketOptions {
        response: ResponseChoice::Declared(Response::Srgb),
        inputs,
        gt_frames,
        encode: EncodeSpec::Field,
        ..BracketOptions::default()
    }
}

pub fn exposure_txt(set: &Path) -> String {
    std::fs::read_to_string(set.join("exposure.txt")).expect("exposure.txt")
}

/// A log ramp over 80 columns, 2^−19 … 2^−0.2: the brightest quarter clips even in a stop-2
/// frame, the darkest columns are a few codes in a stop-6 frame.
pub fn ramp_scene(x: usize, _y: usize) -> f64 {
    (-19.0 + 18.8 * x as f64 / 79.0).exp2()
}

// ---------------------------------------------------------------------------------------------
// Noisy brackets and their calibration into a profile.

/// How the unit-variance draws of [`noisy_png_bracket`] are correlated in space.
#[derive(Clone, Copy)]
pub enum Spatial {
    White,
    /// The mean of 2×2 neighbouring draws times 2 (same variance, neighbours correlated as a
    /// denoiser's or demosaicker's residual is).
    Box2,
    /// Draws filtered by a separable Gaussian kernel exp(−i²/2s²), |i| ≤ ⌈3s⌉, normalised to
    /// Σk² = 1 per axis (unit variance), written out here from its definition.
    Gauss(f64),
    /// Every two channels of a pixel correlated by ρ: √(1 − ρ)·z_c + √ρ·z_s, z_s a fresh draw
    /// per pixel (chroma noise).
    Channel(f64),
}

/// The test's own Gaussian kernel (k(−R) … k(R)) of [`Spatial::Gauss`].
pub fn gauss_kernel(s: f64) -> Vec<f64> {
    let r = (3.0 * s).ceil() as i64;
    let k: Vec<f64> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * s * s)).exp())
        .collect();
    let norm = k.iter().map(|v| v * v).sum::<f64>().sqrt();
    k.iter().map(|v| v / norm).collect()
}

/// A bracket of 8-bit sRGB PNGs (exposure.txt stops) of a smooth scene with noise of variance
/// a·L + b added to the linear signal L before the encoding, spatially `spatial`.
pub fn noisy_png_bracket(dir: &Path, a: f64, b: f64, stops: &[f64], spatial: Spatial) {
    noisy_png_scene(dir, a, b, stops, spatial, 0.0);
}

/// [`noisy_png_bracket`] of a scene with fine texture: the ramp times 1 + `texture`·(a sum of
/// three gratings of periods 3.7 to 9.3 px, in [−1, 1]), the same in every frame.
pub fn noisy_png_scene(dir: &Path, a: f64, b: f64, stops: &[f64], spatial: Spatial, texture: f64) {
    noisy_png_device(dir, a, b, stops, spatial, texture, Isp::default());
}

/// What a device's processing does beyond noise and its sRGB curve, in [`noisy_png_device`].
#[derive(Clone, Copy, Default)]
pub struct Isp {
    /// The noisy linear signal x becomes max(0, x − floor)/(1 − floor) before the encoding
    /// (crushed shadows).
    pub floor: f64,
    /// Frame i's linear signal is multiplied by 1 + shading·sin(2π(x cos θᵢ + y sin θᵢ)/48),
    /// θᵢ = i·60°: a gain that varies over the frame and differs between the frames, as a
    /// local tone mapper's does.
    pub shading: f64,
}

/// [`noisy_png_scene`] from a device whose processing does what `isp` says.
pub fn noisy_png_device(
    dir: &Path,
    a: f64,
    b: f64,
    stops: &[f64],
    spatial: Spatial,
    texture: f64,
    isp: Isp,
) {
    let floor = isp.floor;
    std::fs::create_dir_all(dir).expect("mkdir");
    let (w, h) = (192usize, 144usize);
    let pad = 8usize;
    let (fw, fh) = (w + 2 * pad, h + 2 * pad);
    let mut rng = TestNoise(7);
    for (i, s) in stops.iter().enumerate() {
        let mut img = image::RgbImage::new(w as u32, h as u32);
        let field: Vec<f64> = (0..fw * fh * 3).map(|_| rng.normal()).collect();
        let shared: Vec<f64> = match spatial {
            Spatial::Channel(_) => (0..fw * fh).map(|_| rng.normal()).collect(),
            _ => Vec::new(),
        };
        let f = |x: usize, y: usize, c: usize| field[(y * fw + x) * 3 + c];
        let filtered: Vec<f64> = match spatial {
            Spatial::Gauss(sigma) => {
                let k = gauss_kernel(sigma);
                let r = k.len() / 2;
                let mut rows = vec![0.0; fw * fh * 3];
                for y in 0..fh {
                    for x in r..fw - r {
                        for c in 0..3 {
                            rows[(y * fw + x) * 3 + c] =
                                (0..k.len()).map(|j| k[j] * f(x + j - r, y, c)).sum();
                        }
                    }
                }
                let mut out = vec![0.0; fw * fh * 3];
                for y in r..fh - r {
                    for x in 0..fw {
                        for c in 0..3 {
                            out[(y * fw + x) * 3 + c] = (0..k.len())
                                .map(|j| k[j] * rows[((y + j - r) * fw + x) * 3 + c])
                                .sum();
                        }
                    }
                }
                out
            }
            _ => Vec::new(),
        };
        let draw = |x: usize, y: usize, c: usize| {
            let (x, y) = (x + pad, y + pad);
            match spatial {
                Spatial::White => f(x, y, c),
                Spatial::Box2 => {
                    (f(x, y, c) + f(x + 1, y, c) + f(x, y + 1, c) + f(x + 1, y + 1, c)) / 2.0
                }
                Spatial::Gauss(_) => filtered[(y * fw + x) * 3 + c],
                Spatial::Channel(r) => {
                    (1.0 - r).sqrt() * f(x, y, c) + r.sqrt() * shared[y * fw + x]
                }
            }
        };
        for y in 0..h {
            for x in 0..w {
                // A gentle ramp from 2^−7 to 2^0 of white at stop 0, a slight tint per channel.
                let tau = std::f64::consts::TAU;
                let (xf, yf) = (x as f64, y as f64);
                let grating = ((tau * xf / 3.7).sin() * (tau * yf / 5.3).cos()
                    + (tau * (xf + yf) / 9.3).sin()
                    + (tau * (xf - 2.0 * yf) / 6.1).cos())
                    / 3.0;
                let theta = i as f64 * tau / 6.0;
                let gain =
                    1.0 + isp.shading * (tau * (xf * theta.cos() + yf * theta.sin()) / 48.0).sin();
                let l0 = (-7.0 + 7.0 * x as f64 / (w - 1) as f64).exp2()
                    * s.exp2()
                    * (1.0 + texture * grating)
                    * gain;
                let px = [(0, 0.9), (1, 1.0), (2, 0.8)].map(|(c, k): (usize, f64)| {
                    let l = (k * l0).min(1.0);
                    let n = (a * l + b).sqrt() * draw(x, y, c);
                    let crushed = ((l + n - floor) / (1.0 - floor)).max(0.0);
                    (srgb(crushed) * 255.0).round() as u8
                });
                img.put_pixel(x as u32, y as u32, image::Rgb(px));
            }
        }
        img.save(dir.join(format!("f{i}.png"))).expect("png");
    }
    let text: String = stops.iter().map(|s| format!("{s}\n")).collect();
    std::fs::write(dir.join("exposure.txt"), text).expect("exposure.txt");
}

/// `calibrate brackets` on `dir` as most tests call it: the frames declared sRGB, a new
/// profile written to `out`.
pub fn calibrate_srgb(
    dir: &Path,
    scan: ScanOptions,
    out: &Path,
    correlated: bool,
) -> hdrsynth::capture::profile::BracketCalibration {
    use hdrsynth::capture::profile::{BracketProfileOptions, calibrate_brackets};
    calibrate_brackets(
        dir,
        &BracketProfileOptions {
            scan,
            response: ResponseChoice::Declared(Response::Srgb),
            out: out.to_path_buf(),
            name: None,
            correlated,
        },
    )
    .expect("calibrate")
}
