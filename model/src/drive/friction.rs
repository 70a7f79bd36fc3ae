//! LuGre friction (Canudas de Wit, Olsson, Åström & Lischinsky, IEEE TAC 40(3), 1995).
//!
//! The contact is a brush of elastic bristles with mean deflection `z` (m):
//!
//! ```text
//! dz/dt = v - |v| z / g(v)
//! g(v)  = (Fc + (Fs - Fc) exp(-(|v|/vs)^δ)) / σ0      (Stribeck curve as a deflection, m)
//! F     = σ0 z + σ1 dz/dt + σ2 v                        (friction force opposing motion, N)
//! ```
//!
//! with σ0 the bristle stiffness (N/m), σ1 the bristle damping (N·s/m), σ2 the viscous
//! coefficient (N·s/m), Fc the Coulomb and Fs the static (breakaway) force (N), vs the Stribeck
//! velocity (m/s) and δ its exponent (2 is usual). In steady sliding `z = g(v) sign(v)` and
//! `F = Fc + (Fs - Fc) exp(-(|v|/vs)^δ) + σ2 |v|` (times sign v): the Stribeck curve, whose
//! falling part gives stick-slip against a compliant drive; at a reversal the bristles must deflect
//! through `2 g` before sliding again, which delays the friction reversal (pre-sliding).
//!
//! Integration over a step `h` with the velocity held: the bristle equation is linear in `z`,
//! `dz/dt = v - a z` with `a = |v|/g(v) >= 0` (g the deflection, m), and is integrated exactly:
//! `z(h) = z_ss + (z0 - z_ss) exp(-a h)`, `z_ss = v/a = g(v) sign(v)` (and `z0 + v h` when
//! `a = 0`). This is unconditionally stable, so the stiff bristles (σ0 of 1e7–1e9 N/m) do not
//! limit the step. A contact stepped many times with one `h` keeps the constants of the step
//! ([`LuGreStep`]: `1/vs`, `1/σ0`, `hσ0`, `1/h`, and `a h / |v|` on the Coulomb plateau), so that
//! a step takes one division (none on the plateau) and one or two `exp`.

pub(crate) use super::exp::exp;

/// Parameters of a LuGre contact, SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LuGreParams {
    /// Bristle stiffness σ0, N/m (> 0).
    pub sigma0_n_per_m: f64,
    /// Bristle damping σ1, N·s/m (>= 0).
    pub sigma1_n_s_per_m: f64,
    /// Viscous friction σ2, N·s/m (>= 0).
    pub sigma2_n_s_per_m: f64,
    /// Coulomb friction Fc, N (>= 0).
    pub coulomb_n: f64,
    /// Static (breakaway) friction Fs, N (>= Fc).
    pub static_n: f64,
    /// Stribeck velocity vs, m/s (> 0).
    pub stribeck_m_s: f64,
    /// Stribeck exponent δ (> 0; 2 for the Gaussian shape).
    pub stribeck_exponent: f64,
}

impl LuGreParams {
    /// No friction at all.
    pub const NONE: LuGreParams = LuGreParams {
        sigma0_n_per_m: 1.0,
        sigma1_n_s_per_m: 0.0,
        sigma2_n_s_per_m: 0.0,
        coulomb_n: 0.0,
        static_n: 0.0,
        stribeck_m_s: 1.0,
        stribeck_exponent: 2.0,
    };

    /// `g(v)`: the steady-state bristle deflection at sliding speed `v`, m.
    #[inline]
    pub fn stribeck_deflection(&self, v: f64) -> f64 {
        self.stribeck_force(v) / self.sigma0_n_per_m
    }

    /// The Stribeck force `Fc + (Fs - Fc) exp(-(|v|/vs)^δ)`, N (without the viscous part).
    #[inline]
    pub fn stribeck_force(&self, v: f64) -> f64 {
        Stribeck::new(self).force(v.abs())
    }

    /// Steady sliding friction at constant velocity `v`, N (signed, opposing `v`'s direction).
    pub fn steady_state_force(&self, v: f64) -> f64 {
        if v == 0.0 {
            return 0.0;
        }
        self.stribeck_force(v) * v.signum() + self.sigma2_n_s_per_m * v
    }

    /// A description of the first invalid value, if any.
    pub fn check(&self) -> Result<(), String> {
        let finite = [
            self.sigma0_n_per_m,
            self.sigma1_n_s_per_m,
            self.sigma2_n_s_per_m,
            self.coulomb_n,
            self.static_n,
            self.stribeck_m_s,
            self.stribeck_exponent,
        ]
        .iter()
        .all(|v| v.is_finite());
        if !finite {
            return Err("LuGre parameters must be finite numbers".into());
        }
        if self.sigma0_n_per_m <= 0.0 || self.stribeck_m_s <= 0.0 || self.stribeck_exponent <= 0.0 {
            return Err("σ0, the Stribeck velocity and exponent must be > 0".into());
        }
        if self.sigma1_n_s_per_m < 0.0 || self.sigma2_n_s_per_m < 0.0 || self.coulomb_n < 0.0 {
            return Err("σ1, σ2 and the Coulomb force must be >= 0".into());
        }
        if self.static_n < self.coulomb_n {
            return Err(format!(
                "the static force {} N is below the Coulomb force {} N; it must be >= it",
                self.static_n, self.coulomb_n
            ));
        }
        Ok(())
    }
}

/// The Stribeck curve of a contact with its constants: `1/vs`, `Fs - Fc`, and whether the curve
/// is Gaussian and reaches `Fc` exactly on its plateau.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Stribeck {
    coulomb_n: f64,
    rise_n: f64,
    inv_velocity: f64,
    exponent: f64,
    gaussian: bool,
    exact_plateau: bool,
}

