//! Chebyshev type I band-pass design: the spec is met, Kim et al.'s published coefficients are
//! reproduced, and the second-order sections run stably.

use proptest::prelude::*;
use vmt_chatter::filter::{BandPassSpec, ChebyshevBandPass, direct_form_filter};

/// Worst pass-band deviation from 0 dB (either way) and least stop-band attenuation, from 2000 frequencies in
/// each band (stop bands from the stop edges to DC and to Nyquist).
fn measured(f: &ChebyshevBandPass) -> (f64, f64) {
    let s = f.spec;
    let nyq = s.sample_rate_hz / 2.0;
    let grid = |a: f64, b: f64| (0..=2000).map(move |i| a + (b - a) * i as f64 / 2000.0);
    // |gain| so that an overshoot above 0 dB counts as well as a dip.
    let ripple = grid(s.pass_hz.0, s.pass_hz.1)
        .map(|x| f.gain_db(x).abs())
        .fold(f64::NEG_INFINITY, f64::max);
    let atten = grid(1e-3 * nyq, s.stop_hz.0)
        .chain(grid(s.stop_hz.1, 0.999 * nyq))
        .map(|x| -f.gain_db(x))
        .fold(f64::INFINITY, f64::min);
    (ripple, atten)
}

#[test]
fn kim_spec_at_20_khz_is_met_with_order_six() {
    let f = ChebyshevBandPass::design(BandPassSpec::kim(20_000.0)).unwrap();
    assert_eq!(f.prototype_order, 3, "band-pass order 6, as in the paper");
    let (b, a) = f.direct_form();
    eprintln!(
        "6–7 kHz at 20 kHz: b = {b:?}\n a = {a:.6?}\n sections = {:?}",
        f.sections
    );
    let (ripple, atten) = measured(&f);
    assert!(ripple <= 0.1 + 1e-9, "pass-band ripple {ripple} dB");
    assert!(atten >= 10.0, "stop-band attenuation {atten} dB");
    // Peak of the ripple is 0 dB (odd order): some pass-band frequency reaches it.
    let top = (0..=1000)
        .map(|i| f.gain_db(6000.0 + i as f64))
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(top.abs() < 1e-3, "pass-band maximum {top} dB");
}

/// The paper's eq. (2) is the bilinear transform of its eq. (1) at fs = 100 kHz with the edges
/// pre-warped for 100 kHz (its G(s) has ω0 = √(Ωp1·Ωp2) = 4.130e4 rad/s and B = 6556 rad/s,
/// the pre-warped 6 and 7 kHz at 100 kHz; unwarped they would be 4.072e4 and 6283). At the
/// 20 kHz the paper samples at, those coefficients pass 1.2–1.4 kHz instead of 6–7 kHz. Our
/// design for 100 kHz reproduces every printed coefficient to its last printed digit.
#[test]
fn reproduces_the_papers_coefficients_at_100_khz() {
    let f = ChebyshevBandPass::design(BandPassSpec::kim(100_000.0)).unwrap();
    let (b, a) = f.direct_form();
    let paper_a: [f64; 7] = [1.0, -5.395, 12.58, -16.17, 12.08, -4.974, 0.885];
    let paper_b = [4.78e-5, 0.0, -1.434e-4, 0.0, 1.434e-4, 0.0, -4.78e-5];
    for (i, (&ours, &theirs)) in a.iter().zip(&paper_a).enumerate() {
        // Half a unit in the last printed digit.
        let half_ulp = if theirs.abs() >= 10.0 { 0.005 } else { 0.0005 };
        assert!(
            (ours - theirs).abs() <= half_ulp,
            "a{i}: ours {ours}, paper {theirs}"
        );
    }
    for (i, (&ours, &theirs)) in b.iter().zip(&paper_b).enumerate() {
        assert!(
            (ours - theirs).abs() <= 5e-8,
            "b{i}: ours {ours:e}, paper {theirs:e}"
        );
    }
}

