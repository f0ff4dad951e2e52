//! Hostile and careless inputs, and runs cut short: crafted files (a few hundred bytes at most,
//! made here, none committed), resumed and repeated training runs, corrupted checkpoints,
//! FIFOs where files belong, and non-finite or out-of-range config values. docs/reliability.md lists the
//! classes and the test of each.

mod common;

use hdrsynth::capture::linearise::ResponseChoice;
use hdrsynth::data::layout;
use hdrsynth::data::loader::{Loader, LoaderConfig};
use hdrsynth::io::limits::DecodeLimits;
use hdrsynth::io::{BitDepth, ExrPrecision, Image, read_image, write_exr, write_ldr};
use std::path::{Path, PathBuf};

// ---------------------------------------------------------------------------------------------
// Decompression bombs. Every file declares 100000×100000 pixels (120 GB as f32 RGB);
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
// Frame sizes are checked against the set, never trusted from meta.toml.

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
// Outputs outside inputs, one writer per output, nothing half-written.

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
    // a/b/loop → a: the old walk followed it without end (41 nested copies).
    std::os::unix::fs::symlink(&a, a.join("b/loop")).unwrap();
    let files = guard::images_under(&a).unwrap();
    assert_eq!(files, vec![a.join("b/f.png")]);
}

fn bin() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_hdrsynth"))
}

/// `hdrsynth realism --iso 100 --profile PROFILE --in INPUT --out OUT`.
fn realism_cmd(profile: &Path, input: &Path, out: &Path) -> std::process::Command {
    let mut c = bin();
    c.args(["realism", "--iso", "100", "--profile"])
        .arg(profile)
        .arg("--in")
        .arg(input)
        .arg("--out")
        .arg(out);
    c
}

/// The shipped synthetic example profile (no real device's numbers).
fn example_profile() -> PathBuf {
    SensorProfile::shipped_dir().join("example_synthetic.toml")
}

