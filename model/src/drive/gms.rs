//! The Generalized Maxwell-Slip friction model (Al-Bender, Lampaert & Swevers, "The
//! generalized Maxwell-slip model: a novel model for friction simulation and compensation",
//! IEEE Trans. Automatic Control 50(11), 2005): a friction law other than LuGre, with
//! hysteresis with non-local memory in pre-sliding.
//!
//! `N` elastoslip elements act in parallel; element `i` is a spring of stiffness `k_i` whose
//! end sticks to the surface until its force reaches `α_i s(v)`, then slips:
//!
//! ```text
//! stick:  dF_i/dt = k_i v                                 while |F_i| < α_i s(v)
//! slip:   dF_i/dt = sgn(v) C (α_i − F_i / s(v))           until v changes sign
//! s(v)  = Fc + (Fs − Fc) exp(−(|v|/vs)^δ)                 Stribeck curve, Σ α_i = 1
//! F     = Σ F_i + (σ1/σ0) Σ dF_i/dt + σ2 v                friction force opposing motion, N
//! ```
//!
//! with `C` the attraction parameter (N/s: how fast a slipping element follows the Stribeck
//! curve), σ0 = Σ k_i the pre-sliding stiffness, σ1 a damping of the elements' deformation (the
//! LuGre bristle damping, so that the pre-sliding mode is as damped as with LuGre) and σ2 the
//! viscous coefficient. In steady sliding every element slips at `α_i s(v)`: `F = s(v) + σ2 v`,
//! the Stribeck curve. From rest the virgin curve is `F(x) = Σ min(k_i x, α_i Fs)`, piecewise
//! linear; after a reversal at `(x_r, F_r)` the curve is Masing's, `F_r − 2 F_virgin((x_r−x)/2)`,
//! and an inner loop closes where it began (non-local memory), which LuGre's single state
//! cannot do.
//!
//! The elements are derived from the contact's LuGre parameters ([`GmsParams::matching`]), so
//! that the law changes and the levels do not: the same Stribeck curve and viscous term, the
//! initial stiffness σ0 and the saturation at Fs of the LuGre virgin curve
//! `Fs (1 − exp(−x/x0))`, `x0 = Fs/σ0`. Its derivative `σ0 exp(−x/x0)` is the stiffness still
//! sticking at `x`: the breakaway displacements `Δ_i` are exponentially distributed with mean
//! `x0`. N equal-probability bins of that distribution give `k_i = σ0/N`, `Δ_i = x0 m_i`
//! (`m_i` the mean of Exp(1) over bin i) and `α_i = k_i Δ_i / Fs = m_i / N`, which sum to 1;
//! the last element breaks away at `x0 (1 + ln N)`. The default attraction is `C = σ0 vs`
//! (a slipping element relaxes over about x0 at the Stribeck velocity, LuGre's length).
//!
//! Integration over a step `h` with the velocity held, as the LuGre contact is: a sticking
//! element's force grows by `k_i v h` exactly (clamped at `α_i s(v)`, where it starts to
//! slip), a slipping element's relaxes exactly, `F_i = F_ss + (F_i − F_ss) exp(−C h / s(v))`,
//! `F_ss = sgn(v) α_i s(v)`; the damping uses the change of `Σ F_i` over the step. Sticking
//! stiffness σ0 and damping σ1 are those of the LuGre contact, so its step check holds.
//!
//! Plausible parameters: those of the contact's LuGre model (guideway Coulomb 40–70 N, static
//! 55–90 N, σ0 of 20 N/µm on the built-in machine, x0 ≈ 3 µm), 2–8 elements (Al-Bender et al.
//! identify 4–10 on linear guides).

use super::friction::{LuGreParams, exp};

/// Most elements of a GMS contact.
pub const MAX_GMS_ELEMENTS: usize = 8;

/// A GMS contact's parameters with its elements.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GmsParams {
    /// Stribeck curve, σ0 (total stiffness), σ1 (damping) and σ2 (viscous), as LuGre's.
    pub curve: LuGreParams,
    /// Number of elements N (1 to [`MAX_GMS_ELEMENTS`]).
    pub elements: usize,
    /// Element stiffnesses k_i, N/m.
    pub stiffness_n_per_m: [f64; MAX_GMS_ELEMENTS],
    /// Element fractions α_i of the Stribeck force (sum 1).
    pub fraction: [f64; MAX_GMS_ELEMENTS],
    /// Attraction parameter C, N/s (> 0).
    pub attraction_n_per_s: f64,
}

