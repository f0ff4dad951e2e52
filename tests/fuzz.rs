//! Bounded mutation fuzzing of every parser of outside input. Each target
//! starts from small valid inputs (written here, never committed) and feeds the parser
//! seeded random mutations of them (bit flips, "interesting" bytes and integers such as
//! 0xFFFFFFFF or 100000 in either byte order, insertions, deletions, truncation, duplicated
//! ranges, and for text formats tokens such as `nan`, `-1e309`, `[`, `"`). A parser may
//! return any error; a panic fails the test and saves the input that caused it next to the
//! test's temp folder path in the message.
//!
//! Budget per target: `HDRSYNTH_FUZZ_SECS` seconds (default 1) or, when set,
//! `HDRSYNTH_FUZZ_ITERS` executions (the dev-time long run: docs/reliability.md). The mutation
//! sequence is a pure function of the target's name, so a count reproduces a run exactly.

mod common;

use hdrsynth::data::layout::{self, hdrsynth as lh};

use hdrsynth::io::{
    BitDepth, ExrPrecision, Format, Image, read_image_bytes, write_exr, write_hdr, write_ldr,
};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// SplitMix64: independent of the crate's RNG, so the fuzzer does not test itself.
struct Rng(u64);

impl Rng {
    fn new(name: &str) -> Rng {
        Rng(name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
            (h ^ b as u64).wrapping_mul(0x100_0000_01b3)
        }))
    }
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

const INTERESTING_U32: [u32; 10] = [
    0,
    1,
    0x7F,
    0xFF,
    0xFFFF,
    100_000,
    0x7FFF_FFFF,
    0x8000_0000,
    0xFFFF_FFFF,
    16385,
];
const TOKENS: [&str; 16] = [
    "nan",
    "inf",
    "-inf",
    "-1e309",
    "1e30",
    "-1",
    "0",
    "[",
    "]",
    "\"",
    "=",
    "\n",
    "[[",
    "{",
    "99999999999999999999",
    "\u{feff}",
];

fn mutate(seed: &[u8], rng: &mut Rng, text: bool) -> Vec<u8> {
    let mut d = seed.to_vec();
    for _ in 0..1 + rng.below(4) {
        let len = d.len();
        match rng.below(if text { 8 } else { 7 }) {
            0 if len > 0 => {
                let i = rng.below(len);
                d[i] ^= 1 << rng.below(8);
            }
            1 if len > 0 => {
                let i = rng.below(len);
                d[i] = [0, 0xFF, 0x7F, 0x80, rng.next() as u8][rng.below(5)];
            }
            2 if len >= 4 => {
                let i = rng.below(len - 3);
                let v = INTERESTING_U32[rng.below(INTERESTING_U32.len())];
                let b = if rng.below(2) == 0 {
                    v.to_le_bytes()
                } else {
                    v.to_be_bytes()
                };
                d[i..i + 4].copy_from_slice(&b);
            }
            3 => {
                let i = rng.below(len + 1);
                let n = 1 + rng.below(8);
                let bytes: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
                d.splice(i..i, bytes);
            }
            4 if len > 0 => {
                let i = rng.below(len);
                let n = 1 + rng.below((len - i).min(64));
                d.drain(i..i + n);
            }
            5 if len > 0 => d.truncate(rng.below(len)),
            6 if len > 1 => {
                let i = rng.below(len);
                let n = 1 + rng.below((len - i).min(64));
                let chunk = d[i..i + n].to_vec();
                let at = rng.below(d.len() + 1);
                d.splice(at..at, chunk);
            }
            7 => {
                let i = rng.below(len + 1);
                let t = TOKENS[rng.below(TOKENS.len())].as_bytes().to_vec();
                d.splice(i..i, t);
            }
            _ => {}
        }
    }
    d
}

/// Run `target` on mutations of `seeds` within the budget; returns the number of executions.
fn fuzz(name: &str, seeds: &[Vec<u8>], text: bool, target: impl Fn(&[u8])) -> u64 {
    fuzz_with(name, seeds, text, |d| d, target)
}

/// [`fuzz`] with `fix` applied to each mutation before the target sees it (e.g. PNG's chunk
/// checksums, so that mutations reach the decoder instead of stopping at the CRC check).
fn fuzz_with(
    name: &str,
    seeds: &[Vec<u8>],
    text: bool,
    fix: impl Fn(Vec<u8>) -> Vec<u8>,
    target: impl Fn(&[u8]),
) -> u64 {
    assert!(!seeds.is_empty());
    // Every seed must be accepted as-is by the harness (a sanity check of the target).
    for s in seeds {
        target(s);
    }
    let iters: Option<u64> = std::env::var("HDRSYNTH_FUZZ_ITERS")
        .ok()
        .map(|v| v.parse().expect("HDRSYNTH_FUZZ_ITERS: a whole number"));
    let secs: f64 = std::env::var("HDRSYNTH_FUZZ_SECS")
        .ok()
        .map_or(1.0, |v| v.parse().expect("HDRSYNTH_FUZZ_SECS: a number"));
    let budget = Duration::from_secs_f64(secs);
    let mut rng = Rng::new(name);
    let t0 = Instant::now();
    let mut n = 0u64;
    loop {
        match iters {
            Some(max) if n >= max => break,
            None if t0.elapsed() >= budget => break,
            _ => {}
        }
        let seed = &seeds[rng.below(seeds.len())];
        let input = fix(mutate(seed, &mut rng, text));
        if catch_unwind(AssertUnwindSafe(|| target(&input))).is_err() {
            let crash = std::env::temp_dir().join(format!("hdrsynth-fuzz-{name}-{n}.bin"));
            std::fs::write(&crash, &input).unwrap();
            panic!(
                "{name}: the parser panicked on execution {n}; input saved to {}",
                crash.display()
            );
        }
        n += 1;
    }
    eprintln!(
        "fuzz {name}: {n} executions in {:.1} s, no panic",
        t0.elapsed().as_secs_f64()
    );
    n
}

