//! Interpolation (sub-divisional) error of an incremental sin/cos encoder.
//!
//! An optical or magnetic encoder gives two signals in quadrature, one period per signal
//! period λ (m of travel: the grating or magnetic pitch of a linear scale, `lead / periods`
//! of a rotary encoder on the motor). The electronics interpolate the position within a period
//! from the angle of the signal pair. Real signals carry offsets, unequal amplitudes and a
//! quadrature phase error (Heydemann, "Determination and correction of quadrature fringe
//! measurement errors in interferometers", Applied Optics 20(19), 1981):
//!
//! ```text
//! φ      = 2π x / λ                             the true phase of position x (m)
//! u_cos  = cos(φ − β/2) + o_c                   cosine channel (amplitude 1)
//! u_sin  = r sin(φ + β/2) + o_s                 sine channel
//! φ̂      = atan2(u_sin, u_cos)                  the interpolated phase
//! e(x)   = λ/2π · wrap(φ̂ − φ)                   interpolation error, m (wrap to ±π)
//! ```
//!
//! with the offsets `o_c`, `o_s` and the amplitude ratio `r` relative to the cosine channel's
//! amplitude and β the departure from 90° between the channels (rad), split evenly between them
//! so that it adds no constant offset. The reading is `x + e(x)`; the loop that closes on it
//! follows the reading, so within its bandwidth the axis carries `−e`. To first order in the
//! distortions (Heydemann's linearisation)
//!
//! ```text
//! e ≈ λ/2π · [ o_s cos φ − o_c sin φ  +  (r − 1)/2 · sin 2φ  +  β/2 · cos 2φ ]
//! ```
//!
//! an error once per signal period from the offsets (amplitude `λ/2π·√(o_c² + o_s²)`) and twice
//! per period from the amplitude and phase errors (`λ/4π·√((r−1)² + β²)`). The model evaluates
//! the exact `atan2`, not the linearisation.
//!
//! Plausible sizes: interpolation errors of ±0.5–2 % of the signal period for the optical
//! scales of this machine class (20 µm grating: ±0.1–0.4 µm; manufacturers' data sheets quote
//! ±1 % of the period), ±1–2 µm on magnetic scales of 1–2 mm pitch, and on a motor encoder
//! with 2048 periods per revolution on a 10 mm lead (λ = 4.9 µm) some tens of nanometres:
//! offsets and amplitude mismatch of 0.5–2 % of the amplitude, phase errors of 0.5–2°.

use std::f64::consts::{PI, TAU};

/// The distorted signals of a sin/cos encoder, SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EncoderSignals {
    /// Signal period λ in travel, m (> 0).
    pub period_m: f64,
    /// Offset of the cosine channel, relative to its amplitude.
    pub offset_cos: f64,
    /// Offset of the sine channel, relative to the cosine channel's amplitude.
    pub offset_sin: f64,
    /// Amplitude of the sine channel over the cosine channel's (1 for equal amplitudes, > 0).
    pub amplitude_ratio: f64,
    /// Departure from quadrature β, rad.
    pub phase_error_rad: f64,
}

impl EncoderSignals {
    /// A description of the first value that is not a sin/cos encoder's, if any: the signals
    /// must keep the origin inside their Lissajous figure, or the interpolation loses periods.
    pub fn check(&self) -> Result<(), String> {
        let all = [
            self.period_m,
            self.offset_cos,
            self.offset_sin,
            self.amplitude_ratio,
            self.phase_error_rad,
        ];
        if !all.iter().all(|v| v.is_finite()) {
            return Err("the signal parameters must be finite numbers".into());
        }
        if self.period_m <= 0.0 || self.amplitude_ratio <= 0.0 {
            return Err("the signal period and the amplitude ratio must be > 0".into());
        }
        // The interpolation counts periods only while the signal pair circles the origin:
        // offsets below a fifth of the smaller amplitude and a phase error below 30° keep it
        // far inside (real encoders are within a few per cent and a few degrees).
        let smaller = self.amplitude_ratio.min(1.0);
        if self.offset_cos.hypot(self.offset_sin) > 0.2 * smaller {
            return Err(format!(
                "offsets of {:.3} and {:.3} are not accepted: they must stay below a fifth of the smaller amplitude ({:.3}) or the interpolation loses periods",
                self.offset_cos,
                self.offset_sin,
                0.2 * smaller
            ));
        }
        if self.phase_error_rad.abs() > PI / 6.0 {
            return Err("a quadrature phase error beyond ±30° is not an encoder's".into());
        }
        Ok(())
    }