/// Run `cmd` to its end and return its status and stderr; a run still going after `secs` is
/// killed and fails the test as `what` (a command that waits on a FIFO or ignores a lock).
fn finish_within(
    mut cmd: std::process::Command,
    secs: u64,
    what: &str,
) -> (std::process::ExitStatus, String) {
    let mut child = cmd
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawn");
    // stderr is read on a thread so that a chatty child cannot block on a full pipe.
    let mut pipe = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut err = String::new();
        let _ = std::io::Read::read_to_string(&mut pipe, &mut err);
        err
    });
    let t0 = std::time::Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t0.elapsed().as_secs() > secs {
            child.kill().unwrap();
            child.wait().unwrap();
            panic!("{what}: still running after {secs} s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    (status, reader.join().unwrap())
}

#[test]
fn realism_refuses_to_write_into_its_input() {
    let dir = tempfile::tempdir().unwrap();
    let x = dir.path().join("x");
    write_ldr(&x.join("f.png"), &Image::new(8, 8), BitDepth::Eight).unwrap();
    let before = std::fs::read(x.join("f.png")).unwrap();
    for out in [x.clone(), x.join("out")] {
        let o = realism_cmd(&example_profile(), &x, &out).output().unwrap();
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
    let mut child = std::process::Command::new("flock")
        .arg("-o")
        .arg(&lock_file)
        .args(["sleep", "20"])
        .spawn()
        .expect("util-linux `flock` runs (the cross-process half of this test needs it)");
    let t0 = std::time::Instant::now();
    while OutputLock::acquire(&out, "probe").is_ok() {
        assert!(t0.elapsed().as_secs() < 10, "flock never took the lock");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    // flock forks its `sleep` before that child closes the inherited descriptor: killed in
    // that window, the child still shares the lock for the moment it takes to close it.
    let t0 = std::time::Instant::now();
    while let Err(e) = OutputLock::acquire(&out, "after kill") {
        assert!(
            t0.elapsed().as_secs() < 5,
            "a dead holder's lock is released: {e}"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
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
        infer: Box::new(|frames: [&Image; 3], _, _| Ok(frames[1].clone())),
    };
    let opts = EvalOptions {
        progress: false,
        ..EvalOptions::default()
    };
    let e = evaluate::evaluate(&data, &method, &out, &opts).expect_err("locked");
    assert_refused_lock(&out, &e.to_string(), &before);
}

/// A 24×16 radiance ramp over 8 stops.
fn radiance_ramp() -> Image {
    Image::from_fn(24, 16, |x, _| [(x as f32 / 3.0 - 4.0).exp2(); 3])
}

/// `dir/radiance` holding the ramp as `a.exr`; test-set options at ISO 100 without noise; the
/// shipped Canon profile.
fn testset_inputs(dir: &Path) -> (PathBuf, TestsetOptions, SensorProfile) {
    let src = dir.join("radiance");
    std::fs::create_dir_all(&src).unwrap();
    write_exr(&src.join("a.exr"), &radiance_ramp(), ExrPrecision::Float).unwrap();
    let opts = TestsetOptions {
        isos: vec![100.0],
        noise: NoiseModel::None,
        ..TestsetOptions::default()
    };
    let profile =
        SensorProfile::load(&SensorProfile::shipped_dir().join("canon_eos_550d.toml")).unwrap();
    (src, opts, profile)
}

#[test]
fn testset_refuses_a_locked_output() {
    let dir = tempfile::tempdir().unwrap();
    let (src, opts, profile) = testset_inputs(dir.path());
    let out = dir.path().join("ts");
    let (_held, before) = locked_output(&out);
    let e = testset::build(&src, &profile, &opts, &out).expect_err("locked");
    assert_refused_lock(&out, &e.to_string(), &before);
}

#[test]
fn a_bracket_testset_refuses_a_locked_output() {
    use hdrsynth::capture::linearise::ResponseChoice;
    use hdrsynth::capture::testset::{self, BracketOptions};
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
    let e = testset::build(&brackets, &opts, &out).expect_err("locked");
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
    let cfg = hdrsynth::experiments::ablate::AblateConfig::load(&cfg_path).unwrap();
    let (_held, before) = locked_output(&cfg.out);
    let e = hdrsynth::experiments::ablate::run(&cfg, &cfg_path, false).expect_err("locked");
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
    let out = dir.path().join("out");
    let (_held, before) = locked_output(&out);
    let mut infer = bin();
    infer
        .args(["infer", "--checkpoint"])
        .arg(dir.path().join("run"))
        .arg("--inputs")
        .args([x.join("f.png"), x.join("f.png")])
        .arg("--out")
        .arg(&out);
    let mut diagnose = bin();
    diagnose
        .arg("diagnose")
        .arg(dir.path().join("captures.toml"))
        .arg("--out")
        .arg(&out);
    let mut quickstart = bin();
    quickstart
        .args(["quickstart", "--quiet", "--out"])
        .arg(&out);
    let commands = [
        ("realism", realism_cmd(&example_profile(), &x, &out)),
        ("infer", infer),
        ("diagnose", diagnose),
        ("quickstart", quickstart),
    ];
    for (what, cmd) in commands {
        let (status, err) = finish_within(cmd, 60, &format!("{what} ignored the lock"));
        assert!(!status.success(), "{what}: {err}");
        assert_refused_lock(&out, &err, &before);
    }
}

#[test]
fn a_failed_eval_leaves_no_output_folder() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    common::generate(&data, 6, 2, (48, 32), "[-2.0, 0.0, 2.0]");
    let calls = std::sync::atomic::AtomicUsize::new(0);
    // Scores the first set, fails on the second: the first set's files must not be left.
    let method = Network2 {
        description: "fails on the second set".into(),
        infer: Box::new(move |frames: [&Image; 3], _, _| {
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
/// output folder and no staging folder, not the good frame written.
#[test]
fn a_failed_realism_leaves_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let x = dir.path().join("x");
    write_ldr(&x.join("a.png"), &Image::new(8, 8), BitDepth::Eight).unwrap();
    std::fs::write(x.join("b.png"), b"not a png").unwrap();
    let out = dir.path().join("out");
    let o = realism_cmd(&example_profile(), &x, &out).output().unwrap();
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
    let (src, mut opts, profile) = testset_inputs(dir.path());
    std::fs::write(src.join("b.exr"), b"not an exr").unwrap();
    opts.evs = vec![-2.0, 0.0, 2.0];
    let out = dir.path().join("ts");
    let e = testset::build(&src, &profile, &opts, &out)
        .unwrap_err()
        .to_string();
    assert!(e.contains("b.exr"), "{e}");
    assert!(!out.exists(), "a 1-set test set was left here");
    assert!(layout::detect(&out).is_err());
    // Fixed input, same command: the staged first set is kept, the second added.
    write_exr(&src.join("b.exr"), &radiance_ramp(), ExrPrecision::Float).unwrap();
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
// Values that make no sense are errors naming the file, the line and the key.

fn write_cfg(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// What a shipped config file is, by its top-level keys.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Train,
    Generate,
    Profile,
    Ablate,
}

/// Every file under configs/ with its kind; a file of no known kind fails the test, so a new
/// kind of config cannot slip past the tests below.
fn shipped_configs() -> Vec<(PathBuf, Kind)> {
    let mut todo = vec![Path::new(env!("CARGO_MANIFEST_DIR")).join("configs")];
    let mut out = Vec::new();
    while let Some(dir) = todo.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let p = entry.unwrap().path();
            if p.is_dir() {
                todo.push(p);
                continue;
            }
            let doc: toml::Table = toml::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
            let kind = if doc.contains_key("run") {
                Kind::Train
            } else if doc.contains_key("base") {
                Kind::Ablate
            } else if doc.contains_key("levels") {
                Kind::Profile
            } else if doc.contains_key("count") {
                Kind::Generate
            } else {
                panic!("{}: a config of no known kind", p.display())
            };
            out.push((p, kind));
        }
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

/// The key paths (`a.b[2]`) of every number in `v`, each with whether it is an integer.
fn numbers(v: &toml::Value, key: &str, out: &mut Vec<(String, bool)>) {
    match v {
        toml::Value::Float(_) => out.push((key.to_string(), false)),
        toml::Value::Integer(_) => out.push((key.to_string(), true)),
        toml::Value::Table(t) => {
            for (k, x) in t {
                let k = match key {
                    "" => k.clone(),
                    _ => format!("{key}.{k}"),
                };
                numbers(x, &k, out);
            }
        }
        toml::Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                numbers(x, &format!("{key}[{i}]"), out);
            }
        }
        _ => {}
    }
}

/// Set the key path `key` (`a.b[2].c`) of `v` to `to`, creating missing tables.
fn toml_set(v: &mut toml::Value, key: &str, to: toml::Value) {
    let mut parts = Vec::new();
    for seg in key.split('.') {
        let mut it = seg.split('[');
        parts.push(Ok(it.next().unwrap()));
        parts.extend(it.map(|i| Err(i.trim_end_matches(']').parse::<usize>().unwrap())));
    }
    let (last, path) = parts.split_last().unwrap();
    let mut cur = v;
    for p in path {
        cur = match p {
            Ok(name) => cur
                .as_table_mut()
                .unwrap()
                .entry(name.to_string())
                .or_insert_with(|| toml::Value::Table(toml::Table::new())),
            Err(i) => &mut cur.as_array_mut().unwrap()[*i],
        };
    }
    match last {
        Ok(name) => {
            cur.as_table_mut().unwrap().insert(name.to_string(), to);
        }
        Err(i) => cur.as_array_mut().unwrap()[*i] = to,
    }
}

/// A TOML value written as in a file (`0.5`, `"unet"`, `[1, 2]`, `{ kind = "lut" }`).
fn toml_literal(text: &str) -> toml::Value {
    let t: toml::Table = toml::from_str(&format!("v = {text}")).unwrap();
    t["v"].clone()
}

/// The value rules of `text` as a config of `kind`: Err when it does not parse, else the
/// struct's own `validate`.
fn rules_of(
    kind: Kind,
    text: &str,
    path: &Path,
) -> Result<Result<(), hdrsynth::config::KeyError>, String> {
    use hdrsynth::config::parse_toml;
    use hdrsynth::data::generate::GenerateConfig;
    use hdrsynth::train::config::TrainConfig;
    let e = |e: hdrsynth::error::Error| e.to_string();
    match kind {
        Kind::Train => parse_toml::<TrainConfig>(text, path)
            .map(|c| c.validate())
            .map_err(e),
        Kind::Generate => parse_toml::<GenerateConfig>(text, path)
            .map(|c| c.validate())
            .map_err(e),
        Kind::Profile => parse_toml::<SensorProfile>(text, path)
            .map(|c| c.validate())
            .map_err(e),
        Kind::Ablate => hdrsynth::experiments::ablate::AblateConfig::parse(text, path)
            .map(|_| Ok(()))
            .map_err(e),
    }
}

/// The message a user gets for `text` as the file `path` of `kind` (each kind's loader parses
/// and checks through `config::parse_checked`), None when it is accepted.
fn load_message(kind: Kind, text: &str, path: &Path) -> Option<String> {
    use hdrsynth::config::parse_checked;
    use hdrsynth::data::generate::GenerateConfig;
    use hdrsynth::train::config::TrainConfig;
    let e = |e: hdrsynth::error::Error| e.to_string();
    match kind {
        Kind::Train => parse_checked(text, path, TrainConfig::validate)
            .err()
            .map(e),
        Kind::Generate => parse_checked(text, path, GenerateConfig::validate)
            .err()
            .map(e),
        Kind::Profile => parse_checked(text, path, SensorProfile::validate)
            .err()
            .map(e),
        Kind::Ablate => rules_of(kind, text, path).err(),
    }
}

/// `msg` names `file` with a line (`name:12:`) and the key.
fn assert_names_line_and_key(msg: &str, file: &Path, key: &str) {
    let name = file.file_name().unwrap().to_string_lossy();
    let at = format!("{name}:");
    let line = msg
        .find(&at)
        .map(|i| &msg[i + at.len()..])
        .is_some_and(|rest| rest.starts_with(|c: char| c.is_ascii_digit()));
    assert!(
        line && msg.contains(&format!("key '{key}': ")),
        "should name {name}:LINE and '{key}': {msg}"
    );
}

/// A numeric key's range rule as the test knows it (`[]` stands for any index): values outside
/// it, and, for a key no shipped file holds, the keys and valid values that add it.
struct Rule {
    kind: Kind,
    key: &'static str,
    bad: &'static [f64],
    setup: &'static [(&'static str, &'static str)],
}

const fn rule(kind: Kind, key: &'static str, bad: &'static [f64]) -> Rule {
    Rule {
        kind,
        key,
        bad,
        setup: &[],
    }
}

/// Numeric keys without a range: any value is meaningful.
const UNBOUNDED: &[(Kind, &str)] = &[
    (Kind::Train, "run.seed"),
    (Kind::Generate, "seed"),
    // Any warm-up length works (one longer than the run never reaches optim.lr).
    (Kind::Train, "schedule.warmup_steps"),
];

const RULES: &[Rule] = {
    use Kind::*;
    &[
        rule(Train, "run.steps", &[0.0]),
        rule(Train, "run.checkpoint_every", &[0.0]),
        rule(Train, "run.keep_checkpoints", &[0.0]),
        rule(Train, "run.log_every", &[0.0]),
        rule(Train, "model.base_width", &[0.0]),
        rule(Train, "model.depth", &[11.0]),
        rule(Train, "model.classes", &[1.0, 257.0]),
        rule(Train, "model.res_blocks", &[65.0]),
        rule(Train, "model.hdr_input_scale", &[0.0, -0.25, 1.5]),
        Rule {
            setup: &[
                ("model.variant", "\"unet\""),
                ("model.unet_merger_widths", "[4, 8, 8]"),
            ],
            ..rule(Train, "model.unet_merger_widths[]", &[0.0])
        },
        rule(Train, "data.patch", &[4.0, 30.0]),
        rule(Train, "data.batch_size", &[0.0]),
        rule(Train, "data.workers", &[0.0]),
        rule(Train, "data.isos[]", &[0.0, -100.0]),
        rule(Train, "data.exposure", &[0.0, -1.0]),
        Rule {
            setup: &[("data.ev_jitter", "0.5")],
            ..rule(Train, "data.ev_jitter", &[-0.5, 5.0])
        },
        Rule {
            setup: &[("data.metering.mid_grey", "0.128")],
            ..rule(Train, "data.metering.mid_grey", &[0.0, 1.0])
        },
        Rule {
            setup: &[("data.metering.max_clipped", "0.02")],
            ..rule(Train, "data.metering.max_clipped", &[-0.1, 0.5])
        },
        rule(Train, "data.target_sigma", &[-1.0]),
        rule(Train, "optim.lr", &[0.0, -1e-4]),
        Rule {
            setup: &[("optim.beta1", "0.9")],
            ..rule(Train, "optim.beta1", &[-0.1, 1.0])
        },
        rule(Train, "optim.beta2", &[-0.1, 1.0]),
        rule(Train, "optim.epsilon", &[0.0, -1.0]),
        Rule {
            setup: &[("optim.weight_decay", "0.0")],
            ..rule(Train, "optim.weight_decay", &[-5.0])
        },
        Rule {
            setup: &[("schedule.every", "100")],
            ..rule(Train, "schedule.every", &[0.0])
        },
        Rule {
            setup: &[("schedule.gamma", "0.5")],
            ..rule(Train, "schedule.gamma", &[0.0, 1.5])
        },
        rule(Train, "schedule.min_lr", &[-1e-6, 1.0]),
        rule(Train, "loss.alpha_samples", &[0.0]),
        Rule {
            setup: &[("loss.label_sigma", "8.0")],
            ..rule(Train, "loss.label_sigma", &[0.0, 300.0])
        },
        rule(Train, "validation.every", &[0.0]),
        rule(Train, "validation.samples", &[0.0]),
        rule(Train, "validation.patch", &[4.0]),
        Rule {
            setup: &[("validation.target_sigma", "0.0")],
            ..rule(Train, "validation.target_sigma", &[-1.0])
        },
        rule(Generate, "count", &[0.0]),
        rule(Generate, "width", &[8.0, 5000.0]),
        rule(Generate, "height", &[8.0, 5000.0]),
        rule(Generate, "evs[]", &[17.0, -17.0]),
        rule(Generate, "bit_depth", &[12.0]),
        rule(Generate, "scene.subjects[]", &[65.0]),
        rule(Generate, "scene.articulated_fraction", &[-0.1, 1.1]),
        rule(Generate, "scene.motion_scale", &[-1.0, 11.0]),
        rule(Generate, "scene.real_background_probability", &[-0.1, 1.1]),
        rule(Generate, "scene.min_dynamic_range", &[-1.0, 33.0]),
        rule(Generate, "camera.target_over", &[-0.1, 1.0]),
        rule(Generate, "camera.target_under", &[-0.1, 1.0]),
        rule(Generate, "camera.over_threshold", &[0.0, 1.0]),
        rule(Generate, "camera.under_threshold", &[0.0, 1.0]),
        rule(Generate, "camera.candidates", &[0.0]),
        rule(Profile, "levels.black_level", &[-1.0, 70000.0]),
        rule(Profile, "levels.white_level", &[0.0, 70000.0]),
        rule(Profile, "levels.bit_depth", &[0.0, 17.0]),
        rule(Profile, "noise[].iso", &[0.0, -100.0]),
        rule(Profile, "noise[].a[]", &[2.0, -2.0]),
        rule(Profile, "noise[].b[]", &[2.0, -2.0]),
        Rule {
            setup: &[("noise[0].a_stderr", "[1e-7, 1e-7, 1e-7]")],
            ..rule(Profile, "noise[].a_stderr[]", &[-1e-7])
        },
        Rule {
            setup: &[("noise[0].b_stderr", "[1e-9, 1e-9, 1e-9]")],
            ..rule(Profile, "noise[].b_stderr[]", &[-1e-9])
        },
        rule(Profile, "colour.matrix[][]", &[11.0, -11.0]),
        Rule {
            setup: &[(
                "colour.root_polynomial",
                "[[1.0, 0, 0, 0, 0, 0], [0, 1.0, 0, 0, 0, 0], [0, 0, 1.0, 0, 0, 0]]",
            )],
            ..rule(Profile, "colour.root_polynomial[][]", &[11.0])
        },
        rule(Profile, "response.gamma", &[0.0, 11.0]),
        Rule {
            setup: &[("source_response", "{ kind = \"gamma\", gamma = 2.2 }")],
            ..rule(Profile, "source_response.gamma", &[0.0, 11.0])
        },
        Rule {
            setup: &[("response", "{ kind = \"lut\", lut = [0.0, 0.5, 1.0] }")],
            ..rule(Profile, "response.lut[]", &[1.5, -0.1])
        },
    ]
};

/// `a[2].b[10]` → `a[].b[]`.
fn key_pattern(key: &str) -> String {
    let mut out = String::new();
    let mut skipping = false;
    for c in key.chars() {
        match c {
            '[' => {
                skipping = true;
                out.push('[');
            }
            ']' => {
                skipping = false;
                out.push(']');
            }
            _ if skipping => {}
            _ => out.push(c),
        }
    }
    out
}

/// Every numeric key of `doc` (a config of `kind` read from `file`) set in turn to each value
/// outside its rule's range: refused, naming that key (or, for an EV list losing its 0, the
/// list), and the user's message names the file, the line and the key. `only`: just that rule.
/// Counts the cases per rule into `hits`.
fn check_ranges(
    kind: Kind,
    file: &Path,
    doc: &toml::Value,
    only: Option<usize>,
    hits: &mut [usize],
) {
    let mut keys = Vec::new();
    numbers(doc, "", &mut keys);
    for (key, integer) in keys {
        let pattern = key_pattern(&key);
        if UNBOUNDED.contains(&(kind, pattern.as_str())) {
            continue;
        }
        let i = RULES
            .iter()
            .position(|r| r.kind == kind && r.key == pattern)
            .unwrap_or_else(|| panic!("{}: no range rule for {kind:?} key {key}", file.display()));
        if only.is_some_and(|o| o != i) {
            continue;
        }
        for &bad in RULES[i].bad {
            let mut d = doc.clone();
            let value = match integer {
                true => toml::Value::Integer(bad as i64),
                false => toml::Value::Float(bad),
            };
            toml_set(&mut d, &key, value);
            let text = toml::to_string(&d).unwrap();
            let e = rules_of(kind, &text, file)
                .unwrap_or_else(|e| panic!("{}: {key} = {bad} does not parse: {e}", file.display()))
                .expect_err(&format!("{}: {key} = {bad} accepted", file.display()));
            let list = key.rsplit_once('[').map_or(key.as_str(), |(l, _)| l);
            assert!(
                e.key == key || (e.key == list && list == "evs"),
                "{}: {key} = {bad} blamed '{}': {e}",
                file.display(),
                e.key
            );
            let msg = load_message(kind, &text, file).expect("refused");
            assert_names_line_and_key(&msg, file, &e.key);
            println!("{key} = {bad}: {msg}");
            hits[i] += 1;
        }
    }
}

/// Every shipped config and profile parses and passes its rules; every number in them has a
/// range rule (or is listed as unbounded), and each value outside it is refused naming the
/// file, the line and the key. Keys no shipped file holds are added to the first file of
/// their kind that takes them.
#[test]
fn every_numeric_key_of_every_shipped_config_has_a_range_and_refuses_values_outside_it() {
    let files = shipped_configs();
    let mut hits = vec![0usize; RULES.len()];
    for (file, kind) in &files {
        let text = std::fs::read_to_string(file).unwrap();
        let ok = rules_of(*kind, &text, file);
        assert!(ok == Ok(Ok(())), "{}: {ok:?}", file.display());
        if *kind != Kind::Ablate {
            let doc: toml::Value = toml::from_str(&text).unwrap();
            check_ranges(*kind, file, &doc, None, &mut hits);
        }
    }
    for (i, r) in RULES.iter().enumerate() {
        if hits[i] > 0 {
            continue;
        }
        assert!(
            !r.setup.is_empty(),
            "no shipped file holds {:?} {}",
            r.kind,
            r.key
        );
        for (file, _) in files.iter().filter(|(_, k)| *k == r.kind) {
            let mut doc: toml::Value =
                toml::from_str(&std::fs::read_to_string(file).unwrap()).unwrap();
            for (key, value) in r.setup {
                toml_set(&mut doc, key, toml_literal(value));
            }
            if rules_of(r.kind, &toml::to_string(&doc).unwrap(), file) == Ok(Ok(())) {
                check_ranges(r.kind, file, &doc, Some(i), &mut hits);
                break;
            }
        }
        assert!(hits[i] > 0, "no shipped {:?} file takes {}", r.kind, r.key);
    }
    assert!(hits.iter().sum::<usize>() > 300, "{hits:?}");
}

/// Rules between keys (and the few rules that are not ranges) name the key that breaks them.
#[test]
fn rules_between_keys_are_errors_naming_the_key_and_line() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs");
    /// The file's kind and name, the edits (key, TOML value), the key blamed, a piece of
    /// the message.
    type Case = (Kind, &'static str, Edits, &'static str, &'static str);
    type Edits = &'static [(&'static str, &'static str)];
    let cases: &[Case] = &[
        (
            Kind::Train,
            "net1_pretrain.toml",
            &[("schedule.min_lr", "1e-3")],
            "schedule.min_lr",
            "in [0, 0.0001]",
        ),
        (
            Kind::Train,
            "net1_pretrain.toml",
            &[(
                "run.devices",
                "[\"flex\", \"flex\", \"flex\", \"flex\", \"flex\"]",
            )],
            "run.devices",
            "5 devices need data.batch_size ≥ 5",
        ),
        (
            Kind::Train,
            "net1_pretrain.toml",
            &[("schedule.kind", "\"step\"")],
            "schedule.every",
            "needs",
        ),
        (
            Kind::Train,
            "net1_pretrain.toml",
            &[("init.checkpoint", "\"a\""), ("init.safetensors", "\"b\"")],
            "init",
            "exactly one",
        ),
        (
            Kind::Train,
            "net1_pretrain.toml",
            &[("data.patch", "120")],
            "data.patch",
            "multiple of 16",
        ),
        (
            Kind::Train,
            "net1_pretrain.toml",
            &[("data.profile", "\"configs/sensors/canon_eos_550d.toml\"")],
            "data.isos",
            "non-empty",
        ),
        (
            Kind::Generate,
            "generate.toml",
            &[("scene.real_background_probability", "1.0")],
            "scene.real_background_probability",
            "backgrounds_dir",
        ),
        (
            Kind::Generate,
            "generate.toml",
            &[("scene.subjects", "[4, 2]")],
            "scene.subjects",
            "min > max",
        ),
        (
            Kind::Generate,
            "generate.toml",
            &[
                ("camera.target_over", "0.6"),
                ("camera.target_under", "0.5"),
            ],
            "camera.target_under",
            "below 1",
        ),
        (
            Kind::Generate,
            "generate.toml",
            &[("camera.under_threshold", "0.99")],
            "camera.under_threshold",
            "below over_threshold",
        ),
        (
            Kind::Generate,
            "generate.toml",
            &[("evs", "[0.0, -3.0]")],
            "evs",
            "ascending",
        ),
        (
            Kind::Generate,
            "generate.toml",
            &[("evs", "[-3.0, -1.0]")],
            "evs",
            "must contain 0",
        ),
        (
            Kind::Generate,
            "generate.toml",
            &[("width", "4000"), ("height", "4000")],
            "width",
            "shorter side",
        ),
        (
            Kind::Profile,
            "sensors/canon_eos_550d.toml",
            &[("levels.white_level", "1000.0")],
            "levels.white_level",
            "above black_level",
        ),
        (
            Kind::Profile,
            "sensors/canon_eos_550d.toml",
            &[("noise[1].iso", "100.0")],
            "noise[1].iso",
            "strictly ascending",
        ),
        (
            Kind::Profile,
            "sensors/canon_eos_550d.toml",
            &[("colour.use_root_polynomial", "true")],
            "colour.use_root_polynomial",
            "no root_polynomial",
        ),
        (
            Kind::Profile,
            "sensors/canon_eos_550d.toml",
            &[("response", "{ kind = \"lut\", lut = [0.0, 0.6, 0.5, 1.0] }")],
            "response.lut[2]",
            "never falls",
        ),
        (
            Kind::Profile,
            "sensors/canon_eos_550d.toml",
            &[("effects", "[{ id = \"prnu\", sigma = 0.7, seed = 1 }]")],
            "effects[0]",
            "sigma 0.7 must be in [0, 0.5)",
        ),
        (
            Kind::Profile,
            "sensors/canon_eos_550d.toml",
            &[("effects", "[{ id = \"no_such_effect\" }]")],
            "effects[0]",
            "catalogue",
        ),
    ];
    for (kind, name, edits, key, what) in cases {
        let file = root.join(name);
        let mut doc: toml::Value =
            toml::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
        for (k, v) in *edits {
            toml_set(&mut doc, k, toml_literal(v));
        }
        let text = toml::to_string(&doc).unwrap();
        let msg = load_message(*kind, &text, &file).unwrap_or_else(|| panic!("{edits:?} accepted"));
        assert_names_line_and_key(&msg, &file, key);
        assert!(msg.contains(what), "{edits:?}: {msg}");
        println!("{edits:?}: {msg}");
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
// Leftovers of a killed run are cleaned; --resume on a finished run succeeds.

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
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    // Only the newest checkpoint kept: an older step folder is then a leftover.
    let text = resume_config(ResumeCase::plain(false), &run, 2, 1)
        .replace("keep_checkpoints = 1000", "keep_checkpoints = 1");
    let cfg = train_cfg(&text);
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
    // A finished run resumes to success, not to an error.
    let s = hdrsynth::train::run(&cfg, &quiet(true)).expect("a finished run resumes to success");
    assert!(s.already_finished && s.start_step == 2, "{s:?}");
    for p in leftovers.iter().chain(&temps) {
        assert!(!p.exists(), "{} should be gone", p.display());
    }
    // The `step-` folder without a state file is incomplete: moved aside whole, not deleted.
    let aside = root
        .join("incomplete")
        .join("step-00000001")
        .join("model.mpk");
    assert_eq!(std::fs::read(&aside).unwrap(), b"partial");
    assert_eq!(
        hdrsynth::train::checkpoint::latest(&run).unwrap().unwrap(),
        last
    );
}

// ---------------------------------------------------------------------------------------------
// Exact resume: a run stopped after any checkpoint and resumed ends bit-identical to an
// uninterrupted one, and checkpoint bytes are a function of the run.

/// One point of the trainer's option matrix, and the crop side.
#[derive(Clone, Copy, Debug)]
struct ResumeCase {
    network2: bool,
    beta1: f64,
    cosine: bool,
    workers: usize,
    augment: bool,
    batch: usize,
    patch: usize,
}

impl ResumeCase {
    /// The plainest run of a network: β1 0.5, constant schedule, one worker, no augmentation,
    /// batch 1, at a patch the network's receptive field spans (Network-2 64, Network-1 32).
    fn plain(network2: bool) -> ResumeCase {
        ResumeCase {
            network2,
            beta1: 0.5,
            cosine: false,
            workers: 1,
            augment: false,
            batch: 1,
            patch: if network2 { 64 } else { 32 },
        }
    }
}

/// A small dataset per network (Network-1 needs EV −3/0, Network-2 −2/0/+2), made once.
fn resume_dataset(network2: bool) -> &'static Path {
    use std::sync::OnceLock;
    static SETS: [OnceLock<tempfile::TempDir>; 2] = [OnceLock::new(), OnceLock::new()];
    SETS[usize::from(network2)]
        .get_or_init(|| {
            let dir = tempfile::tempdir().expect("tmp");
            let evs = if network2 {
                "[-2.0, 0.0, 2.0]"
            } else {
                "[-3.0, 0.0]"
            };
            common::generate(dir.path(), 41, 3, (80, 72), evs);
            dir
        })
        .path()
}

/// A tiny run of `c` into `out`: `steps` steps, a checkpoint every `every`, all kept, every
/// step logged, pure data.
fn resume_config(c: ResumeCase, out: &Path, steps: u64, every: u64) -> String {
    let model = if c.network2 {
        "kind = \"wu\"\nbase_width = 4\nres_blocks = 1\n"
    } else {
        "kind = \"blend_unet\"\nbase_width = 4\ndepth = 2\nbatch_norm = true\n"
    };
    let schedule = if c.cosine {
        "kind = \"cosine\"\nwarmup_steps = 2\n"
    } else {
        "kind = \"constant\"\n"
    };
    format!(
        "[run]\nout = {out:?}\nseed = 5\nsteps = {steps}\ncheckpoint_every = {every}\n\
         log_every = 1\nkeep_checkpoints = 1000\n[model]\n{model}\
         [data]\ndataset = {:?}\npatch = {}\nbatch_size = {}\nworkers = {}\n\
         augment = {}\nprofile = \"pure\"\n[optim]\nlr = 2e-4\nbeta1 = {}\n[schedule]\n{schedule}",
        resume_dataset(c.network2),
        c.patch,
        c.batch,
        c.workers,
        c.augment,
        c.beta1,
    )
}

fn train_cfg(text: &str) -> hdrsynth::train::config::TrainConfig {
    let cfg: hdrsynth::train::config::TrainConfig =
        hdrsynth::config::parse_toml(text, Path::new("train.toml")).expect("config");
    cfg.validate().expect("valid");
    cfg
}

fn quiet(resume: bool) -> hdrsynth::train::TrainOptions {
    hdrsynth::train::TrainOptions {
        resume,
        progress: false,
    }
}

/// The logged training losses (`step loss` of every interval line; no timings).
fn logged_losses(run: &Path) -> Vec<String> {
    std::fs::read_to_string(run.join("log.jsonl"))
        .expect("log")
        .lines()
        .filter(|l| l.contains("\"loss\"") && !l.contains("validation"))
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            format!("{} {}", f[0], f[2])
        })
        .collect()
}

/// Every float the final checkpoint holds, as bits, by module path (independent of how the
/// record file is laid out).
fn final_weights(run: &Path) -> Vec<(String, Vec<u32>)> {
    use burn::module::{Module, ModuleVisitor, Param};
    use burn::tensor::{Device, Tensor};
    use hdrsynth::models::ModelConfig;
    use hdrsynth::train::checkpoint;
    struct V(Vec<String>, Vec<(String, Vec<u32>)>);
    impl ModuleVisitor for V {
        fn enter_module(&mut self, name: &str, _: &str) {
            self.0.push(name.to_string());
        }
        fn exit_module(&mut self, _: &str, _: &str) {
            self.0.pop();
        }
        fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
            let v = p.val().into_data().try_to_vec::<f32>().expect("f32");
            self.1
                .push((self.0.join("."), v.iter().map(|x| x.to_bits()).collect()));
        }
    }
    let dir = checkpoint::resolve(run).expect("checkpoint");
    let state = checkpoint::read_state(&dir).expect("state");
    let dev = Device::flex();
    let mut v = V(Vec::new(), Vec::new());
    match state.model {
        ModelConfig::Wu(m) => checkpoint::load_model(m.init(&dev).expect("init"), &dir)
            .expect("load")
            .visit(&mut v),
        ModelConfig::BlendUnet(m) => checkpoint::load_model(m.init(&dev).expect("init"), &dir)
            .expect("load")
            .visit(&mut v),
    }
    v.1
}

/// `steps` straight, then the same run cut back to its checkpoint at `at` (as a kill right
/// after that checkpoint leaves it: later checkpoints and log lines are what the killed
/// process would not have written) and resumed: every logged loss and every final weight
/// must be equal.
fn assert_resume_exact(c: ResumeCase, steps: u64, every: u64, at: u64) {
    use hdrsynth::train::checkpoint;
    let tmp = tempfile::tempdir().expect("tmp");
    let run = tmp.path().join("run");
    let cfg = train_cfg(&resume_config(c, &run, steps, every));
    hdrsynth::train::run(&cfg, &quiet(false)).expect("uninterrupted run");
    let straight = record(&run);
    assert_eq!(straight.0.len() as u64, steps, "{c:?}");
    let root = checkpoint::dir_of(&run);
    for entry in std::fs::read_dir(&root).expect("checkpoints") {
        let path = entry.expect("entry").path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if let Some(step) = name
            .strip_prefix("step-")
            .and_then(|s| s.parse::<u64>().ok())
            && step > at
        {
            std::fs::remove_dir_all(&path).expect("remove");
        }
    }
    std::fs::write(root.join("latest"), format!("step-{at:08}")).expect("latest");
    let s = hdrsynth::train::run(&cfg, &quiet(true)).expect("resumed run");
    assert_eq!(s.start_step, at, "{c:?}");
    assert_same(
        &straight,
        &record(&run),
        &format!("{c:?} resumed at step {at}"),
    );
}

/// What a finished run leaves to compare: its logged losses and its final weights.
type Record = (Vec<String>, Vec<(String, Vec<u32>)>);

fn record(run: &Path) -> Record {
    (logged_losses(run), final_weights(run))
}

/// Every logged loss and every final weight equal.
fn assert_same(a: &Record, b: &Record, what: &str) {
    for (i, (x, y)) in a.0.iter().zip(&b.0).enumerate() {
        assert_eq!(x, y, "{what}: log line {i} differs");
    }
    assert_eq!(a.0.len(), b.0.len(), "{what}");
    assert_eq!(a.1.len(), b.1.len(), "{what}");
    for ((name, x), (_, y)) in a.1.iter().zip(&b.1) {
        assert!(x == y, "{what}: {name} differs");
    }
}

/// A tiny Network-2 run (β1 0.5, constant schedule, batch 1, one worker, no augmentation, a
/// checkpoint every 5 steps), 40 steps straight, against the same run stopped after 20 steps
/// and `--resume`d with run.steps raised to 40, and against one killed with SIGKILL through
/// the binary once it has written its checkpoint at step 10 or later, then `train --resume`d.
#[test]
fn a_network2_run_stopped_or_killed_and_resumed_matches_the_uninterrupted_run() {
    use hdrsynth::train::checkpoint;
    let c = ResumeCase::plain(true);
    let tmp = tempfile::tempdir().expect("tmp");
    let run = tmp.path().join("straight");
    hdrsynth::train::run(&train_cfg(&resume_config(c, &run, 40, 5)), &quiet(false))
        .expect("straight");
    let straight = record(&run);
    assert_eq!(straight.0.len(), 40);

    let stopped = tmp.path().join("stopped");
    hdrsynth::train::run(
        &train_cfg(&resume_config(c, &stopped, 20, 5)),
        &quiet(false),
    )
    .expect("first half");
    hdrsynth::train::run(&train_cfg(&resume_config(c, &stopped, 40, 5)), &quiet(true))
        .expect("resumed");
    assert_same(&straight, &record(&stopped), "stopped at step 20");

    let killed = tmp.path().join("killed");
    let cfg = tmp.path().join("killed.toml");
    std::fs::write(&cfg, resume_config(c, &killed, 40, 5)).expect("write");
    let mut child = bin()
        .args(["train", "--quiet", "--config"])
        .arg(&cfg)
        .spawn()
        .expect("spawn");
    let began = std::time::Instant::now();
    let at = loop {
        let step = checkpoint::latest(&killed)
            .ok()
            .flatten()
            .and_then(|d| checkpoint::read_state(&d).ok())
            .map_or(0, |s| s.step);
        if step >= 10 {
            break step;
        }
        assert!(began.elapsed().as_secs() < 300, "no checkpoint appeared");
        std::thread::sleep(std::time::Duration::from_millis(2));
    };
    child.kill().expect("SIGKILL");
    child.wait().expect("wait");
    assert!(at < 40, "the run finished before the kill");
    let st = bin()
        .args(["train", "--quiet", "--resume", "--config"])
        .arg(&cfg)
        .status()
        .expect("resume");
    assert!(st.success());
    assert_same(
        &straight,
        &record(&killed),
        &format!("killed after step {at}"),
    );
}

/// The whole option matrix, 2⁶ = 64 runs: Network-1 and Network-2 × β1 0.5 and 0.9 × constant
/// and cosine schedules × one and two workers × augmentation off and on × batch 1 and 2; each
/// 5 steps with a checkpoint after every step, cut back to a checkpoint drawn (seeded) among
/// steps 1–3 and resumed. Tiny networks on 16-pixel patches keep it cheap.
#[test]
fn runs_resumed_at_a_random_checkpoint_match_uninterrupted_ones_for_every_option() {
    let (steps, every) = (5, 1);
    let mut draw = 0x9e37_79b9_7f4a_7c15u64;
    let began = std::time::Instant::now();
    for bits in 0..64u32 {
        let on = |i: u32| bits >> i & 1 == 1;
        let c = ResumeCase {
            network2: on(0),
            beta1: if on(1) { 0.9 } else { 0.5 },
            cosine: on(2),
            workers: if on(3) { 2 } else { 1 },
            augment: on(4),
            batch: if on(5) { 2 } else { 1 },
            patch: 16,
        };
        draw = draw
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        // A checkpoint with at least two steps after it: the first resumed step uses the
        // restored weights, the later ones the restored optimizer too.
        let at = 1 + (draw >> 33) % (steps - 2);
        assert_resume_exact(c, steps, every, at);
    }
    println!("64 resume cases in {:.1} s", began.elapsed().as_secs_f64());
}

/// Burn draws from one generator that every thread shares, and Network-2's initialisers draw
/// as its layers are built: a seeded initialisation gives the same weights while other threads
/// build networks of their own (as a loader of checkpoints, a memory estimate or another test
/// does), for both networks.
#[test]
fn a_seeded_initialisation_is_the_same_while_other_threads_build_networks() {
    use hdrsynth::models::{BlendUNetConfig, WuConfig, seeded_init};
    use hdrsynth::train::checkpoint::model_to_bytes;
    use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
    let dev = burn::tensor::Device::flex();
    let wu = WuConfig {
        base_width: 4,
        res_blocks: 1,
        ..WuConfig::default()
    };
    let unet = BlendUNetConfig {
        base_width: 4,
        depth: 2,
        ..BlendUNetConfig::default()
    };
    let path = Path::new("m");
    let seeded = || {
        let a = seeded_init(&dev, 3, || wu.init(&dev)).unwrap();
        let b = seeded_init(&dev, 3, || unet.init(&dev)).unwrap();
        (
            model_to_bytes(&a, path).unwrap(),
            model_to_bytes(&b, path).unwrap(),
        )
    };
    let reference = seeded();
    let stop = AtomicBool::new(false);
    let differ = std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| {
                while !stop.load(Relaxed) {
                    std::hint::black_box(wu.init(&dev).unwrap());
                    std::hint::black_box(unet.init(&dev).unwrap());
                }
            });
        }
        let differ = (0..100).filter(|_| seeded() != reference).count();
        stop.store(true, Relaxed);
        differ
    });
    assert_eq!(differ, 0, "{differ} of 100 seeded initialisations differ");
}

