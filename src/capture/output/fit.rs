//! The noise level and floor the device-output check compares, fitted to the frames
//! ([`fit_noise_level`]).

use super::{BinOffset, FLOOR, LEVEL, OutputCheck, OutputCheckOptions, check_scanned};
use crate::capture::scan;
use crate::error::Result;
use crate::sensor::profile::SensorProfile;

/// The fitted scale of a channel's noise stays within this factor of the measured one: a
/// larger gap is not a level error the fit should paper over.
pub const MAX_LEVEL_SCALE: f64 = 16.0;

/// What [`fit_noise_level`] found.
#[derive(Clone, Debug)]
pub struct NoiseFit {
    /// The profile with every ISO's a_c and b_c scaled by `scale[c]`, `floor[c]`·a_c added to
    /// b_c (before scaling) where a floor is fitted.
    pub profile: SensorProfile,
    pub scale: [f64; 3],
    /// The floor fitted per channel, as the linear signal whose shot noise equals it (None:
    /// the check found that channel's floor in line with its level).
    pub floor: [Option<f64>; 3],
    /// The check of `profile`.
    pub check: OutputCheck,
}

/// The noise level the check compares, fitted: every ISO's a and b of channel c scaled by
/// k_c so that the simulated frames' noise-level statistic (mean ln σ² of the codes from 1/8)
/// matches the real frames' (a secant on ln k: the first step assumes the statistic moves by
/// ln k, as it does for noise well above the 8-bit step; quantisation, clipping and a
/// response with a steep toe bend it). Then, in each channel whose noise floor (the codes
/// under 1/8) the check still finds significant at that level (more than a scale mends), a
/// floor f_c·a_c is added to b_c before the scaling (f_c a linear signal: the floor follows
/// each ISO's gain as the shot noise does), k_c and f_c fitted together to the level and the
/// floor bin by bin: each bin's simulated ln σ² moves with ln(k·(x + b/a + f)) at its linear
/// value x, so the two statistics' offsets give the next (k, f) in closed form (a bisection
/// on f), and a check of them the next offsets. `rounds` checks for each, `first` being the
/// check of `profile` itself; the round whose largest |measured − simulated| statistic
/// fitted is smallest wins, and the fit with floors only where that is the smaller. The
/// statistics are the ones the check takes (pairs, or each frame against the others'
/// merge): the noise the frames hold beyond what the profile's flat-region measurement gave,
/// whatever its source (JPEG processing, a read-noise floor the flat regions hid), is then in
/// the simulation.
pub fn fit_noise_level(
    scan: &scan::BracketScan,
    profile: &SensorProfile,
    first: &OutputCheck,
    opts: &OutputCheckOptions,
    rounds: usize,
) -> Result<NoiseFit> {
    let fit = NoiseFitter {
        scan,
        profile,
        opts,
    };
    let level = fit.level(first, rounds)?;
    let floors = FLOOR.map(|i| level.check.stats[i].significant);
    if !floors.contains(&true) {
        return Ok(level);
    }
    let with_floors = fit.floors(&level, floors, rounds)?;
    Ok(
        if NoiseFitter::worst(&with_floors.check, floors) < NoiseFitter::worst(&level.check, floors)
        {
            with_floors
        } else {
            level
        },
    )
}

/// The two fits of [`fit_noise_level`].
struct NoiseFitter<'a> {
    scan: &'a scan::BracketScan,
    profile: &'a SensorProfile,
    opts: &'a OutputCheckOptions,
}

/// Range of a fitted floor, as a linear signal.
const FLOOR_RANGE: (f64, f64) = (1e-7, 0.5);

