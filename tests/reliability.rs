//! Issue 16: hostile and careless inputs. Each file here is crafted byte by byte (a few hundred
//! bytes at most); none is committed.

mod common;

use hdrsynth::data::layout;
use hdrsynth::data::loader::{Loader, LoaderConfig};
use hdrsynth::io::limits::DecodeLimits;
use hdrsynth::io::{BitDepth, ExrPrecision, Image, read_image, write_exr, write_ldr};
use std::path::{Path, PathBuf};

// ---------------------------------------------------------------------------------------------
// Item 1: decompression bombs. Every file declares 100000×100000 pixels (120 GB as f32 RGB);
// before the limits, each aborted the process on the pixel buffer's allocation.

const BOMB: u32 = 100_000;

fn png_chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend((data.len() as u32).to_be_bytes());
    let mut body = kind.to_vec();
    body.extend(data);
    out.extend(&body);
    out.extend(common::crc32(&body).to_be_bytes());
}

fn bomb_png(w: u32, h: u32) -> Vec<u8> {
    let mut out = vec![0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a];
    let mut ihdr = Vec::new();
    ihdr.extend(w.to_be_bytes());
    ihdr.extend(h.to_be_bytes());
    ihdr.extend([8, 2, 0, 0, 0]); // 8-bit RGB, deflate, adaptive filter, no interlace
    png_chunk(&mut out, b"IHDR", &ihdr);
    // A zlib stream of a few zero bytes: far too short, but the size is what must be refused.
    png_chunk(
        &mut out,
        b"IDAT",
        &[0x78, 0x9c, 0x63, 0x00, 0x00, 0x00, 0x01, 0x00, 0x01],
    );
    png_chunk(&mut out, b"IEND", &[]);
    out
}

/// A little-endian classic TIFF with one IFD of (tag, type, count, inline value) entries and
/// `data` after it; entries' values must fit in 4 bytes.
fn tiff_with(entries: &[(u16, u16, u32, u32)], data: &[u8]) -> Vec<u8> {
    let mut out = b"II".to_vec();
    out.extend(42u16.to_le_bytes());
    out.extend(8u32.to_le_bytes());
    out.extend((entries.len() as u16).to_le_bytes());
    for &(tag, typ, count, val) in entries {
        out.extend(tag.to_le_bytes());
        out.extend(typ.to_le_bytes());
        out.extend(count.to_le_bytes());
        if typ == 3 {
            out.extend((val as u16).to_le_bytes());
            out.extend([0, 0]);
        } else {
            out.extend(val.to_le_bytes());
        }
    }
    out.extend(0u32.to_le_bytes());
    out.extend(data);
    out
}

fn data_offset(entries: usize) -> u32 {
    (8 + 2 + 12 * entries + 4) as u32
}

fn bomb_tiff() -> Vec<u8> {
    let n = 9;
    tiff_with(
        &[
            (256, 4, 1, BOMB),           // ImageWidth
            (257, 4, 1, BOMB),           // ImageLength
            (258, 3, 1, 8),              // BitsPerSample (one value: all channels)
            (259, 3, 1, 1),              // no compression
            (262, 3, 1, 1),              // BlackIsZero grey
            (273, 4, 1, data_offset(n)), // StripOffsets
            (277, 3, 1, 1),              // SamplesPerPixel
            (278, 4, 1, BOMB),           // RowsPerStrip
            (279, 4, 1, 16),             // StripByteCounts
        ],
        &[0u8; 16],
    )
}

fn bomb_dng() -> Vec<u8> {
    // The DNG reader accepts up to 65536 per side in its header checks; 60000² of 16-bit
    // samples is 7.2 GB of raw buffer.
    let side = 60_000;
    let n = 12;
    let mut d = tiff_with(
        &[
            (254, 4, 1, 0),              // NewSubfileType: main image
            (256, 4, 1, side),           // ImageWidth
            (257, 4, 1, side),           // ImageLength
            (258, 3, 1, 16),             // BitsPerSample
            (259, 3, 1, 1),              // no compression
            (262, 3, 1, 32803),          // CFA
            (273, 4, 1, data_offset(n)), // StripOffsets
            (277, 3, 1, 1),              // SamplesPerPixel
            (278, 4, 1, side),           // RowsPerStrip
            (279, 4, 1, 16),             // StripByteCounts
            (33421, 3, 2, 2 | (2 << 16)),
            (33422, 1, 4, u32::from_le_bytes([0, 1, 1, 2])), // RGGB
        ],
        &[0u8; 16],
    );
    // Type-3 entries with count 2 keep both shorts inline: rewrite the CFARepeatPatternDim
    // value field as two little-endian shorts (tiff_with wrote only the low one).
    let entry = 8 + 2 + 12 * 10;
    d[entry + 8..entry + 12].copy_from_slice(&[2, 0, 2, 0]);
    d
}