/// Two identical runs write byte-identical checkpoint files (model, optimizer, state, α,
/// checksums): no random parameter ids, no hash-map order in them.
#[test]
fn two_identical_runs_write_byte_identical_checkpoints() {
    use hdrsynth::train::checkpoint;
    for network2 in [true, false] {
        let c = ResumeCase::plain(network2);
        let tmp = tempfile::tempdir().expect("tmp");
        let files = |name: &str| {
            let run = tmp.path().join(name);
            hdrsynth::train::run(&train_cfg(&resume_config(c, &run, 3, 3)), &quiet(false))
                .expect("run");
            snapshot(&checkpoint::resolve(&run).expect("checkpoint"))
                .into_iter()
                .map(|(p, b)| (PathBuf::from(p.file_name().unwrap()), b))
                .collect::<std::collections::BTreeMap<_, _>>()
        };
        let (x, y) = (files("x"), files("y"));
        // Every differing file is named, not only the first.
        let differ: Vec<String> = x
            .iter()
            .filter(|(path, bytes)| y.get(*path) != Some(*bytes))
            .map(|(path, _)| path.display().to_string())
            .collect();
        assert!(
            differ.is_empty(),
            "{differ:?} differ between two identical runs (Network-2: {network2})"
        );
        assert!(x.len() >= 4, "{:?}", x.keys());
    }
}

