//! A preloaded double nut whose preload may be lost: Hertzian contacts in series with the
//! screw shaft and bearings.
//!
//! The two halves of a double nut (or the two flanks of an offset-lead nut) are pressed
//! against each other by the preload `P`. Each half bears on the screw through its balls with
//! Hertzian point contacts, axial deflection `δ = c F^(2/3)` (Harris & Kotzalas, "Rolling
//! Bearing Analysis", 5th ed., ch. 7; the ball-screw catalogues' rigidity rule
//! `K ∝ (F_a0)^(1/3)`, e.g. THK's `K = K_cat·(F_a0/0.1 C_a)^(1/3)`). Under an axial load the
//! nut moves by `x` against the screw; one half is compressed to `δ0 + x`, the other relieved
//! to `δ0 − x`, `δ0 = c P^(2/3)`:
//!
//! ```text
//! F_nut(x) = ((δ0 + x)⁺ / c)^(3/2) − ((δ0 − x)⁺ / c)^(3/2)        N, (·)⁺ = max(·, 0)
//! K_nut    = dF_nut/dx (0) = 3 P^(1/3) / c                        rigidity about zero load
//! ```
//!
//! so `c = 3 P^(1/3)/K_nut` from a catalogue rigidity `K_nut` at the preload `P` the nut was
//! made with. The relieved half lifts off at `x = δ0`, an external load of
//! `F_nut(δ0) = (2δ0/c)^(3/2) = 2^(3/2) P ≈ 2.83 P` (the textbook limit of a preloaded pair).
//! Wear of the balls and grooves lowers the preload to `P_r` (same `c`); with `P_r = 0` the nut
//! is soft about zero load (`F ∝ x^(3/2)`, no rigidity at all), and a reversal of the load
//! from `+F` to `−F` moves it by `2 c F^(2/3)`: an elastic lost motion, backlash by another
//! mechanism, that grows with the friction it reverses against.
//!
//! The nut is in series with the rest of the transmission (screw shaft, thrust bearings and
//! housing), a linear spring `k_r`: the drive's screw stiffness `k` is the series stiffness at
//! the nut's original preload, `1/k = 1/k_r + 1/K_nut`. For a stretch `d` of the transmission
//! (after the backlash dead zone, see `transmission`) the force solves
//!
//! ```text
//! k_r (d − x) = F_nut(x)                                           for the nut's share x
//! ```
//!
//! by Newton's method on this monotone equation, bracketed between 0 and `d` (bisection where
//! a Newton step would leave the bracket), started from the nut's linear share of `d`,
//! converged to 1e-15 m (a few iterations per plant step). The
//! drive adds the screw damping `c_s (v_nut − v_c)` as before. The largest stiffness of the
//! series is below `k_r`, which bounds the step check.
//!
//! Plausible sizes for the 32 mm, 10 mm lead screws of a 500 × 400 × 400 mm machining centre
//! (dynamic load rating C_a ≈ 30–40 kN): preload 2–10 % of C_a (light to medium preload,
//! 0.6–4 kN), nut rigidity 500–1000 N/µm at that preload; a worn nut keeps 0–50 % of it.

/// A preloaded double nut, SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreloadedNut {
    /// The preload the nut was made with, N (> 0).
    pub preload_n: f64,
    /// The nut's rigidity at that preload (catalogue K), N/m (> the drive's screw stiffness).
    pub stiffness_n_per_m: f64,
    /// The preload left by wear, N (0 to `preload_n`).
    pub remaining_preload_n: f64,
}