impl NoiseFitter<'_> {
    fn off(c: &OutputCheck, i: usize) -> f64 {
        c.stats[i].measured - c.stats[i].sim_mean
    }

    /// The largest |measured − simulated| of the levels and of the floors `floors` marks.
    fn worst(c: &OutputCheck, floors: [bool; 3]) -> f64 {
        (0..3)
            .flat_map(|ch| [Some(LEVEL[ch]), floors[ch].then_some(FLOOR[ch])])
            .flatten()
            .map(|i| Self::off(c, i).abs())
            .fold(0.0, f64::max)
    }

    /// `profile` with `scale` and `floor`, its check, and how far it is off.
    fn try_fit(
        &self,
        scale: [f64; 3],
        floor: [Option<f64>; 3],
        floors: [bool; 3],
    ) -> Result<(f64, NoiseFit)> {
        let profile = scaled_noise(self.profile, scale, floor);
        let check = check_scanned(self.scan.clone(), &profile, self.opts)?;
        let worst = Self::worst(&check, floors);
        Ok((
            worst,
            NoiseFit {
                profile,
                scale,
                floor,
                check,
            },
        ))
    }

    /// The level alone: `rounds` secant steps on ln k from the profile (check `first`).
    fn level(&self, first: &OutputCheck, rounds: usize) -> Result<NoiseFit> {
        let limit = MAX_LEVEL_SCALE.ln();
        let mut ln_k = [0.0f64; 3];
        let mut prev: [Option<(f64, f64)>; 3] = [None; 3];
        let mut d = LEVEL.map(|i| Self::off(first, i));
        let mut best = (
            Self::worst(first, [false; 3]),
            NoiseFit {
                profile: self.profile.clone(),
                scale: [1.0; 3],
                floor: [None; 3],
                check: first.clone(),
            },
        );
        for _ in 0..rounds {
            for c in 0..3 {
                if !d[c].is_finite() {
                    continue;
                }
                // The statistic's slope in ln k from the last two rounds, else 1.
                let slope = prev[c]
                    .filter(|&(x, _)| (ln_k[c] - x).abs() > 1e-9)
                    .map_or(1.0, |(x, e)| ((e - d[c]) / (ln_k[c] - x)).clamp(0.1, 10.0));
                prev[c] = Some((ln_k[c], d[c]));
                ln_k[c] = (ln_k[c] + d[c] / slope).clamp(-limit, limit);
            }
            let tried = self.try_fit(ln_k.map(f64::exp), [None; 3], [false; 3])?;
            d = LEVEL.map(|i| Self::off(&tried.1.check, i));
            if tried.0 < best.0 {
                best = tried;
            }
        }
        Ok(best.1)
    }

    /// Level and floor together in the channels `floors` marks, from `from` (the level's
    /// fit): `rounds` rounds of the bin model's closed form, each checked.
    fn floors(&self, from: &NoiseFit, floors: [bool; 3], rounds: usize) -> Result<NoiseFit> {
        // Each channel's own floor b/a in the profile, as a linear signal.
        let own = [0, 1, 2].map(|c| {
            let r: Vec<f64> = self
                .profile
                .noise
                .iter()
                .map(|n| n.b[c] / n.a[c].max(1e-30))
                .collect();
            r.iter().sum::<f64>() / r.len().max(1) as f64
        });
        let mut scale = from.scale;
        let mut floor = [0.0f64; 3];
        let mut check = from.check.clone();
        let mut best: Option<(f64, NoiseFit)> = None;
        for _ in 0..rounds {
            for c in (0..3).filter(|&c| floors[c]) {
                let bins: Vec<&BinOffset> = check.bins.iter().filter(|b| b.channel == c).collect();
                (scale[c], floor[c]) = model_step(&bins, own[c], scale[c], floor[c]);
            }
            let f = [0, 1, 2].map(|c| floors[c].then_some(floor[c]));
            let tried = self.try_fit(scale, f, floors)?;
            check = tried.1.check.clone();
            if best.as_ref().is_none_or(|b| tried.0 < b.0) {
                best = Some(tried);
            }
        }
        Ok(best.map_or_else(|| from.clone(), |b| b.1))
    }
}

/// The next (k, f) of one channel from its bins, checked at (k, f): each bin's simulated
/// ln σ² taken to move by ln(k'·(x + own + f')) − ln(k·(x + own + f)), f' is the floor whose
/// predicted offset of the dark bins from the light ones matches the real frames' (a
/// bisection on ln f', the offset growing with f'), and k' the scale that then matches the
/// light bins (the level). Pixel-weighted means, as the statistics take them.
fn model_step(bins: &[&BinOffset], own: f64, k: f64, f: f64) -> (f64, f64) {
    let mean = |dark: bool, v: &dyn Fn(&BinOffset) -> f64| {
        let (s, w) = bins
            .iter()
            .filter(|b| b.dark == dark)
            .fold((0.0, 0.0), |(s, w), b| (s + b.weight * v(b), w + b.weight));
        if w > 0.0 { s / w } else { f64::NAN }
    };
    let gain = |g: f64| move |b: &BinOffset| ((b.linear + own + g) / (b.linear + own + f)).ln();
    let off = |b: &BinOffset| b.measured - b.simulated;
    let want = mean(true, &off) - mean(false, &off);
    let shape = |g: f64| mean(true, &gain(g)) - mean(false, &gain(g));
    if !want.is_finite() || !shape(f).is_finite() {
        return (k, f);
    }
    let next = if shape(0.0) >= want {
        0.0
    } else if shape(FLOOR_RANGE.1) <= want {
        FLOOR_RANGE.1
    } else {
        let (lo, hi) = (FLOOR_RANGE.0.ln(), FLOOR_RANGE.1.ln());
        crate::stats::bisect(lo, hi, 60, |m| shape(m.exp()) < want).exp()
    };
    let ln_k = mean(false, &off) - mean(false, &gain(next));
    let limit = MAX_LEVEL_SCALE.ln();
    ((k.ln() + ln_k).clamp(-limit, limit).exp(), next)
}

/// `profile` with `floor[c]`·a added to every ISO's b of channel c where a floor is given,
/// then that channel's a and b multiplied by `k[c]`.
fn scaled_noise(profile: &SensorProfile, k: [f64; 3], floor: [Option<f64>; 3]) -> SensorProfile {
    let mut p = profile.clone();
    for row in &mut p.noise {
        for c in 0..3 {
            row.b[c] = k[c] * (row.b[c] + floor[c].unwrap_or(0.0) * row.a[c]);
            row.a[c] *= k[c];
        }
        // The standard errors were the flat-region fit's; they do not describe the scaled one.
        row.a_stderr = None;
        row.b_stderr = None;
    }
    let floors = if floor.iter().any(Option::is_some) {
        let f = floor.map(|f| f.map_or("none".to_string(), |f| format!("{f:.3e}")));
        format!(
            ", with a floor of the shot noise at linear ({}, {}, {}) added to b first to match \
             their noise under code 1/8",
            f[0], f[1], f[2]
        )
    } else {
        String::new()
    };
    p.provenance.noise = format!(
        "{}; scaled by ({:.3}, {:.3}, {:.3}) per channel to match the frames' noise level on \
         their cross-frame residuals (the device-output check's statistic){floors}",
        profile.provenance.noise, k[0], k[1], k[2]
    );
    p
}
