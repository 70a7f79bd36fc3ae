//! Ground truth of a cut: whether and when chatter set in, and at which frequency, from the
//! simulated tool motion (never from the sensors).
//!
//! Onset: the tool point is sampled once per tooth period (each time the spindle turns by one
//! pitch; a Poincaré section, after the once-per-revolution sampling of Schmitz, Medicus &
//! Dutterer, "Exploring once-per-revolution audio signal variance as a chatter indicator",
//! Machining Science and Technology 6(2), 2002). A stable cut settles to the periodic forced response, so
//! successive samples converge; regenerative chatter is at a frequency incommensurate with the
//! tooth passing, so they keep moving. The deviation d_n = |u_n - u_{n-1}| (|u_n - u_{n-N}|,
//! one revolution back, when the tool has run-out, whose forced response repeats once per
//! revolution, not per tooth; with an even tooth count also the alternating component over the
//! last revolution, where flip chatter, periodic over two teeth, shows: `alternation`) is compared with thresholds on the feed per tooth: an interval
//! opens at the first of [`CONSECUTIVE`] tooth periods with d > [`ON_FRACTION`]·f_t and closes
//! at the first of as many with d < [`OFF_FRACTION`]·f_t. It is chatter if d grows in it (see
//! `growth_onset`): a transient after the start of the cut or a change of speed decays,
//! while regenerative chatter grows until the tool leaves the cut. The onset is where that
//! growth starts. A cut so deep that its entry transient alone throws the tool out of the cut
//! has no room to grow: an interval that lasts to the end of the cut with d at
//! [`SATURATED_FRACTION`]·f_t or more and not decaying (its last third at least half its first
//! third, see `saturated`) is chatter from the start of the interval; a stable cut's transient
//! decays by the monodromy's radius every tooth period, far below half over a third of a cut. A chatter vibration of the threshold's size changes the
//! chip by a few per cent at least; a developed one throws the tool out of the cut (d ≈ f_t).
//!
//! Frequency: the strongest peak of the Hann-windowed spectrum of u_x and u_y (output rate, from
//! the onset to the end of the chatter, at most the last 0.25 s of it) between 20 Hz and the
//! Nyquist frequency, away (±2 % of f_tp plus two resolution bins) from the harmonics of the
//! tooth-passing frequency f_tp (of the spindle frequency with run-out) at the lowest and the
//! highest spindle speed of the segment, refined by a parabola
//! through the peak's neighbours.

use serde_json::{Value, json};

/// Fraction of f_t above which a tooth period counts as chattering.
pub const ON_FRACTION: f64 = 0.02;
/// Fraction of f_t below which a tooth period counts as calm.
pub const OFF_FRACTION: f64 = 0.01;
/// Tooth periods in a row that switch the state.
pub const CONSECUTIVE: usize = 5;
/// Growth of d that makes an interval chatter.
pub const GROWTH: f64 = 5.0;
/// Fraction of f_t at or above which a sustained, non-decaying d is saturated chatter.
pub const SATURATED_FRACTION: f64 = 0.25;

/// Once-per-tooth samples of the tool point.
#[derive(Default)]
pub(crate) struct ToothSamples {
    pub times_s: Vec<f64>,
    pub u: Vec<[f64; 2]>,
}

/// Intervals of chatter, s (end `None` if it lasted to the end of the cut).
pub(crate) fn chatter_intervals(
    s: &ToothSamples,
    lag: usize,
    feed_per_tooth: f64,
) -> Vec<(f64, Option<f64>)> {
    let on = ON_FRACTION * feed_per_tooth;
    let d: Vec<f64> = (lag..s.u.len())
        .map(|n| {
            let (a, b) = (s.u[n], s.u[n - lag]);
            (a[0] - b[0])
                .hypot(a[1] - b[1])
                .max(alternation(&s.u, n, lag))
        })
        .collect();
    let time = |i: usize| s.times_s[i + lag];
    raw_intervals(&d, on, OFF_FRACTION * feed_per_tooth)
        .into_iter()
        .filter_map(|(a, b)| {
            let seg = &d[a..b.unwrap_or(d.len())];
            let onset = growth_onset(seg, on).or_else(|| {
                (b.is_none() && saturated(seg, SATURATED_FRACTION * feed_per_tooth)).then_some(0)
            })?;
            Some((time(a + onset), b.map(time)))
        })
        .collect()
}