fn bomb_hdr() -> Vec<u8> {
    let mut b = format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {BOMB} +X {BOMB}\n").into_bytes();
    b.extend([0u8; 32]);
    b
}

/// A 1×1 EXR written by the crate, its dataWindow rewritten to (0,0)–(99999,99999).
fn bomb_exr(dir: &Path) -> Vec<u8> {
    let p = dir.join("one.exr");
    write_exr(&p, &Image::new(1, 1), ExrPrecision::Half).unwrap();
    let mut b = std::fs::read(&p).unwrap();
    let key = b"dataWindow\0box2i\0";
    let at = b
        .windows(key.len())
        .position(|w| w == key)
        .expect("dataWindow attribute")
        + key.len()
        + 4; // attribute size
    let max = (BOMB - 1).to_le_bytes();
    b[at + 8..at + 12].copy_from_slice(&max);
    b[at + 12..at + 16].copy_from_slice(&max);
    b
}

fn assert_refused(path: &Path, e: &str) {
    let name = path.file_name().unwrap().to_string_lossy();
    assert!(
        e.contains(&*name) && e.contains("decode limit"),
        "error should name {name} and the decode limit: {e}"
    );
}

#[test]
fn decompression_bombs_are_refused_by_every_decoder_with_the_file_named() {
    let dir = tempfile::tempdir().unwrap();
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("bomb.png", bomb_png(BOMB, BOMB)),
        ("bomb.tif", bomb_tiff()),
        ("bomb.hdr", bomb_hdr()),
        ("bomb.exr", bomb_exr(dir.path())),
    ];
    for (name, bytes) in cases {
        assert!(bytes.len() < 1024, "{name} is a tiny file");
        let p = dir.path().join(name);
        std::fs::write(&p, &bytes).unwrap();
        let e = read_image(&p).expect_err(name).to_string();
        assert_refused(&p, &e);
    }
    let p = dir.path().join("bomb.dng");
    std::fs::write(&p, bomb_dng()).unwrap();
    let e = hdrsynth::sensor::dng::read_dng(&p)
        .expect_err("dng bomb")
        .to_string();
    assert_refused(&p, &e);
}

#[test]
fn the_side_limit_alone_refuses_a_long_thin_png() {
    // 20000×1 is only 240 kB decoded but over 16384 per side.
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("thin.png");
    std::fs::write(&p, bomb_png(20_000, 1)).unwrap();
    assert_refused(&p, &read_image(&p).unwrap_err().to_string());
}

#[test]
fn decode_limits_default_parse_and_check_by_hand() {
    let d = DecodeLimits::parse(None, None).unwrap();
    assert_eq!((d.max_side, d.max_decoded_bytes), (16384, 1 << 30));
    let l = DecodeLimits::parse(Some("100"), Some("2M")).unwrap();
    assert_eq!((l.max_side, l.max_decoded_bytes), (100, 2 * 1024 * 1024));
    for bad in ["", "0", "-5", "12x", "1.5G"] {
        let e = DecodeLimits::parse(Some(bad), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("HDRSYNTH_MAX_IMAGE_SIDE"), "{bad:?}: {e}");
    }
    let p = Path::new("f.png");
    // 100×100 f32 RGB = 120000 bytes: the byte limit is inclusive.
    let l = DecodeLimits {
        max_side: 100,
        max_decoded_bytes: 120_000,
    };
    assert!(l.check(p, "PNG", 100, 100).is_ok());
    assert!(l.check(p, "PNG", 101, 1).is_err());
    let l = DecodeLimits {
        max_side: 100,
        max_decoded_bytes: 119_999,
    };
    assert!(l.check(p, "PNG", 100, 100).is_err());
    // A 4032×3024 phone frame (146 MB) passes the defaults.
    assert!(d.check(p, "PNG", 4032, 3024).is_ok());
}