    /// The interpolation error at position `x` (m): reading minus true position, m.
    #[inline]
    pub fn error_m(&self, x: f64) -> f64 {
        let k = TAU / self.period_m;
        let phi = k * x;
        let half = 0.5 * self.phase_error_rad;
        let u_cos = (phi - half).cos() + self.offset_cos;
        let u_sin = self.amplitude_ratio * (phi + half).sin() + self.offset_sin;
        let (s, c) = phi.sin_cos();
        // φ̂ − φ as the angle of the signal vector turned back by φ: no wrapping needed.
        let dphi = (u_sin * c - u_cos * s).atan2(u_cos * c + u_sin * s);
        dphi / k
    }

    /// The first-order amplitudes of the error's first and second harmonics over the signal
    /// period, m (the linearisation in the module docs).
    pub fn first_order_amplitudes_m(&self) -> [f64; 2] {
        let scale = self.period_m / TAU;
        [
            scale * self.offset_cos.hypot(self.offset_sin),
            0.5 * scale * (self.amplitude_ratio - 1.0).hypot(self.phase_error_rad),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Amplitude of harmonic `n` of `f` over one period of `samples` points (a DFT written
    /// here, independent of the model).
    fn harmonic(f: &[f64], n: usize) -> f64 {
        let len = f.len() as f64;
        let (mut re, mut im) = (0.0, 0.0);
        for (i, v) in f.iter().enumerate() {
            let a = TAU * (n * i) as f64 / len;
            re += v * a.cos();
            im += v * a.sin();
        }
        2.0 * re.hypot(im) / len
    }

    /// Against Heydemann's first-order amplitudes: for distortions of ε the exact atan2
    /// error's harmonics differ from them by O(ε²), so within a few per cent at ε of 1–2 %.
    #[test]
    fn harmonics_of_the_exact_error_match_the_first_order_theory() {
        let cases = [
            (0.01, 0.0, 1.0, 0.0),
            (0.0, -0.015, 1.0, 0.0),
            (0.008, 0.006, 1.02, 0.0),
            (0.0, 0.0, 0.985, 0.0),
            (0.0, 0.0, 1.0, 1.0_f64.to_radians()),
            (0.005, -0.01, 1.01, -1.5_f64.to_radians()),
        ];
        for (oc, os, r, beta) in cases {
            let e = EncoderSignals {
                period_m: 20e-6,
                offset_cos: oc,
                offset_sin: os,
                amplitude_ratio: r,
                phase_error_rad: beta,
            };
            e.check().unwrap();
            let n = 512;
            let f: Vec<f64> = (0..n)
                .map(|i| e.error_m(e.period_m * i as f64 / n as f64))
                .collect();
            let [a1, a2] = e.first_order_amplitudes_m();
            let size = [oc, os, r - 1.0, beta]
                .iter()
                .fold(0.0_f64, |m, v| m.max(v.abs()));
            // Second-order remainder: ε² λ/2π (a second-order term of the expansion).
            let tol = 2.0 * size * size * e.period_m / TAU + 1e-15;
            assert!(
                (harmonic(&f, 1) - a1).abs() < tol,
                "{oc} {os} {r} {beta}: first"
            );
            assert!(
                (harmonic(&f, 2) - a2).abs() < tol,
                "{oc} {os} {r} {beta}: second"
            );
            // And the mean (a constant offset) is of second order too.
            let mean = f.iter().sum::<f64>() / n as f64;
            assert!(mean.abs() < tol, "mean {mean}");
        }
    }

    #[test]
    fn perfect_signals_interpolate_exactly_and_bad_ones_are_refused() {
        let e = EncoderSignals {
            period_m: 4e-6,
            offset_cos: 0.0,
            offset_sin: 0.0,
            amplitude_ratio: 1.0,
            phase_error_rad: 0.0,
        };
        for i in 0..1000 {
            let x = -0.3 + i as f64 * 7.3e-4;
            assert!(e.error_m(x).abs() < 1e-18, "{x}");
        }
        let bad = [
            EncoderSignals {
                offset_cos: 0.3,
                ..e
            },
            EncoderSignals {
                amplitude_ratio: 0.0,
                ..e
            },
            EncoderSignals {
                phase_error_rad: 1.0,
                ..e
            },
            EncoderSignals {
                period_m: f64::NAN,
                ..e
            },
        ];
        for b in bad {
            assert!(b.check().is_err(), "{b:?}");
        }
    }
}
