//! The training loader: determinism across workers, aligned augmentation, the Network-2
//! reference from the static set, fresh noise per epoch.

use hdrsynth::config::parse_toml;
use hdrsynth::data::generate::GenerateConfig;
use hdrsynth::data::ground_truth::blend_classes;
use hdrsynth::data::loader::{Loader, LoaderConfig, Sample, SampleKind, Target, dihedral};
use hdrsynth::io::Image;
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn dataset(evs: &str, dir: &Path) {
    let text = format!(
        "seed = 5\ncount = 4\nwidth = 96\nheight = 80\nevs = {evs}\n[camera]\ncandidates = 4\n"
    );
    let mut c: GenerateConfig = parse_toml(&text, Path::new("t.toml")).expect("config");
    c.source = None;
    hdrsynth::data::generate::generate(&c, dir, false).expect("generate");
}

fn loader_cfg(dir: &Path, kind: &str, workers: usize, realism: bool) -> LoaderConfig {
    let profile: PathBuf =
        hdrsynth::sensor::profile::SensorProfile::shipped_dir().join("example_synthetic.toml");
    let r = if realism {
        format!(
            "[realism]\nprofile = {:?}\nisos = [100.0, 800.0, 3200.0]\n",
            profile
        )
    } else {
        String::new()
    };
    let text = format!(
        "dataset = {:?}\nkind = \"{kind}\"\npatch = 48\nbatch_size = 3\nworkers = {workers}\nseed = 9\n{r}",
        dir
    );
    parse_toml(&text, Path::new("loader.toml")).expect("loader config")
}

fn epoch(cfg: &LoaderConfig, e: u64) -> Vec<Sample> {
    let l = Arc::new(Loader::new(cfg).expect("loader"));
    l.epoch(e).flat_map(|b| b.expect("batch")).collect()
}

#[test]
fn samples_are_identical_for_1_2_and_4_workers_and_noise_changes_per_epoch() {
    let dir = tempfile::tempdir().expect("tmp");
    dataset("[-3.0, 0.0]", dir.path());
    let one = epoch(&loader_cfg(dir.path(), "network1", 1, true), 0);
    assert_eq!(one.len(), 4);
    for w in [2, 4] {
        assert_eq!(
            one,
            epoch(&loader_cfg(dir.path(), "network1", w, true), 0),
            "{w} workers"
        );
    }
    let next = epoch(&loader_cfg(dir.path(), "network1", 2, true), 1);
    assert_ne!(
        one[0].input, next[0].input,
        "epoch 1 must draw new crops/noise"
    );
    // Same (seed, epoch, index) → same sample, also when asked directly.
    let l = Loader::new(&loader_cfg(dir.path(), "network1", 1, true)).expect("loader");
    assert_eq!(l.sample(0, 2).expect("sample"), one[2]);
    let s = &one[0];
    assert_eq!((s.channels, s.size, s.input.len()), (6, 48, 6 * 48 * 48));
    assert!(s.iso.is_some());
    // 8-bit quantised inputs.
    assert!(
        s.input
            .iter()
            .all(|v| ((v * 255.0).round() - v * 255.0).abs() < 1e-3)
    );
}

#[test]
fn noise_differs_between_epochs_for_the_same_crop() {
    // Square 64×64 sets and a 64 px patch: the crop is the whole frame, so two samples of the
    // same set differ only by noise (augmentation off, one ISO).
    let dir = tempfile::tempdir().expect("tmp");
    let text = "seed = 5\ncount = 3\nwidth = 64\nheight = 64\nevs = [-3.0, 0.0]\n[camera]\ncandidates = 4\n";
    let mut c: GenerateConfig = parse_toml(text, Path::new("t.toml")).expect("config");
    c.source = None;
    hdrsynth::data::generate::generate(&c, dir.path(), false).expect("generate");
    let mut cfg = loader_cfg(dir.path(), "network1", 1, true);
    cfg.augment = false;
    cfg.patch = 64;
    cfg.realism.as_mut().expect("realism").isos = vec![800.0];
    let l = Loader::new(&cfg).expect("loader");
    let a = l.sample(0, 0).expect("a");
    let b = (0..3)
        .map(|j| l.sample(1, j).expect("b"))
        .find(|b| b.set == a.set)
        .expect("same set in epoch 1");
    assert_ne!(
        a.input, b.input,
        "same set and crop in another epoch must get new noise"
    );
    assert_eq!(
        a,
        l.sample(0, 0).expect("again"),
        "same (seed, epoch, index) must repeat"
    );
    let mut pure_cfg = cfg.clone();
    pure_cfg.realism = None;
    let pure = Loader::new(&pure_cfg).expect("pure");
    let pa = pure.sample(0, 0).expect("pure");
    let pb = (0..3)
        .map(|j| pure.sample(1, j).expect("pb"))
        .find(|p| p.set == a.set)
        .expect("pure same set");
    assert_eq!(
        pa.input, pb.input,
        "pure mode: the same set and crop give the same frames"
    );
}