/// A file-based target: each input is written to `dir/name` and `read` is called on it.
fn file_target<'a>(dir: &'a Path, name: &'a str, read: impl Fn(&Path) + 'a) -> impl Fn(&[u8]) + 'a {
    let path = dir.join(name);
    move |bytes: &[u8]| {
        std::fs::write(&path, bytes).unwrap();
        read(&path);
    }
}

fn image(w: usize, h: usize) -> Image {
    let v = common::values(w * h * 3, 7);
    Image::from_vec(w, h, v.iter().map(|x| x * 4.0).collect())
}

fn written(dir: &Path, name: &str, write: impl FnOnce(&Path)) -> Vec<u8> {
    let p = dir.join(format!("seed-{name}"));
    write(&p);
    std::fs::read(&p).unwrap()
}

/// An image target, in memory: `read_image_bytes` is the decoder path `read_image` takes after
/// reading the file (same limits and checks), so no file is written per execution.
fn image_target(name: &str, format: Format, seeds: impl FnOnce(&Path) -> Vec<Vec<u8>>) {
    // Half the PNG mutations get their chunk CRCs recomputed: the other half still tests
    // the CRC check itself.
    let half = std::cell::Cell::new(false);
    let fix = |d: Vec<u8>| {
        half.set(!half.get());
        if format == Format::Png && half.get() {
            fix_png_crcs(d)
        } else {
            d
        }
    };
    let dir = tempfile::tempdir().unwrap();
    let seeds = seeds(dir.path());
    let path = Path::new(name);
    for s in &seeds {
        read_image_bytes(s, format, path).expect("the seed image is valid");
    }
    fuzz_with(name, &seeds, false, fix, |bytes| {
        let _ = read_image_bytes(bytes, format, path);
    });
}

/// Rewrite the CRC of every whole chunk after PNG's 8-byte signature (length, type, data, CRC).
fn fix_png_crcs(mut d: Vec<u8>) -> Vec<u8> {
    let mut at = 8;
    while at + 12 <= d.len() {
        let len = u32::from_be_bytes(d[at..at + 4].try_into().unwrap()) as usize;
        let Some(end) = (at + 8).checked_add(len).filter(|&e| e + 4 <= d.len()) else {
            break;
        };
        let crc = common::crc32(&d[at + 4..end]);
        d[end..end + 4].copy_from_slice(&crc.to_be_bytes());
        at = end + 4;
    }
    d
}

#[test]
fn fuzz_png() {
    image_target("png", Format::Png, |d| {
        let img = image(6, 5).map(|v| v / 4.0);
        vec![
            written(d, "8.png", |p| write_ldr(p, &img, BitDepth::Eight).unwrap()),
            written(d, "16.png", |p| {
                write_ldr(p, &img, BitDepth::Sixteen).unwrap()
            }),
        ]
    });
}

#[test]
fn fuzz_tiff() {
    image_target("tiff", Format::Tiff, |d| {
        let img = image(6, 5).map(|v| v / 4.0);
        vec![
            written(d, "8.tif", |p| write_ldr(p, &img, BitDepth::Eight).unwrap()),
            written(d, "16.tif", |p| {
                write_ldr(p, &img, BitDepth::Sixteen).unwrap()
            }),
        ]
    });
}

#[test]
fn fuzz_radiance_hdr() {
    image_target("hdr", Format::Hdr, |d| {
        vec![
            written(d, "a.hdr", |p| write_hdr(p, &image(6, 5)).unwrap()),
            // Wide enough for the run-length encoded scan lines (8 ≤ width < 32768).
            written(d, "b.hdr", |p| write_hdr(p, &image(12, 3)).unwrap()),
        ]
    });
}

#[test]
fn fuzz_exr() {
    image_target("exr", Format::Exr, |d| {
        vec![
            written(d, "f.exr", |p| {
                write_exr(p, &image(6, 5), ExrPrecision::Float).unwrap()
            }),
            written(d, "h.exr", |p| {
                write_exr(p, &image(6, 5), ExrPrecision::Half).unwrap()
            }),
        ]
    });
}

