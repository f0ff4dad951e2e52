//! `vignetting`: radial gain falloff g = 1 − k·r² (r = distance from the frame centre over the
//! half-diagonal, so k is the relative falloff in the corners), applied to the signal before
//! noise (optics come first).
//!
//! Statistic (flat bursts): regress the channel-mean temporal mean above black on r² over
//! non-hot pixels, k̂ = −slope / intercept. Fixed patterns (PRNU, DSNU, columns) are zero-mean
//! and uncorrelated with r², so they add scatter, not bias; PRNU's own statistic removes a
//! quadratic surface first, so the two do not confuse each other.
//! Fit: k = measured k̂ − simulated k̂ (the simulated model has no vignetting).

use super::not_fitted;
use super::plan::id;
use super::summary::normalised_xy;
use super::{Entry, FitCtx, Protocol, Stat, Summary, float, table};
use crate::error::Result;
use crate::sensor::captures::BurstKind;

pub const ID: &str = id::VIGNETTING;
const NAME: &str = "radial falloff k (flat mean vs r²)";

pub const ENTRY: Entry = Entry {
    id: ID,
    about: "radial gain falloff 1 − k·r² (r: distance from the centre / half-diagonal)",
    needs: "a flat burst",
    statistics,
    fit,
    adjust: None,
};

/// Gain at pixel (x, y) of a w×h frame.
pub fn gain(k: f32, x: usize, y: usize, w: usize, h: usize) -> f32 {
    let (u, v) = normalised_xy(x, y, w, h);
    (1.0 - k as f64 * (u * u + v * v)).max(0.0) as f32
}

/// k̂ of one flat burst.
pub fn radial_k(s: &Summary, black: f64) -> f64 {
    let (w, h) = (s.width, s.height);
    let (mut n, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) * 3;
            if !(s.not_hot(i) && s.not_hot(i + 1) && s.not_hot(i + 2)) {
                continue;
            }
            let v = (s.mean[i] + s.mean[i + 1] + s.mean[i + 2]) / 3.0 - black;
            let (u, t) = s.xy(x, y);
            let r2 = u * u + t * t;
            n += 1.0;
            sx += r2;
            sy += v;
            sxx += r2 * r2;
            sxy += r2 * v;
        }
    }
    let slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
    let intercept = (sy - slope * sx) / n;
    -slope / intercept
}

fn statistics(p: &Protocol, s: &[Summary], out: &mut Vec<Stat>) {
    for b in s.iter().filter(|b| b.kind == BurstKind::Flat) {
        out.push(Stat {
            key: format!("{}: {NAME}", p.bursts[b.burst].name),
            effect: Some(ID),
            value: radial_k(b, p.black),
            min_effect: 0.01,
            sd_floor: 1e-4,
            unit: "",
        });
    }
}

fn fit(ctx: &FitCtx) -> Result<toml::Table> {
    let k = ctx.mean_excess(ID, NAME)?;
    if !(0.0..0.99).contains(&k) {
        return Err(not_fitted(
            ID,
            format!("fitted falloff {k:.4} is outside [0, 0.99)"),
        ));
    }
    Ok(table(&[("strength", float(k))]))
}
