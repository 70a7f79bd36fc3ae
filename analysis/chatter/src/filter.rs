//! Chebyshev type I band-pass IIR filters designed from a specification, run sample by sample
//! as second-order sections.
//!
//! # Design (digital band-pass from an analogue prototype)
//!
//! Source: the classical procedure (Parks & Burrus, *Digital Filter Design*, 1987, ch. 7;
//! Oppenheim & Schafer, *Discrete-Time Signal Processing*, 3rd ed., §7.1–7.2), as used by Kim,
//! Song & Koh (2015) for their 6–7 kHz chatter band.
//!
//! 1. Pre-warp every edge frequency f (Hz) to the analogue frequency the bilinear transform maps
//!    onto it: Ω = 2·fs·tan(π·f/fs) (rad/s).
//! 2. Band-pass → low-pass prototype: ω0² = Ωp1·Ωp2, B = Ωp2 − Ωp1; a stop edge Ωs maps to
//!    |Ωs² − ω0²| / (Ωs·B); the prototype stop frequency λs is the smaller of the two.
//! 3. Minimum order: N = ⌈acosh(√((10^(As/10) − 1)/(10^(Rp/10) − 1))) / acosh(λs)⌉, with
//!    Rp the pass-band ripple and As the stop-band attenuation (dB).
//! 4. Prototype poles (pass-band edge 1 rad/s): ε = √(10^(Rp/10) − 1), μ = asinh(1/ε)/N,
//!    θk = (2k − 1)·π/(2N), pk = −sinh μ·sin θk + j·cosh μ·cos θk (k = 1..N);
//!    H(s) = K / Π(s − pk) with K = Π(−pk), divided by √(1 + ε²) for even N (the response at
//!    DC is then the bottom of the ripple).
//! 5. Low-pass → band-pass: s → (s² + ω0²)/(B·s): each pk gives the two roots of
//!    s² − pk·B·s + ω0² = 0; N zeros at s = 0 and N at infinity.
//! 6. Bilinear transform z = (1 + s/(2fs))/(1 − s/(2fs)): zeros at s = 0 go to z = 1, zeros at
//!    infinity to z = −1; the gain is set so that the digital response at the image of jω0
//!    equals the analogue one there.
//!
//! Kim et al.'s eq. (2)/(3) are this design for fs = **100 kHz** (their G(s), eq. (1), has
//! ω0 = 4.130·10⁴ rad/s and B = 6556 rad/s: the 6 and 7 kHz edges pre-warped at 100 kHz), not for
//! the 20 kHz they sample at: run at 20 kHz those coefficients would pass 1.2–1.4 kHz. For
//! 20 kHz the same specification gives (order 6, tests/filter.rs)
//! b = 4.7177·10⁻³·[1, 0, −3, 0, 3, 0, −1],
//! a = [1, 2.452345, 4.361164, 4.473512, 3.568054, 1.633828, 0.545379].
//!
//! The result is kept as second-order sections (each b = g·[1, 0, −1], a = [1, a1, a2]): a
//! 6th-order direct form is sensitive to coefficient rounding (the paper's printed 4-digit
//! coefficients put poles outside the unit circle; see the tests). The direct-form polynomials
//! are also given, for comparison with published difference equations.

use nalgebra::Complex;
use std::f64::consts::PI;
use thiserror::Error;

type C64 = Complex<f64>;

