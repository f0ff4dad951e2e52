//! `column_noise`: column fixed-pattern noise, an offset N(0, σ²) DN per column, fixed across
//! frames (from the pattern seed), shared by the three channels (offset stage).
//!
//! Statistic (dark bursts): the covariance over columns of the top-half and bottom-half column
//! means of the temporal mean (non-hot values, channels pooled). A column offset is in both
//! halves; DSNU, hot pixels (masked) and temporal noise are independent between the halves, so
//! E = σ² (the total spatial variance of a dark mean would also fire on DSNU and hot pixels).
//! Fit: σ² = measured − simulated.

use super::plan::id;
use super::{Entry, FitCtx, Protocol, Stat, Summary, float, hashed_normal};
use super::{seed_value, table};
use crate::error::Result;
use crate::sensor::captures::BurstKind;

pub const ID: &str = id::COLUMN_NOISE;
const NAME: &str = "column offset covariance (top × bottom half)";

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "column offsets N(0, sigma_dn²), fixed across frames",
    needs: "a dark burst with ≥ 2 frames",
    statistics,
    fit,
    adjust: None,
};

pub fn offset(sigma: f32, seed: u64, x: usize) -> f32 {
    sigma * hashed_normal(seed, &[x as u64, 0xc0])
}

/// Covariance over columns of the top- and bottom-half column means.
#[allow(clippy::needless_range_loop)] // (x, y, c) index arithmetic reads clearer
pub fn column_cov(b: &Summary) -> f64 {
    let (w, h) = (b.width, b.height);
    let mut t = vec![(0.0, 0.0); w];
    let mut d = vec![(0.0, 0.0); w];
    for y in 0..h {
        let half = if y < h / 2 { &mut t } else { &mut d };
        for x in 0..w {
            for c in 0..3 {
                let i = (y * w + x) * 3 + c;
                if b.not_hot(i) {
                    half[x].0 += b.mean[i];
                    half[x].1 += 1.0;
                }
            }
        }
    }
    let pairs: Vec<(f64, f64)> = t
        .iter()
        .zip(&d)
        .filter(|(a, b)| a.1 > 0.0 && b.1 > 0.0)
        .map(|(a, b)| (a.0 / a.1, b.0 / b.1))
        .collect();
    let n = pairs.len() as f64;
    let (ma, mb) = (
        pairs.iter().map(|p| p.0).sum::<f64>() / n,
        pairs.iter().map(|p| p.1).sum::<f64>() / n,
    );
    pairs.iter().map(|p| (p.0 - ma) * (p.1 - mb)).sum::<f64>() / (n - 1.0)
}

fn statistics(p: &Protocol, s: &[Summary], out: &mut Vec<Stat>) {
    for b in s
        .iter()
        .filter(|b| b.kind == BurstKind::Dark && !b.var.is_empty())
    {
        out.push(Stat::dark_dn2(p, b, ID, NAME, column_cov(b)));
    }
}

fn fit(ctx: &FitCtx) -> Result<toml::Table> {
    let s = ctx.excess_sigma(ID, NAME, "column covariance")?;
    Ok(table(&[
        ("sigma_dn", float(s)),
        ("seed", seed_value(ctx.seed)),
    ]))
}