impl Stribeck {
    fn new(p: &LuGreParams) -> Self {
        let rise_n = p.static_n - p.coulomb_n;
        Self {
            coulomb_n: p.coulomb_n,
            rise_n,
            inv_velocity: 1.0 / p.stribeck_m_s,
            exponent: p.stribeck_exponent,
            // δ = 2 is the usual Gaussian shape: avoid the general power there.
            gaussian: p.stribeck_exponent == 2.0,
            // Far above vs the Stribeck term is below half an ulp of Fc, so the sum is Fc
            // exactly: exp(-50) < 2e-22, and rise < 1e5 Fc makes the term < 2e-17 Fc < 2^-54 Fc.
            exact_plateau: rise_n < 1e5 * p.coulomb_n,
        }
    }

    /// The force at sliding speed `speed` (>= 0, m/s), N.
    #[inline]
    fn force(&self, speed: f64) -> f64 {
        let x = speed * self.inv_velocity;
        let r = if self.gaussian {
            x * x
        } else {
            x.powf(self.exponent)
        };
        if r > 50.0 && self.exact_plateau {
            return self.coulomb_n;
        }
        self.coulomb_n + self.rise_n * exp(-r)
    }
}

/// The state of one LuGre contact: the mean bristle deflection.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct LuGre {
    /// Bristle deflection z, m.
    pub z_m: f64,
}

impl LuGre {
    /// Advances the bristles by `h` seconds at sliding velocity `v` (m/s) and returns the
    /// friction force over the step, N (opposing the motion for positive parameters). For many
    /// steps of one `h`, [`LuGreStep::advance`] saves recomputing the constants.
    pub fn step(&mut self, p: &LuGreParams, v: f64, h: f64) -> f64 {
        LuGreStep::new(p, h).advance(self, v)
    }
}

/// A contact's parameters with the constants of a step of `h` seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LuGreStep {
    params: LuGreParams,
    /// Any friction at all (`Fs > 0` or `σ2 > 0`).
    active: bool,
    h: f64,
    inv_h: f64,
    stribeck: Stribeck,
    inv_sigma0: f64,
    h_sigma0: f64,
    /// On the plateau `F = Fc`: `g = Fc/σ0` and `a h = |v| hσ0/Fc` (∞ without Coulomb force).
    coulomb_deflection: f64,
    coulomb_a_h_per_speed: f64,
}

impl LuGreStep {
    /// The constants of `p` for steps of `h` (s).
    pub fn new(p: &LuGreParams, h: f64) -> Self {
        let h_sigma0 = h * p.sigma0_n_per_m;
        Self {
            params: *p,
            active: !(p.static_n == 0.0 && p.sigma2_n_s_per_m == 0.0),
            h,
            inv_h: 1.0 / h,
            stribeck: Stribeck::new(p),
            inv_sigma0: 1.0 / p.sigma0_n_per_m,
            h_sigma0,
            coulomb_deflection: p.coulomb_n / p.sigma0_n_per_m,
            // Without Coulomb force g = 0 on the plateau: a = |v|/g is infinite and the
            // bristles stay at z = 0 (speed · ∞ = ∞; at rest 0 · ∞ is NaN, which `settle`
            // takes as no slip).
            coulomb_a_h_per_speed: if p.coulomb_n > 0.0 {
                h_sigma0 / p.coulomb_n
            } else {
                f64::INFINITY
            },
        }
    }

    /// Advances `contact` by one step at sliding velocity `v` (m/s) and returns the friction
    /// force over the step, N. A step is `LuGreStep::slip`, `exp(-a h)` and
    /// `LuGreStep::settle`: batches of contacts take them stage by stage, so that their
    /// chains (an `exp`, a division, another `exp`) overlap in the pipeline.
    #[inline]
    pub fn advance(&self, contact: &mut LuGre, v: f64) -> f64 {
        let slip = self.slip(v);
        self.settle(contact, v, slip, exp(-slip.1))
    }

    /// `g(v)` (m) and `a h` at velocity `v`; the plateau's are constants. Where the Stribeck
    /// force is 0 (no Coulomb force, far above vs or with no static force either) `a h` is
    /// infinite when sliding and NaN at rest.
    #[inline]
    pub(crate) fn slip(&self, v: f64) -> (f64, f64) {
        let speed = v.abs();
        let force = self.stribeck.force(speed);
        if force == self.params.coulomb_n {
            (self.coulomb_deflection, speed * self.coulomb_a_h_per_speed)
        } else {
            (force * self.inv_sigma0, speed * self.h_sigma0 / force)
        }
    }

    /// The bristles' deflection after the step from `g` and `a h` (`slip`) and `exp(-a h)`
    /// (`decay`), and the friction force, N.
    #[inline]
    pub(crate) fn settle(
        &self,
        contact: &mut LuGre,
        v: f64,
        (g, a_h): (f64, f64),
        decay: f64,
    ) -> f64 {
        if !self.active {
            return 0.0;
        }
        let p = &self.params;
        let z0 = contact.z_m;
        // a h NaN (g = 0 at rest) is false here: the bristles keep their deflection.
        let z1 = if a_h > 1e-12 {
            let zss = g.copysign(v);
            zss + (z0 - zss) * decay
        } else {
            z0 + v * self.h
        };
        // dz/dt averaged over the step, consistent with the exact z update.
        let dz = (z1 - z0) * self.inv_h;
        contact.z_m = z1;
        p.sigma0_n_per_m * z1 + p.sigma1_n_s_per_m * dz + p.sigma2_n_s_per_m * v
    }
}
