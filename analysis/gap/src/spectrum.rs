//! Band levels of an accelerometer signal: where a vibration gap sits in frequency.
//!
//! - Bands: one-third-octave bands of IEC 61260-1 (base 10): centres `f_n = 10^(n/10)` Hz,
//!   edges `f_n·10^(±1/20)`, from the first band at least [`LOWEST_HZ`] up to the last whose
//!   upper edge stays below 0.45 of the sample rate (under an anti-alias filter's knee).
//! - Power spectral density by Welch's method: segments of [`SEGMENT`] samples, Hann window,
//!   50 % overlap, mean removed per segment, one-sided
//!   `P_k = c_k |X_k|² / (f_s Σ w²)` with `c_k = 2` except at DC and Nyquist (m²/s⁴/Hz).
//! - Band level: `L_b = sqrt(Σ_{f_k ∈ [lo, hi)} P_k Δf)`, the RMS acceleration in the band
//!   (m/s²); by Parseval the levels of all bins sum to the signal's variance.

use realfft::RealFftPlanner;

/// Welch segment length, samples (0.1 s at 20 kHz, bins of 9.8 Hz).
pub const SEGMENT: usize = 2048;
/// Lowest band centre, Hz: a third-octave is 23 % wide, so at 160 Hz it holds about four bins
/// of a 2048-sample segment at 20 kHz.
pub const LOWEST_HZ: f64 = 150.0;

/// A one-third-octave band.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Band {
    /// Exact centre, Hz.
    pub centre_hz: f64,
    /// Lower edge, Hz.
    pub lo_hz: f64,
    /// Upper edge, Hz.
    pub hi_hz: f64,
}

impl Band {
    /// Whether `f` (Hz) falls in the band.
    pub fn holds(&self, f: f64) -> bool {
        (self.lo_hz..self.hi_hz).contains(&f)
    }

    /// Width, Hz.
    pub fn width_hz(&self) -> f64 {
        self.hi_hz - self.lo_hz
    }
}

/// The third-octave bands analysed at sample rate `fs` (Hz).
pub fn bands(fs: f64) -> Vec<Band> {
    let edge = 10f64.powf(0.05);
    let first = (10.0 * LOWEST_HZ.log10()).ceil() as i32;
    (first..)
        .map(|n| {
            let centre_hz = 10f64.powf(f64::from(n) / 10.0);
            Band {
                centre_hz,
                lo_hz: centre_hz / edge,
                hi_hz: centre_hz * edge,
            }
        })
        .take_while(|b| b.hi_hz <= 0.45 * fs)
        .collect()
}

/// One-sided Welch PSD of `x` at `fs` (m²/s⁴/Hz per bin of `fs / SEGMENT`), or `None` when
/// `x` is shorter than one segment.
pub fn welch(x: &[f64], fs: f64) -> Option<Vec<f64>> {
    let n = SEGMENT;
    if x.len() < n {
        return None;
    }
    let window: Vec<f64> = (0..n)
        .map(|i| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n as f64).cos())
        .collect();
    let norm = fs * window.iter().map(|w| w * w).sum::<f64>();
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
    let (mut input, mut output) = (fft.make_input_vec(), fft.make_output_vec());
    let mut psd = vec![0.0; n / 2 + 1];
    let mut segments = 0usize;
    for start in (0..=x.len() - n).step_by(n / 2) {
        let seg = &x[start..start + n];
        let mean = seg.iter().sum::<f64>() / n as f64;
        for ((v, s), w) in input.iter_mut().zip(seg).zip(&window) {
            *v = (s - mean) * w;
        }
        // Lengths match the plan, so the transform cannot fail.
        fft.process(&mut input, &mut output).ok()?;
        for (k, (p, c)) in psd.iter_mut().zip(&output).enumerate() {
            let one_sided = if k == 0 || k == n / 2 { 1.0 } else { 2.0 };
            *p += one_sided * c.norm_sqr() / norm;
        }
        segments += 1;
    }
    psd.iter_mut().for_each(|p| *p /= segments as f64);
    Some(psd)
}

/// RMS level (m/s²) of `x` in each of `bands`, or `None` when `x` is shorter than a segment.
pub fn band_levels(x: &[f64], fs: f64, bands: &[Band]) -> Option<Vec<f64>> {
    let psd = welch(x, fs)?;
    let df = fs / SEGMENT as f64;
    Some(
        bands
            .iter()
            .map(|b| {
                psd.iter()
                    .enumerate()
                    .filter(|(k, _)| b.holds(*k as f64 * df))
                    .map(|(_, p)| p * df)
                    .sum::<f64>()
                    .sqrt()
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// A sine of amplitude A at a band's centre has the level A/√2 in that band and
        /// (with the Hann window's leakage) almost nothing two bands away.
        #[test]
        fn a_sine_has_its_rms_in_its_band(a in 0.1f64..100.0, pick in 0usize..15, turn in 0.0f64..1.0) {
            let fs = 20_000.0;
            let b = bands(fs);
            let band = b[pick];
            let x: Vec<f64> = (0..20_000)
                .map(|i| a * (std::f64::consts::TAU * band.centre_hz * i as f64 / fs + std::f64::consts::TAU * turn).sin())
                .collect();
            let levels = band_levels(&x, fs, &b).unwrap();
            let rms = a / 2f64.sqrt();
            prop_assert!((levels[pick] - rms).abs() < 0.02 * rms, "{} vs {}", levels[pick], rms);
            if pick + 2 < b.len() {
                prop_assert!(levels[pick + 2] < 0.02 * rms);
            }
        }
    }

    #[test]
    fn white_noise_levels_follow_the_band_width() {
        // Uniform white noise of variance σ² spreads σ²/(fs/2) per Hz: a band holds σ²·bw/(fs/2).
        use rand::SeedableRng;
        let fs = 20_000.0;
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let sigma = 2.0;
        let x: Vec<f64> = (0..200_000)
            .map(|_| (rng.random::<f64>() - 0.5) * sigma * 12f64.sqrt())
            .collect();
        let b = bands(fs);
        let levels = band_levels(&x, fs, &b).unwrap();
        for (band, l) in b.iter().zip(&levels).skip(4) {
            let expected = sigma * (band.width_hz() / (fs / 2.0)).sqrt();
            assert!(
                (l - expected).abs() < 0.1 * expected,
                "{band:?}: {l} vs {expected}"
            );
        }
        assert!(band_levels(&x[..100], fs, &b).is_none());
    }

    #[test]
    fn bands_are_third_octaves_under_the_anti_alias_knee() {
        let b = bands(20_000.0);
        assert!((b[0].centre_hz - 158.489).abs() < 1e-3);
        assert!(b.last().unwrap().hi_hz <= 9000.0);
        for w in b.windows(2) {
            assert!((w[1].lo_hz - w[0].hi_hz).abs() < 1e-9);
            assert!((w[1].centre_hz / w[0].centre_hz - 10f64.powf(0.1)).abs() < 1e-12);
        }
    }
}