// ---------------------------------------------------------------------------------------------
// Item 2: frame sizes are checked against the set, never trusted from meta.toml.

fn static_pngs(set: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(set.join("static"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            let n = p.file_name().unwrap().to_string_lossy();
            n.starts_with("ev") && n.ends_with(".png")
        })
        .collect();
    v.sort();
    v
}

fn pure_loader(dir: &Path, kind: &str) -> LoaderConfig {
    let text = format!(
        "dataset = {dir:?}\nkind = \"{kind}\"\npatch = 48\nbatch_size = 1\nworkers = 1\nseed = 9\n"
    );
    hdrsynth::config::parse_toml(&text, Path::new("loader.toml")).unwrap()
}

#[test]
fn a_frame_smaller_than_its_set_is_an_error_naming_it_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    common::generate(dir.path(), 3, 1, (96, 80), "[-3.0, -2.0, 0.0, 2.0, 3.0]");
    let set = common::first_set(dir.path());
    let frames = static_pngs(&set);
    assert_eq!(frames.len(), 5);
    // Every static frame 60×50: any crop of a 96×80 set (patch 48) reaches past it.
    for f in &frames {
        write_ldr(f, &Image::new(60, 50), BitDepth::Eight).unwrap();
    }
    for kind in ["network1", "network2"] {
        let l = Loader::new(&pure_loader(dir.path(), kind)).unwrap();
        let e = l.sample(0, 0).expect_err(kind).to_string();
        assert!(
            e.contains("60×50") && e.contains("96×80") && e.contains("static"),
            "{kind}: {e}"
        );
    }
}

#[test]
fn a_larger_frame_is_refused_rather_than_silently_cropped() {
    let dir = tempfile::tempdir().unwrap();
    common::generate(dir.path(), 3, 1, (96, 80), "[-3.0, -2.0, 0.0, 2.0, 3.0]");
    let set = common::first_set(dir.path());
    for f in static_pngs(&set) {
        write_ldr(&f, &Image::new(128, 96), BitDepth::Eight).unwrap();
    }
    let l = Loader::new(&pure_loader(dir.path(), "network1")).unwrap();
    let e = l.sample(0, 0).unwrap_err().to_string();
    assert!(e.contains("128×96"), "{e}");
}

#[test]
fn verify_decodes_every_file_and_lists_truncated_empty_and_wrong_size_ones() {
    let dir = tempfile::tempdir().unwrap();
    common::generate(dir.path(), 4, 1, (64, 48), "[-3.0, 0.0, 3.0]");
    let set = common::first_set(dir.path());
    let info = layout::detect(dir.path()).unwrap();
    assert!(layout::verify(&info).is_empty(), "a fresh dataset verifies");

    let frames = static_pngs(&set);
    let bytes = std::fs::read(&frames[0]).unwrap();
    std::fs::write(&frames[0], &bytes[..bytes.len() / 2]).unwrap(); // truncated
    std::fs::write(&frames[1], b"").unwrap(); // 0 bytes
    write_ldr(&frames[2], &Image::new(32, 48), BitDepth::Eight).unwrap(); // wrong size
    // `info` without --verify reads only the metadata, so detection still succeeds.
    let info = layout::detect(dir.path()).unwrap();
    let mut bad: Vec<PathBuf> = layout::verify(&info).into_iter().map(|(p, _)| p).collect();
    bad.sort();
    assert_eq!(bad, frames);
}

// ---------------------------------------------------------------------------------------------
// Items 3–5: outputs outside inputs, one writer per output, nothing half-written.

use hdrsynth::data::testset::{self, TestsetOptions};
use hdrsynth::eval::evaluate::{self, EvalOptions, Network2};
use hdrsynth::io::guard::{self, OutputLock};
use hdrsynth::sensor::profile::SensorProfile;
use hdrsynth::sensor::realism::NoiseModel;