impl GmsParams {
    /// N elements matching the LuGre contact `p` (module docs): its Stribeck curve and
    /// viscous term, its pre-sliding stiffness σ0 and its saturation at Fs. `attraction`: C
    /// in N/s, or `None` for σ0·vs.
    pub fn matching(
        p: &LuGreParams,
        elements: usize,
        attraction: Option<f64>,
    ) -> Result<Self, String> {
        if !(1..=MAX_GMS_ELEMENTS).contains(&elements) {
            return Err(format!(
                "{elements} elements are not accepted; 1 to {MAX_GMS_ELEMENTS}"
            ));
        }
        p.check()?;
        let c = attraction.unwrap_or(p.sigma0_n_per_m * p.stribeck_m_s);
        if !(c.is_finite() && c > 0.0) {
            return Err(format!(
                "an attraction of {c} N/s is not accepted; a finite number > 0"
            ));
        }
        let n = elements as f64;
        let mut out = Self {
            curve: *p,
            elements,
            stiffness_n_per_m: [0.0; MAX_GMS_ELEMENTS],
            fraction: [0.0; MAX_GMS_ELEMENTS],
            attraction_n_per_s: c,
        };
        for i in 0..elements {
            // Bin i of Exp(1) with probability 1/N: [a, b], a = -ln(1 - i/N).
            let a = -(1.0 - i as f64 / n).ln();
            let mean = if i + 1 == elements {
                a + 1.0
            } else {
                let b = -(1.0 - (i + 1) as f64 / n).ln();
                let (ea, eb) = ((-a).exp(), (-b).exp());
                (a * ea - b * eb + ea - eb) / (ea - eb)
            };
            out.stiffness_n_per_m[i] = p.sigma0_n_per_m / n;
            out.fraction[i] = mean / n;
        }
        Ok(out)
    }

    /// The breakaway displacement of element `i` from rest, `α_i Fs / k_i`, m.
    pub fn breakaway_m(&self, i: usize) -> f64 {
        self.fraction[i] * self.curve.static_n / self.stiffness_n_per_m[i]
    }

    /// The virgin curve from rest, `Σ min(k_i x, α_i Fs)` (N) at displacement `x` (m, >= 0), at
    /// a speed far below the Stribeck velocity.
    pub fn virgin_force(&self, x: f64) -> f64 {
        (0..self.elements)
            .map(|i| (self.stiffness_n_per_m[i] * x).min(self.fraction[i] * self.curve.static_n))
            .sum()
    }
}

/// The state of a GMS contact: each element's force and whether (and which way) it slips.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gms {
    params: GmsParams,
    /// 1/σ0 · σ1, s (the damping's factor on dΣF/dt).
    damping_s: f64,
    force_n: [f64; MAX_GMS_ELEMENTS],
    /// 0 sticking, ±1 slipping in the direction of v's sign.
    slip: [i8; MAX_GMS_ELEMENTS],
}

impl Gms {
    /// A contact at rest with unloaded elements.
    pub fn new(params: GmsParams) -> Self {
        Self {
            params,
            damping_s: params.curve.sigma1_n_s_per_m / params.curve.sigma0_n_per_m,
            force_n: [0.0; MAX_GMS_ELEMENTS],
            slip: [0; MAX_GMS_ELEMENTS],
        }
    }

    /// The parameters.
    pub fn params(&self) -> &GmsParams {
        &self.params
    }