/// Period doubling seen once per revolution: with run-out the section is taken a revolution
/// back (`lag` = N teeth), and for an even N the flip chatter of an interrupted cut (the tool
/// alternating tooth by tooth, period 2 tooth periods) repeats every revolution and leaves
/// u_n − u_{n−N} at zero. Its alternating component over the last revolution,
/// a_n = (2/N)·|Σ_{j<N} (−1)^j u_{n−j}|, is 2·A for an alternation of amplitude A (the d of
/// the once-per-tooth section) and zero for the forced response with run-out, whose tooth-to-
/// tooth pattern cos(2πj/N + θ) has no (−1)^j component for N ≥ 3 (clipping of the chip adds
/// a small, constant one). Zero for an odd N or without run-out.
fn alternation(u: &[[f64; 2]], n: usize, lag: usize) -> f64 {
    if lag < 4 || !lag.is_multiple_of(2) || n + 1 < lag {
        return 0.0;
    }
    let mut sum = [0.0; 2];
    for j in 0..lag {
        let sign = if j % 2 == 0 { 1.0 } else { -1.0 };
        sum[0] += sign * u[n - j][0];
        sum[1] += sign * u[n - j][1];
    }
    2.0 / lag as f64 * sum[0].hypot(sum[1])
}

/// Whether `d` (an interval to the end of the cut) holds at `level` or more without decaying:
/// the mean of its last third at least `level` and at least half the mean of its first third.
fn saturated(d: &[f64], level: f64) -> bool {
    let third = d.len() / 3;
    if third < CONSECUTIVE {
        return false;
    }
    let mean = |s: &[f64]| s.iter().sum::<f64>() / s.len() as f64;
    let (first, last) = (mean(&d[..third]), mean(&d[d.len() - third..]));
    last >= level && last >= 0.5 * first
}

/// Index ranges where d is above `on` (switched after [`CONSECUTIVE`] samples above `on`,
/// back after as many below `off`).
fn raw_intervals(d: &[f64], on: f64, off: f64) -> Vec<(usize, Option<usize>)> {
    let mut intervals: Vec<(usize, Option<usize>)> = Vec::new();
    let (mut chattering, mut run) = (false, 0);
    for (n, &v) in d.iter().enumerate() {
        let switching = if chattering { v < off } else { v > on };
        run = if switching { run + 1 } else { 0 };
        if run == CONSECUTIVE {
            let first = n + 1 - CONSECUTIVE;
            match intervals.last_mut() {
                Some(last) if chattering => last.1 = Some(first),
                _ => intervals.push((first, None)),
            }
            chattering = !chattering;
            run = 0;
        }
    }
    intervals
}

/// Index in `d` where chatter starts, if it is chatter: d must grow by [`GROWTH`] from its
/// lowest value before its peak to the peak (a transient after the start of the cut or a change
/// of speed decays, beating by a factor of 2 to 3 at most in the benchmark near its lobes;
/// regenerative chatter grows by one to two orders of magnitude). The onset is the first tooth
/// period with d above `on` from the running minimum at which d first grew by [`GROWTH`] (so a
/// later jump, a change of speed during chatter, does not move it).
fn growth_onset(d: &[f64], on: f64) -> Option<usize> {
    let peak = (0..d.len()).fold(0, |m, i| if d[i] > d[m] { i } else { m });
    let lowest = d[..=peak].iter().copied().fold(f64::INFINITY, f64::min);
    if d[peak] < GROWTH * lowest {
        return None;
    }
    let mut low = 0;
    let grown = (0..=peak).find(|&i| {
        if d[i] < d[low] {
            low = i;
        }
        d[i] >= GROWTH * d[low]
    })?;
    (low..=grown).find(|&i| d[i] > on)
}

