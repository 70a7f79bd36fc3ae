//! Errors seen in the residual of the fitted model: local shapes at axis reversals, the start
//! of a run, oscillations and periodic errors along an axis.
//!
//! All of them work on the residual `r = Δr − model` of each trace at full sample rate, with
//! the sample noise σₙ estimated robustly from first differences,
//! `σₙ = 1.4826 · MAD(rᵢ − rᵢ₋₁) / √2` (white noise survives differencing with variance 2σₙ²,
//! while smooth unmodelled shapes do not).
//!
//! - Reversal spike (Kwon's "dynamic backlash"; a quadrant glitch): after an axis reverses, its
//!   friction changes sign and the velocity loop needs time to build the new torque, so the
//!   carriage lags and the path bulges. Height: the extreme of the residual, smoothed over
//!   [`SMOOTH_MS`], within [`SPIKE_ZONE_DEG`] after the reversal, above the level around it;
//!   width: its full width at half height, ms.
//! - Per-side backlash: the step of the partial residual (residual plus the axis' backlash term)
//!   across each reversal, from medians of the windows 2…12° before and after it.
//! - Stick-slip: at creep speed near its reversal an axis sticks and jumps; the residual's
//!   high-pass part (minus a moving mean over 2°) within 10° of the reversals of an axis against
//!   the same away from all reversals: RMS ratio and peak-to-peak.
//! - High servo gain vibration: the largest line of the residual's amplitude spectrum (against
//!   time) above 5 Hz, with its frequency and amplitude; significant when it stands above the
//!   spectrum's median.
//! - Start transient: the extreme of the smoothed residual within the first 5° of a run.
//! - Cyclic error of an axis, `δ = A sin(2π x/P + φ)` along its own coordinate x (screw lead,
//!   encoder): the periodogram of the residual regressed on `cos θ · {sin, cos}(2π k x)` (for the
//!   p axis; `sin θ` for q) over spatial frequencies k from 1/R to 1/[`MIN_PITCH_MM`].

use crate::signatures::Point;
use realfft::RealFftPlanner;

/// Smoothing window for local shapes, ms.
pub const SMOOTH_MS: f64 = 4.0;
/// Zone after a reversal in which a spike is looked for, deg.
pub const SPIKE_ZONE_DEG: f64 = 3.0;
/// Shortest pitch searched for cyclic errors, mm.
pub const MIN_PITCH_MM: f64 = 4.0;

/// One trace's residual with what is needed to place its samples.
pub struct Residual<'a> {
    /// Unwrapped angles, deg.
    pub angle_deg: &'a [f64],
    /// Signature points of the samples.
    pub points: &'a [Point],
    /// Residual per sample, µm.
    pub r: Vec<f64>,
    /// The residual smoothed over [`SMOOTH_MS`] (see [`Residual::smooth`]).
    pub smooth: Vec<f64>,
    /// Sample period, ms.
    pub dt_ms: f64,
}

/// Robust white-noise σ of a series from its first differences.
pub fn noise_sigma(r: &[f64]) -> f64 {
    let d: Vec<f64> = r.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    if d.is_empty() {
        return 0.0;
    }
    1.4826 * median(d) / std::f64::consts::SQRT_2
}

/// Median (NaN-free input).
pub fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
    *m
}

/// Moving mean over `w` samples (centred, shrinking at the ends).
pub fn moving_mean(r: &[f64], w: usize) -> Vec<f64> {
    let half = w / 2;
    let mut prefix = Vec::with_capacity(r.len() + 1);
    prefix.push(0.0);
    for x in r {
        prefix.push(prefix.last().copied().unwrap_or(0.0) + x);
    }
    (0..r.len())
        .map(|i| {
            let (a, b) = (i.saturating_sub(half), (i + half + 1).min(r.len()));
            (prefix[b] - prefix[a]) / (b - a) as f64
        })
        .collect()
}