#[test]
fn augmentation_keeps_inputs_and_targets_aligned() {
    // An asymmetric pattern: each of the 8 transforms gives a different plane, and applying
    // the same transform to a per-pixel function of the input gives the function of the
    // transformed input.
    let n = 5;
    let plane: Vec<u16> = (0..n * n).map(|i| i as u16 * 7 % 23).collect();
    let mut seen = Vec::new();
    for t in 0..8u8 {
        let d = dihedral(&plane, n, 1, t);
        assert!(!seen.contains(&d), "transform {t} repeats another");
        seen.push(d);
    }
    // Rotating four times is the identity; flip twice too.
    let r = (0..4).fold(plane.clone(), |p, _| dihedral(&p, n, 1, 1));
    assert_eq!(r, plane);
    // The loader's pairing: blend classes of transformed frames = transformed classes.
    let size = 16;
    let low = Image::from_fn(size, size, |x, y| {
        [x as f32 / 20.0, (y * y) as f32 / 300.0, 0.1]
    });
    let high = low.map(|v| (v * 8.0).min(1.0));
    let classes = blend_classes(&low, &high).expect("classes");
    for t in 0..8u8 {
        let tl = Image::from_vec(size, size, dihedral(&low.data, size, 3, t));
        let th = Image::from_vec(size, size, dihedral(&high.data, size, 3, t));
        assert_eq!(
            blend_classes(&tl, &th).expect("classes"),
            dihedral(&classes, size, 1, t),
            "t = {t}"
        );
    }
}

#[test]
fn network2_reference_comes_from_the_static_set() {
    let dir = tempfile::tempdir().expect("tmp");
    dataset("[-2.0, 0.0, 2.0]", dir.path());
    let mut cfg = loader_cfg(dir.path(), "network2", 1, false);
    cfg.augment = false;
    let l = Loader::new(&cfg).expect("loader");
    let info = hdrsynth::data::layout::detect(dir.path()).expect("detect");
    for i in 0..4 {
        let s = l.sample(0, i).expect("sample");
        assert_eq!(
            (s.channels, s.exposure_times.clone()),
            (18, vec![0.25, 1.0, 4.0])
        );
        let set = info.sets.iter().find(|x| x.name == s.set).expect("set");
        let stat = hdrsynth::io::read_image(&set.static_frames[1]).expect("static ref");
        let dynm = hdrsynth::io::read_image(&set.dynamic_frames[0]).expect("dynamic low");
        let p = s.size;
        // Find the crop: the reference channel block (frame 1 LDR = channels 6..9) must equal
        // the static reference at some offset; the low frame the dynamic EV−2 frame there.
        let plane = |k: usize| &s.input[k * p * p..(k + 1) * p * p];
        let mut found = false;
        'search: for y0 in 0..=set.height - p {
            for x0 in 0..=set.width - p {
                let ok = (0..p * p).all(|q| {
                    let (x, y) = (x0 + q % p, y0 + q / p);
                    (plane(6)[q] - stat.get(x, y)[0]).abs() < 1e-6
                        && (plane(0)[q] - dynm.get(x, y)[0]).abs() < 1e-6
                });
                if ok {
                    found = true;
                    break 'search;
                }
            }
        }
        assert!(
            found,
            "sample {i}: reference not from the static set at any crop"
        );
        match &s.target {
            Target::Hdr(h) => assert_eq!(h.len(), 3 * p * p),
            Target::Classes(_) => panic!("network2 target must be HDR"),
        }
    }
    // The kind is checked against the dataset's EVs.
    let e = Loader::new(&loader_cfg(dir.path(), "network1", 1, false))
        .err()
        .expect("needs EV −3");
    assert!(e.to_string().contains("needs"), "{e}");
    let _ = SampleKind::Network1;
}