// ---------------------------------------------------------------------------------------------
// Checkpoint integrity: every file of a checkpoint is checked against the SHA-256 recorded
// when it was written, by every command that loads one.

/// A finished one-step Network-1 run (its final checkpoint carries model, optimizer, state, α).
fn one_step_run(dir: &Path) -> (hdrsynth::train::config::TrainConfig, PathBuf) {
    let c = ResumeCase {
        beta1: 0.9,
        ..ResumeCase::plain(false)
    };
    let run = dir.join("run");
    let cfg = train_cfg(&resume_config(c, &run, 2, 1));
    hdrsynth::train::run(&cfg, &quiet(false)).expect("train");
    let ckpt = hdrsynth::train::checkpoint::resolve(&run).expect("checkpoint");
    (cfg, ckpt)
}

/// Every way a checkpoint file is read, by the file it reads.
fn load_checkpoint_file(name: &str, ckpt: &Path) -> hdrsynth::error::Result<()> {
    use hdrsynth::models::ModelConfig;
    use hdrsynth::train::checkpoint;
    match name {
        "model.bpk" => {
            let state = checkpoint::read_state(ckpt)?;
            let ModelConfig::BlendUnet(m) = state.model else {
                panic!("Network-1 expected")
            };
            let dev = burn::tensor::Device::flex();
            checkpoint::load_model(m.init(&dev)?, ckpt).map(|_| ())
        }
        "optimizer.bpk" => {
            checkpoint::load_optimizer(burn::optim::AdamConfig::new().init(), ckpt).map(|_| ())
        }
        "state.toml" => checkpoint::read_state(ckpt).map(|_| ()),
        other => checkpoint::read_verified(ckpt, other).map(|_| ()),
    }
}