#[test]
fn outputs_inside_inputs_are_refused_however_spelled() {
    let dir = tempfile::tempdir().unwrap();
    let x = dir.path().join("x");
    std::fs::create_dir_all(x.join("sub")).unwrap();
    std::os::unix::fs::symlink(&x, dir.path().join("link")).unwrap();
    for out in [
        x.clone(),
        x.join("out"),
        x.join("sub/../new"),
        dir.path().join("link/out"),
        dir.path().join("y/../x"),
    ] {
        let e = guard::refuse_output_inside(&x, &out).expect_err(&out.display().to_string());
        assert!(e.to_string().contains("input"), "{e}");
    }
    assert!(guard::refuse_output_inside(&x, &dir.path().join("y")).is_ok());
    assert!(guard::refuse_output_inside(&x, &dir.path().join("x2")).is_ok());
}

#[test]
fn the_folder_walk_ends_on_a_symlink_loop_and_lists_each_file_once() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a");
    std::fs::create_dir_all(a.join("b")).unwrap();
    write_ldr(&a.join("b/f.png"), &Image::new(2, 2), BitDepth::Eight).unwrap();
    // a/b/loop → a: the old walk followed it without end (41 nested copies in the issue).
    std::os::unix::fs::symlink(&a, a.join("b/loop")).unwrap();
    let files = guard::images_under(&a).unwrap();
    assert_eq!(files, vec![a.join("b/f.png")]);
}

fn bin() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_hdrsynth"))
}

#[test]
fn realism_refuses_to_write_into_its_input() {
    let dir = tempfile::tempdir().unwrap();
    let x = dir.path().join("x");
    write_ldr(&x.join("f.png"), &Image::new(8, 8), BitDepth::Eight).unwrap();
    let before = std::fs::read(x.join("f.png")).unwrap();
    let profile = SensorProfile::shipped_dir().join("example_synthetic.toml");
    for out in [x.clone(), x.join("out")] {
        let o = bin()
            .args(["realism", "--iso", "100", "--profile"])
            .arg(&profile)
            .arg("--in")
            .arg(&x)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains("input"), "{err}");
    }
    assert_eq!(std::fs::read(x.join("f.png")).unwrap(), before);
    assert!(!x.join("out").exists());
}

#[test]
fn a_second_writer_is_refused_and_a_killed_holder_does_not_block() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("data");
    let held = OutputLock::acquire(&out, "test").unwrap();
    let e = OutputLock::acquire(&out, "second").unwrap_err().to_string();
    assert!(
        e.contains("in use") && e.contains(&format!("pid {}", std::process::id())),
        "{e}"
    );
    // generate takes the same lock: a second generator into the folder is refused.
    let cfg: hdrsynth::data::generate::GenerateConfig = hdrsynth::config::parse_toml(
        "seed = 1\ncount = 1\nwidth = 32\nheight = 32\nevs = [-3.0, 0.0]\n",
        Path::new("g.toml"),
    )
    .unwrap();
    let e = hdrsynth::data::generate::generate(&cfg, &out, false).unwrap_err();
    assert!(format!("{e:#}").contains("in use"), "{e:#}");
    drop(held);
    OutputLock::acquire(&out, "after").expect("released on drop");

    // Another process holds the lock, then dies by SIGKILL: the OS releases it.
    std::fs::create_dir_all(&out).unwrap();
    let lock_file = out.join(guard::LOCK_FILE);
    // `-o`: flock itself holds the lock and its `sleep` child does not inherit it, so killing
    // flock kills the only holder (the orphaned sleep exits on its own).
    let Ok(mut child) = std::process::Command::new("flock")
        .arg("-o")
        .arg(&lock_file)
        .args(["sleep", "20"])
        .spawn()
    else {
        eprintln!("skipped the cross-process half: util-linux `flock` is absent");
        return;
    };
    let t0 = std::time::Instant::now();
    while OutputLock::acquire(&out, "probe").is_ok() {
        assert!(t0.elapsed().as_secs() < 10, "flock never took the lock");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    OutputLock::acquire(&out, "after kill").expect("a dead holder's lock is released");
}

// Every writer refuses an output folder another holds. The test holds the lock through the
// library's `OutputLock` (flock is per open file, so a second open in this process conflicts
// as another process's would), calls the command, and checks the error names the folder and
// that nothing in it changed (the holder's lock file included).

