//! Where a log of any sample rate shows the forced lines of a cut, checked against what our code
//! did not produce: the closed form f_a = (f_s/2π)·arccos(cos(2π·f/f_s)) (the principal value
//! of arccos lies in [0, π], so the sampled cosine cos(2π·f·j/f_s) = cos(2π·f_a·j/f_s) for every
//! j with f_a in [0, f_s/2]), and the peak of a directly summed discrete-time Fourier transform
//! of the sampled line.

use proptest::prelude::*;
use std::f64::consts::{PI, TAU};
use vmt_chatter::detect::forced::{AliasBand, alias_hz, forced_comb, tooth_passing_hz};

/// The alias by the arccos closed form.
fn closed_form(f: f64, fs: f64) -> f64 {
    fs / (2.0 * PI) * (TAU * f / fs).cos().clamp(-1.0, 1.0).acos()
}

/// The frequency in [0, fs/2] (on a grid of `step` Hz) where the magnitude of the DTFT of
/// `n` samples of cos(2π·f·j/fs + φ) is largest, by direct summation.
fn dtft_peak(f: f64, fs: f64, phase: f64, n: usize, step: f64) -> f64 {
    let x: Vec<f64> = (0..n)
        .map(|j| (TAU * f * j as f64 / fs + phase).cos())
        .collect();
    let mut best = (0.0, f64::NEG_INFINITY);
    let mut g = 0.0;
    while g <= fs / 2.0 {
        let (mut re, mut im) = (0.0, 0.0);
        for (j, v) in x.iter().enumerate() {
            // Hann window: its sidelobes keep the search on the main lobe.
            let w = 0.5 - 0.5 * (TAU * j as f64 / n as f64).cos();
            let a = TAU * g * j as f64 / fs;
            re += w * v * a.cos();
            im -= w * v * a.sin();
        }
        let m = re * re + im * im;
        if m > best.1 {
            best = (g, m);
        }
        g += step;
    }
    best.0
}

proptest! {
    /// The alias of any line against the arccos closed form, for rates from 1 kHz to 50 kHz and
    /// lines up to 40 sample rates.
    #[test]
    fn alias_matches_the_arccos_closed_form(fs in 1000.0f64..50_000.0, r in 0.0f64..40.0) {
        let f = r * fs;
        let a = alias_hz(f, fs);
        prop_assert!((0.0..=fs / 2.0).contains(&a));
        // arccos loses digits near 0 and π (its slope is infinite there): compare the cosines,
        // which are what the samples are.
        let c = closed_form(f, fs);
        prop_assert!(((TAU * a / fs).cos() - (TAU * c / fs).cos()).abs() < 1e-9,
            "f {f} at {fs}: {a} against {c}");
        prop_assert!((a - c).abs() < 1e-6 * fs + 0.5, "f {f} at {fs}: {a} against {c}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// A sampled line peaks at its alias: the directly summed DTFT of 800 samples of a line
    /// above the Nyquist frequency, searched on a 0.5 Hz grid, within a bin of it.
    #[test]
    fn a_sampled_line_peaks_at_its_alias(f in 900.0f64..6000.0, phase in 0.0f64..TAU) {
        let fs = 1650.0;
        let peak = dtft_peak(f, fs, phase, 800, 0.5);
        let a = alias_hz(f, fs);
        // Away from 0 and fs/2, where a line and its mirror image overlap.
        prop_assume!(a > 10.0 && a < fs / 2.0 - 10.0);
        prop_assert!((peak - a).abs() <= fs / 800.0, "{f} Hz: peak {peak}, alias {a}");
    }
}

/// 12 000 rev/min, 4 teeth at 1.65 kHz (the real exports' case: 800 Hz tooth passing above a
/// quarter of the rate): orders 1–4 show where they are, order 8 (1600 Hz) at 50 Hz, order 5
/// (1000 Hz) at 650 Hz; the tooth-passing flags are every fourth order; the comb stops at the
/// sample rate by default.
#[test]
fn the_comb_of_a_fast_cut_at_a_low_rate() {
    let comb = forced_comb(12_000.0, 4, 1650.0, AliasBand::default());
    assert_eq!(comb.len(), 8, "orders up to 1650 Hz");
    let at = |k: u32| comb[k as usize - 1].alias_hz;
    assert_eq!(tooth_passing_hz(12_000.0, 4), 800.0);
    for (k, expected) in [(1, 200.0), (4, 800.0), (5, 650.0), (6, 450.0), (8, 50.0)] {
        assert!((at(k) - expected).abs() < 1e-9, "order {k}: {}", at(k));
    }
    for l in &comb {
        assert_eq!(l.tooth_passing, l.order % 4 == 0);
        assert_eq!(l.folded(1650.0), l.frequency_hz > 825.0);
        assert!((l.alias_hz - closed_form(l.frequency_hz, 1650.0)).abs() < 1e-6);
    }
    let wider = forced_comb(12_000.0, 4, 1650.0, AliasBand { sample_rates: 2.0 });
    assert_eq!(wider.len(), 16);
    assert!(forced_comb(0.0, 4, 1650.0, AliasBand::default()).is_empty());
}