#[test]
fn fuzz_jpeg() {
    image_target("jpeg", Format::Jpeg, |_| {
        let img = image(17, 9).map(|v| v / 4.0);
        let rgb: Vec<u8> = img.data.iter().map(|v| (v * 255.0).round() as u8).collect();
        let grey: Vec<u8> = rgb.chunks(3).map(|p| p[1]).collect();
        let enc = |data: &[u8], colour: image::ExtendedColorType| {
            let mut out = Vec::new();
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 90)
                .encode(data, 17, 9, colour)
                .unwrap();
            out
        };
        vec![
            enc(&rgb, image::ExtendedColorType::Rgb8),
            enc(&grey, image::ExtendedColorType::L8),
        ]
    });
}

/// A valid 4×4 16-bit RGGB DNG (one uncompressed strip), little-endian.
fn small_dng() -> Vec<u8> {
    let (w, h) = (4u32, 4u32);
    // (tag, type, count, 4 value bytes)
    let mut entries: Vec<(u16, u16, u32, [u8; 4])> = vec![
        (254, 4, 1, 0u32.to_le_bytes()),
        (256, 4, 1, w.to_le_bytes()),
        (257, 4, 1, h.to_le_bytes()),
        (258, 3, 1, [16, 0, 0, 0]),
        (259, 3, 1, [1, 0, 0, 0]),
        (262, 3, 1, [0x23, 0x80, 0, 0]), // 32803 CFA
        (273, 4, 1, [0; 4]),             // StripOffsets, set below
        (277, 3, 1, [1, 0, 0, 0]),
        (278, 4, 1, h.to_le_bytes()),
        (279, 4, 1, (w * h * 2).to_le_bytes()),
        (33421, 3, 2, [2, 0, 2, 0]),
        (33422, 1, 4, [0, 1, 1, 2]),
        (50714, 3, 1, [64, 0, 0, 0]),
        (50717, 3, 1, [0xFF, 0x0F, 0, 0]),
    ];
    let data_off = (8 + 2 + 12 * entries.len() + 4) as u32;
    entries[6].3 = data_off.to_le_bytes();
    let mut out = b"II".to_vec();
    out.extend(42u16.to_le_bytes());
    out.extend(8u32.to_le_bytes());
    out.extend((entries.len() as u16).to_le_bytes());
    for (tag, typ, count, val) in entries {
        out.extend(tag.to_le_bytes());
        out.extend(typ.to_le_bytes());
        out.extend(count.to_le_bytes());
        out.extend(val);
    }
    out.extend(0u32.to_le_bytes());
    for i in 0..w * h {
        out.extend((64 + (i * 200) as u16).to_le_bytes());
    }
    out
}

/// Found by the long run of `fuzz_dng`: a numeric tag with count 0 (here BitsPerSample)
/// indexed an empty list and panicked.
#[test]
fn a_dng_tag_with_no_values_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let mut d = small_dng();
    let count_at = 8 + 2 + 12 * 3 + 4; // entry 3 (BitsPerSample), its count field
    d[count_at..count_at + 4].copy_from_slice(&0u32.to_le_bytes());
    let p = dir.path().join("zero.dng");
    std::fs::write(&p, d).unwrap();
    let e = hdrsynth::sensor::dng::read_dng(&p).unwrap_err().to_string();
    assert!(e.contains("zero.dng") && e.contains("no values"), "{e}");
}

#[test]
fn fuzz_dng() {
    let seed = small_dng();
    let path = Path::new("input.dng");
    hdrsynth::sensor::dng::read_dng_bytes(&seed, path).expect("the seed DNG is valid");
    fuzz("dng", &[seed], false, |bytes| {
        let _ = hdrsynth::sensor::dng::read_dng_bytes(bytes, path);
    });
}

/// The tag reader of `calibrate dng` and what is computed from the tags (colour, levels,
/// noise), on the same seed.
#[test]
fn fuzz_dng_tags() {
    let seed = small_dng();
    let path = Path::new("input.dng");
    hdrsynth::sensor::dng::read_dng_tags_bytes(&seed, path).expect("the seed DNG's tags read");
    fuzz("dng_tags", &[seed], false, |bytes| {
        if let Ok(t) = hdrsynth::sensor::dng::read_dng_tags_bytes(bytes, path) {
            let _ = hdrsynth::sensor::dng::colour::dng_colour(&t, path);
            let _ = t.channel_levels(path);
            let _ = t.noise_per_channel(path);
        }
    });
}

fn repo(rel: &str) -> Vec<u8> {
    std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)).unwrap()
}

fn text_target<T: serde::de::DeserializeOwned>(
    name: &str,
    seeds: &[Vec<u8>],
    validate: impl Fn(&T),
) {
    fuzz(name, seeds, true, |bytes| {
        let Ok(text) = std::str::from_utf8(bytes) else {
            return;
        };
        if let Ok(v) = hdrsynth::config::parse_toml::<T>(text, Path::new("fuzz.toml")) {
            validate(&v);
        }
    });
}

#[test]
fn fuzz_generate_config() {
    text_target::<hdrsynth::data::generate::GenerateConfig>(
        "generate_toml",
        &[
            repo("configs/generate.toml"),
            repo("configs/data/net2_train.toml"),
        ],
        |c| {
            let _ = c.validate();
        },
    );
}