/// A specification that no Chebyshev band-pass can meet.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum FilterError {
    /// The edges are not 0 < stop1 < pass1 < pass2 < stop2 < fs/2.
    #[error(
        "band edges must satisfy 0 < stop_low < pass_low < pass_high < stop_high < fs/2 = {nyquist} Hz; got stop {stop_low}, pass {pass_low}..{pass_high}, stop {stop_high} Hz"
    )]
    Edges {
        /// Lower stop edge, Hz.
        stop_low: f64,
        /// Lower pass edge, Hz.
        pass_low: f64,
        /// Upper pass edge, Hz.
        pass_high: f64,
        /// Upper stop edge, Hz.
        stop_high: f64,
        /// Half the sample rate, Hz.
        nyquist: f64,
    },
    /// Ripple or attenuation out of range.
    #[error(
        "need 0 < ripple ({ripple_db} dB) < attenuation ({attenuation_db} dB) <= 300 dB and ripple <= 10 dB"
    )]
    Levels {
        /// Pass-band ripple, dB.
        ripple_db: f64,
        /// Stop-band attenuation, dB.
        attenuation_db: f64,
    },
    /// The minimum order exceeds what the sections can hold accurately.
    #[error(
        "the specification needs order {order} (> {max}) prototype; widen the transition bands"
    )]
    Order {
        /// Needed prototype order.
        order: usize,
        /// Largest accepted.
        max: usize,
    },
}

/// A band-pass specification. Frequencies in Hz, levels in dB.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BandPassSpec {
    /// Pass band (low, high) edges, Hz: the gain stays within `ripple_db` of 0 dB between them.
    pub pass_hz: (f64, f64),
    /// Stop band edges (low, high), Hz: the gain is at least `attenuation_db` down at and beyond them.
    pub stop_hz: (f64, f64),
    /// Pass-band ripple Rp, dB.
    pub ripple_db: f64,
    /// Stop-band attenuation As, dB.
    pub attenuation_db: f64,
    /// Sample rate fs, Hz.
    pub sample_rate_hz: f64,
}

impl BandPassSpec {
    /// Kim, Song & Koh's filter (§2.2): pass 6–7 kHz, 0.1 dB ripple, 10 dB at 5.5 and 7.5 kHz.
    pub fn kim(sample_rate_hz: f64) -> Self {
        Self {
            pass_hz: (6000.0, 7000.0),
            stop_hz: (5500.0, 7500.0),
            ripple_db: 0.1,
            attenuation_db: 10.0,
            sample_rate_hz,
        }
    }

    fn validate(&self) -> Result<(), FilterError> {
        let nyquist = self.sample_rate_hz / 2.0;
        let (s1, s2) = self.stop_hz;
        let (p1, p2) = self.pass_hz;
        let ordered = 0.0 < s1 && s1 < p1 && p1 < p2 && p2 < s2 && s2 < nyquist;
        if !(ordered && nyquist.is_finite()) {
            return Err(FilterError::Edges {
                stop_low: s1,
                pass_low: p1,
                pass_high: p2,
                stop_high: s2,
                nyquist,
            });
        }
        let (rp, a) = (self.ripple_db, self.attenuation_db);
        if !(rp > 0.0 && rp <= 10.0 && a > rp && a <= 300.0) {
            return Err(FilterError::Levels {
                ripple_db: rp,
                attenuation_db: a,
            });
        }
        Ok(())
    }

    /// Ω = 2·fs·tan(π·f/fs), rad/s.
    fn warp(&self, f: f64) -> f64 {
        2.0 * self.sample_rate_hz * (PI * f / self.sample_rate_hz).tan()
    }

    /// Minimum prototype order N (step 3); the band-pass order is 2N.
    pub fn min_order(&self) -> Result<usize, FilterError> {
        self.validate()?;
        let (w1, w2) = (self.warp(self.pass_hz.0), self.warp(self.pass_hz.1));
        let (w0sq, b) = (w1 * w2, w2 - w1);
        let lambda = |ws: f64| (ws * ws - w0sq).abs() / (ws * b);
        let ls = lambda(self.warp(self.stop_hz.0)).min(lambda(self.warp(self.stop_hz.1)));
        let ratio = ((10f64.powf(self.attenuation_db / 10.0) - 1.0)
            / (10f64.powf(self.ripple_db / 10.0) - 1.0))
            .sqrt();
        // The tiny slack keeps an exactly met spec (N = 3.0000000001 by rounding) at N = 3.
        Ok((ratio.acosh() / ls.acosh() - 1e-9).ceil().max(1.0) as usize)
    }
}