/// Sample indices at which an axis reverses: where sin θ (p axis, `axis` 0) or cos θ (q axis)
/// changes sign.
pub fn reversals(points: &[Point], axis: usize) -> Vec<usize> {
    let f = |p: &Point| if axis == 0 { p.sin } else { p.cos };
    (1..points.len())
        .filter(|&i| (f(&points[i]) > 0.0) != (f(&points[i - 1]) > 0.0))
        .collect()
}

impl<'a> Residual<'a> {
    /// The residual `r` of a trace with angles `angle_deg`, points and sample period `dt_ms`.
    pub fn new(angle_deg: &'a [f64], points: &'a [Point], r: Vec<f64>, dt_ms: f64) -> Self {
        let w = ((SMOOTH_MS / dt_ms).round() as usize).max(1);
        Self {
            angle_deg,
            points,
            smooth: moving_mean(&r, w),
            r,
            dt_ms,
        }
    }

    /// Samples per degree (mean).
    fn per_deg(&self) -> f64 {
        let n = self.angle_deg.len();
        (n - 1) as f64 / (self.angle_deg[n - 1] - self.angle_deg[0]).abs().max(1e-9)
    }

    /// Index range of the samples within `[from, to]` degrees of travel from sample `i`
    /// (negative: before it), clipped to the trace.
    fn window(&self, i: usize, from: f64, to: f64) -> std::ops::Range<usize> {
        let k = self.per_deg();
        let n = self.r.len() as f64;
        let a = (i as f64 + from * k).round().clamp(0.0, n) as usize;
        let b = (i as f64 + to * k).round().clamp(0.0, n) as usize;
        a..b
    }

    /// Whether the samples `from..to` degrees around `i` are all in the trace.
    fn has(&self, i: usize, from: f64, to: f64) -> bool {
        let k = self.per_deg();
        i as f64 + from * k >= 0.0 && i as f64 + to * k <= (self.r.len() - 1) as f64
    }
}

/// A reversal spike: height (µm, + outward) and full width at half height (ms).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spike {
    /// Height above the surrounding level, µm.
    pub height_um: f64,
    /// Full width at half height, ms.
    pub width_ms: f64,
}

/// The spike after the reversal at sample `i`, if the trace holds the zone around it.
pub fn spike(res: &Residual, i: usize) -> Option<Spike> {
    if !res.has(i, -12.0, 12.0) {
        return None;
    }
    let smooth = &res.smooth;
    let around: Vec<f64> = res
        .window(i, -12.0, -2.0)
        .chain(res.window(i, SPIKE_ZONE_DEG + 2.0, 12.0))
        .map(|j| smooth[j])
        .collect();
    let level = median(around);
    let zone = res.window(i, 0.0, SPIKE_ZONE_DEG);
    let peak = zone.clone().max_by(|&a, &b| {
        (smooth[a] - level)
            .abs()
            .total_cmp(&(smooth[b] - level).abs())
    })?;
    let h = smooth[peak] - level;
    let half = |j: usize| (smooth[j] - level) * h.signum() >= 0.5 * h.abs();
    let mut a = peak;
    while a > zone.start.saturating_sub(zone.len()) && half(a - 1) {
        a -= 1;
    }
    let mut b = peak;
    while b + 1 < res.r.len() && b < zone.end + zone.len() && half(b + 1) {
        b += 1;
    }
    Some(Spike {
        height_um: h,
        width_ms: (b - a + 1) as f64 * res.dt_ms,
    })
}

/// The step (after minus before, µm) of `partial` across the reversal at sample `i`.
pub fn step(res: &Residual, partial: &[f64], i: usize) -> Option<f64> {
    if !res.has(i, -12.0, 12.0) {
        return None;
    }
    let m = |r: std::ops::Range<usize>| median(partial[r].to_vec());
    Some(m(res.window(i, 2.0, 12.0)) - m(res.window(i, -12.0, -2.0)))
}