#[test]
fn fuzz_train_config() {
    text_target::<hdrsynth::train::config::TrainConfig>(
        "train_toml",
        &[
            repo("configs/net1_pretrain.toml"),
            repo("configs/net2_pretrain.toml"),
        ],
        |c| {
            let _ = c.validate();
        },
    );
}

#[test]
fn fuzz_sensor_profile() {
    text_target::<hdrsynth::sensor::profile::SensorProfile>(
        "profile_toml",
        &[
            repo("configs/sensors/canon_eos_550d.toml"),
            repo("configs/sensors/example_synthetic.toml"),
        ],
        |p| {
            let _ = p.validate();
        },
    );
}

/// Every catalogue effect with valid parameters (the effect-parameter target's seed).
const ALL_EFFECTS: &str = "[[effects]]\nid = \"vignetting\"\nstrength = 0.2\n\
[[effects]]\nid = \"prnu\"\nsigma = 0.01\nseed = 1\n\
[[effects]]\nid = \"nonlinear_response\"\nshape = \"toe_shoulder\"\ntoe = 0.05\nshoulder = 0.8\n\
[[effects]]\nid = \"channel_noise\"\na_scale = [1.0, 1.1, 0.9]\nb_scale = [1, 1, 1]\n\
[[effects]]\nid = \"heavy_tailed_read_noise\"\ndof = 6\n\
[[effects]]\nid = \"correlated_noise\"\nrho_h = 0.2\nrho_v = 0.3\n\
[[effects]]\nid = \"black_level\"\noffset_dn = 2.5\n\
[[effects]]\nid = \"row_noise\"\nsigma_dn = 1.0\n\
[[effects]]\nid = \"column_noise\"\nsigma_dn = 0.5\nseed = 2\n\
[[effects]]\nid = \"dsnu\"\nsigma_dn = 0.5\nseed = 3\n\
[[effects]]\nid = \"hot_pixels\"\nfraction = 0.001\noffset_dn = 200\nseed = 4\n";

#[test]
fn fuzz_effect_parameters() {
    use hdrsynth::sensor::effects::Plan;
    use hdrsynth::sensor::profile::EffectSpec;
    #[derive(serde::Deserialize)]
    struct Effects {
        effects: Vec<EffectSpec>,
    }
    let power_law = ALL_EFFECTS
        .replace(
            "shape = \"toe_shoulder\"\ntoe = 0.05\nshoulder = 0.8",
            "exponent = 0.9",
        )
        .replace("rho_h = 0.2\nrho_v = 0.3", "rho = 0.25");
    for seed in [ALL_EFFECTS, &power_law] {
        let e: Effects = toml::from_str(seed).unwrap();
        Plan::from_effects(&e.effects).expect("the seed's parameters are valid");
    }
    text_target::<Effects>(
        "effect_parameters",
        &[ALL_EFFECTS.as_bytes().to_vec(), power_law.into_bytes()],
        |e| {
            let _ = Plan::from_effects(&e.effects);
        },
    );
}

#[test]
fn fuzz_captures_manifest() {
    let seed = b"format = \"hdrsynth-captures/1\"\n[sensor]\nname = \"p\"\nwhite_level = 4095\n\
                 black_level = 64\n[[burst]]\nname = \"flat_iso100_0\"\nkind = \"flat\"\n\
                 iso = 100\nexposure_s = 0.0068\nframes = [\"a/000.png\", \"a/001.png\"]\n"
        .to_vec();
    hdrsynth::sensor::captures::CaptureManifest::parse(
        std::str::from_utf8(&seed).unwrap(),
        Path::new("captures.toml"),
    )
    .expect("the seed manifest is valid");
    fuzz("captures_toml", &[seed], true, |bytes| {
        if let Ok(text) = std::str::from_utf8(bytes)
            && let Ok(m) =
                hdrsynth::sensor::captures::CaptureManifest::parse(text, Path::new("captures.toml"))
        {
            let _ = m.validate();
        }
    });
}

/// An exposure file's text through the code both layout readers run on it: `parse_stops` (3
/// values) and `relative_evs` (stops relative to the reference frame, distinct exposures).
fn stops_target(name: &str, file: &str, seeds: &[Vec<u8>]) {
    let path = Path::new(file);
    let run = |text: &str| {
        layout::parse_stops(text, path, 3).and_then(|s| layout::relative_evs(path, &s, 1))
    };
    for s in seeds {
        run(std::str::from_utf8(s).unwrap()).expect("the seed is valid");
    }
    fuzz(name, seeds, true, |bytes| {
        if let Ok(text) = std::str::from_utf8(bytes) {
            let _ = run(text);
        }
    });
}

#[test]
fn fuzz_kalantari_exposure_txt() {
    stops_target(
        "exposure_txt",
        "exposure.txt",
        &[b"0\n2\n4\n".to_vec(), b"-2.0\r\n0.0\r\n2.0\r\n".to_vec()],
    );
}

/// Wu et al.'s `input_exp.txt` (any order; the reader sorts frames by number, not stop).
#[test]
fn fuzz_wu_input_exp_txt() {
    stops_target(
        "input_exp_txt",
        "input_exp.txt",
        &[b"-2 0 2\n".to_vec(), b"2.0\n0.0\n-2.0\n".to_vec()],
    );
}