impl PreloadedNut {
    /// A description of the first value that is not a nut's, if any; `screw_n_per_m` is the
    /// drive's series stiffness, which must be below the nut's own.
    pub fn check(&self, screw_n_per_m: f64) -> Result<(), String> {
        let all = [
            self.preload_n,
            self.stiffness_n_per_m,
            self.remaining_preload_n,
        ];
        if !all.iter().all(|v| v.is_finite()) {
            return Err("the nut's preload and rigidity must be finite numbers".into());
        }
        if self.preload_n <= 0.0 || self.stiffness_n_per_m <= 0.0 {
            return Err("the nut's preload and rigidity must be > 0".into());
        }
        if !(0.0..=self.preload_n).contains(&self.remaining_preload_n) {
            return Err(format!(
                "a remaining preload of {} N is not accepted: from 0 to the preload the nut was made with, {} N",
                self.remaining_preload_n, self.preload_n
            ));
        }
        if self.stiffness_n_per_m <= screw_n_per_m {
            return Err(format!(
                "a nut rigidity of {} N/µm is not accepted: the screw's stiffness ({} N/µm) is the nut, shaft and bearings in series, so the nut alone must be stiffer",
                self.stiffness_n_per_m * 1e-6,
                screw_n_per_m * 1e-6
            ));
        }
        Ok(())
    }

    /// The compliance constant c of `δ = c F^(2/3)` per half, m/N^(2/3).
    pub fn compliance(&self) -> f64 {
        3.0 * self.preload_n.cbrt() / self.stiffness_n_per_m
    }

    /// This nut in series with the rest of a transmission whose total stiffness at the
    /// original preload is `screw_n_per_m` (N/m).
    pub fn in_series(&self, screw_n_per_m: f64) -> NutSeries {
        let c = self.compliance();
        let mut s = NutSeries {
            c,
            delta0_m: c * self.remaining_preload_n.powf(2.0 / 3.0),
            rest_n_per_m: 1.0 / (1.0 / screw_n_per_m - 1.0 / self.stiffness_n_per_m),
            share: 0.0,
        };
        let (_, k0) = s.nut_force(0.0);
        s.share = s.rest_n_per_m / (s.rest_n_per_m + k0);
        s
    }
}

/// A [`PreloadedNut`] in series with the linear rest of the transmission.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NutSeries {
    /// Compliance constant c, m/N^(2/3).
    c: f64,
    /// Preload deflection of each half δ0 at the remaining preload, m.
    delta0_m: f64,
    /// Stiffness k_r of the shaft and bearings, N/m.
    rest_n_per_m: f64,
    /// The nut's share of a small stretch, `k_r / (k_r + K_nut(0))`.
    share: f64,
}

impl NutSeries {
    /// Stiffness of the shaft and bearings alone, N/m (the series' upper bound).
    pub fn rest_stiffness_n_per_m(&self) -> f64 {
        self.rest_n_per_m
    }

    /// The nut's force (N) at its deflection `x` (m) and its derivative (N/m).
    #[inline]
    pub fn nut_force(&self, x: f64) -> (f64, f64) {
        let half = |delta: f64| {
            if delta <= 0.0 {
                (0.0, 0.0)
            } else {
                let r = (delta / self.c).sqrt();
                (r * r * r, 1.5 * r / self.c)
            }
        };
        let (f1, k1) = half(self.delta0_m + x);
        let (f2, k2) = half(self.delta0_m - x);
        (f1 - f2, k1 + k2)
    }

    /// A first guess of the nut's deflection at stretch `d` (m): its share of `d` with the
    /// nut's rigidity about zero load at the remaining preload.
    #[inline]
    pub fn linear_guess(&self, d: f64) -> f64 {
        d * self.share
    }