#[test]
fn flipped_bytes_anywhere_in_any_checkpoint_file_are_an_error_naming_the_file() {
    let tmp = tempfile::tempdir().unwrap();
    let (_, ckpt) = one_step_run(tmp.path());
    let names = [
        "model.bpk",
        "optimizer.bpk",
        "state.toml",
        "class_weights.toml",
    ];
    for name in names {
        load_checkpoint_file(name, &ckpt).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    let mut draw = 0x2545_f491_4f6c_dd1du64;
    for name in names {
        let path = ckpt.join(name);
        let good = std::fs::read(&path).unwrap();
        // 40 single-byte flips spread over the whole file, and one 64-byte run in its middle.
        let mut damaged: Vec<Vec<u8>> = (0..40)
            .map(|_| {
                draw ^= draw << 13;
                draw ^= draw >> 7;
                draw ^= draw << 17;
                let mut b = good.clone();
                let at = (draw % b.len() as u64) as usize;
                b[at] ^= 1 << (draw >> 60 & 7);
                b
            })
            .collect();
        let mut run = good.clone();
        let mid = run.len() / 2 - 32.min(run.len() / 2);
        for b in run.iter_mut().skip(mid).take(64) {
            *b ^= 0xa5;
        }
        damaged.push(run);
        for bytes in damaged {
            std::fs::write(&path, &bytes).unwrap();
            let e = load_checkpoint_file(name, &ckpt)
                .expect_err(&format!("a damaged {name} was loaded"))
                .to_string();
            assert!(e.contains(name), "{name}: {e}");
        }
        std::fs::write(&path, &good).unwrap();
    }
    // A damaged checksums file blames itself or the file it no longer vouches for.
    let sums = ckpt.join("checksums.sha256");
    let text = std::fs::read_to_string(&sums).unwrap();
    let damaged: String = text
        .lines()
        .map(|l| match l.strip_suffix("  model.bpk") {
            Some(hex) => format!("{}  model.bpk\n", hex.chars().rev().collect::<String>()),
            None => format!("{l}\n"),
        })
        .collect();
    std::fs::write(&sums, damaged).unwrap();
    let e = load_checkpoint_file("model.bpk", &ckpt)
        .unwrap_err()
        .to_string();
    assert!(e.contains("checksum") && e.contains("model.bpk"), "{e}");
    std::fs::write(&sums, "not a checksum line\n").unwrap();
    let e = load_checkpoint_file("model.bpk", &ckpt)
        .unwrap_err()
        .to_string();
    assert!(e.contains("checksums.sha256"), "{e}");
    std::fs::write(&sums, &text).unwrap();
    // The file is what `sha256sum -c` reads.
    assert!(
        text.lines().all(|l| l.len() > 66 && &l[64..66] == "  "),
        "{text}"
    );
}

#[test]
fn a_corrupted_checkpoint_is_refused_by_eval_infer_and_export_and_set_aside_by_resume() {
    use hdrsynth::train::checkpoint;
    let tmp = tempfile::tempdir().unwrap();
    let (cfg, ckpt) = one_step_run(tmp.path());
    let model = ckpt.join("model.bpk");
    let good = std::fs::read(&model).unwrap();
    let mut bad = good.clone();
    let mid = bad.len() / 2;
    for b in &mut bad[mid - 32..mid + 32] {
        *b = !*b;
    }
    std::fs::write(&model, &bad).unwrap();
    // infer and export through the binary, the damaged checkpoint named explicitly.
    let set = common::first_set(resume_dataset(false));
    let o = bin()
        .args(["infer", "--checkpoint"])
        .arg(&ckpt)
        .arg("--set")
        .arg(&set)
        .arg("--out")
        .arg(tmp.path().join("inferred"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.code() == Some(1) && err.contains("model.bpk") && err.contains("checksum"),
        "infer: {err}"
    );
    // eval, on the library path it and `ablate` share.
    let e = hdrsynth::runner::LoadedNetwork::from_checkpoint(
        &ckpt,
        &hdrsynth::eval::infer::NetworkOptions::default(),
        &burn::tensor::Device::flex(),
    )
    .map(|_| ())
    .expect_err("eval of a damaged checkpoint")
    .to_string();
    assert!(
        e.contains("model.bpk") && e.contains("checksum"),
        "eval: {e}"
    );
    // train --resume (raising the step count): the damaged step 2 is moved aside, bytes kept,
    // and the run continues from step 1.
    let mut longer = cfg.clone();
    longer.run.steps = 4;
    let s = hdrsynth::train::run(&longer, &quiet(true)).expect("resume past a damaged checkpoint");
    assert!(s.start_step == 1 && s.steps == 4, "{s:?}");
    let aside = checkpoint::dir_of(&cfg.run.out)
        .join("incomplete")
        .join("step-00000002");
    assert_eq!(std::fs::read(aside.join("model.bpk")).unwrap(), bad);
    let e = checkpoint::resolve(&aside).unwrap_err().to_string();
    assert!(
        e.contains("step-00000002") && e.contains("model.bpk fails its checksum"),
        "{e}"
    );
    // Without a checksums file (a checkpoint from before them): loads, with a warning.
    std::fs::write(aside.join("model.bpk"), &good).unwrap();
    std::fs::remove_file(aside.join("checksums.sha256")).unwrap();
    load_checkpoint_file("model.bpk", &aside).expect("an unverifiable checkpoint still loads");
}

/// A finished tiny Network-1 run of 4 steps with checkpoints at steps 2 and 4; its config is
/// also written to a file for the binary. Returns (run folder, config file).
fn two_checkpoint_run(dir: &Path) -> (PathBuf, PathBuf) {
    let run = dir.join("run");
    let text = resume_config(ResumeCase::plain(false), &run, 4, 2);
    hdrsynth::train::run(&train_cfg(&text), &quiet(false)).expect("train");
    let cfg = dir.join("train.toml");
    std::fs::write(&cfg, text).unwrap();
    (run, cfg)
}

/// The files of a folder by name, with their bytes.
fn files_by_name(dir: &Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    snapshot(dir)
        .into_iter()
        .map(|(p, b)| (p.file_name().unwrap().to_string_lossy().into_owned(), b))
        .collect()
}

/// `file` removed from a finished run's newest checkpoint (step 4), then `train --resume`
/// through the binary: exit 0; the step-4 folder is moved whole into `incomplete/`, its other
/// files byte for byte; stderr names it, what is missing, where it went and the checkpoint
/// resumed from (step 2); the run trains steps 2..4 and writes a new, complete step 4 with
/// the weights the damaged one held (resume is bit-identical).
fn assert_incomplete_latest_is_set_aside_on_resume(file: &str) {
    use hdrsynth::train::checkpoint;
    let tmp = tempfile::tempdir().unwrap();
    let (run, cfg) = two_checkpoint_run(tmp.path());
    let root = checkpoint::dir_of(&run);
    let (step2, step4) = (root.join("step-00000002"), root.join("step-00000004"));
    let weights = std::fs::read(step4.join("model.bpk")).unwrap();
    std::fs::remove_file(step4.join(file)).unwrap();
    let kept = files_by_name(&step4);
    let o = bin()
        .args(["train", "--quiet", "--resume", "--config"])
        .arg(&cfg)
        .output()
        .unwrap();
    let (out, err) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    assert!(o.status.success(), "{file}: {out}\n{err}");
    let aside = root.join("incomplete").join("step-00000004");
    for want in [
        format!("checkpoint {} is incomplete", step4.display()),
        format!("{file} is missing"),
        format!("moved aside to {}", aside.display()),
        format!("resuming from {}", step2.display()),
    ] {
        assert!(err.contains(&want), "{file}: no '{want}' in: {err}");
    }
    assert_eq!(
        files_by_name(&aside),
        kept,
        "{file}: the set-aside files changed"
    );
    assert!(!aside.join(file).exists(), "{file}");
    assert!(out.contains("trained steps 2..4"), "{file}: {out}");
    let last = checkpoint::latest(&run).unwrap().unwrap();
    assert_eq!(last, step4, "{file}");
    assert_eq!(checkpoint::read_state(&last).unwrap().step, 4, "{file}");
    assert_eq!(checkpoint::incomplete(&last), None, "{file}");
    assert_eq!(
        std::fs::read(last.join("model.bpk")).unwrap(),
        weights,
        "{file}: the resumed run's step 4 differs from the uninterrupted one's"
    );
}

#[test]
fn resume_sets_aside_a_latest_checkpoint_without_its_state_file_and_continues() {
    assert_incomplete_latest_is_set_aside_on_resume("state.toml");
}

#[test]
fn resume_sets_aside_a_latest_checkpoint_without_its_optimizer_and_continues() {
    assert_incomplete_latest_is_set_aside_on_resume("optimizer.bpk");
}

/// Readers of a run whose newest checkpoint lacks its state file: `checkpoint::resolve` and
/// `latest` give step 2, `infer` and `export` use it and name the skipped step 4 on stderr,
/// the step-4 folder named explicitly is an error naming it, and nothing on disk changes.
#[test]
fn readers_of_a_run_with_an_incomplete_latest_checkpoint_use_the_previous_and_say_so() {
    use hdrsynth::train::checkpoint;
    let tmp = tempfile::tempdir().unwrap();
    let (run, _) = two_checkpoint_run(tmp.path());
    let root = checkpoint::dir_of(&run);
    let (step2, step4) = (root.join("step-00000002"), root.join("step-00000004"));
    std::fs::remove_file(step4.join("state.toml")).unwrap();
    let before = snapshot(&root);
    assert_eq!(checkpoint::resolve(&run).unwrap(), step2);
    assert_eq!(checkpoint::latest(&run).unwrap().unwrap(), step2);
    let (used, skipped) = checkpoint::newest_complete(&run).unwrap();
    assert_eq!(used.as_deref(), Some(step2.as_path()));
    assert_eq!(
        skipped,
        vec![checkpoint::Skipped {
            dir: step4.clone(),
            why: "state.toml is missing".into()
        }]
    );
    let e = checkpoint::resolve(&step4).unwrap_err().to_string();
    assert!(
        e.contains("step-00000004") && e.contains("state.toml is missing"),
        "{e}"
    );
    let set = common::first_set(resume_dataset(false));
    let mut readers = vec![{
        let mut c = bin();
        c.args(["infer", "--engine", "burn", "--checkpoint"])
            .arg(&run)
            .arg("--set")
            .arg(&set)
            .arg("--out")
            .arg(tmp.path().join("inferred"));
        ("infer", c)
    }];
    if cfg!(feature = "onnx") {
        let mut c = bin();
        c.args(["export", "onnx", "--checkpoint"])
            .arg(&run)
            .arg("--out")
            .arg(tmp.path().join("m.onnx"));
        readers.push(("export", c));
    }
    for (what, mut c) in readers {
        let o = c.output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{what}: {err}");
        for want in [
            format!("checkpoint {} is incomplete", step4.display()),
            "state.toml is missing".to_string(),
            format!("using {} instead", step2.display()),
        ] {
            assert!(err.contains(&want), "{what}: no '{want}' in: {err}");
        }
    }
    assert_eq!(snapshot(&root), before, "a reader changed the checkpoints");
}

// ---------------------------------------------------------------------------------------------
// Degenerate images: a side of 0 pixels is refused at decode, in every reader, naming the file.

fn zero_width_tiff() -> Vec<u8> {
    let n = 7;
    tiff_with(
        &[
            (256, 4, 1, 0),              // ImageWidth 0
            (257, 4, 1, 64),             // ImageLength
            (258, 3, 1, 8),              // BitsPerSample
            (259, 3, 1, 1),              // no compression
            (262, 3, 1, 1),              // BlackIsZero grey
            (273, 4, 1, data_offset(n)), // StripOffsets
            (277, 3, 1, 1),              // SamplesPerPixel
        ],
        &[0u8; 16],
    )
}

/// A 1×1 EXR written by the crate, its dataWindow rewritten to an empty column range.
fn zero_width_exr(dir: &Path) -> Vec<u8> {
    let p = dir.join("one0.exr");
    write_exr(&p, &Image::new(1, 1), ExrPrecision::Half).unwrap();
    let mut b = std::fs::read(&p).unwrap();
    let key = b"dataWindow\0box2i\0";
    let at = b.windows(key.len()).position(|w| w == key).unwrap() + key.len() + 4;
    b[at + 8..at + 12].copy_from_slice(&(-1i32).to_le_bytes()); // xMax = xMin − 1
    b
}

/// A 1×1 baseline JPEG (encoded by the `image` crate) whose SOF0 declares width 0.
fn zero_width_jpeg() -> Vec<u8> {
    let mut b = Vec::new();
    image::codecs::jpeg::JpegEncoder::new(&mut b)
        .encode(&[128, 128, 128], 1, 1, image::ExtendedColorType::Rgb8)
        .unwrap();
    let sof = b.windows(2).position(|w| w == [0xff, 0xc0]).expect("SOF0");
    // FFC0, length (2), precision (1), height (2), width (2).
    b[sof + 7..sof + 9].copy_from_slice(&[0, 0]);
    b
}

fn zero_width_dng() -> Vec<u8> {
    let mut d = bomb_dng();
    // ImageWidth (the second entry) and ImageLength: 0 × 64.
    for (entry, v) in [(1usize, 0u32), (2, 64)] {
        let at = 8 + 2 + 12 * entry + 8;
        d[at..at + 4].copy_from_slice(&v.to_le_bytes());
    }
    d
}

#[test]
fn images_with_a_side_of_zero_are_refused_by_every_reader_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("zero.png", bomb_png(0, 64)),
        ("zero_h.png", bomb_png(64, 0)),
        ("zero.tif", zero_width_tiff()),
        (
            "zero.hdr",
            b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 64 +X 0\n".to_vec(),
        ),
        (
            "zero_h.hdr",
            b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 0 +X 64\n".to_vec(),
        ),
        ("zero.exr", zero_width_exr(dir.path())),
        ("zero.jpg", zero_width_jpeg()),
    ];
    for (name, bytes) in cases {
        let p = dir.path().join(name);
        std::fs::write(&p, &bytes).unwrap();
        let e = read_image(&p).expect_err(name).to_string();
        assert!(e.contains(name), "{name}: {e}");
    }
    let p = dir.path().join("zero.dng");
    std::fs::write(&p, zero_width_dng()).unwrap();
    let e = hdrsynth::sensor::dng::read_dng(&p).unwrap_err().to_string();
    assert!(e.contains("zero.dng"), "{e}");
    // The Radiance case by the declared-size check itself, the one every decoder calls.
    let e = DecodeLimits::default()
        .check(Path::new("f.hdr"), "Radiance HDR", 0, 64)
        .unwrap_err()
        .to_string();
    assert!(e.contains("f.hdr") && e.contains("0×64"), "{e}");
}

#[test]
fn realism_on_a_zero_width_radiance_file_is_an_error_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    std::fs::create_dir_all(&input).unwrap();
    std::fs::write(
        input.join("empty.hdr"),
        b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 64 +X 0\n",
    )
    .unwrap();
    let o = realism_cmd(&example_profile(), &input, &dir.path().join("out"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("empty.hdr") && !err.contains("panicked"),
        "{err}"
    );
}

// ---------------------------------------------------------------------------------------------
// Inputs that are not regular files (a FIFO, a device, a folder) are refused, on the file
// opened without waiting: a plain open of a FIFO for reading blocks until a writer comes.

#[cfg(unix)]
fn mkfifo(path: &Path) {
    let st = std::process::Command::new("mkfifo")
        .arg(path)
        .status()
        .expect("mkfifo");
    assert!(st.success());
}

/// `f()` within 20 s, or a failure (the FIFO is then opened for writing, which releases a
/// reader blocked on it, so the test process can end).
#[cfg(unix)]
fn within_deadline<T: Send + 'static>(
    what: &str,
    fifo: &Path,
    f: impl FnOnce() -> T + Send + 'static,
) -> T {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    match rx.recv_timeout(std::time::Duration::from_secs(20)) {
        Ok(v) => v,
        Err(_) => {
            let _ = std::fs::OpenOptions::new().write(true).open(fifo);
            panic!("{what}: blocked on the FIFO {}", fifo.display());
        }
    }
}