/// A set's `meta.toml` and the dataset's `dataset.toml`, in memory, through the parsers the
/// hdrsynth layout reader uses, and the names it derives from the parsed EVs.
#[test]
fn fuzz_set_meta_and_dataset_manifest() {
    let dir = tempfile::tempdir().unwrap();
    common::generate(dir.path(), 2, 1, (16, 16), "[-2.0, 0.0, 2.0]");
    let meta_seed = std::fs::read(common::first_set(dir.path()).join("meta.toml")).unwrap();
    let manifest_seed = std::fs::read(dir.path().join("dataset.toml")).unwrap();
    let names = |evs: &[f32]| {
        for &ev in evs {
            let _ = hdrsynth::data::scene::ev_tag(ev);
            let _ = lh::clean_frame_name(ev);
        }
    };
    let (mp, dp) = (Path::new("meta.toml"), Path::new("dataset.toml"));
    lh::parse_set_meta(std::str::from_utf8(&meta_seed).unwrap(), mp).expect("valid seed");
    lh::parse_manifest(std::str::from_utf8(&manifest_seed).unwrap(), dp).expect("valid seed");
    fuzz("meta_toml", &[meta_seed], true, |bytes| {
        if let Ok(text) = std::str::from_utf8(bytes)
            && let Ok(m) = lh::parse_set_meta(text, mp)
        {
            names(&m.evs);
        }
    });
    fuzz("dataset_toml", &[manifest_seed], true, |bytes| {
        if let Ok(text) = std::str::from_utf8(bytes)
            && let Ok(m) = lh::parse_manifest(text, dp)
        {
            names(&m.evs);
            if let Some(g) = m.generator {
                let _ = g.validate();
            }
        }
    });
}

/// darktable's noise presets flattened to CSV (`profile import-darktable`), through the parser,
/// the camera selection and the conversion to profile noise entries.
#[test]
fn fuzz_darktable_csv() {
    use hdrsynth::sensor::darktable::{NegativeRule, Query, parse_csv, select, to_noise};
    let seed = "maker,model,iso,a_R,a_G,a_B,b_R,b_G,b_B,profile_name\n\
        Canon,EOS 550D,100,4.5e-06,2.1e-06,3.1e-06,2.5e-08,-2.0e-08,2.6e-08,EOS 550D iso 100\n\
        Canon,EOS 550D,200,9.0e-06,4.2e-06,6.3e-06,5.1e-08,4.1e-08,5.3e-08,EOS 550D iso 200\n\
        Canon,EOS 550D,200,9.1e-06,4.3e-06,6.2e-06,5.0e-08,4.0e-08,5.2e-08,\"EOS 550D, second\"\n"
        .as_bytes()
        .to_vec();
    let path = Path::new("noiseprofiles.csv");
    let levels = hdrsynth::sensor::profile::Levels {
        black_level: 2048.0,
        white_level: 15000.0,
        bit_depth: 14,
    };
    let run = |text: &str| -> Option<usize> {
        let rows = parse_csv(text, path).ok()?;
        let first = rows.first()?;
        let q = Query {
            maker: first.maker.clone(),
            model: first.model.clone(),
            profile_name: None,
            set: Some(1),
        };
        let sel = select(&rows, &q, path).ok()?;
        for rule in [
            NegativeRule::Floor,
            NegativeRule::Verbatim,
            NegativeRule::Zero,
        ] {
            let _ = to_noise(&sel, rule, &levels);
        }
        Some(sel.rows.len())
    };
    assert_eq!(run(std::str::from_utf8(&seed).unwrap()), Some(2));
    fuzz("darktable_csv", &[seed], true, |bytes| {
        if let Ok(text) = std::str::from_utf8(bytes) {
            run(text);
        }
    });
}

/// `calibrate colour --illuminant`: a name or three comma-separated gains.
#[test]
fn fuzz_illuminant_argument() {
    let seeds = [b"D65".to_vec(), b"1.9, 1.0, 1.6".to_vec()];
    fuzz("illuminant_arg", &seeds, true, |bytes| {
        if let Ok(text) = std::str::from_utf8(bytes) {
            let _ = text.parse::<hdrsynth::sensor::colour::chart::Illuminant>();
        }
    });
}

// End to end through the layout detector on files (each execution writes the file and
// detects the folder: slower, so the long run reaches fewer executions; docs/reliability.md).

/// A Kalantari set (three tiny 16-bit TIFFs, exposure.txt, HDRImg.hdr) in `root/001`.
fn kalantari(root: &Path) -> PathBuf {
    let set = root.join("001");
    let img = image(8, 6).map(|v| v / 4.0);
    for n in ["a.tif", "b.tif", "c.tif"] {
        write_ldr(&set.join(n), &img, BitDepth::Sixteen).unwrap();
    }
    write_hdr(&set.join("HDRImg.hdr"), &image(8, 6)).unwrap();
    std::fs::write(set.join("exposure.txt"), "0\n2\n4\n").unwrap();
    set
}