    /// The force (N) through the series at stretch `d` (m), and the nut's deflection (m),
    /// solved from the deflection `guess` (any: it is kept within the bracket).
    #[inline]
    pub fn force(&self, d: f64, guess: f64) -> (f64, f64) {
        let (lo, hi) = if d >= 0.0 { (0.0, d) } else { (d, 0.0) };
        let (mut lo, mut hi) = (lo, hi);
        let mut x = guess.clamp(lo, hi);
        for _ in 0..60 {
            let (f, k) = self.nut_force(x);
            // g(x) = k_r (d − x) − F(x), decreasing in x.
            let g = self.rest_n_per_m * (d - x) - f;
            if g > 0.0 {
                lo = x;
            } else {
                hi = x;
            }
            let newton = x + g / (self.rest_n_per_m + k);
            let next = if newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            };
            let done = (next - x).abs() <= 1e-15 + 1e-12 * x.abs();
            x = next;
            if done || hi - lo <= 1e-15 {
                break;
            }
        }
        (self.rest_n_per_m * (d - x), x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nut(remaining: f64) -> PreloadedNut {
        PreloadedNut {
            preload_n: 2000.0,
            stiffness_n_per_m: 800e6,
            remaining_preload_n: remaining,
        }
    }

    /// Against the textbook limit of a preloaded pair: the relieved half lifts off at
    /// 2^(3/2) P, and the rigidity about zero load is the catalogue's.
    #[test]
    fn the_relieved_half_lifts_off_at_2_83_times_the_preload() {
        for p in [500.0, 2000.0, 3800.0] {
            let n = PreloadedNut {
                remaining_preload_n: p,
                preload_n: p,
                ..nut(0.0)
            };
            let s = n.in_series(180e6);
            let delta0 = s.c * p.powf(2.0 / 3.0);
            let (at_lift, _) = s.nut_force(delta0);
            assert!((at_lift / p - 2f64.powf(1.5)).abs() < 1e-12, "{at_lift}");
            // Just before lift-off both halves carry load; beyond, the force is one half's.
            let (beyond, _) = s.nut_force(1.5 * delta0);
            assert!((beyond - (2.5 * delta0 / s.c).powf(1.5)).abs() < 1e-9 * beyond);
            let (_, k0) = s.nut_force(0.0);
            assert!((k0 / n.stiffness_n_per_m - 1.0).abs() < 1e-12, "{k0}");
        }
    }

    /// Against the closed form of a reversal ±F: the series stretches by
    /// `F/k_r + δ(F)` where the nut's share follows from its two halves; with no preload
    /// left, `2 c F^(2/3) + 2F/k_r`.
    #[test]
    fn a_lost_preload_gives_an_elastic_lost_motion() {
        let k = 180e6;
        for f in [20.0, 50.0, 150.0] {
            let s = nut(0.0).in_series(k);
            let stretch = |target: f64| {
                // Bisection on the series' force (the model's own solve inside).
                let (mut lo, mut hi) = (-1e-3, 1e-3);
                for _ in 0..200 {
                    let mid = 0.5 * (lo + hi);
                    if s.force(mid, 0.0).0 < target {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                0.5 * (lo + hi)
            };
            let lost = stretch(f) - stretch(-f);
            let c = 3.0 * 2000f64.cbrt() / 800e6;
            let rest = 1.0 / (1.0 / k - 1.0 / 800e6);
            let expected = 2.0 * c * f.powf(2.0 / 3.0) + 2.0 * f / rest;
            assert!((lost / expected - 1.0).abs() < 1e-7, "{lost} {expected}");
            // The intact nut: nearly linear at these loads, 2F/k.
            let intact = nut(2000.0).in_series(k);
            let (fp, _) = intact.force(f / k, 0.0);
            assert!((fp / f - 1.0).abs() < 0.01, "{fp}");
        }
    }

    #[test]
    fn the_solve_agrees_with_the_nut_force_from_any_guess() {
        let s = nut(300.0).in_series(180e6);
        for i in -50..=50 {
            let d = i as f64 * 2e-7;
            for guess in [-1e-5, 0.0, 3e-7, 1e-5] {
                let (f, x) = s.force(d, guess);
                let (fn_, _) = s.nut_force(x);
                assert!(
                    (f - fn_).abs() < 1e-6 * (1.0 + f.abs()),
                    "{d} {guess}: {f} {fn_}"
                );
            }
        }
        assert!(nut(2000.0).check(180e6).is_ok());
        assert!(nut(2500.0).check(180e6).is_err());
        assert!(nut(0.0).check(900e6).is_err());
    }
}
