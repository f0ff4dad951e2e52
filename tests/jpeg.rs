//! A JPEG's quantisation tables and IJG quality, against Pillow (libjpeg's
//! `jpeg_set_quality`): tests/data/jpeg_quality, written by tools/jpeg_quality_oracle.py.

use hdrsynth::io::jpeg::{file_quality, quant_tables};
use std::path::Path;

fn data(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/jpeg_quality")
        .join(name)
}

#[test]
fn the_tables_read_are_the_ones_libjpeg_wrote_and_give_back_its_quality() {
    for q in [10u32, 50, 75, 90, 95, 100] {
        let path = data(&format!("q{q}.jpg"));
        let bytes = std::fs::read(&path).expect("read");
        let tables = quant_tables(&bytes, &path).expect("tables");
        let text = std::fs::read_to_string(data(&format!("q{q}_tables.txt"))).expect("oracle");
        for line in text.lines() {
            let (id, values) = line.split_once(": ").expect("id: values");
            let id: u8 = id.parse().expect("id");
            let want: Vec<u16> = values
                .split(' ')
                .map(|v| v.parse().expect("value"))
                .collect();
            let t = tables.iter().find(|t| t.id == id).expect("table read");
            assert_eq!(t.values.to_vec(), want, "q{q}, table {id}");
        }
        assert_eq!(tables.len(), text.lines().count(), "q{q}");
        let (got, mismatch) = file_quality(&path).expect("read").expect("tables");
        assert_eq!((got, mismatch), (q, 0.0), "q{q}");
    }
}

#[test]
fn a_file_that_is_not_a_jpeg_or_is_cut_short_is_named() {
    let path = Path::new("frame.jpg");
    let e = quant_tables(b"\x89PNG\r\n", path).unwrap_err().to_string();
    assert!(
        e.contains("frame.jpg") && e.contains("start-of-image"),
        "{e}"
    );
    let bytes = std::fs::read(data("q75.jpg")).expect("read");
    // Cut inside the first DQT segment.
    let dqt = bytes
        .windows(2)
        .position(|w| w == [0xFF, 0xDB])
        .expect("a DQT");
    let e = quant_tables(&bytes[..dqt + 30], path)
        .unwrap_err()
        .to_string();
    assert!(e.contains("frame.jpg") && e.contains("past the end"), "{e}");
}