    /// Advances the elements by `h` seconds at sliding velocity `v` (m/s) and returns the
    /// friction force over the step, N (opposing the motion).
    #[inline]
    pub fn advance(&mut self, v: f64, h: f64) -> f64 {
        let p = &self.params;
        let c = &p.curve;
        let r = {
            let x = v.abs() / c.stribeck_m_s;
            if c.stribeck_exponent == 2.0 {
                x * x
            } else {
                x.powf(c.stribeck_exponent)
            }
        };
        let s = c.coulomb_n + (c.static_n - c.coulomb_n) * exp(-r);
        if s <= 0.0 {
            // No Stribeck force: the elements hold nothing.
            self.force_n = [0.0; MAX_GMS_ELEMENTS];
            self.slip = [0; MAX_GMS_ELEMENTS];
            return c.sigma2_n_s_per_m * v;
        }
        let dir: i8 = if v > 0.0 {
            1
        } else if v < 0.0 {
            -1
        } else {
            0
        };
        let decay = exp(-p.attraction_n_per_s * h / s);
        let before: f64 = self.force_n[..p.elements].iter().sum();
        for i in 0..p.elements {
            let limit = p.fraction[i] * s;
            let f = &mut self.force_n[i];
            if self.slip[i] != 0 && self.slip[i] == dir {
                let steady = limit * dir as f64;
                *f = steady + (*f - steady) * decay;
                continue;
            }
            self.slip[i] = 0;
            *f += p.stiffness_n_per_m[i] * v * h;
            if f.abs() >= limit {
                *f = limit.copysign(*f);
                self.slip[i] = dir;
            }
        }
        let after: f64 = self.force_n[..p.elements].iter().sum();
        after + self.damping_s * (after - before) / h + c.sigma2_n_s_per_m * v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn contact(coulomb: f64, stat: f64) -> LuGreParams {
        LuGreParams {
            sigma0_n_per_m: 2e7,
            sigma1_n_s_per_m: 0.0,
            sigma2_n_s_per_m: 0.0,
            coulomb_n: coulomb,
            static_n: stat,
            stribeck_m_s: 1e-3,
            stribeck_exponent: 2.0,
        }
    }

    /// Moves `g` from its state by `dx` (m) at speed `speed` (m/s) in steps of `h`; returns
    /// the force after each step with the displacement.
    fn travel(g: &mut Gms, dx: f64, speed: f64, h: f64) -> Vec<(f64, f64)> {
        let steps = (dx.abs() / (speed * h)).round() as usize;
        let v = speed.copysign(dx);
        (1..=steps)
            .map(|k| (k as f64 * v * h, g.advance(v, h)))
            .collect()
    }

    /// The element set reproduces the LuGre levels: initial stiffness σ0, saturation at Fs,
    /// fractions summing to 1 (the closed forms of the exponential distribution's bins).
    #[test]
    fn the_elements_match_the_lugre_stiffness_and_static_force() {
        for n in 1..=MAX_GMS_ELEMENTS {
            let p = GmsParams::matching(&contact(50.0, 65.0), n, None).unwrap();
            let k: f64 = p.stiffness_n_per_m[..n].iter().sum();
            let a: f64 = p.fraction[..n].iter().sum();
            assert!((k / 2e7 - 1.0).abs() < 1e-12, "{n}: {k}");
            assert!((a - 1.0).abs() < 1e-12, "{n}: {a}");
            let x0 = 65.0 / 2e7;
            // The last breaks away at x0 (1 + ln N), the mean of Exp(1)'s top bin.
            let last = p.breakaway_m(n - 1);
            assert!((last / (x0 * (1.0 + (n as f64).ln())) - 1.0).abs() < 1e-12);
            assert!((p.virgin_force(2.0 * last) - 65.0).abs() < 1e-9);
        }
    }

    /// Against the piecewise-linear virgin curve `Σ min(k_i x, α_i Fs)`, Masing's rule for the
    /// reversal, `F_r − 2 F_virgin((x_r − x)/2)`, down to the mirror of the reversal point, and
    /// from there the virgin curve of the other side, `−F_virgin(−x)` (the loop wiped out;
    /// Fc = Fs: a constant slip force, where all of it holds exactly).
    #[test]
    fn virgin_curve_masing_reversal_and_wiping_out() {
        let p = GmsParams::matching(&contact(60.0, 60.0), 5, None).unwrap();
        let mut g = Gms::new(p);
        let (speed, h) = (1e-6, 1e-4);
        let xr = 1.5 * 60.0 / 2e7;
        let up = travel(&mut g, xr, speed, h);
        for (x, f) in &up {
            let expected = p.virgin_force(*x);
            assert!((f - expected).abs() < 1e-9 * 60.0, "{x}: {f} {expected}");
        }
        let fr = up.last().unwrap().1;
        assert!(fr < 59.0, "the reversal is in pre-sliding: {fr}");
        let down = travel(&mut g, -(xr + 2.0 * p.breakaway_m(4)), speed, h);
        for (dx, f) in &down {
            let back = -dx;
            let expected = if back <= 2.0 * xr {
                fr - 2.0 * p.virgin_force(back / 2.0)
            } else {
                -p.virgin_force(back - xr)
            };
            assert!((f - expected).abs() < 1e-9 * 60.0, "{back}: {f} {expected}");
        }
        assert!((down.last().unwrap().1 + 60.0).abs() < 1e-9);
    }

    /// Against the Stribeck curve: in steady sliding every element slips at α_i s(v), so the
    /// force is `s(v) + σ2 v` at every speed.
    #[test]
    fn steady_sliding_follows_the_stribeck_curve() {
        let lugre = LuGreParams {
            sigma2_n_s_per_m: 200.0,
            sigma1_n_s_per_m: 3e4,
            ..contact(50.0, 65.0)
        };
        for v in [-0.03f64, -2e-3, -5e-4, 2e-4, 1e-3, 1.7e-3, 0.05] {
            let mut g = Gms::new(GmsParams::matching(&lugre, 4, None).unwrap());
            let h = 1e-4;
            let mut f = 0.0;
            // Long enough to break every element loose and relax: 0.5 s or 1 mm.
            let steps = ((1e-3 / (v.abs() * h)) as usize).max(5000);
            for _ in 0..steps {
                f = g.advance(v, h);
            }
            let expected = lugre.steady_state_force(v);
            assert!(
                (f - expected).abs() < 1e-6 * expected.abs(),
                "{v}: {f} {expected}"
            );
        }
    }
}