#[cfg(unix)]
#[test]
fn fifos_given_as_configs_profiles_images_or_checkpoints_are_refused_not_waited_on() {
    use hdrsynth::data::generate::GenerateConfig;
    use hdrsynth::experiments::ablate::AblateConfig;
    use hdrsynth::train::config::TrainConfig;
    let dir = tempfile::tempdir().unwrap();
    type Load = fn(&Path) -> hdrsynth::error::Result<()>;
    let loads: Vec<(&str, Load)> = vec![
        ("gen.toml", |p| GenerateConfig::load(p).map(|_| ())),
        ("train.toml", |p| TrainConfig::load(p).map(|_| ())),
        ("ablate.toml", |p| AblateConfig::load(p).map(|_| ())),
        ("profile.toml", |p| SensorProfile::load(p).map(|_| ())),
        ("frame.png", |p| read_image(p).map(|_| ())),
        ("frame.exr", |p| read_image(p).map(|_| ())),
        ("raw.dng", |p| {
            hdrsynth::sensor::dng::read_dng(p).map(|_| ())
        }),
        ("class_weights.toml", |p| {
            hdrsynth::data::ground_truth::ClassWeights::load(p).map(|_| ())
        }),
        ("weights.safetensors", |p| {
            let dev = burn::tensor::Device::flex();
            let m = hdrsynth::models::WuConfig::default().init(&dev)?;
            hdrsynth::models::import::import_weights(m, p).map(|_| ())
        }),
        ("captures.toml", |p| {
            hdrsynth::sensor::captures::CaptureSet::load(p).map(|_| ())
        }),
        ("bracket.tif", |p| {
            hdrsynth::capture::scan::read_exif(p).map(|_| ())
        }),
        ("radiance.exr", |p| {
            hdrsynth::data::testset::radiance::to_rec709_matrix(p).map(|_| ())
        }),
        #[cfg(feature = "onnx")]
        ("model.onnx", |p| {
            hdrsynth::onnx::runtime::OnnxModel::load(p, None).map(|_| ())
        }),
    ];
    for (name, load) in loads {
        let fifo = dir.path().join(name);
        mkfifo(&fifo);
        let p = fifo.clone();
        let e = within_deadline(name, &fifo, move || load(&p).map_err(|e| e.to_string()))
            .expect_err(name);
        assert!(e.contains(name) && e.contains("FIFO"), "{name}: {e}");
    }
    // A checkpoint whose model file is a FIFO.
    let (_, ckpt) = one_step_run(dir.path());
    let model = ckpt.join("model.bpk");
    std::fs::remove_file(&model).unwrap();
    mkfifo(&model);
    let c = ckpt.clone();
    let e = within_deadline("model.bpk", &model, move || {
        load_checkpoint_file("model.bpk", &c).map_err(|e| e.to_string())
    })
    .expect_err("model.bpk");
    assert!(e.contains("model.bpk") && e.contains("FIFO"), "{e}");
    // A character device as a config.
    let e = GenerateConfig::load(Path::new("/dev/zero"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("/dev/zero") && e.contains("device"), "{e}");
}

/// The one opener of single-file inputs tests the file it opened: a FIFO is refused even with
/// a writer attached (when a plain open would not block), so the refusal comes from the
/// file's type, not from a wait; a regular file comes back in blocking mode.
#[cfg(unix)]
#[test]
fn open_input_refuses_what_it_opened_unless_a_regular_file_and_never_blocks() {
    use std::os::fd::AsRawFd;
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe");
    mkfifo(&fifo);
    // Both ends held here (O_RDWR on a FIFO does not block on Linux).
    let _held = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(&fifo)
        .unwrap();
    let p = fifo.clone();
    let e = within_deadline("open_input", &fifo, move || {
        guard::open_input(&p).map(|_| ()).map_err(|e| e.to_string())
    })
    .expect_err("a FIFO was opened as an input");
    assert!(e.contains("not a regular file but a FIFO"), "{e}");
    // Without a writer: refused at once, not waited on.
    let lone = dir.path().join("lone");
    mkfifo(&lone);
    let p = lone.clone();
    within_deadline("open_input", &lone, move || {
        guard::open_input(&p).map(|_| ()).map_err(|e| e.to_string())
    })
    .expect_err("a FIFO was opened as an input");

    let file = dir.path().join("f.txt");
    std::fs::write(&file, "abc").unwrap();
    let link = dir.path().join("link.txt");
    std::os::unix::fs::symlink(&file, &link).unwrap();
    for p in [&file, &link] {
        let mut f = guard::open_input(p).unwrap();
        // SAFETY: F_GETFL on a descriptor `f` owns.
        let flags = unsafe { libc::fcntl(f.as_raw_fd(), libc::F_GETFL) };
        assert_eq!(flags & libc::O_NONBLOCK, 0, "left non-blocking");
        let mut text = String::new();
        std::io::Read::read_to_string(&mut f, &mut text).unwrap();
        assert_eq!(text, "abc");
    }
    let e = guard::open_input(dir.path()).unwrap_err();
    assert!(e.to_string().contains("a folder"), "{e}");
    let e = guard::open_input(&dir.path().join("missing")).unwrap_err();
    assert_eq!(e.kind(), std::io::ErrorKind::NotFound);
    let e = guard::read_text(Path::new("/dev/null"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("/dev/null") && e.contains("character device"),
        "{e}"
    );
}

#[cfg(unix)]
#[test]
fn generate_and_realism_refuse_a_fifo_config_or_profile_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe.toml");
    mkfifo(&fifo);
    let input = dir.path().join("in");
    write_ldr(&input.join("f.png"), &Image::new(8, 8), BitDepth::Eight).unwrap();
    let mut generate = bin();
    generate
        .args(["generate", "--config"])
        .arg(&fifo)
        .arg("--out")
        .arg(dir.path().join("gen"));
    let runs = [
        ("generate", generate),
        (
            "realism",
            realism_cmd(&fifo, &input, &dir.path().join("real")),
        ),
    ];
    for (what, cmd) in runs {
        let (status, err) = finish_within(cmd, 20, &format!("{what} blocked on a FIFO"));
        assert_eq!(status.code(), Some(1), "{what}: {err}");
        assert!(
            err.contains("pipe.toml") && err.contains("FIFO"),
            "{what}: {err}"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Non-finite numbers: NaN and infinities are refused in every config and profile, naming the
// key and the line.

#[test]
fn a_nan_exposure_in_a_train_config_is_refused_naming_the_key() {
    let text = "[run]\nout = \"r\"\nseed = 1\nsteps = 1\n[model]\nkind = \"wu\"\n\
                [data]\ndataset = \"d\"\npatch = 64\nbatch_size = 1\nprofile = \"pure\"\n\
                exposure = nan\n";
    let e = hdrsynth::config::parse_toml::<hdrsynth::train::config::TrainConfig>(
        text,
        Path::new("t.toml"),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("t.toml:12") && e.contains("data.exposure") && e.contains("nan"),
        "{e}"
    );
}

/// Every float of every shipped config and profile, replaced in turn by NaN, +inf and −inf,
/// is refused by that file's own loader with the file, line and key named.
#[test]
fn every_float_key_of_every_shipped_config_refuses_nan_and_infinities() {
    let mut checked = 0;
    for (file, kind) in shipped_configs() {
        let doc: toml::Value = toml::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
        let mut keys = Vec::new();
        numbers(&doc, "", &mut keys);
        for (key, _) in keys.into_iter().filter(|(_, integer)| !integer) {
            for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                let mut d = doc.clone();
                toml_set(&mut d, &key, toml::Value::Float(bad));
                let text = toml::to_string(&d).unwrap();
                let e = rules_of(kind, &text, &file)
                    .expect_err(&format!("{}: {key} = {bad} accepted", file.display()));
                assert!(
                    e.contains("not a finite number"),
                    "{}: {key} = {bad}: {e}",
                    file.display()
                );
                assert_names_line_and_key(&e, &file, &key);
                checked += 1;
            }
        }
    }
    assert!(checked > 100, "only {checked} cases");
}

/// Type errors name the key as well as the line.
#[test]
fn type_errors_in_configs_name_the_key() {
    use hdrsynth::config::parse_toml;
    use hdrsynth::train::config::TrainConfig;
    let base = "[run]\nout = \"r\"\nseed = 1\nsteps = 1\n[model]\nkind = \"wu\"\n\
                [data]\ndataset = \"d\"\npatch = 64\nbatch_size = 1\nprofile = \"pure\"\n";
    for (from, to, key) in [
        ("steps = 1", "steps = -1", "run.steps"),
        ("seed = 1", "seed = \"1\"", "run.seed"),
        ("batch_size = 1", "batch_size = \"two\"", "data.batch_size"),
        (
            "kind = \"wu\"",
            "kind = \"wu\"\nres_blocks = -1",
            "model.res_blocks",
        ),
    ] {
        let text = base.replace(from, to);
        let e = parse_toml::<TrainConfig>(&text, Path::new("t.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.toml:") && e.contains(&format!("'{key}'")),
            "{to}: {e}"
        );
    }
    let e = parse_toml::<hdrsynth::data::generate::GenerateConfig>(
        "seed = 1\ncount = \"two\"\n",
        Path::new("g.toml"),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("g.toml:2") && e.contains("'count'"), "{e}");
    // A 2×2 colour matrix in a profile, `seeds = "1"` in an ablation config.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs");
    let profile = std::fs::read_to_string(root.join("sensors/canon_eos_550d.toml")).unwrap();
    let line = profile
        .lines()
        .find(|l| l.starts_with("matrix = "))
        .unwrap();
    let text = profile.replace(line, "matrix = [[1.0, 0.0], [0.0, 1.0]]");
    let e = parse_toml::<SensorProfile>(&text, Path::new("p.toml"))
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(e.contains("p.toml:") && e.contains("'colour.matrix"), "{e}");
    let ablate = std::fs::read_to_string(root.join("experiments/exp1_network1.toml")).unwrap();
    let text = ablate.replace("seeds = [1, 2, 3]", "seeds = \"1\"");
    let e = hdrsynth::experiments::ablate::AblateConfig::parse(&text, Path::new("a.toml"))
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(e.contains("a.toml:") && e.contains("'seeds'"), "{e}");
    // A test set's options obey `testset`'s own rules inside an ablation config.
    let ablate = std::fs::read_to_string(root.join("experiments/cpu/exp2_network2.toml")).unwrap();
    let text = ablate.replace("evs = [-2.0, 0.0, 2.0]", "evs = [-2.0, 2.0]");
    let e = hdrsynth::experiments::ablate::AblateConfig::parse(&text, Path::new("a.toml"))
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("a.toml") && e.contains("'options.evs'") && e.contains("must include 0"),
        "{e}"
    );
}

// ---------------------------------------------------------------------------------------------
// Messages name the culprit.

/// A Kalantari-layout set whose reference (middle) frame declares 100000×100000: the error
/// names that frame, not a frame that merely differs from the size it declares.
#[test]
fn a_reference_frame_declaring_a_huge_size_is_the_file_blamed() {
    let dir = tempfile::tempdir().unwrap();
    let set = dir.path().join("Test").join("001");
    std::fs::create_dir_all(&set).unwrap();
    write_ldr(
        &set.join("frame_0.tif"),
        &Image::new(64, 64),
        BitDepth::Sixteen,
    )
    .unwrap();
    std::fs::write(set.join("frame_1.tif"), bomb_tiff()).unwrap();
    write_ldr(
        &set.join("frame_2.tif"),
        &Image::new(64, 64),
        BitDepth::Sixteen,
    )
    .unwrap();
    std::fs::write(set.join("exposure.txt"), "-2\n0\n2\n").unwrap();
    hdrsynth::io::write_hdr(&set.join("HDRImg.hdr"), &Image::new(64, 64)).unwrap();
    let e = match layout::detect(&set) {
        Ok(_) => panic!("a set with a 100000×100000 reference frame was accepted"),
        Err(e) => e.to_string(),
    };
    assert!(
        e.contains("frame_1.tif") && e.contains("decode limit"),
        "{e}"
    );
}

/// A grey (single-channel) chart capture: the error names the capture, not the profile that
/// would have been written from it.
#[test]
fn a_grey_chart_capture_is_blamed_rather_than_the_profile_written() {
    use hdrsynth::sensor::colour::calibrate::{CalibrateOptions, calibrate};
    let dir = tempfile::tempdir().unwrap();
    let grey = dir.path().join("grey.exr");
    // The rendered chart, its three channels replaced by their mean.
    let mut img = hdrsynth::sensor::colour::chart::render_chart(
        600,
        400,
        &hdrsynth::sensor::colour::chart::Illuminant::D65,
        0.5,
    );
    for p in img.data.chunks_exact_mut(3) {
        let m = (p[0] + p[1] + p[2]) / 3.0;
        p.fill(m);
    }
    write_exr(&grey, &img, ExrPrecision::Float).unwrap();
    let out = dir.path().join("prof.toml");
    let opts = CalibrateOptions::new(grey.clone(), out.clone(), "test".into());
    let e = calibrate(&opts).map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("grey.exr") && !e.contains("prof.toml"), "{e}");
    assert!(!out.exists());
}

#[test]
fn a_generate_size_out_of_range_names_the_key() {
    use hdrsynth::data::generate::GenerateConfig;
    let dir = tempfile::tempdir().unwrap();
    for (w, h, key, line) in [(0, 64, "width", 3), (64, 1_000_000, "height", 4)] {
        let p = write_cfg(
            dir.path(),
            "g.toml",
            &format!("seed = 1\ncount = 1\nwidth = {w}\nheight = {h}\nevs = [-2.0, 0.0, 2.0]\n"),
        );
        let e = GenerateConfig::load(&p).unwrap_err().to_string();
        assert!(
            e.contains(&format!("g.toml:{line}: key '{key}': ")) && e.contains("out of range"),
            "{e}"
        );
    }
}

/// A TIFF bracket frame whose EXIF ExposureTime is a DOUBLE (as some software writes it) has
/// that exposure, not none.
#[test]
fn an_exif_exposure_time_stored_as_double_is_read() {
    // TIFF: IFD0 = { ExifIFDPointer → IFD at 26 }, Exif IFD = { ExposureTime DOUBLE @ 44 }.
    let mut b = b"II".to_vec();
    b.extend(42u16.to_le_bytes());
    b.extend(8u32.to_le_bytes());
    b.extend(1u16.to_le_bytes()); // IFD0 at 8: one entry
    b.extend(34665u16.to_le_bytes());
    b.extend(4u16.to_le_bytes()); // LONG
    b.extend(1u32.to_le_bytes());
    b.extend(26u32.to_le_bytes());
    b.extend(0u32.to_le_bytes()); // no next IFD; 8 + 2 + 12 + 4 = 26
    b.extend(1u16.to_le_bytes()); // Exif IFD at 26: one entry
    b.extend(33434u16.to_le_bytes());
    b.extend(12u16.to_le_bytes()); // DOUBLE
    b.extend(1u32.to_le_bytes());
    b.extend(44u32.to_le_bytes());
    b.extend(0u32.to_le_bytes()); // 26 + 2 + 12 + 4 = 44
    b.extend(0.004f64.to_le_bytes());
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("frame.tif");
    std::fs::write(&p, &b).unwrap();
    let exif = hdrsynth::capture::scan::read_exif(&p).expect("exif");
    assert_eq!(exif.exposure_time, Some(0.004));
}

// ---------------------------------------------------------------------------------------------
// A refused run leaves its output folder as it was before the command.

#[test]
fn a_refused_training_run_leaves_no_run_folder() {
    use hdrsynth::train::config::TrainConfig;
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let base = resume_config(ResumeCase::plain(false), &run, 2, 1);
    let cases = [
        (
            "a backend not built in",
            base.replace("seed = 5\n", "seed = 5\nbackend = \"cuda\"\n"),
        ),
        (
            "init.checkpoint = its own output",
            format!("{base}[init]\ncheckpoint = {run:?}\n"),
        ),
        (
            "a missing validation dataset",
            format!(
                "{base}[validation]\ndataset = {:?}\nevery = 1\n",
                dir.path().join("nowhere")
            ),
        ),
    ];
    for (what, text) in cases {
        if what.contains("backend") && cfg!(feature = "cuda") {
            continue;
        }
        let cfg: TrainConfig = hdrsynth::config::parse_toml(&text, Path::new("t.toml")).unwrap();
        let e = hdrsynth::train::run(&cfg, &quiet(false)).expect_err(what);
        assert!(!run.exists(), "{what} ({e}) left {}", run.display());
    }
}

/// Every trainable parameter of both networks (all but BatchNorm's running statistics) gets a
/// gradient, freshly initialised and after a checkpoint reload alike: a parameter that trains
/// only after a reload makes a resumed run differ from an uninterrupted one.
#[test]
fn every_parameter_of_both_networks_gets_a_gradient_before_and_after_a_reload() {
    use burn::module::{Module, ModuleVisitor, Param, ParamId};
    use burn::optim::GradientsParams;
    use burn::tensor::{Device, Tensor, TensorData};
    use hdrsynth::models::seeded_init;
    use hdrsynth::models::{BlendUNetConfig, WuConfig};
    struct Ids(Vec<String>, Vec<(String, ParamId, usize)>);
    impl ModuleVisitor for Ids {
        fn enter_module(&mut self, name: &str, _: &str) {
            self.0.push(name.to_string());
        }
        fn exit_module(&mut self, _: &str, _: &str) {
            self.0.pop();
        }
        fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
            let path = self.0.join(".");
            if !path.ends_with("running_mean") && !path.ends_with("running_var") {
                self.1.push((path, p.id, D));
            }
        }
    }
    fn check<M: Module>(what: &str, model: &M, loss: Tensor<1>) {
        let grads = GradientsParams::from_grads(loss.backward(), model);
        let mut ids = Ids(Vec::new(), Vec::new());
        model.visit(&mut ids);
        let missing: Vec<&str> = ids
            .1
            .iter()
            .filter(|(_, id, d)| match d {
                1 => grads.get::<1>(*id).is_none(),
                4 => grads.get::<4>(*id).is_none(),
                _ => panic!("a parameter of rank {d}"),
            })
            .map(|(p, _, _)| p.as_str())
            .collect();
        assert!(missing.is_empty(), "{what}: no gradient for {missing:?}");
    }
    let ad = Device::flex().autodiff();
    let input = |c: usize| {
        let n = 2 * c * 32 * 32;
        Tensor::<4>::from_data(TensorData::new(common::values(n, 3), [2, c, 32, 32]), &ad)
    };
    let tmp = tempfile::tempdir().unwrap();
    let wu = WuConfig {
        base_width: 4,
        res_blocks: 1,
        ..WuConfig::default()
    };
    let net2 = seeded_init(&ad, 1, || wu.init(&ad)).unwrap();
    check("Network-2", &net2, net2.forward(input(18)).sum());
    let bytes = hdrsynth::train::checkpoint::model_to_bytes(&net2, &tmp.path().join("m")).unwrap();
    let reloaded = hdrsynth::train::checkpoint::model_from_bytes(
        wu.init(&ad).unwrap(),
        bytes,
        &tmp.path().join("m"),
    )
    .unwrap();
    check(
        "Network-2 reloaded",
        &reloaded,
        reloaded.forward(input(18)).sum(),
    );
    let bu = BlendUNetConfig {
        base_width: 4,
        depth: 2,
        batch_norm: true,
        ..BlendUNetConfig::default()
    };
    let net1 = seeded_init(&ad, 1, || bu.init(&ad)).unwrap();
    check("Network-1", &net1, net1.forward(input(6)).sum());
}