/// A Wu set (input_{1,2,3}_aligned.tif, input_exp.txt, ref_hdr_aligned.hdr) in `root/001`.
fn wu(root: &Path) -> PathBuf {
    let set = root.join("001");
    let img = image(8, 6).map(|v| v / 4.0);
    for i in 1..=3 {
        let p = set.join(format!("input_{i}_aligned.tif"));
        write_ldr(&p, &img, BitDepth::Sixteen).unwrap();
    }
    write_hdr(&set.join("ref_hdr_aligned.hdr"), &image(8, 6)).unwrap();
    std::fs::write(set.join("input_exp.txt"), "-2 0 2\n").unwrap();
    set
}

fn detector_target(name: &str, make: fn(&Path) -> PathBuf, file: &str, seeds: &[Vec<u8>]) {
    let dir = tempfile::tempdir().unwrap();
    let set = make(dir.path());
    layout::detect(dir.path()).expect("the seed set is valid");
    fuzz(
        name,
        seeds,
        true,
        file_target(&set, file, |_| {
            let _ = layout::detect(dir.path());
        }),
    );
}

#[test]
fn fuzz_exposure_txt_through_the_layout_detector() {
    let seeds = [b"0\n2\n4\n".to_vec(), b"-2.0\r\n0.0\r\n2.0\r\n".to_vec()];
    detector_target("detect_exposure_txt", kalantari, "exposure.txt", &seeds);
}

#[test]
fn fuzz_input_exp_txt_through_the_layout_detector() {
    let seeds = [b"-2 0 2\n".to_vec(), b"2.0\n0.0\n-2.0\n".to_vec()];
    detector_target("detect_input_exp_txt", wu, "input_exp.txt", &seeds);
}

/// An ablation grid config (`hdrsynth ablate CONFIG`), parsed and checked in memory.
#[test]
fn fuzz_ablate_config() {
    let seeds = [
        repo("configs/experiments/cpu/exp2_network2.toml"),
        repo("configs/experiments/exp1_network1.toml"),
    ];
    let path = Path::new("ablate.toml");
    for s in &seeds {
        let text = std::str::from_utf8(s).unwrap();
        hdrsynth::experiments::ablate::AblateConfig::parse(text, path).expect("the seed is valid");
    }
    fuzz("ablate_toml", &seeds, true, |bytes| {
        if let Ok(text) = std::str::from_utf8(bytes) {
            let _ = hdrsynth::experiments::ablate::AblateConfig::parse(text, path);
        }
    });
}

/// A dataset's `class_weights.toml` (read by train), parsed and checked in memory.
#[test]
fn fuzz_class_weights() {
    use hdrsynth::data::ground_truth::{ClassWeights, MertensWeights};
    let mut hist = [0u64; 256];
    for (i, h) in hist.iter_mut().enumerate() {
        *h = (i as u64 * 37) % 11;
    }
    let cw = ClassWeights::new(&hist, MertensWeights::OPENCV_DEFAULT, 3);
    let seed = toml::to_string(&cw).unwrap().into_bytes();
    let path = Path::new("class_weights.toml");
    ClassWeights::parse(std::str::from_utf8(&seed).unwrap(), path).expect("the seed is valid");
    fuzz("class_weights_toml", &[seed], true, |bytes| {
        if let Ok(text) = std::str::from_utf8(bytes) {
            let _ = ClassWeights::parse(text, path);
        }
    });
}

/// A checkpoint's `state.toml` (`eval --checkpoint`, `infer`, `train --resume`), in memory.
#[test]
fn fuzz_checkpoint_state() {
    use hdrsynth::train::checkpoint::parse_state;
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    common::generate(&data, 3, 1, (32, 32), "[-3.0, 0.0]");
    let cfg_path = dir.path().join("t.toml");
    std::fs::write(
        &cfg_path,
        format!(
            "[run]\nout = {:?}\nseed = 1\nsteps = 1\ncheckpoint_every = 1\n\
             [model]\nkind = \"blend_unet\"\nbase_width = 2\ndepth = 1\n\
             [data]\ndataset = {data:?}\npatch = 16\nbatch_size = 1\nworkers = 1\n\
             profile = \"pure\"\n",
            dir.path().join("run")
        ),
    )
    .unwrap();
    let cfg = hdrsynth::train::config::TrainConfig::load(&cfg_path).unwrap();
    let opts = hdrsynth::train::TrainOptions {
        resume: false,
        progress: false,
    };
    hdrsynth::train::run(&cfg, &opts).unwrap();
    let ckpt = hdrsynth::train::checkpoint::resolve(&dir.path().join("run")).unwrap();
    let state = std::fs::read(ckpt.join("state.toml")).unwrap();
    let path = Path::new("state.toml");
    parse_state(std::str::from_utf8(&state).unwrap(), path).expect("the seed is valid");
    fuzz("checkpoint_state_toml", &[state], true, |bytes| {
        if let Ok(text) = std::str::from_utf8(bytes) {
            let _ = parse_state(text, path);
        }
    });
}

/// A small Wu ResNet (width 2, one residual block) for the weight-file targets: every kind
/// of tensor (convolutions, deconvolutions, BatchNorm) with few bytes to mutate and decode.
fn small_wu() -> hdrsynth::models::wu::WuNet {
    let dev = burn::tensor::Device::flex();
    let cfg = hdrsynth::models::wu::WuConfig {
        res_blocks: 1,
        ..hdrsynth::models::wu::WuConfig::resnet(2)
    };
    hdrsynth::models::seeded_init(&dev, 0, || cfg.init(&dev)).unwrap()
}