/// One biquad b0 + b1 z⁻¹ + b2 z⁻² over 1 + a1 z⁻¹ + a2 z⁻².
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Section {
    /// Numerator b0, b1, b2.
    pub b: [f64; 3],
    /// Denominator a1, a2 (a0 = 1).
    pub a: [f64; 2],
}

/// A designed Chebyshev type I band-pass filter.
#[derive(Debug, Clone, PartialEq)]
pub struct ChebyshevBandPass {
    /// The specification it was designed for.
    pub spec: BandPassSpec,
    /// Prototype order N (band-pass order 2N).
    pub prototype_order: usize,
    /// Second-order sections, applied in series.
    pub sections: Vec<Section>,
}

/// Largest prototype order accepted (band-pass order 40).
pub const MAX_PROTOTYPE_ORDER: usize = 20;

impl ChebyshevBandPass {
    /// Designs the minimum-order filter meeting `spec` (steps 1–6 of the module doc).
    pub fn design(spec: BandPassSpec) -> Result<Self, FilterError> {
        let n = spec.min_order()?;
        if n > MAX_PROTOTYPE_ORDER {
            return Err(FilterError::Order {
                order: n,
                max: MAX_PROTOTYPE_ORDER,
            });
        }
        Ok(Self::with_order(spec, n))
    }

    fn with_order(spec: BandPassSpec, n: usize) -> Self {
        let fs = spec.sample_rate_hz;
        let (w1, w2) = (spec.warp(spec.pass_hz.0), spec.warp(spec.pass_hz.1));
        let (w0, b) = ((w1 * w2).sqrt(), w2 - w1);
        let eps = (10f64.powf(spec.ripple_db / 10.0) - 1.0).sqrt();
        let mu = (1.0 / eps).asinh() / n as f64;
        let proto: Vec<C64> = (1..=n)
            .map(|k| {
                let th = (2 * k - 1) as f64 * PI / (2 * n) as f64;
                C64::new(-mu.sinh() * th.sin(), mu.cosh() * th.cos())
            })
            .collect();
        // Analogue band-pass poles and the analogue response at jω0.
        let mut poles = Vec::with_capacity(2 * n);
        for p in &proto {
            let disc = (p * p * b * b - 4.0 * w0 * w0).sqrt();
            poles.push((p * b + disc) / 2.0);
            poles.push((p * b - disc) / 2.0);
        }
        let even_gain = if n.is_multiple_of(2) {
            1.0 / (1.0 + eps * eps).sqrt()
        } else {
            1.0
        };
        // At s = jω0 the prototype sees s' = 0, so |H| = K/Π|pk| = even_gain.
        let bilinear =
            |s: C64| (C64::new(1.0, 0.0) + s / (2.0 * fs)) / (C64::new(1.0, 0.0) - s / (2.0 * fs));
        let zpoles: Vec<C64> = poles.iter().map(|&p| bilinear(p)).collect();
        let mut sections = pair_sections(&zpoles);
        let z0 = bilinear(C64::new(0.0, w0));
        let unscaled: C64 = sections.iter().map(|s| s.response(z0)).product();
        let g = (even_gain / unscaled.norm()).powf(1.0 / sections.len() as f64);
        for s in &mut sections {
            s.b = s.b.map(|v| v * g);
        }
        Self {
            spec,
            prototype_order: n,
            sections,
        }
    }

    /// Complex response at frequency `f_hz`.
    pub fn response(&self, f_hz: f64) -> C64 {
        let z = C64::from_polar(1.0, 2.0 * PI * f_hz / self.spec.sample_rate_hz);
        self.sections.iter().map(|s| s.response(z)).product()
    }

    /// Gain at `f_hz`, dB.
    pub fn gain_db(&self, f_hz: f64) -> f64 {
        20.0 * self.response(f_hz).norm().log10()
    }