/// Every file under `dir` with its bytes.
fn snapshot(dir: &Path) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                todo.push(p);
            } else {
                out.insert(p.clone(), std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

/// A locked output folder holding one earlier result; returns the lock and the folder's state.
fn locked_output(out: &Path) -> (OutputLock, std::collections::BTreeMap<PathBuf, Vec<u8>>) {
    std::fs::create_dir_all(out).unwrap();
    std::fs::write(out.join("earlier.txt"), "an earlier run's output").unwrap();
    let held = OutputLock::acquire(out, "holder").unwrap();
    let before = snapshot(out);
    (held, before)
}

fn assert_refused_lock(out: &Path, e: &str, before: &std::collections::BTreeMap<PathBuf, Vec<u8>>) {
    assert!(
        e.contains("in use by another hdrsynth process")
            && e.contains(&out.display().to_string())
            && e.contains("holder"),
        "{e}"
    );
    assert_eq!(
        &snapshot(out),
        before,
        "the refused writer changed {}",
        out.display()
    );
    let partial = out.with_file_name(format!(
        ".{}.partial",
        out.file_name().unwrap().to_string_lossy()
    ));
    assert!(
        !partial.exists(),
        "the refused writer staged {}",
        partial.display()
    );
}

#[test]
fn eval_refuses_a_locked_output() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    common::generate(&data, 6, 1, (48, 32), "[-2.0, 0.0, 2.0]");
    let out = dir.path().join("eval");
    let (_held, before) = locked_output(&out);
    let method = Network2 {
        description: "identity".into(),
        infer: Box::new(|frames: [&Image; 3], _| Ok(frames[1].clone())),
    };
    let opts = EvalOptions {
        progress: false,
        ..EvalOptions::default()
    };
    let e = evaluate::evaluate(&data, &method, &out, &opts).expect_err("locked");
    assert_refused_lock(&out, &e.to_string(), &before);
}

#[test]
fn testset_refuses_a_locked_output() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("radiance");
    std::fs::create_dir_all(&src).unwrap();
    let ramp = Image::from_fn(24, 16, |x, _| [(x as f32 / 3.0 - 4.0).exp2(); 3]);
    write_exr(&src.join("a.exr"), &ramp, ExrPrecision::Float).unwrap();
    let opts = TestsetOptions {
        isos: vec![100.0],
        noise: NoiseModel::None,
        ..TestsetOptions::default()
    };
    let profile =
        SensorProfile::load(&SensorProfile::shipped_dir().join("canon_eos_550d.toml")).unwrap();
    let out = dir.path().join("ts");
    let (_held, before) = locked_output(&out);
    let e = testset::build(&src, &profile, &opts, &out).expect_err("locked");
    assert_refused_lock(&out, &e.to_string(), &before);
}

#[test]
fn a_bracket_testset_refuses_a_locked_output() {
    use hdrsynth::data::bracket_testset::{self, BracketOptions, ResponseChoice};
    use hdrsynth::sensor::profile::Response;
    let dir = tempfile::tempdir().unwrap();
    let brackets = dir.path().join("brackets");
    std::fs::create_dir_all(&brackets).unwrap();
    let opts = BracketOptions {
        scan: Default::default(),
        response: ResponseChoice::Declared(Response::Srgb),
        align: None,
        ..BracketOptions::default()
    };
    let out = dir.path().join("ts");
    let (held, before) = locked_output(&out);
    let e = bracket_testset::build(&brackets, &opts, &out).expect_err("locked");
    assert_refused_lock(&out, &e.to_string(), &before);
    drop(held);
}

#[test]
fn ablate_refuses_a_locked_output() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    std::fs::create_dir_all(root.join("testset")).unwrap();
    std::fs::write(root.join("base.toml"), "[run]\nsteps = 1\n").unwrap();
    let cfg_path = root.join("grid.toml");
    std::fs::write(
        &cfg_path,
        format!(
            "title = \"t\"\nout = {:?}\nbase = {:?}\n[testset]\ndir = {:?}\n\
             [[rows]]\nname = \"a\"\nlabel = \"A\"\nset = {{ optim = {{ lr = 1e-3 }} }}\n",
            root.join("grid"),
            root.join("base.toml"),
            root.join("testset"),
        ),
    )
    .unwrap();
    let cfg = hdrsynth::eval::ablate::AblateConfig::load(&cfg_path).unwrap();
    let (_held, before) = locked_output(&cfg.out);
    let e = hdrsynth::eval::ablate::run(&cfg, &cfg_path, false).expect_err("locked");
    assert_refused_lock(&cfg.out, &e.to_string(), &before);
}

