//! EXIF orientation: frames are read upright, and a set whose frames disagree is refused.

use crate::helpers::{Entry, Tags, assert_close, ifd, scan, stops_rel, write_jpeg};
use hdrsynth::capture::scan::{self, ScanOptions};
use std::path::Path;

/// The stored 3×2 test image's labels: row 0 = A B C, row 1 = D E F.
const LABELS: [[u8; 3]; 6] = [
    [250, 10, 10],   // A
    [10, 250, 10],   // B
    [10, 10, 250],   // C
    [250, 250, 10],  // D
    [10, 250, 250],  // E
    [130, 130, 130], // F
];

/// The displayed label grid (rows of label indices, A = 0) for each Orientation, rotated by
/// hand from the EXIF 2.32 definitions (where stored row 0 and column 0 appear).
fn displayed(o: u16) -> Vec<Vec<usize>> {
    let (a, b, c, d, e, f) = (0, 1, 2, 3, 4, 5);
    match o {
        1 => vec![vec![a, b, c], vec![d, e, f]],
        2 => vec![vec![c, b, a], vec![f, e, d]],
        3 => vec![vec![f, e, d], vec![c, b, a]],
        4 => vec![vec![d, e, f], vec![a, b, c]],
        5 => vec![vec![a, d], vec![b, e], vec![c, f]],
        6 => vec![vec![d, a], vec![e, b], vec![f, c]],
        7 => vec![vec![f, c], vec![e, b], vec![d, a]],
        8 => vec![vec![c, f], vec![b, e], vec![a, d]],
        _ => unreachable!(),
    }
}

/// The stored image, each label a `block`×`block` square.
fn label_pixels(block: usize) -> (usize, usize, Vec<u8>) {
    let (w, h) = (3 * block, 2 * block);
    let mut rgb = Vec::with_capacity(w * h * 3);
    for y in 0..h {
        for x in 0..w {
            rgb.extend(LABELS[(y / block) * 3 + x / block]);
        }
    }
    (w, h, rgb)
}

/// A little-endian baseline 8-bit RGB TIFF (uncompressed, one strip) with Orientation `o`.
fn write_oriented_tiff(path: &Path, block: usize, o: u16) {
    let (w, h, rgb) = label_pixels(block);
    let entries = |strip_at: u32| -> Vec<Entry> {
        vec![
            (256, 4, 1, (w as u32).to_le_bytes().to_vec()),
            (257, 4, 1, (h as u32).to_le_bytes().to_vec()),
            (
                258,
                3,
                3,
                [8u16, 8, 8].iter().flat_map(|v| v.to_le_bytes()).collect(),
            ),
            (259, 3, 1, 1u16.to_le_bytes().to_vec()),
            (262, 3, 1, 2u16.to_le_bytes().to_vec()),
            (273, 4, 1, strip_at.to_le_bytes().to_vec()),
            (274, 3, 1, o.to_le_bytes().to_vec()),
            (277, 3, 1, 3u16.to_le_bytes().to_vec()),
            (278, 4, 1, (h as u32).to_le_bytes().to_vec()),
            (279, 4, 1, (rgb.len() as u32).to_le_bytes().to_vec()),
        ]
    };
    let strip_at = 8 + ifd(8, entries(0)).len() as u32;
    let mut out = b"II*\0".to_vec();
    out.extend(8u32.to_le_bytes());
    out.extend(ifd(8, entries(strip_at)));
    assert_eq!(out.len(), strip_at as usize);
    out.extend(rgb);
    std::fs::write(path, out).expect("write tiff");
}