    /// Direct-form polynomials (b, a) in powers of z⁻¹, `a[0] = 1`: `y[k] = Σ b_i x[k−i] − Σ_{i≥1} a_i y[k−i]`.
    pub fn direct_form(&self) -> (Vec<f64>, Vec<f64>) {
        let mut b = vec![1.0];
        let mut a = vec![1.0];
        for s in &self.sections {
            b = convolve(&b, &s.b);
            a = convolve(&a, &[1.0, s.a[0], s.a[1]]);
        }
        (b, a)
    }

    /// A filter with zero initial state.
    pub fn runner(&self) -> SosFilter {
        SosFilter::new(self.sections.clone())
    }
}

impl Section {
    /// H(z) of this section.
    pub fn response(&self, z: C64) -> C64 {
        let zi = z.inv();
        let num = self.b[0] + zi * (self.b[1] + zi * self.b[2]);
        let den = C64::new(1.0, 0.0) + zi * (self.a[0] + zi * self.a[1]);
        num / den
    }
}

/// Groups digital poles into sections: a pole with Im > 0 and its conjugate, then the real poles
/// two by two (they come in pairs: each real prototype pole gives two band-pass poles). Every
/// section gets one zero at z = 1 and one at z = −1: numerator 1 − z⁻².
fn pair_sections(poles: &[C64]) -> Vec<Section> {
    let tol = 1e-12;
    let mut a: Vec<[f64; 2]> = poles
        .iter()
        .filter(|p| p.im > tol)
        .map(|p| [-2.0 * p.re, p.norm_sqr()])
        .collect();
    let mut real: Vec<f64> = poles
        .iter()
        .filter(|p| p.im.abs() <= tol)
        .map(|p| p.re)
        .collect();
    real.sort_by(f64::total_cmp);
    for pair in real.chunks(2) {
        let (r1, r2) = (pair[0], pair.get(1).copied().unwrap_or(0.0));
        a.push([-(r1 + r2), r1 * r2]);
    }
    a.into_iter()
        .map(|a| Section {
            b: [1.0, 0.0, -1.0],
            a,
        })
        .collect()
}

fn convolve(x: &[f64], y: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; x.len() + y.len() - 1];
    for (i, xi) in x.iter().enumerate() {
        for (j, yj) in y.iter().enumerate() {
            out[i + j] += xi * yj;
        }
    }
    out
}

/// Second-order sections in series, transposed direct form II, run one sample at a time:
/// y = b0·x + s1; s1 ← b1·x − a1·y + s2; s2 ← b2·x − a2·y.
#[derive(Debug, Clone, PartialEq)]
pub struct SosFilter {
    sections: Vec<Section>,
    state: Vec<[f64; 2]>,
}

impl SosFilter {
    /// A filter at rest.
    pub fn new(sections: Vec<Section>) -> Self {
        let state = vec![[0.0; 2]; sections.len()];
        Self { sections, state }
    }

    /// Filters one sample.
    pub fn step(&mut self, x: f64) -> f64 {
        let mut v = x;
        for (s, st) in self.sections.iter().zip(&mut self.state) {
            let y = s.b[0] * v + st[0];
            st[0] = s.b[1] * v - s.a[0] * y + st[1];
            st[1] = s.b[2] * v - s.a[1] * y;
            v = y;
        }
        v
    }

    /// Filters a whole signal from the current state.
    pub fn run(&mut self, x: &[f64]) -> Vec<f64> {
        x.iter().map(|&v| self.step(v)).collect()
    }
}

/// A direct-form difference equation `y[k] = Σ b_i x[k−i] − Σ_{i≥1} a_i y[k−i]` (`a[0] = 1`),
/// for running published coefficients as printed.
pub fn direct_form_filter(b: &[f64], a: &[f64], x: &[f64]) -> Vec<f64> {
    let mut y: Vec<f64> = Vec::with_capacity(x.len());
    for k in 0..x.len() {
        let fwd: f64 = (0..b.len().min(k + 1)).map(|i| b[i] * x[k - i]).sum();
        let back: f64 = (1..a.len().min(k + 1)).map(|i| a[i] * y[k - i]).sum();
        y.push(fwd - back);
    }
    y
}