/// The commands whose folder logic sits in the CLI (realism, infer, diagnose, quickstart),
/// through the binary: another process, as a user would run it. Each must be refused at once;
/// a command that ignored the lock would run on (quickstart for minutes), so it is killed
/// after 60 s and the test fails.
#[test]
fn the_cli_writers_refuse_a_locked_output() {
    let dir = tempfile::tempdir().unwrap();
    let x = dir.path().join("x");
    write_ldr(&x.join("f.png"), &Image::new(8, 8), BitDepth::Eight).unwrap();
    let profile = SensorProfile::shipped_dir().join("example_synthetic.toml");
    let out = dir.path().join("out");
    let (_held, before) = locked_output(&out);
    let p = |p: &Path| p.display().to_string();
    let commands: Vec<Vec<String>> = vec![
        vec![
            "realism".into(),
            "--iso".into(),
            "100".into(),
            "--profile".into(),
            p(&profile),
            "--in".into(),
            p(&x),
            "--out".into(),
            p(&out),
        ],
        vec![
            "infer".into(),
            "--checkpoint".into(),
            p(&dir.path().join("run")),
            "--inputs".into(),
            p(&x.join("f.png")),
            p(&x.join("f.png")),
            "--out".into(),
            p(&out),
        ],
        vec![
            "diagnose".into(),
            p(&dir.path().join("captures.toml")),
            "--out".into(),
            p(&out),
        ],
        vec![
            "quickstart".into(),
            "--quiet".into(),
            "--out".into(),
            p(&out),
        ],
    ];
    for args in commands {
        let mut child = bin()
            .args(&args)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let t0 = std::time::Instant::now();
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            if t0.elapsed().as_secs() > 60 {
                child.kill().unwrap();
                child.wait().unwrap();
                panic!("`hdrsynth {}` ignored the lock and ran on", args[0]);
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        };
        let mut err = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
        assert!(!status.success(), "{}: {err}", args[0]);
        assert_refused_lock(&out, &err, &before);
    }
}

#[test]
fn a_failed_eval_leaves_no_output_folder() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    common::generate(&data, 6, 2, (48, 32), "[-2.0, 0.0, 2.0]");
    let calls = std::sync::atomic::AtomicUsize::new(0);
    // Scores the first set, fails on the second: the old code left the first set's files.
    let method = Network2 {
        description: "fails on the second set".into(),
        infer: Box::new(move |frames: [&Image; 3], _| {
            if calls.fetch_add(1, std::sync::atomic::Ordering::SeqCst) == 1 {
                return Err(hdrsynth::error::Error::Invalid("crafted failure".into()));
            }
            Ok(frames[1].clone())
        }),
    };
    let out = dir.path().join("eval");
    let opts = EvalOptions {
        progress: false,
        ..EvalOptions::default()
    };
    evaluate::evaluate(&data, &method, &out, &opts).expect_err("second set fails");
    assert!(!out.exists(), "no partial eval output");
    assert!(
        !dir.path().join(".eval.partial").exists(),
        "staging removed"
    );
}

/// realism stages its output: a corrupt frame after a good one (file-name order) leaves no
/// output folder and no staging folder, where the issue found the good frame written.
#[test]
fn a_failed_realism_leaves_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let x = dir.path().join("x");
    write_ldr(&x.join("a.png"), &Image::new(8, 8), BitDepth::Eight).unwrap();
    std::fs::write(x.join("b.png"), b"not a png").unwrap();
    let out = dir.path().join("out");
    let profile = SensorProfile::shipped_dir().join("example_synthetic.toml");
    let o = bin()
        .args(["realism", "--iso", "100", "--profile"])
        .arg(&profile)
        .arg("--in")
        .arg(&x)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("b.png"), "{err}");
    assert!(!out.exists(), "realism left a partial output");
    assert!(
        !dir.path().join(".out.partial").exists(),
        "staging left behind"
    );
}