/// Assert that `img` shows `displayed(o)` with `block`-pixel labels (centres within `tol`).
fn assert_displayed(img: &hdrsynth::io::Image, o: u16, block: usize, tol: f32, what: &str) {
    let grid = displayed(o);
    assert_eq!(
        (img.width, img.height),
        (grid[0].len() * block, grid.len() * block),
        "{what}: size"
    );
    for (gy, row) in grid.iter().enumerate() {
        for (gx, &label) in row.iter().enumerate() {
            let p = img.get(gx * block + block / 2, gy * block + block / 2);
            for c in 0..3 {
                let want = f32::from(LABELS[label][c]) / 255.0;
                assert!(
                    (p[c] - want).abs() <= tol,
                    "{what}: orientation {o}, cell ({gx}, {gy}) channel {c}: {} vs {want}",
                    p[c]
                );
            }
        }
    }
}

fn scan_one_set(dir: &Path) -> scan::BracketSet {
    let s = scan(dir);
    assert_eq!(s.sets.len(), 1, "{:?}", s.notes);
    s.sets.into_iter().next().expect("set")
}

#[test]
fn every_exif_orientation_is_applied_to_tiff_and_jpeg_frames() {
    let tmp = tempfile::tempdir().expect("tmp");
    for o in 1..=8u16 {
        // TIFF: exact pixels, stops from Kalantari's exposure.txt.
        let d = tmp.path().join(format!("tif_{o}"));
        std::fs::create_dir_all(&d).expect("mkdir");
        for n in ["a.tif", "b.tif", "c.tif"] {
            write_oriented_tiff(&d.join(n), 1, o);
        }
        std::fs::write(d.join("exposure.txt"), "0\n2\n4\n").expect("expo");
        let set = scan_one_set(&d);
        for f in &set.frames {
            assert_eq!(f.exif.orientation, Some(o));
            let img = scan::read_frame_image(f).expect("read");
            assert_displayed(&img, o, 1, 0.0, "tiff");
        }
        // JPEG: 16-px label blocks (block centres are clear of the codec's edge ringing).
        let d = tmp.path().join(format!("jpg_{o}"));
        std::fs::create_dir_all(&d).expect("mkdir");
        let (w, h, rgb) = label_pixels(16);
        for (n, den) in [("a.jpg", 400u32), ("b.jpg", 100), ("c.jpg", 25)] {
            let t = Tags {
                exposure_time: Some((1, den)),
                orientation: Some(o),
                ..Tags::default()
            };
            write_jpeg(&d.join(n), w as u32, h as u32, &rgb, Some(&t));
        }
        let set = scan_one_set(&d);
        assert_close(&stops_rel(&set), &[0.0, 2.0, 4.0], 1e-9);
        for f in &set.frames {
            let img = scan::read_frame_image(f).expect("read");
            assert_displayed(&img, o, 16, 0.05, "jpeg");
        }
    }
}

#[test]
fn frames_of_one_set_with_different_orientations_are_refused_naming_them() {
    let tmp = tempfile::tempdir().expect("tmp");
    let d = tmp.path().join("portrait");
    std::fs::create_dir_all(&d).expect("mkdir");
    for (n, o) in [("a.tif", 6u16), ("b.tif", 1), ("c.tif", 6)] {
        write_oriented_tiff(&d.join(n), 1, o);
    }
    std::fs::write(d.join("exposure.txt"), "0\n2\n4\n").expect("expo");
    let e = scan::scan(tmp.path(), &ScanOptions::default())
        .expect_err("mixed orientations")
        .to_string();
    assert!(e.contains("different EXIF orientations"), "{e}");
    for n in ["a.tif", "b.tif", "c.tif"] {
        assert!(e.contains(n), "{e}");
    }
    // An Orientation outside 1–8 is an error naming the file, not a panic.
    let d = tmp.path().join("bad");
    std::fs::create_dir_all(&d).expect("mkdir");
    write_oriented_tiff(&d.join("x.tif"), 1, 9);
    write_oriented_tiff(&d.join("y.tif"), 1, 1);
    std::fs::write(d.join("exposure.txt"), "0\n2\n").expect("expo");
    let e = scan::scan(&d, &ScanOptions::default())
        .expect_err("orientation 9")
        .to_string();
    assert!(e.contains("x.tif") && e.contains("Orientation"), "{e}");
}