#[test]
fn preview_writes_a_contact_sheet_of_the_expected_size() {
    let dir = tempfile::tempdir().expect("tmp");
    dataset("[-3.0, 0.0]", dir.path());
    let out = dir.path().join("sheet.png");
    let args = hdrsynth::data::preview::PreviewOptions {
        dir: dir.path().to_path_buf(),
        profile: hdrsynth::sensor::profile::SensorProfile::shipped_dir()
            .join("canon_eos_550d.toml"),
        iso: 800.0,
        kind: None,
        count: 3,
        patch: 48,
        seed: 0,
        out: out.clone(),
    };
    hdrsynth::data::preview::preview(&args).expect("preview");
    let img = hdrsynth::io::read_image(&out).expect("sheet");
    // Network-1: 2 pure + 2 realistic frames + target = 5 tiles of 48 px + 4 px gaps, 3 rows.
    assert_eq!((img.width, img.height), (5 * 52, 3 * 52));
}

/// The sample's two frames (channel-major 6×p×p input) as images.
fn pair_of(s: &Sample) -> (Image, Image) {
    let p = s.size;
    let frame = |k: usize| {
        Image::from_fn(p, p, |x, y| {
            std::array::from_fn(|c| s.input[(k * 3 + c) * p * p + y * p + x])
        })
    };
    (frame(0), frame(1))
}

fn classes_of(s: &Sample) -> Vec<u8> {
    match &s.target {
        Target::Classes(c) => c.clone(),
        Target::Hdr(_) => panic!("a Network-1 sample"),
    }
}

/// Network-1's default targets are the Mertens classes of the same crop rendered without the
/// noise draw: exactly the classes of the frames a noise-free loader gives for that sample,
/// while the inputs stay the noisy ones; `target_frames = "noisy"` gives the classes of the
/// inputs themselves.
#[test]
fn network1_targets_come_from_the_noise_free_render_of_the_same_crop() {
    let dir = tempfile::tempdir().expect("tmp");
    dataset("[-3.0, 0.0]", dir.path());
    let mut clean = loader_cfg(dir.path(), "network1", 1, true);
    clean.augment = false;
    let mut noisy = clean.clone();
    noisy.target_frames = hdrsynth::data::loader::TargetFrames::Noisy;
    let mut quiet = clean.clone();
    if let Some(r) = quiet.realism.as_mut() {
        r.noise = hdrsynth::sensor::realism::NoiseModel::None;
    }
    let (c, n, q) = (
        Loader::new(&clean).expect("clean"),
        Loader::new(&noisy).expect("noisy"),
        Loader::new(&quiet).expect("quiet"),
    );
    let mut differ = 0;
    for i in 0..4 {
        let (sc, sn, sq) = (
            c.sample(0, i).expect("c"),
            n.sample(0, i).expect("n"),
            q.sample(0, i).expect("q"),
        );
        assert_eq!(sc.input, sn.input, "the option changes targets only");
        assert_ne!(sc.input, sq.input, "the inputs carry noise");
        let (ql, qh) = pair_of(&sq);
        assert_eq!(classes_of(&sc), blend_classes(&ql, &qh).expect("classes"));
        let (nl, nh) = pair_of(&sn);
        assert_eq!(classes_of(&sn), blend_classes(&nl, &nh).expect("classes"));
        differ += usize::from(classes_of(&sc) != classes_of(&sn));
    }
    assert!(
        differ > 0,
        "noise changes the Mertens classes of some sample"
    );
}