/// Three 8-bit sRGB PNGs of a ramp, 1/4, 1 and 4 s (OpenCV's list.txt: inverse times).
fn png_bracket(dir: &Path) {
    std::fs::create_dir_all(dir).unwrap();
    for (i, t) in [0.25f64, 1.0, 4.0].iter().enumerate() {
        let img = image::RgbImage::from_fn(48, 32, |x, y| {
            let l = (-6.0 + 8.0 * f64::from(x) / 47.0).exp2() * t * (1.0 + f64::from(y) / 64.0);
            let v = (common::srgb(l.min(1.0)) * 255.0).round() as u8;
            image::Rgb([v, v, v])
        });
        img.save(dir.join(format!("f{i}.png"))).unwrap();
    }
    std::fs::write(dir.join("list.txt"), "f0.png 4\nf1.png 1\nf2.png 0.25\n").unwrap();
}

#[test]
fn a_bracket_testset_appears_whole_or_not_at_all_and_refuses_before_any_work() {
    use hdrsynth::capture::testset::{self, BracketOptions, EncodeSpec, InputChoice};
    let dir = tempfile::tempdir().unwrap();
    let brackets = dir.path().join("brackets");
    png_bracket(&brackets.join("a"));
    png_bracket(&brackets.join("b"));
    let out = dir.path().join("ts");
    let nothing_left = |what: &str| {
        assert!(!out.exists(), "{what}: {out:?} was left");
        let partial = dir.path().join(".ts.partial");
        assert!(!partial.exists(), "{what}: {partial:?} was left");
    };
    // A corrupt frame in the second scene: the first scene, complete, is not left behind,
    // nor the response estimated before it.
    std::fs::write(brackets.join("b/f1.png"), b"not a png").unwrap();
    let e = testset::build(&brackets, &BracketOptions::default(), &out)
        .unwrap_err()
        .to_string();
    assert!(e.contains("f1.png"), "{e}");
    nothing_left("a corrupt frame");
    png_bracket(&brackets.join("b"));
    // Refusals known from the options come before the response is estimated.
    let opts = BracketOptions {
        inputs: InputChoice::Indices([0, 1, 1]),
        ..BracketOptions::default()
    };
    let e = testset::build(&brackets, &opts, &out)
        .unwrap_err()
        .to_string();
    assert!(e.contains("--inputs 0,1,1"), "{e}");
    nothing_left("--inputs 0,1,1");
    let missing = dir.path().join("missing.toml");
    let opts = BracketOptions {
        encode: EncodeSpec::Profile(missing.clone()),
        ..BracketOptions::default()
    };
    let e = testset::build(&brackets, &opts, &out)
        .unwrap_err()
        .to_string();
    assert!(e.contains(&missing.display().to_string()), "{e}");
    nothing_left("--encode profile: of a missing file");
    // Whole: both scenes, the response table and the record, and nothing staged left.
    let built = testset::build(&brackets, &BracketOptions::default(), &out).unwrap();
    assert_eq!(built.sets.len(), 2);
    for f in [
        "a/HDRImg.hdr",
        "b/HDRImg.hdr",
        "crf_debevec.csv",
        "encoding.toml",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    assert!(!dir.path().join(".ts.partial").exists());
    assert!(
        built
            .notes
            .iter()
            .any(|n| n.contains("written as crf_debevec.csv")),
        "{:?}",
        built.notes
    );
}

#[test]
fn absurd_or_duplicated_exposures_are_refused_naming_the_file_and_line() {
    use hdrsynth::capture::scan::{self, ScanOptions};
    let dir = tempfile::tempdir().unwrap();
    let set = dir.path().join("b");
    png_bracket(&set);
    let scan_err = |opts: &ScanOptions| {
        scan::scan(dir.path(), opts)
            .expect_err("refused")
            .to_string()
    };
    let list = set.join("list.txt");
    // 1e-30 as 1/t: an exposure of 1e30 s.
    std::fs::write(&list, "f0.png 4\nf1.png 1\nf2.png 1e-30\n").unwrap();
    let e = scan_err(&ScanOptions::default());
    assert!(
        e.contains("list.txt") && e.contains("line 3") && e.contains("not an exposure time"),
        "{e}"
    );
    std::fs::write(&list, "f0.png 4\nf1.png 1\nf2.png 0.25\nf1.png 2\n").unwrap();
    let e = scan_err(&ScanOptions::default());
    assert!(
        e.contains("'f1.png' is listed twice (lines 2 and 4)"),
        "{e}"
    );
    std::fs::remove_file(&list).unwrap();
    std::fs::write(set.join("exposure.txt"), "0\n4\n105.66\n").unwrap();
    let e = scan_err(&ScanOptions::default());
    assert!(e.contains("exposure.txt") && e.contains("105.66"), "{e}");
    std::fs::remove_file(set.join("exposure.txt")).unwrap();
    let e = scan_err(&ScanOptions {
        evs: Some(vec![-1000.0, 0.0, 1000.0]),
        ..ScanOptions::default()
    });
    assert!(e.contains("--declared-evs") && e.contains("at most"), "{e}");
    // In range: the same folder scans.
    let ok = scan::scan(
        dir.path(),
        &ScanOptions {
            evs: Some(vec![-2.0, 0.0, 2.0]),
            ..ScanOptions::default()
        },
    )
    .expect("scan");
    assert_eq!(ok.sets.len(), 1);
}

/// A bracket of three 8-bit PNGs of `w`×`h` filled by `code(frame, x, y)`, with list.txt.
fn png_bracket_of(dir: &Path, w: u32, h: u32, code: impl Fn(usize, u32, u32) -> u8) {
    std::fs::create_dir_all(dir).unwrap();
    for i in 0..3 {
        let img = image::RgbImage::from_fn(w, h, |x, y| image::Rgb([code(i, x, y); 3]));
        img.save(dir.join(format!("f{i}.png"))).unwrap();
    }
    std::fs::write(dir.join("list.txt"), "f0.png 4\nf1.png 1\nf2.png 0.25\n").unwrap();
}

#[test]
fn brackets_without_signal_are_refused_before_a_response_is_estimated() {
    use hdrsynth::capture::testset::{self, BracketOptions};
    let dir = tempfile::tempdir().unwrap();
    type Codes = fn(usize, u32, u32) -> u8;
    let cases: [(&str, u32, u32, Codes); 3] = [
        ("black", 48, 32, |_, _, _| 0),
        ("white", 48, 32, |_, _, _| 255),
        // 3×2 pixels: a response from six pixels.
        ("tiny", 3, 2, |i, x, y| {
            (40 + 60 * i as u32 + 7 * x + 11 * y) as u8
        }),
    ];
    for (name, w, h, code) in cases {
        let brackets = dir.path().join(name);
        png_bracket_of(&brackets.join("s"), w, h, code);
        let out = dir.path().join(format!("{name}_ts"));
        let e = testset::build(&brackets, &BracketOptions::default(), &out)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("holds no signal") && e.contains(&brackets.join("s").display().to_string()),
            "{name}: {e}"
        );
        assert!(!out.exists(), "{name}: output left");
    }
    // With a declared response nothing is estimated: an all-black or all-white set is
    // refused at its reference frame, naming it, and nothing is left.
    let declared = BracketOptions {
        response: ResponseChoice::Declared(hdrsynth::sensor::profile::Response::Srgb),
        ..BracketOptions::default()
    };
    for name in ["black", "white"] {
        let out = dir.path().join(format!("{name}_declared_ts"));
        let e = testset::build(&dir.path().join(name), &declared, &out)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("f1.png")
                && e.contains("100.00 % clipped or dark")
                && e.contains("no scene to score"),
            "{name}: {e}"
        );
        assert!(!out.exists(), "{name}: output left");
        // Nor is a profile calibrated from it (its metering frame is the same frame).
        let profile = dir.path().join(format!("{name}.toml"));
        let e = hdrsynth::capture::profile::calibrate_brackets(
            &dir.path().join(name),
            &hdrsynth::capture::profile::BracketProfileOptions {
                scan: hdrsynth::capture::scan::ScanOptions::default(),
                response: declared.response.clone(),
                out: profile.clone(),
                name: None,
                correlated: false,
            },
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("f1.png") && e.contains("no scene to score or measure"),
            "{name}: {e}"
        );
        assert!(!profile.exists(), "{name}: a profile was written");
    }
    // A ramp of the same size passes, with either response.
    let brackets = dir.path().join("ramp");
    png_bracket_of(&brackets.join("s"), 48, 32, |i, x, _| {
        (10 + 4 * x + 20 * i as u32).min(255) as u8
    });
    testset::build(
        &brackets,
        &BracketOptions::default(),
        &dir.path().join("ok"),
    )
    .expect("a ramp has signal");
    testset::build(&brackets, &declared, &dir.path().join("ok_declared"))
        .expect("a ramp has signal");
}