/// A checkpoint's `model.bpk` (Burn's record), decoded into the model in memory.
#[test]
fn fuzz_checkpoint_model_record() {
    use hdrsynth::train::checkpoint::{model_from_bytes, model_to_bytes};
    let model = small_wu();
    let path = Path::new("model.bpk");
    let seed = model_to_bytes(&model, path).unwrap();
    model_from_bytes(model.clone(), seed.clone(), path).expect("the seed is valid");
    fuzz("checkpoint_model_bpk", &[seed], false, |bytes| {
        let _ = model_from_bytes(model.clone(), bytes.to_vec(), path);
    });
}

/// Found by the long run of `fuzz_checkpoint_model_record` (execution 972,913): one byte of
/// the record header changed, a float tensor's dtype "F32" read as "U32", and Burn panicked
/// while loading it into the model.
#[test]
fn a_checkpoint_tensor_of_the_wrong_dtype_is_an_error() {
    use hdrsynth::train::checkpoint::{model_from_bytes, model_to_bytes};
    let model = small_wu();
    let path = Path::new("run/step-00000001/model.bpk");
    let mut bytes = model_to_bytes(&model, path).unwrap();
    let at = bytes
        .windows(9)
        .position(|w| w == b"dtypecF32")
        .expect("a CBOR dtype entry");
    bytes[at + 6] = b'U';
    let e = model_from_bytes(model, bytes, path)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("model.bpk") && e.contains("corrupt checkpoint"),
        "{e}"
    );
}

/// Pretrained weights in SafeTensors (`[init] safetensors`), imported in memory.
#[test]
fn fuzz_safetensors_import() {
    use hdrsynth::models::import::import_weights_bytes;
    let dir = tempfile::tempdir().unwrap();
    let model = small_wu();
    let file = dir.path().join("w.safetensors");
    hdrsynth::models::wu::export_weights(&model, &file).unwrap();
    let seed = std::fs::read(&file).unwrap();
    let path = Path::new("w.safetensors");
    import_weights_bytes(model.clone(), seed.clone(), path).expect("the seed is valid");
    fuzz("safetensors", &[seed], false, |bytes| {
        let _ = import_weights_bytes(model.clone(), bytes.to_vec(), path);
    });
}

/// EXIF exposure tags of a bracket JPEG (`testset --brackets`), through `scan::read_exif`,
/// which reads a file: each execution writes one (put TMPDIR on a RAM disk for long runs).
#[test]
fn fuzz_bracket_exif() {
    // Little-endian TIFF: IFD0 at 8 holds only the Exif IFD pointer; the Exif IFD at 26 holds
    // ExposureTime (RATIONAL at 68), ISOSpeedRatings and ExposureBiasValue (SRATIONAL at 76).
    let mut tiff = b"II*\0".to_vec();
    tiff.extend(8u32.to_le_bytes());
    let entry = |t: &mut Vec<u8>, tag: u16, typ: u16, count: u32, val: u32| {
        t.extend(tag.to_le_bytes());
        t.extend(typ.to_le_bytes());
        t.extend(count.to_le_bytes());
        t.extend(val.to_le_bytes());
    };
    tiff.extend(1u16.to_le_bytes());
    entry(&mut tiff, 0x8769, 4, 1, 26);
    tiff.extend(0u32.to_le_bytes());
    tiff.extend(3u16.to_le_bytes());
    entry(&mut tiff, 0x829A, 5, 1, 68);
    entry(&mut tiff, 0x8827, 3, 1, 100);
    entry(&mut tiff, 0x9204, 10, 1, 76);
    tiff.extend(0u32.to_le_bytes());
    assert_eq!(tiff.len(), 68);
    for v in [1u32, 250, (-2i32) as u32, 3] {
        tiff.extend(v.to_le_bytes());
    }
    let mut jpeg = vec![0xFF, 0xD8, 0xFF, 0xE1];
    jpeg.extend(((tiff.len() + 8) as u16).to_be_bytes());
    jpeg.extend(b"Exif\0\0");
    jpeg.extend(&tiff);
    let mut body = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut body, 90)
        .encode(&[128u8; 8 * 8 * 3], 8, 8, image::ExtendedColorType::Rgb8)
        .unwrap();
    jpeg.extend(&body[2..]); // the encoder's stream after its SOI
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("seed.jpg");
    std::fs::write(&p, &jpeg).unwrap();
    let e = hdrsynth::capture::scan::read_exif(&p).expect("the seed is valid");
    assert_eq!((e.exposure_time, e.iso), (Some(1.0 / 250.0), Some(100.0)));
    fuzz(
        "bracket_exif",
        &[jpeg],
        false,
        file_target(dir.path(), "input.jpg", |p| {
            let _ = hdrsynth::capture::scan::read_exif(p);
        }),
    );
}