#[test]
fn a_testset_failing_on_its_second_file_leaves_nothing_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("radiance");
    std::fs::create_dir_all(&src).unwrap();
    let ramp = Image::from_fn(24, 16, |x, _| [(x as f32 / 3.0 - 4.0).exp2(); 3]);
    write_exr(&src.join("a.exr"), &ramp, ExrPrecision::Float).unwrap();
    std::fs::write(src.join("b.exr"), b"not an exr").unwrap();
    let opts = TestsetOptions {
        isos: vec![100.0],
        evs: vec![-2.0, 0.0, 2.0],
        noise: NoiseModel::None,
        ..TestsetOptions::default()
    };
    let profile =
        SensorProfile::load(&SensorProfile::shipped_dir().join("canon_eos_550d.toml")).unwrap();
    let out = dir.path().join("ts");
    let e = testset::build(&src, &profile, &opts, &out)
        .unwrap_err()
        .to_string();
    assert!(e.contains("b.exr"), "{e}");
    assert!(!out.exists(), "the old code left a 1-set test set here");
    assert!(layout::detect(&out).is_err());
    // Fixed input, same command: the staged first set is kept, the second added.
    write_exr(&src.join("b.exr"), &ramp, ExrPrecision::Float).unwrap();
    let s = testset::build(&src, &profile, &opts, &out).unwrap();
    let written: Vec<bool> = s.sets.iter().map(|s| s.written).collect();
    assert_eq!(written, vec![false, true]);
    assert_eq!(layout::detect(&out).unwrap().sets.len(), 2);
    // An output inside the radiance folder is refused.
    let e = testset::build(&src, &profile, &opts, &src.join("ts"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("inside the input"), "{e}");
}

// ---------------------------------------------------------------------------------------------
// Item 6: values that make no sense are errors naming the key and the file.

fn write_cfg(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn nonsense_generate_values_are_errors_naming_key_and_file() {
    let dir = tempfile::tempdir().unwrap();
    let base = "seed = 1\ncount = 1\nwidth = 32\nheight = 32\n";
    for (key, extra) in [
        ("evs", "evs = [-300.0, 0.0]\n"),
        (
            "camera.candidates",
            "evs = [-3.0, 0.0]\n[camera]\ncandidates = 0\n",
        ),
        (
            "scene.min_dynamic_range",
            "evs = [-3.0, 0.0]\n[scene]\nmin_dynamic_range = 1000.0\n",
        ),
        (
            "scene.real_background_probability",
            "evs = [-3.0, 0.0]\n[scene]\nreal_background_probability = 1.0\n",
        ),
    ] {
        let p = write_cfg(dir.path(), "g.toml", &format!("{base}{extra}"));
        let e = hdrsynth::data::generate::GenerateConfig::load(&p)
            .expect_err(key)
            .to_string();
        assert!(e.contains(key) && e.contains("g.toml"), "{key}: {e}");
    }
    // The shipped configs (probability 0.5, backgrounds commented out) stay valid.
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/generate.toml");
    hdrsynth::data::generate::GenerateConfig::load(&shipped).expect("configs/generate.toml");
}

#[test]
fn nonsense_optimiser_values_are_errors_naming_key_and_file() {
    let dir = tempfile::tempdir().unwrap();
    for (key, line) in [
        ("optim.epsilon", "epsilon = -1.0"),
        ("optim.weight_decay", "weight_decay = -5.0"),
    ] {
        let text = format!(
            "[run]\nout = \"r\"\nseed = 1\nsteps = 2\ncheckpoint_every = 1\nlog_every = 1\n\
             [model]\nkind = \"blend_unet\"\nbase_width = 4\ndepth = 2\nbatch_norm = true\n\
             [data]\ndataset = \"d\"\npatch = 32\nbatch_size = 1\nworkers = 1\n\
             profile = \"pure\"\n[optim]\nlr = 1e-3\n{line}\n"
        );
        let p = write_cfg(dir.path(), "t.toml", &text);
        let e = hdrsynth::train::config::TrainConfig::load(&p)
            .expect_err(key)
            .to_string();
        assert!(e.contains(key) && e.contains("t.toml"), "{key}: {e}");
    }
}

#[test]
fn a_singular_or_zero_colour_matrix_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let canon =
        std::fs::read_to_string(SensorProfile::shipped_dir().join("canon_eos_550d.toml")).unwrap();
    let line = canon
        .lines()
        .find(|l| l.starts_with("matrix = "))
        .expect("the canon profile has a colour matrix");
    for (what, m) in [
        (
            "zero",
            "[[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]",
        ),
        // Third row = first + second: rank 2.
        (
            "singular",
            "[[0.6, 0.3, 0.1], [0.1, 0.7, 0.2], [0.7, 1.0, 0.3]]",
        ),
    ] {
        let p = write_cfg(
            dir.path(),
            "p.toml",
            &canon.replace(line, &format!("matrix = {m}")),
        );
        let e = SensorProfile::load(&p).expect_err(what).to_string();
        assert!(
            e.contains("colour.matrix") && e.contains("singular") && e.contains("p.toml"),
            "{what}: {e}"
        );
    }
    SensorProfile::load(&SensorProfile::shipped_dir().join("canon_eos_550d.toml"))
        .expect("the shipped matrix is fine");
}