/// With a declared response (no estimate to fail first), frames under 11×11 (the SSIM window)
/// are refused naming the frame: 3×2 files, and a 1×1 region of larger ones.
#[test]
fn a_frame_smaller_than_the_ssim_window_is_refused_naming_it_with_a_declared_response() {
    use hdrsynth::capture::linearise::ResponseChoice;
    use hdrsynth::capture::scan::{Region, ScanOptions};
    use hdrsynth::capture::testset::{self, BracketOptions};
    use hdrsynth::sensor::profile::Response;
    let dir = tempfile::tempdir().unwrap();
    let ramp = |i: usize, x: u32, y: u32| (40 + 60 * i as u32 + 3 * x + 5 * y).min(255) as u8;
    let tiny = dir.path().join("tiny");
    png_bracket_of(&tiny.join("s"), 3, 2, ramp);
    let cut = dir.path().join("cut");
    png_bracket_of(&cut.join("s"), 48, 32, ramp);
    let declared = BracketOptions {
        response: ResponseChoice::Declared(Response::Srgb),
        scan: ScanOptions {
            region: Some(Region::Rect {
                x: 0,
                y: 0,
                w: 1,
                h: 1,
            }),
            ..ScanOptions::default()
        },
        ..BracketOptions::default()
    };
    let whole = BracketOptions {
        response: ResponseChoice::Declared(Response::Srgb),
        ..BracketOptions::default()
    };
    for (name, brackets, opts, size) in [
        ("tiny", &tiny, whole, "3×2 pixels"),
        ("cut", &cut, declared, "1×1 pixels in region 0,0,1,1"),
    ] {
        let out = dir.path().join(format!("{name}_ts"));
        let e = testset::build(brackets, &opts, &out)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(size) && e.contains("f1.png") && e.contains("at least 11×11"),
            "{name}: {e}"
        );
        assert!(!out.exists(), "{name}: output left");
    }
}

#[cfg(unix)]
#[test]
fn a_link_back_to_a_folder_already_read_is_refused_naming_it() {
    use hdrsynth::capture::scan::{self, ScanOptions};
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("b");
    png_bracket(&root);
    std::os::unix::fs::symlink(".", root.join("loop")).unwrap();
    let e = scan::scan(&root, &ScanOptions::default())
        .expect_err("refused")
        .to_string();
    assert!(e.contains("loop") && e.contains("a link"), "{e}");
}

#[test]
fn calibrate_brackets_refuses_a_profile_inside_its_bracket_folder() {
    use hdrsynth::capture::linearise::ResponseChoice;
    use hdrsynth::capture::profile::{BracketProfileOptions, calibrate_brackets};
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("b");
    png_bracket(&root);
    let before = snapshot(&root);
    let e = calibrate_brackets(
        &root,
        &BracketProfileOptions {
            scan: Default::default(),
            response: ResponseChoice::new(None, None).unwrap(),
            out: root.join("prof.toml"),
            name: None,
            correlated: false,
        },
    )
    .expect_err("refused")
    .to_string();
    assert!(e.contains("inside the input"), "{e}");
    assert_eq!(snapshot(&root), before, "the bracket folder changed");
}

#[test]
fn a_checkpoint_with_a_nan_weight_is_refused_naming_the_file_and_the_parameter() {
    use burn::module::{Module, ModuleMapper, Param};
    use burn::tensor::Tensor;
    use hdrsynth::models::ModelConfig;
    use hdrsynth::train::checkpoint;
    let dir = tempfile::tempdir().unwrap();
    let (_, ckpt) = one_step_run(dir.path());
    let state = checkpoint::read_state(&ckpt).unwrap();
    let ModelConfig::BlendUnet(m) = state.model else {
        panic!("Network-1 expected")
    };
    let dev = burn::tensor::Device::flex();
    let model = checkpoint::load_model(m.init(&dev).unwrap(), &ckpt).expect("finite loads");
    // The first float parameter's tensor times NaN, as a diverged run leaves it.
    struct FirstNan(bool);
    impl ModuleMapper for FirstNan {
        fn map_float<const D: usize>(&mut self, p: Param<Tensor<D>>) -> Param<Tensor<D>> {
            if std::mem::replace(&mut self.0, false) {
                p.map(|t| t.mul_scalar(f32::NAN))
            } else {
                p
            }
        }
    }
    let bad = model.map(&mut FirstNan(true));
    let path = ckpt.join("model.bpk");
    let bytes = checkpoint::model_to_bytes(&bad, &path).unwrap();
    let e = checkpoint::model_from_bytes(m.init(&dev).unwrap(), bytes, &path)
        .expect_err("refused")
        .to_string();
    assert!(
        e.contains("model.bpk") && e.contains("holds a NaN") && e.contains("parameter '"),
        "{e}"
    );
    eprintln!("{e}");
}

#[test]
fn a_bracket_folder_that_is_a_file_or_missing_is_named_as_such_once() {
    use hdrsynth::capture::scan::{self, ScanOptions};
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("f.png");
    std::fs::write(&file, b"x").unwrap();
    let e = scan::scan(&file, &ScanOptions::default())
        .expect_err("a file")
        .to_string();
    assert!(
        e.contains("f.png") && e.contains("is a file, not a bracket folder"),
        "{e}"
    );
    let e = scan::scan(&dir.path().join("none"), &ScanOptions::default())
        .expect_err("missing")
        .to_string();
    assert!(
        e.contains("none") && e.contains("no such bracket folder"),
        "{e}"
    );
    // Through the binary: one message, no "Caused by" repeating it.
    let out = bin()
        .args(["testset", "--brackets"])
        .arg(&file)
        .arg("--out")
        .arg(dir.path().join("ts"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(!out.status.success());
    assert!(
        text.contains("is a file, not a bracket folder") && !text.contains("Caused by"),
        "{text}"
    );
}

#[test]
fn an_empty_or_text_file_named_as_a_frame_is_called_not_an_image() {
    use hdrsynth::capture::scan::read_exif;
    let dir = tempfile::tempdir().unwrap();
    let empty = dir.path().join("a.png");
    std::fs::write(&empty, b"").unwrap();
    let e = read_exif(&empty).expect_err("empty").to_string();
    assert!(
        e.contains("a.png") && e.contains("an empty file (0 bytes), not an image"),
        "{e}"
    );
    let text = dir.path().join("b.jpg");
    std::fs::write(&text, b"hello\n").unwrap();
    let e = read_exif(&text).expect_err("text").to_string();
    assert!(
        e.contains("b.jpg") && e.contains("not an image: its 6 bytes") && !e.contains("EXIF"),
        "{e}"
    );
    // A real image without EXIF still reads as "no tags".
    let png = dir.path().join("c.png");
    write_ldr(&png, &Image::new(4, 4), BitDepth::Eight).unwrap();
    assert_eq!(read_exif(&png).expect("png").exposure_time, None);
}

#[test]
fn radiance_flags_given_with_brackets_are_refused_not_ignored() {
    let dir = tempfile::tempdir().unwrap();
    for flag in [["--isos", "100"], ["--bits", "16"], ["--evs", "-2,0,2"]] {
        let out = bin()
            .args(["testset", "--brackets"])
            .arg(dir.path())
            .args(flag)
            .arg("--out")
            .arg(dir.path().join("ts"))
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stderr).to_string();
        assert_eq!(out.status.code(), Some(2), "{text}");
        assert!(
            text.contains(flag[0])
                && text.contains("--brackets")
                && text.contains("cannot be used"),
            "{text}"
        );
        assert!(!dir.path().join("ts").exists());
    }
}

#[test]
fn frames_of_one_set_in_different_sizes_are_refused_naming_both() {
    use hdrsynth::capture::linearise::ResponseChoice;
    use hdrsynth::capture::profile::{BracketProfileOptions, calibrate_brackets};
    use hdrsynth::capture::testset::{self, BracketOptions};
    use hdrsynth::sensor::profile::Response;
    let dir = tempfile::tempdir().unwrap();
    let b = dir.path().join("b");
    let ramp = |w: usize, h: usize, k: f32| {
        let data = (0..w * h * 3)
            .map(|i| ((i % 97) as f32 / 97.0 * k).min(1.0))
            .collect();
        Image::from_vec(w, h, data)
    };
    write_ldr(&b.join("a.png"), &ramp(32, 24, 0.3), BitDepth::Eight).unwrap();
    write_ldr(&b.join("b.png"), &ramp(32, 24, 0.6), BitDepth::Eight).unwrap();
    write_ldr(&b.join("c.png"), &ramp(30, 24, 1.0), BitDepth::Eight).unwrap();
    std::fs::write(b.join("list.txt"), "a.png 4\nb.png 1\nc.png 0.25\n").unwrap();
    let want = |e: &str| {
        assert!(
            e.contains("c.png: 30×24, but") && e.contains("a.png of the same set is 32×24"),
            "{e}"
        );
    };
    // A declared response (no estimate to stop it): the calibration refuses, writing nothing.
    let out = dir.path().join("p.toml");
    let opts = BracketProfileOptions {
        scan: Default::default(),
        response: ResponseChoice::Declared(Response::Srgb),
        out: out.clone(),
        name: None,
        correlated: false,
    };
    want(
        &calibrate_brackets(&b, &opts)
            .expect_err("sizes")
            .to_string(),
    );
    assert!(!out.exists());
    // An estimated response: the test set refuses before estimating it.
    let ts = dir.path().join("ts");
    let e = testset::build(&b, &BracketOptions::default(), &ts).expect_err("sizes");
    want(&e.to_string());
    assert!(!ts.exists());
}

/// The binary's message says each cause once: an I/O error whose text the library's message
/// already holds gets no "Caused by" (anyhow's default report would repeat it); a cause the
/// message does not hold keeps anyhow's "Caused by:" shape, indented by four spaces.
#[test]
fn a_cause_the_message_already_holds_is_not_repeated() {
    use hdrsynth::cli::error_report;
    let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory");
    let lib = hdrsynth::Error::io("runs/a.toml", io);
    let plain = format!(
        "{:?}",
        anyhow::Error::new(hdrsynth::Error::io(
            "runs/a.toml",
            std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory"),
        ))
    );
    assert!(
        plain.starts_with(
            "runs/a.toml: No such file or directory\n\nCaused by:\n    No such file or directory"
        ),
        "anyhow's own report repeats the cause: {plain}"
    );
    assert_eq!(
        error_report(&anyhow::Error::new(lib)),
        "Error: runs/a.toml: No such file or directory"
    );
    let e = anyhow::Error::new(hdrsynth::Error::context(
        "stage 2 (pretraining)",
        hdrsynth::Error::Invalid("data.batch_size = 0 must be positive".into()),
    ));
    assert_eq!(
        error_report(&e),
        "Error: stage 2 (pretraining)\n\nCaused by:\n    data.batch_size = 0 must be positive"
    );
    // Through the binary: a missing config, named once.
    let dir = tempfile::tempdir().unwrap();
    let out = bin()
        .args(["train", "--config"])
        .arg(dir.path().join("missing.toml"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(
        text.starts_with("Error: ") && text.contains("missing.toml") && !text.contains("Caused by"),
        "{text}"
    );
}

/// `[mix]`: its share is a fraction and its stream must batch with `[data]`'s.
#[test]
fn a_mix_whose_crops_differ_from_the_data_or_whose_share_is_out_of_range_is_refused() {
    use hdrsynth::config::parse_toml;
    use hdrsynth::train::config::TrainConfig;
    let base = "[run]\nout = \"r\"\nseed = 1\nsteps = 1\n[model]\nkind = \"wu\"\n\
                [data]\ndataset = \"d\"\npatch = 64\nbatch_size = 2\nprofile = \"pure\"\n\
                [mix]\nfraction = 0.5\n[mix.data]\ndataset = \"e\"\nbatch_size = 2\npatch = 64\n\
                profile = \"pure\"\n";
    let cfg = parse_toml::<TrainConfig>(base, Path::new("t.toml")).expect("config");
    cfg.validate().expect("a matching mix is valid");
    assert_eq!(cfg.mix.as_ref().map(|m| m.fraction), Some(0.5));
    for (from, to, key) in [
        ("fraction = 0.5", "fraction = 1.5", "mix.fraction"),
        (
            "batch_size = 2\npatch = 64",
            "batch_size = 2\npatch = 32",
            "mix.data",
        ),
    ] {
        let text = base.replace(from, to);
        assert_ne!(text, base, "{to}");
        let cfg = parse_toml::<TrainConfig>(&text, Path::new("t.toml")).expect("parses");
        let e = cfg.validate().expect_err(to).to_string();
        assert!(e.contains(key), "{to}: {e}");
    }
}