/// Strongest spectral peak of (ux, uy) sampled at `fs` away from the multiples of each of
/// `excluded` (Hz: the forcing frequencies, one per spindle speed of the segment), Hz: the
/// power of both axes (mean removed, Hann window, zero-padded to twice the length, real FFT)
/// from 20 Hz to Nyquist, the peak placed between bins by a parabola through its neighbours.
pub(crate) fn chatter_frequency(ux: &[f64], uy: &[f64], fs: f64, excluded: &[f64]) -> Option<f64> {
    let n = ux.len().min(uy.len());
    if n < 64 {
        return None;
    }
    let window: Vec<f64> = (0..n)
        .map(|i| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n as f64).cos())
        .collect();
    let prep = |v: &[f64]| {
        let m = v[..n].iter().sum::<f64>() / n as f64;
        v[..n]
            .iter()
            .zip(&window)
            .map(|(a, w)| (a - m) * w)
            .collect::<Vec<_>>()
    };
    // Twice zero-padded resolution, by one real FFT per axis.
    let m = 2 * n;
    let df = fs / m as f64;
    let fft = realfft::RealFftPlanner::<f64>::new().plan_fft_forward(m);
    let power_of = |v: &[f64]| -> Vec<f64> {
        let mut padded = vec![0.0; m];
        padded[..n].copy_from_slice(v);
        let mut spectrum = fft.make_output_vec();
        // The lengths are the plan's own, so the transform cannot fail.
        let _ = fft.process(&mut padded, &mut spectrum);
        spectrum.iter().map(|c| c.norm_sqr()).collect()
    };
    let (px, py) = (power_of(&prep(ux)), power_of(&prep(uy)));
    let near_harmonic = |f: f64| {
        excluded.iter().filter(|&&e| e > 0.0).any(|&e| {
            let guard = 0.02 * e + 2.0 * fs / n as f64;
            (f - (f / e).round() * e).abs() < guard
        })
    };
    // From 20 Hz up to (not including) the Nyquist frequency.
    let first = (20.0 / df).ceil() as usize;
    let power: Vec<f64> = (first..m / 2)
        .map(|k| {
            if near_harmonic(k as f64 * df) {
                0.0
            } else {
                px[k] + py[k]
            }
        })
        .collect();
    let (k, &p) = power.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
    if p <= 0.0 {
        return None;
    }
    let shift = if k > 0 && k + 1 < power.len() && power[k - 1] > 0.0 && power[k + 1] > 0.0 {
        let (a, c) = (power[k - 1], power[k + 1]);
        0.5 * (a - c) / (a - 2.0 * p + c)
    } else {
        0.0
    };
    // Rounded to 1 µHz: the FFT's kernels differ between processors (AVX, SSE, scalar) in the
    // last bits, and the truth must be the same bytes on every machine.
    Some(((first as f64 + k as f64 + shift) * df * 1e6).round() / 1e6)
}