// ---------------------------------------------------------------------------------------------
// Item 7: leftovers of a killed run are cleaned; --resume on a finished run succeeds.

#[test]
fn temp_names_are_recognised_exactly() {
    use hdrsynth::io::atomic::is_temp_name;
    for yes in [".latest.4242.tmp", ".ev+0.png.17.tmp"] {
        assert!(is_temp_name(yes), "{yes}");
    }
    for no in [
        "latest.4242.tmp",
        ".latest.tmp",
        ".latest.42x.tmp",
        "..1.tmp",
        "ev0.png",
    ] {
        assert!(!is_temp_name(no), "{no}");
    }
}

#[test]
fn a_finished_run_resumes_to_success_and_leftovers_are_removed() {
    use hdrsynth::train::{TrainOptions, config::TrainConfig};
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    common::generate(&data, 7, 2, (48, 48), "[-3.0, 0.0]");
    let run = dir.path().join("run");
    let text = format!(
        "[run]\nout = {run:?}\nseed = 3\nsteps = 2\ncheckpoint_every = 1\nlog_every = 1\n\
         keep_checkpoints = 1\n[model]\nkind = \"blend_unet\"\nbase_width = 4\ndepth = 2\n\
         batch_norm = true\n[data]\ndataset = {data:?}\npatch = 32\nbatch_size = 1\n\
         workers = 1\nprofile = \"pure\"\n\
         [optim]\nlr = 1e-3\n"
    );
    let cfg: TrainConfig = hdrsynth::config::parse_toml(&text, Path::new("t.toml")).unwrap();
    let quiet = |resume| TrainOptions {
        resume,
        progress: false,
    };
    hdrsynth::train::run(&cfg, &quiet(false)).unwrap();
    let last = hdrsynth::train::checkpoint::latest(&run).unwrap().unwrap();
    let root = last.parent().unwrap().to_path_buf();
    // What kills leave: a save cut short, a prune cut short (old and new style), temp files.
    let leftovers = [
        root.join(".tmp-step-00000009"),
        root.join(".prune-step-00000001"),
        root.join("step-00000001"),
    ];
    for d in &leftovers {
        std::fs::create_dir_all(d).unwrap();
        std::fs::write(d.join("model.mpk"), b"partial").unwrap();
    }
    let temps = [root.join(".latest.4242.tmp"), run.join(".log.jsonl.17.tmp")];
    for t in &temps {
        std::fs::write(t, b"partial").unwrap();
    }
    // The old code refused this with "already at step 2 of 2".
    let s = hdrsynth::train::run(&cfg, &quiet(true)).expect("a finished run resumes to success");
    assert!(s.already_finished && s.start_step == 2, "{s:?}");
    for p in leftovers.iter().chain(&temps) {
        assert!(!p.exists(), "{} should be gone", p.display());
    }
    assert_eq!(
        hdrsynth::train::checkpoint::latest(&run).unwrap().unwrap(),
        last
    );
}
