//! The realism-against-quality plot of a sweep's table: each point where the axes' rule puts
//! it (positions computed by hand), its interval drawn as a bar, and a malformed table refused
//! with the file and the line named.

use hdrsynth::experiments::sweep::{read_sweep, realism_plot, write_realism_plot};

const HEADER: &str = "width,steps_factor,moving_training,static_fraction,head,prior,testset,metric,\
net_r,net_s,net_s-net_r,net_s-net_r_ci,net_s-net_r_per_seed,net_s-triangle,net_s-triangle_ci";

fn table(rows: &[&str]) -> String {
    let mut s = HEADER.to_string();
    for r in rows {
        s.push('\n');
        s.push_str(r);
    }
    s.push('\n');
    s
}

fn rgb(img: &hdrsynth::io::Image, x: usize, y: usize) -> [u8; 3] {
    img.get(x, y).map(|v| (v * 255.0).round() as u8)
}

#[test]
fn points_and_bars_land_where_the_axes_put_them() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("sweep.csv");
    std::fs::write(
        &csv,
        table(&[
            // 8x4h on the static validation set: x −0.5, y 1.0 [0.5, 1.5].
            "8,4,True,0.5,merge,triangle,val_static,psnr_t,30,31,1.0,\"[+0.50, +1.50]\",,-0.5,",
            // 8x1hk on the dynamic validation set: x 6.2, y 0.4 [−0.3, 1.1].
            "8,1,True,0.5,kernel,triangle,val_dynamic,psnr_t,30,31,0.4,\"[-0.30, +1.10]\",,6.2,",
            // Another metric: not drawn.
            "8,1,True,0.5,kernel,triangle,val_dynamic,psnr_t_moving,30,31,9.0,\"[8.0, 10.0]\",,20,",
        ]),
    )
    .unwrap();
    let rows = read_sweep(&csv).unwrap();
    assert_eq!(rows[0].point(), "8x4h");
    assert_eq!(rows[1].point(), "8x1hk");
    let img = realism_plot(&rows);
    assert_eq!((img.width, img.height), (720, 480));
    // Axes: x over [⌊−0.5 − ¼⌋, ⌈6.2 + ¼⌉] = [−1, 7], y over [⌊−0.3 − ¼⌋, ⌈1.5 + ¼⌉] = [−1, 2]
    // (the psnr_t_moving row is not drawn, so it does not widen them). The plot area is x 60…700, y 40…430:
    // px(x) = 60 + (x + 1)/8·640, py(y) = 430 − (y + 1)/3·390.
    let blue = [40, 80, 220];
    let red = [210, 40, 40];
    assert_eq!(rgb(&img, 100, 170), blue, "8x4h at (−0.5, 1.0)");
    assert_eq!(rgb(&img, 636, 248), red, "8x1hk at (6.2, 0.4)");
    // 8x4h's bar runs from py(1.5) = 105 to py(0.5) = 235, and not beyond.
    assert_eq!(rgb(&img, 100, 110), blue);
    assert_eq!(rgb(&img, 100, 225), blue);
    assert_ne!(rgb(&img, 100, 95), blue);
    assert_ne!(rgb(&img, 100, 245), blue);
    // The zero lines: x = 0 at column 140, y = 0 at row 300.
    let zero = [90, 90, 90];
    assert_eq!(rgb(&img, 140, 380), zero);
    assert_eq!(rgb(&img, 400, 300), zero);

    let png = dir.path().join("plot.png");
    write_realism_plot(&csv, &png).unwrap();
    let back = hdrsynth::io::read_image(&png).unwrap();
    assert_eq!(rgb(&back, 636, 248), red);
}

#[test]
fn a_malformed_table_is_refused_naming_the_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("sweep.csv");
    std::fs::write(
        &csv,
        table(&["8,4,True,0.5,merge,triangle,val_static,psnr_t,30,31,1.0,\"1.5\",,-0.5,"]),
    )
    .unwrap();
    let e = read_sweep(&csv).unwrap_err().to_string();
    assert!(
        e.contains("sweep.csv") && e.contains("line 2") && e.contains("net_s-net_r_ci"),
        "{e}"
    );

    std::fs::write(&csv, "width,steps_factor\n8,4\n").unwrap();
    let e = read_sweep(&csv).unwrap_err().to_string();
    assert!(e.contains("sweep.csv") && e.contains("line 2"), "{e}");

    std::fs::write(&csv, format!("{HEADER}\n")).unwrap();
    let e = read_sweep(&csv).unwrap_err().to_string();
    assert!(e.contains("no rows"), "{e}");
}

/// A point within ¼ unit of a whole value widens its axis by one unit, so it never sits on the
/// frame: x 6.9 → [⌊0 − ¼⌋, ⌈6.9 + ¼⌉] = [−1, 8]; y 0.5 with bar [0.1, 0.7] → [−1, 1].
#[test]
fn no_point_sits_on_the_frame() {
    use hdrsynth::plot::{Scatter, ScatterPoint};
    let p = ScatterPoint {
        x: 6.9,
        y: 0.5,
        y_range: (0.1, 0.7),
        series: 0,
        label: String::new(),
    };
    assert_eq!(Scatter::spans(&[p]), ((-1.0, 8.0), (-1.0, 1.0)));
}
