//! Issue 16 item 8: bounded mutation fuzzing of every parser of outside input. Each target
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

use hdrsynth::io::{BitDepth, ExrPrecision, Image, read_image, write_exr, write_hdr, write_ldr};
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
        let input = mutate(seed, &mut rng, text);
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

fn image_target(name: &str, ext: &str, seeds: impl FnOnce(&Path) -> Vec<Vec<u8>>) {
    let dir = tempfile::tempdir().unwrap();
    let seeds = seeds(dir.path());
    let file = format!("input.{ext}");
    fuzz(
        name,
        &seeds,
        false,
        file_target(dir.path(), &file, |p| {
            let _ = read_image(p);
        }),
    );
}

#[test]
fn fuzz_png() {
    image_target("png", "png", |d| {
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
    image_target("tiff", "tif", |d| {
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
    image_target("hdr", "hdr", |d| {
        vec![
            written(d, "a.hdr", |p| write_hdr(p, &image(6, 5)).unwrap()),
            // Wide enough for the run-length encoded scan lines (8 ≤ width < 32768).
            written(d, "b.hdr", |p| write_hdr(p, &image(12, 3)).unwrap()),
        ]
    });
}

#[test]
fn fuzz_exr() {
    image_target("exr", "exr", |d| {
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
    let dir = tempfile::tempdir().unwrap();
    let seed = small_dng();
    let p = dir.path().join("seed.dng");
    std::fs::write(&p, &seed).unwrap();
    hdrsynth::sensor::dng::read_dng(&p).expect("the seed DNG is valid");
    fuzz(
        "dng",
        &[seed],
        false,
        file_target(dir.path(), "input.dng", |p| {
            let _ = hdrsynth::sensor::dng::read_dng(p);
        }),
    );
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
    text_target::<hdrsynth::config::GenerateConfig>(
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

/// A Kalantari set (three tiny 16-bit TIFFs, exposure.txt, HDRImg.hdr) in `root/set`.
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

#[test]
fn fuzz_exposure_txt_through_the_layout_detector() {
    let dir = tempfile::tempdir().unwrap();
    let set = kalantari(dir.path());
    hdrsynth::data::layout::detect(dir.path()).expect("the seed set is valid");
    let seeds = [b"0\n2\n4\n".to_vec(), b"-2.0\r\n0.0\r\n2.0\r\n".to_vec()];
    fuzz(
        "exposure_txt",
        &seeds,
        true,
        file_target(&set, "exposure.txt", |_| {
            let _ = hdrsynth::data::layout::detect(dir.path());
        }),
    );
}

#[test]
fn fuzz_set_meta_through_the_layout_detector() {
    let dir = tempfile::tempdir().unwrap();
    common::generate(dir.path(), 2, 1, (16, 16), "[-2.0, 0.0, 2.0]");
    let set = common::first_set(dir.path());
    let meta = set.join("meta.toml");
    let seeds = [std::fs::read(&meta).unwrap()];
    let manifest = dir.path().join("dataset.toml");
    let manifest_seed = std::fs::read(&manifest).unwrap();
    fuzz(
        "meta_toml",
        &seeds,
        true,
        file_target(&set, "meta.toml", |_| {
            let _ = hdrsynth::data::layout::detect(dir.path());
        }),
    );
    std::fs::write(&meta, &seeds[0]).unwrap();
    fuzz(
        "dataset_toml",
        &[manifest_seed],
        true,
        file_target(dir.path(), "dataset.toml", |_| {
            let _ = hdrsynth::data::layout::detect(dir.path());
        }),
    );
}