#[test]
fn papers_printed_difference_equation_is_unstable_but_sections_are_not() {
    // Eq. (3) as printed (4 significant digits): rounding moves poles outside the unit circle
    // (|z| = 1.15), so its impulse response grows without bound.
    let a = [1.0, -5.395, 12.581, -16.174, 12.08, -4.974, 0.885];
    let b = [4.78e-5, 0.0, -1.434e-4, 0.0, 1.434e-4, 0.0, -4.78e-5];
    let mut impulse = vec![0.0; 3000];
    impulse[0] = 1.0;
    let printed = direct_form_filter(&b, &a, &impulse);
    assert!(
        printed[2999].abs() > 1e6,
        "printed eq. (3) stays bounded: {}",
        printed[2999]
    );
    let f = ChebyshevBandPass::design(BandPassSpec::kim(100_000.0)).unwrap();
    let ours = f.runner().run(&impulse);
    let tail = ours[2000..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(
        tail < 1e-4,
        "designed filter's impulse response tail {tail}"
    );
}

#[test]
fn sections_and_direct_form_agree_and_run_as_designed() {
    let f = ChebyshevBandPass::design(BandPassSpec::kim(20_000.0)).unwrap();
    let fs = 20_000.0;
    // A 6.5 kHz sine comes through at the designed gain; a 4 kHz one is cut by the designed gain.
    for freq in [6500.0, 4000.0] {
        let x: Vec<f64> = (0..8000)
            .map(|i| (2.0 * std::f64::consts::PI * freq * i as f64 / fs).sin())
            .collect();
        let y = f.runner().run(&x);
        let (b, a) = f.direct_form();
        let yd = direct_form_filter(&b, &a, &x);
        // RMS·√2 over whole periods (4000 samples) is the amplitude of a sampled sine.
        let amp = (y[4000..].iter().map(|v| v * v).sum::<f64>() / 4000.0 * 2.0).sqrt();
        let expected = f.response(freq).norm();
        assert!(
            (amp - expected).abs() < 0.01 * expected.max(1e-3),
            "{freq} Hz: {amp} vs {expected}"
        );
        let diff = y
            .iter()
            .zip(&yd)
            .fold(0.0f64, |m, (p, q)| m.max((p - q).abs()));
        assert!(diff < 1e-9, "sections and direct form differ by {diff}");
    }
}

#[test]
fn bad_specs_are_refused() {
    let mut s = BandPassSpec::kim(20_000.0);
    s.stop_hz.1 = 10_500.0;
    assert!(
        ChebyshevBandPass::design(s).is_err(),
        "stop edge above Nyquist"
    );
    let mut s = BandPassSpec::kim(20_000.0);
    s.attenuation_db = 0.05;
    assert!(
        ChebyshevBandPass::design(s).is_err(),
        "attenuation below ripple"
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn designs_meet_their_own_spec(
        lo in 0.05f64..0.3,
        width in 0.02f64..0.1,
        t1 in 0.005f64..0.05,
        t2 in 0.005f64..0.05,
        ripple in 0.05f64..2.0,
        atten in 15.0f64..60.0,
    ) {
        let fs = 20_000.0;
        let nyq = fs / 2.0;
        let (p1, p2) = (lo * nyq, (lo + width) * nyq);
        let spec = BandPassSpec {
            pass_hz: (p1, p2),
            stop_hz: (p1 - t1 * nyq, (p2 + t2 * nyq).min(0.99 * nyq)),
            ripple_db: ripple,
            attenuation_db: atten,
            sample_rate_hz: fs,
        };
        let f = ChebyshevBandPass::design(spec).unwrap();
        let (r, a) = measured(&f);
        prop_assert!(r <= ripple + 1e-6, "ripple {} > {} (N = {})", r, ripple, f.prototype_order);
        prop_assert!(a >= atten - 1e-6, "attenuation {} < {} (N = {})", a, atten, f.prototype_order);
    }
}