/// `target_space = "scene"` leaves the inputs as they are and gives Network-2 the target
/// without the colour transform: the device target is T times it, per pixel (by hand from the
/// profile's matrix).
#[test]
fn a_scene_target_is_the_device_target_without_t() {
    use hdrsynth::data::loader::Target;
    use hdrsynth::sensor::realism::TargetSpace;
    let dir = tempfile::tempdir().expect("tmp");
    dataset("[-2.0, 0.0, 2.0]", dir.path());
    let mut device = loader_cfg(dir.path(), "network2", 1, true);
    device.augment = false;
    let mut scene = device.clone();
    scene.realism.as_mut().expect("realism").target_space = TargetSpace::Scene;
    let profile = hdrsynth::sensor::profile::SensorProfile::load(
        &hdrsynth::sensor::profile::SensorProfile::shipped_dir().join("example_synthetic.toml"),
    )
    .expect("profile");
    let m = profile.colour.as_ref().expect("matrix").matrix;
    let (d, s) = (
        Loader::new(&device).expect("device"),
        Loader::new(&scene).expect("scene"),
    );
    let mut checked = 0;
    for i in 0..4 {
        let (sd, ss) = (d.sample(0, i).expect("d"), s.sample(0, i).expect("s"));
        assert_eq!(sd.input, ss.input, "the option changes the target only");
        let (Target::Hdr(td), Target::Hdr(ts)) = (&sd.target, &ss.target) else {
            panic!("network2 targets are HDR");
        };
        let n = td.len() / 3;
        for px in 0..n {
            let sv = [ts[px], ts[n + px], ts[2 * n + px]].map(f64::from);
            let dv = [td[px], td[n + px], td[2 * n + px]].map(f64::from);
            // Away from the clipping point, which applies after T.
            if sv.iter().chain(&dv).any(|&v| v >= 1.0) {
                continue;
            }
            for c in 0..3 {
                let want = (0..3).map(|k| m[c][k] * sv[k]).sum::<f64>().max(0.0);
                assert!(
                    (dv[c] - want).abs() <= 1e-5 * want.max(1e-3),
                    "{dv:?} vs T·{sv:?}"
                );
            }
            checked += 1;
        }
        assert_ne!(td, ts);
    }
    assert!(checked > 1000, "{checked} pixels checked");
}

/// `static_fraction`: a still sample takes every frame from the static set, at the crop the
/// sample would have anyway; the other samples are the default's, unchanged.
#[test]
fn a_still_sample_takes_every_frame_from_the_static_set() {
    let dir = tempfile::tempdir().expect("tmp");
    dataset("[-2.0, 0.0, 2.0]", dir.path());
    let info = hdrsynth::data::layout::detect(dir.path()).expect("detect");
    let with = |f: f64| {
        let mut cfg = loader_cfg(dir.path(), "network2", 1, false);
        cfg.augment = false;
        cfg.static_fraction = f;
        Loader::new(&cfg).expect("loader")
    };
    let (moving, still, half) = (with(0.0), with(1.0), with(0.5));
    let (mut n_still, mut n_moved) = (0, 0);
    for i in 0..16 {
        let (m, s, h) = (
            moving.sample(0, i).expect("sample"),
            still.sample(0, i).expect("sample"),
            half.sample(0, i).expect("sample"),
        );
        let p = s.size;
        let plane = |x: &Sample, k: usize| x.input[k * p * p..(k + 1) * p * p].to_vec();
        assert_eq!(
            (m.set.as_str(), plane(&m, 6)),
            (s.set.as_str(), plane(&s, 6))
        );
        let set = info.sets.iter().find(|x| x.name == s.set).expect("set");
        let stat = hdrsynth::io::read_image(&set.static_frames[0]).expect("static low");
        let refr = hdrsynth::io::read_image(&set.static_frames[1]).expect("static ref");
        // The crop: where the reference plane matches the static reference.
        let crop = (0..=set.height - p)
            .flat_map(|y| (0..=set.width - p).map(move |x| (x, y)))
            .find(|&(x0, y0)| {
                (0..p * p)
                    .all(|q| (plane(&s, 6)[q] - refr.get(x0 + q % p, y0 + q / p)[0]).abs() < 1e-6)
            })
            .expect("the reference crop");
        let low_still = (0..p * p)
            .all(|q| (plane(&s, 0)[q] - stat.get(crop.0 + q % p, crop.1 + q / p)[0]).abs() < 1e-6);
        assert!(
            low_still,
            "sample {i}: the still sample's EV−2 frame is not the static one"
        );
        n_moved += usize::from(plane(&m, 0) != plane(&s, 0));
        if plane(&h, 0) == plane(&s, 0) && plane(&h, 0) != plane(&m, 0) {
            n_still += 1;
        } else {
            assert_eq!(h.input, m.input, "sample {i}: a moving sample changed");
        }
    }
    assert!(
        n_moved > 4,
        "the dataset's subjects move in {n_moved} of 16 crops"
    );
    assert!(
        n_still > 0 && n_still < n_moved,
        "half still: {n_still} of {n_moved}"
    );
}