/// Stick-slip measure of one axis over the traces: (RMS of the high-pass residual near the
/// axis' reversals, the same away from all reversals, peak-to-peak near the reversals), µm.
pub fn stick_slip(residuals: &[Residual], axis: usize) -> Option<(f64, f64, f64)> {
    let (mut near, mut far) = (Vec::new(), Vec::new());
    for res in residuals {
        let w = (2.0 * res.per_deg()).round().max(3.0) as usize;
        let mean = moving_mean(&res.r, w);
        let hp: Vec<f64> = res.r.iter().zip(&mean).map(|(a, b)| a - b).collect();
        let mut zone = vec![0u8; hp.len()];
        for (ax, tag) in [(axis, 1u8), (1 - axis, 2u8)] {
            for i in reversals(res.points, ax) {
                for j in res.window(i, -10.0, 10.0) {
                    zone[j] |= tag;
                }
                if ax == axis {
                    // The spike is a separate error: keep it out of the stick-slip measure.
                    for j in res.window(i, 0.0, SPIKE_ZONE_DEG + 1.0) {
                        zone[j] |= 4;
                    }
                }
            }
        }
        for (v, z) in hp.iter().zip(&zone) {
            match z {
                0 => far.push(*v),
                1 | 3 => near.push(*v),
                _ => {}
            }
        }
    }
    if near.len() < 50 || far.len() < 50 {
        return None;
    }
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
    let (lo, hi) = near
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(*x), b.max(*x))
        });
    Some((rms(&near), rms(&far), hi - lo))
}

/// The strongest line of the residual's spectrum above `min_hz`: (frequency Hz, amplitude µm,
/// median amplitude of the spectrum µm).
pub fn vibration(res: &Residual, min_hz: f64) -> Option<(f64, f64, f64)> {
    // The longest prefix whose length has only the factors 2, 3 and 5: a fast FFT size (the
    // full length can be a product of large primes, which costs an order of magnitude more).
    let n = smooth_length(res.r.len());
    if n < 64 {
        return None;
    }
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n);
    let r = &res.r[..n];
    let mean = r.iter().sum::<f64>() / n as f64;
    let mut input: Vec<f64> = r.iter().map(|x| x - mean).collect();
    let mut spectrum = fft.make_output_vec();
    fft.process(&mut input, &mut spectrum).ok()?;
    let df = 1000.0 / (res.dt_ms * n as f64);
    let amp: Vec<f64> = spectrum.iter().map(|c| 2.0 * c.norm() / n as f64).collect();
    let first = ((min_hz / df).ceil() as usize).max(1);
    if first + 8 >= amp.len() {
        return None;
    }
    let band = &amp[first..amp.len() - 1];
    let (k, a) = band
        .iter()
        .enumerate()
        .max_by(|x, y| x.1.total_cmp(y.1))
        .map(|(k, a)| (k + first, *a))?;
    // Energy of a line between bins: sum the neighbours in quadrature (window-free leakage).
    let lo = k.saturating_sub(1).max(first);
    let a_line = amp[lo..=(k + 1).min(amp.len() - 1)]
        .iter()
        .map(|x| x * x)
        .sum::<f64>()
        .sqrt()
        .max(a);
    Some((k as f64 * df, a_line, median(band.to_vec())))
}

/// The largest m ≤ n of the form 2^a 3^b 5^c.
fn smooth_length(n: usize) -> usize {
    let smooth = |mut m: usize| {
        for f in [2, 3, 5] {
            while m > 1 && m.is_multiple_of(f) {
                m /= f;
            }
        }
        m == 1
    };
    (1..=n).rev().find(|&m| smooth(m)).unwrap_or(1)
}

/// The start transient of a trace: extreme of the smoothed residual in its first 5°, µm, and
/// the robust noise of the smoothed residual elsewhere.
pub fn start_transient(res: &Residual) -> Option<f64> {
    let smooth = &res.smooth;
    let zone = res.window(0, 0.0, 5.0);
    let rest = res.window(0, 10.0, 360.0);
    if zone.is_empty() || rest.len() < 10 {
        return None;
    }
    let level = median(smooth[rest].to_vec());
    zone.map(|j| smooth[j] - level)
        .max_by(|a, b| a.abs().total_cmp(&b.abs()))
}