/// A checkpoint's `optimizer.bpk` (Adam's moments and step counts), decoded in memory.
#[test]
fn fuzz_checkpoint_optimizer_record() {
    use burn::optim::{AdamConfig, GradientsParams};
    use hdrsynth::train::checkpoint::{optimizer_from_bytes, optimizer_to_bytes};
    let dev = burn::tensor::Device::flex().autodiff();
    let cfg = hdrsynth::models::wu::WuConfig {
        res_blocks: 1,
        ..hdrsynth::models::wu::WuConfig::resnet(2)
    };
    let model = hdrsynth::models::seeded_init(&dev, 0, || cfg.init(&dev)).unwrap();
    let x = burn::tensor::Tensor::<4>::from_data(
        burn::tensor::TensorData::new(common::values(18 * 16 * 16, 1), [1, 18, 16, 16]),
        &dev,
    );
    let grads = GradientsParams::from_grads(model.forward(x).sum().backward(), &model);
    let mut optim = AdamConfig::new().init();
    let _ = optim.step(1e-3, model, grads);
    let path = Path::new("optimizer.bpk");
    let seed = optimizer_to_bytes(&optim, path).unwrap();
    optimizer_from_bytes(AdamConfig::new().init(), seed.clone(), path).expect("the seed is valid");
    fuzz("checkpoint_optimizer_bpk", &[seed], false, |bytes| {
        let _ = optimizer_from_bytes(AdamConfig::new().init(), bytes.to_vec(), path);
    });
}

/// Any change to any file of a checkpoint — a flipped bit, a truncation, an insertion,
/// anywhere in the file — is refused by its checksum with the file named; the checksums file
/// itself parses or is refused, never panics.
#[test]
fn fuzz_checkpoint_files_against_their_checksums() {
    use hdrsynth::train::checkpoint::{self, CHECKSUMS_FILE, parse_checksums, verify};
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    common::generate(&data, 3, 1, (32, 32), "[-3.0, 0.0]");
    let text = format!(
        "[run]\nout = {:?}\nseed = 1\nsteps = 1\ncheckpoint_every = 1\n\
         [model]\nkind = \"blend_unet\"\nbase_width = 2\ndepth = 1\n\
         [data]\ndataset = {data:?}\npatch = 16\nbatch_size = 1\nworkers = 1\n\
         profile = \"pure\"\n",
        dir.path().join("run")
    );
    let cfg: hdrsynth::train::config::TrainConfig =
        hdrsynth::config::parse_toml(&text, Path::new("t.toml")).unwrap();
    let opts = hdrsynth::train::TrainOptions {
        resume: false,
        progress: false,
    };
    hdrsynth::train::run(&cfg, &opts).unwrap();
    let ckpt = checkpoint::resolve(&dir.path().join("run")).unwrap();
    let names = [
        "model.bpk",
        "optimizer.bpk",
        "state.toml",
        "class_weights.toml",
    ];
    let files: Vec<Vec<u8>> = names
        .iter()
        .map(|n| std::fs::read(ckpt.join(n)).unwrap())
        .collect();
    for (n, b) in names.iter().zip(&files) {
        verify(&ckpt, n, b).expect("the seed is valid");
    }
    // Every target input is one file's bytes with its index in front.
    let seeds: Vec<Vec<u8>> = files
        .iter()
        .enumerate()
        .map(|(i, b)| [&[i as u8][..], b].concat())
        .collect();
    fuzz("checkpoint_files_checksums", &seeds, false, |bytes| {
        let Some((&i, body)) = bytes.split_first() else {
            return;
        };
        let Some(name) = names.get(i as usize) else {
            return;
        };
        let r = verify(&ckpt, name, body);
        if body == files[i as usize].as_slice() {
            assert!(r.is_ok());
        } else {
            let e = r.expect_err("a changed checkpoint file passed its checksum");
            assert!(e.to_string().contains(name), "{e}");
        }
    });
    let sums = std::fs::read(ckpt.join(CHECKSUMS_FILE)).unwrap();
    let path = Path::new(CHECKSUMS_FILE);
    fuzz("checkpoint_checksums_file", &[sums], true, |bytes| {
        if let Ok(text) = std::str::from_utf8(bytes) {
            let _ = parse_checksums(text, path);
        }
    });
}

/// Found by `fuzz_checkpoint_optimizer_record`: Burn 0.22 panics on an optimizer state tensor
/// without a parameter id ("Optimizer record tensors should carry a parameter id") and on a
/// state of rank 17; either must be an error naming the file.
#[test]
fn an_optimizer_state_without_a_parameter_id_is_an_error() {
    use burn::optim::AdamConfig;
    use hdrsynth::train::checkpoint::optimizer_from_bytes;
    let t = burn_pack::Tensor::new(
        "1.momentum.moment_1".into(),
        burn::tensor::DType::F32,
        [2usize],
        None,
        burn::tensor::Bytes::from_bytes_vec(vec![0u8; 8]),
    );
    let bytes = burn_pack::Writer::new(vec![t])
        .into_bytes()
        .unwrap()
        .to_vec();
    let path = Path::new("run/step-00000001/optimizer.bpk");
    let e = optimizer_from_bytes(AdamConfig::new().init(), bytes, path)
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("optimizer.bpk") && e.contains("corrupt checkpoint"),
        "{e}"
    );
}