/// The chatter keys of the truth object.
pub(crate) fn chatter_json(intervals: &[(f64, Option<f64>)], frequency_hz: Option<f64>) -> Value {
    let onset = intervals.first().map(|i| i.0);
    json!({
        "chatter": onset.is_some(),
        "chatter_onset_s": onset,
        "chatter_frequency_hz": frequency_hz,
        "chatter_intervals_s": intervals
            .iter()
            .map(|(a, b)| json!([a, b]))
            .collect::<Vec<_>>(),
        "chatter_on_threshold_fraction_of_feed": ON_FRACTION,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_peak_is_found_away_from_tooth_passing_harmonics() {
        let fs = 20_000.0;
        let (ft, fc) = (500.0, 937.3);
        let x: Vec<f64> = (0..4000)
            .map(|i| {
                let t = i as f64 / fs;
                5.0 * (std::f64::consts::TAU * ft * t).sin()
                    + (std::f64::consts::TAU * fc * t).sin()
            })
            .collect();
        let f = chatter_frequency(&x, &x, fs, &[ft]).unwrap();
        assert!((f - fc).abs() < 1.0, "{f}");
    }

    #[test]
    fn growing_differences_are_chatter_and_a_decaying_transient_is_not() {
        let mut s = ToothSamples::default();
        for n in 0..120 {
            // A transient of 10 µm decaying by 0.8 per tooth, then chatter growing by 1.2 per
            // tooth from tooth 40 up to 20 µm, gone from tooth 90.
            let transient = 1e-5 * 0.8f64.powi(n);
            let chatter = match n {
                40..90 => (1e-7 * 1.2f64.powi(n - 40)).min(2e-5),
                _ => 0.0,
            };
            let amp = transient + chatter;
            s.times_s.push(n as f64 * 1e-3);
            s.u.push([if n % 2 == 0 { amp } else { -amp }, 0.0]);
        }
        let iv = chatter_intervals(&s, 1, 1e-4);
        assert_eq!(iv.len(), 1, "{iv:?}");
        // d = 2·amp passes 2 µm when 1e-7·1.2^k > 1e-6: k = 13.
        assert!((iv[0].0 - 0.053).abs() < 1.5e-3, "{iv:?}");
        assert!(
            iv[0].1.is_some_and(|e| (e - 0.091).abs() < 1.5e-3),
            "{iv:?}"
        );
    }

    /// With run-out (section one revolution of 4 teeth back) the forced tooth-to-tooth pattern
    /// r·cos(2πn/4 + θ) is no chatter, and flip chatter growing on it (±A alternating tooth by
    /// tooth, which repeats every revolution) is: found by its alternating component, from
    /// where 2·A passes 2 % of the feed.
    #[test]
    fn period_doubling_with_run_out_is_chatter_and_the_run_out_pattern_is_not() {
        let run = |flip: bool| {
            let mut s = ToothSamples::default();
            for n in 0..400 {
                let forced = 1e-5 * (std::f64::consts::FRAC_PI_2 * n as f64 + 0.4).cos();
                let a = if flip && n >= 100 {
                    (1e-8 * 1.1f64.powi(n - 100)).min(2e-5)
                } else {
                    0.0
                };
                s.times_s.push(n as f64 * 1e-3);
                s.u.push([3e-6 + forced + if n % 2 == 0 { a } else { -a }, 2e-6]);
            }
            chatter_intervals(&s, 4, 1e-4)
        };
        assert!(run(false).is_empty(), "{:?}", run(false));
        let iv = run(true);
        assert_eq!(iv.len(), 1, "{iv:?}");
        // 2·1e-8·1.1^k > 2e-6 from k = 49 (tooth 149); the window of 4 teeth lags by up to 3.
        assert!((iv[0].0 - 0.149).abs() < 4e-3, "{iv:?}");
    }

    /// Chatter saturated from the first teeth (the tool leaving the cut at once) is chatter
    /// from the start; a transient of the same size decaying by 0.98 per tooth is not.
    #[test]
    fn saturated_chatter_is_chatter_and_a_large_slow_transient_is_not() {
        let run = |amp: &dyn Fn(i32) -> f64| {
            let mut s = ToothSamples::default();
            for n in 0..300 {
                let a = amp(n);
                s.times_s.push(n as f64 * 1e-3);
                s.u.push([if n % 2 == 0 { a } else { -a }, 0.0]);
            }
            chatter_intervals(&s, 1, 1e-4)
        };
        // d = 2·amp: 60 µm from the start, 0.6 f_t, wobbling but not decaying.
        let saturated = run(&|n| 3e-5 * (1.0 + 0.2 * (n as f64 * 0.37).sin()));
        assert_eq!(saturated.len(), 1, "{saturated:?}");
        assert!(
            saturated[0].0 < 0.01 && saturated[0].1.is_none(),
            "{saturated:?}"
        );
        let decaying = run(&|n| 3e-5 * 0.98f64.powi(n));
        assert!(decaying.is_empty(), "{decaying:?}");
    }
}