/// A cyclic error of one axis: pitch (mm), amplitude (µm), and the amplitude's standard error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cyclic {
    /// Pitch, mm.
    pub pitch_mm: f64,
    /// Amplitude, µm.
    pub amplitude_um: f64,
    /// Standard error of the amplitude, µm.
    pub std_error_um: f64,
}

/// Searches a cyclic error of the p (`axis` 0) or q axis in the residuals evaluated at the
/// group points `points` (residual `r`, weight `w` each).
pub fn cyclic(
    points: &[Point],
    r: &[f64],
    w: &[f64],
    axis: usize,
    sigma_um: f64,
) -> Option<Cyclic> {
    let radius_mm = points.first()?.radius_um * 1e-3;
    let k_max = 1.0 / MIN_PITCH_MM;
    let k_min = 1.0 / radius_mm;
    let dk = 1.0 / (8.0 * radius_mm);
    let rows: Vec<(f64, f64, f64, f64)> = points
        .iter()
        .zip(r.iter().zip(w))
        .map(|(p, (r, w))| {
            let (g, x) = if axis == 0 {
                (p.cos, radius_mm * p.cos)
            } else {
                (p.sin, radius_mm * p.sin)
            };
            (g, x, *r, *w)
        })
        .collect();
    // Rotation by 2π dk x per frequency step, from the first frequency's phase.
    let mut phase: Vec<(f64, f64)> = rows
        .iter()
        .map(|(_, x, _, _)| (std::f64::consts::TAU * k_min * x).sin_cos())
        .collect();
    let step: Vec<(f64, f64)> = rows
        .iter()
        .map(|(_, x, _, _)| (std::f64::consts::TAU * dk * x).sin_cos())
        .collect();
    let mut best: Option<(f64, f64, f64, f64)> = None;
    let mut k = k_min;
    while k <= k_max {
        let (mut ss, mut sc, mut cc, mut rs, mut rc) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for ((g, _, r, w), (s, c)) in rows.iter().zip(&phase) {
            let (a, b) = (g * s, g * c);
            ss += w * a * a;
            sc += w * a * b;
            cc += w * b * b;
            rs += w * r * a;
            rc += w * r * b;
        }
        let det = ss * cc - sc * sc;
        if det > 0.0 {
            let a = (cc * rs - sc * rc) / det;
            let b = (ss * rc - sc * rs) / det;
            let gain = a * rs + b * rc;
            if best.is_none_or(|x| gain > x.0) {
                best = Some((gain, k, (a * a + b * b).sqrt(), (2.0 / (ss + cc)).sqrt()));
            }
        }
        for ((s, c), (ds, dc)) in phase.iter_mut().zip(&step) {
            (*s, *c) = (*s * dc + *c * ds, *c * dc - *s * ds);
        }
        k += dk;
    }
    best.map(|(_, k, amp, se)| Cyclic {
        pitch_mm: 1.0 / k,
        amplitude_um: amp,
        std_error_um: sigma_um * se,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_sigma_of_white_noise_ignores_a_slow_trend() {
        // A deterministic pseudo-random sequence (LCG) with σ = 0.3, on a large slow sine.
        let mut x = 12345u64;
        let r: Vec<f64> = (0..20000)
            .map(|i| {
                let mut g = 0.0;
                for _ in 0..12 {
                    x = x
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    g += (x >> 11) as f64 / (1u64 << 53) as f64;
                }
                0.3 * (g - 6.0) + 5.0 * (i as f64 * 1e-3).sin()
            })
            .collect();
        let s = noise_sigma(&r);
        assert!((s - 0.3).abs() < 0.015, "{s}");
    }
}