/// A Kalantari set (three 16-bit TIFFs, exposure.txt, HDRImg.hdr) of a flat grey at code 0.5
/// in every frame, its exposure file `stops`.
fn kalantari_set(dir: &Path, stops: &str) {
    use hdrsynth::io::{BitDepth, write_hdr, write_ldr};
    std::fs::create_dir_all(dir).expect("mkdir");
    let grey = Image::from_fn(64, 64, |_, _| [0.5; 3]);
    for name in ["a.tif", "b.tif", "c.tif"] {
        write_ldr(&dir.join(name), &grey, BitDepth::Sixteen).expect("tif");
    }
    std::fs::write(dir.join("exposure.txt"), stops).expect("exposure.txt");
    write_hdr(
        &dir.join("HDRImg.hdr"),
        &Image::from_fn(64, 64, |_, _| [0.2; 3]),
    )
    .expect("hdr");
}

#[test]
fn network2_takes_a_three_frame_set_at_the_stops_it_records() {
    let sample = |stops: &str| {
        let dir = tempfile::tempdir().expect("tmp");
        kalantari_set(dir.path(), stops);
        let cfg = loader_cfg(dir.path(), "network2", 1, false);
        epoch(&cfg, 0).remove(0)
    };
    // Two stops apart: Wu's times.
    assert_eq!(sample("0\n2\n4\n").exposure_times, vec![0.25, 1.0, 4.0]);
    // A device's own steps (1.9 and 2.2 stops, as its exposure times made them): taken as
    // recorded, relative to the reference.
    let s = sample("0\n1.9\n4.1\n");
    let want = [(-1.9f32).exp2(), 1.0, 2.2f32.exp2()];
    for (t, w) in s.exposure_times.iter().zip(want) {
        assert!(
            (t - w).abs() < 1e-5,
            "{:?} against {want:?}",
            s.exposure_times
        );
    }
    // Frame 0's linear channel is LDR^2.2 / t₀ (the 8-bit code of 0.5 is 128/255).
    let ldr = (128.0f32 / 255.0).powf(2.2);
    let (c, n) = (s.channels, s.size * s.size);
    assert_eq!(c, 18);
    let hdr0 = s.input[3 * n];
    assert!(
        (hdr0 - ldr / want[0]).abs() < 1e-4,
        "{hdr0} against {}",
        ldr / want[0]
    );
}

#[test]
fn a_mixed_stream_takes_its_share_from_the_second_loader_and_replays_on_resume() {
    let (a, b) = (
        tempfile::tempdir().expect("tmp"),
        tempfile::tempdir().expect("tmp"),
    );
    dataset("[-3.0, 0.0]", a.path());
    dataset("[-3.0, 0.0]", b.path());
    let own = |dir: &Path| Loader::new(&loader_cfg(dir, "network1", 1, true)).expect("loader");
    let other = |seed: u64| {
        let mut c = loader_cfg(b.path(), "network1", 1, true);
        c.seed = seed;
        Loader::new(&c).expect("loader")
    };
    let n = 200u64;
    // Samples of the two streams differ (their seeds do), so each mixed sample says whose it is.
    let (first, second) = (own(a.path()), other(77));
    let from_other = |mixed: &Loader| -> Vec<bool> {
        (0..n)
            .map(|g| {
                let s = mixed.stream_sample(g).expect("sample");
                let o = second.stream_sample(g).expect("sample");
                let mine = first.stream_sample(g).expect("sample");
                assert!(s == o || s == mine, "sample {g} is neither stream's");
                s == o
            })
            .collect()
    };
    let none = from_other(&own(a.path()).mixed(other(77), 0.0));
    assert!(none.iter().all(|&x| !x));
    let all = from_other(&own(a.path()).mixed(other(77), 1.0));
    assert!(all.iter().all(|&x| x));
    let half = from_other(&own(a.path()).mixed(other(77), 0.5));
    let k = half.iter().filter(|&&x| x).count();
    // Binomial(200, ½): 100 ± 7; outside 70–130 is a 1-in-10⁵ event for a fair draw.
    assert!((70..=130).contains(&k), "{k} of {n} from the second stream");
    // A fresh loader (a resumed run) draws the same choice for every index.
    assert_eq!(half, from_other(&own(a.path()).mixed(other(77), 0.5)));
}
