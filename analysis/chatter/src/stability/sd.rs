//! First-order semi-discretization (SD) of linear time-periodic delay-differential equations
//! and its specialisation to milling. Insperger & Stépán, "Semi-discretization method for
//! delayed systems", IJNME 55, 2002; "Updated semi-discretization method for periodic
//! delay-differential equations with discrete delay", IJNME 61, 2004; "Semi-Discretization for
//! Time-Delay Systems", Springer 2011, ch. 3.
//!
//! The system is `ẏ(t) = A(t)·y(t) + B(t)·w(t - τ)` with `w = C·y` (the d delayed outputs of
//! the n states) and A, B periodic with the delay τ. The period is cut into m steps of
//! h = τ/m. On step i, A and B are replaced by their averages A_i, B_i over the step and the
//! delayed term by the line through w_{i-m} and w_{i-m+1}:
//!
//! ```text
//! ẏ = A_i·y + B_i·[(1 - s/h)·w_{i-m} + (s/h)·w_{i-m+1}],   s = t - t_i ∈ [0, h]
//! y_{i+1} = P_i·y_i + R0_i·w_{i-m} + R1_i·w_{i-m+1}
//! exp([A_i·h  B_i·h  0; 0 0 I; 0 0 0]) = [P_i  Γ1  Γ2; …],   R0_i = Γ1 - Γ2,  R1_i = Γ2
//! ```
//!
//! (exact integrals of the step's ODE). The discrete state z_i = (y_i, w_{i-1}, …, w_{i-m}) of
//! size n + m·d maps by z_{i+1} = G_i·z_i, where G_i is the dense block above on top of a shift
//! of the history; the monodromy matrix Φ = G_{m-1}⋯G_0 is stable iff its spectral radius is
//! below 1. Each step is applied to Φ's rows in O((n + d)·(n + 2d)·(n + m·d)) with a ring
//! buffer for the history, never as a dense (n + m·d)² product.

use nalgebra::{DMatrix, Schur};

use super::{Flexibility, MillingSystem, StabilityError, directional_integral};

/// The step matrices of one interval: y_{i+1} = P·y_i + R0·w_{i-m} + R1·w_{i-m+1}.
#[derive(Clone, Debug, PartialEq)]
pub struct Step {
    pub p: DMatrix<f64>,
    pub r0: DMatrix<f64>,
    pub r1: DMatrix<f64>,
}

impl Step {
    /// Exact step matrices of `ẏ = A·y + B·(linear delayed input)` over h (see the module).
    pub fn new(a: &DMatrix<f64>, b: &DMatrix<f64>, h: f64) -> Self {
        let (n, d) = b.shape();
        let mut big = DMatrix::zeros(n + 2 * d, n + 2 * d);
        big.view_mut((0, 0), (n, n)).copy_from(&(a * h));
        big.view_mut((0, n), (n, d)).copy_from(&(b * h));
        big.view_mut((n, n + d), (d, d)).fill_with_identity();
        let e = big.exp();
        let g1 = e.view((0, n), (n, d)).into_owned();
        let g2 = e.view((0, n + d), (n, d)).into_owned();
        Self {
            p: e.view((0, 0), (n, n)).into_owned(),
            r0: g1 - &g2,
            r1: g2,
        }
    }

    /// A step without delayed input: P = exp(A·h), R0 = R1 = 0.
    pub fn free(a: &DMatrix<f64>, d: usize, h: f64) -> Self {
        let n = a.nrows();
        Self {
            p: (a * h).exp(),
            r0: DMatrix::zeros(n, d),
            r1: DMatrix::zeros(n, d),
        }
    }
}

/// The monodromy matrix Φ = G_{m-1}⋯G_0 over the steps (m = steps.len() ≥ 2) for delayed
/// outputs `c` (d×n). Coordinates: y (n), then the history slots w_{-m}, …, w_{-1} (d each).
pub fn monodromy(c: &DMatrix<f64>, steps: &[Step]) -> Result<DMatrix<f64>, StabilityError> {
    let (d, n) = c.shape();
    let m = steps.len();
    if m < 2 {
        return Err(StabilityError::BadSetting {
            name: "steps per period",
            value: m as f64,
            accepted: "at least 2",
        });
    }
    let size = n + m * d;
    // Row-major rows of Φ: row r of state coordinate r as a function of z_0.
    let mut z = vec![0.0; size * size];
    for r in 0..size {
        z[r * size + r] = 1.0;
    }
    let row = |k: usize| k * size..(k + 1) * size;
    let hist = |slot: usize, e: usize| n + (slot % m) * d + e;
    let mut new_y = vec![0.0; n * size];
    for (i, st) in steps.iter().enumerate() {
        let (old, next) = (hist(i, 0), hist(i + 1, 0));
        new_y.fill(0.0);
        for r in 0..n {
            let out = &mut new_y[r * size..(r + 1) * size];
            let terms = (0..n)
                .map(|k| (st.p[(r, k)], k))
                .chain((0..d).map(|e| (st.r0[(r, e)], old + e)))
                .chain((0..d).map(|e| (st.r1[(r, e)], next + e)));
            for (coef, k) in terms.filter(|(coef, _)| *coef != 0.0) {
                axpy(out, coef, &z[row(k)]);
            }
        }
        // The oldest slot w_{i-m} is read; it now takes w_i = C·y_i.
        for e in 0..d {
            let mut w = vec![0.0; size];
            for k in (0..n).filter(|&k| c[(e, k)] != 0.0) {
                axpy(&mut w, c[(e, k)], &z[row(k)]);
            }
            z[row(old + e)].copy_from_slice(&w);
        }
        z[..n * size].copy_from_slice(&new_y);
    }
    Ok(DMatrix::from_row_slice(size, size, &z))
}

fn axpy(out: &mut [f64], a: f64, x: &[f64]) {
    out.iter_mut().zip(x).for_each(|(o, x)| *o += a * x);
}

/// Spectral radius of `m`: columns that are exactly zero (history never read in the period)
/// only add zero eigenvalues and are deflated; the rest goes through a bounded real Schur
/// decomposition, whose 1×1 and 2×2 diagonal blocks give the eigenvalue moduli.
pub fn spectral_radius(m: &DMatrix<f64>) -> Result<f64, StabilityError> {
    let live: Vec<usize> = (0..m.ncols())
        .filter(|&j| m.column(j).iter().any(|&v| v != 0.0))
        .collect();
    if live.is_empty() {
        return Ok(0.0);
    }
    let k = live.len();
    let reduced = DMatrix::from_fn(k, k, |r, c| m[(live[r], live[c])]);
    let t = Schur::try_new(reduced, f64::EPSILON, 100 * k)
        .ok_or(StabilityError::EigenNotConverged { size: k })?
        .unpack()
        .1;
    let mut rho: f64 = 0.0;
    let mut i = 0;
    while i < k {
        if i + 1 < k && t[(i + 1, i)] != 0.0 {
            let (a, b, c, d) = (t[(i, i)], t[(i, i + 1)], t[(i + 1, i)], t[(i + 1, i + 1)]);
            let (half_tr, det) = (0.5 * (a + d), a * d - b * c);
            let disc = half_tr * half_tr - det;
            rho = rho.max(if disc < 0.0 {
                det.sqrt()
            } else {
                half_tr.abs() + disc.sqrt()
            });
            i += 2;
        } else {
            rho = rho.max(t[(i, i)].abs());
            i += 1;
        }
    }
    Ok(rho)
}

/// A linear delay system `ẏ = A(t)·y + B(t)·C·y(t - τ)` with A, B periodic in τ.
pub trait PeriodicDelaySystem {
    /// The delay τ, equal to the principal period.
    fn delay(&self) -> f64;
    /// C (d×n): the outputs that are delayed.
    fn delayed_outputs(&self) -> DMatrix<f64>;
    /// The averages of A (n×n) and B (n×d) over [t0, t1].
    fn mean_coefficients(&self, t0: f64, t1: f64) -> (DMatrix<f64>, DMatrix<f64>);
}

/// Spectral radius of the first-order SD monodromy matrix of `system` with m steps per delay.
pub fn sd_spectral_radius(
    system: &impl PeriodicDelaySystem,
    m: usize,
) -> Result<f64, StabilityError> {
    let h = system.delay() / m as f64;
    let steps: Vec<Step> = (0..m)
        .map(|i| {
            let (a, b) = system.mean_coefficients(i as f64 * h, (i + 1) as f64 * h);
            Step::new(&a, &b, h)
        })
        .collect();
    spectral_radius(&monodromy(&system.delayed_outputs(), &steps)?)
}

/// Discretisation of the milling SD.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SdSettings {
    /// Steps m per tooth period (the delay). 40 reproduces the converged critical depths of
    /// the 1-DOF benchmark within 1 % (tests/stability.rs).
    pub steps: usize,
}

impl Default for SdSettings {
    fn default() -> Self {
        Self { steps: 40 }
    }
}

/// The milling equation at one spindle speed in the SD's modal form, for any depth:
///
/// ```text
/// q̈_k + 2ζ_k·ω_k·q̇_k + ω_k²·q_k = (1/m_k)·[Uᵀ·F]_k,   x = U·q  (U: d×M, 1 where mode k acts)
/// F = a·D_f(t)·(x(t) - x(t - τ))      D_f: D(t) restricted to the flexible directions
/// y = (q, q̇):  A(t) = A0 + [0 0; a·M⁻¹Uᵀ·D_f·U 0],  B(t) = [0; -a·M⁻¹Uᵀ·D_f],  C = [U 0]
/// ```
///
/// D is averaged over each step exactly with the closed-form integral of the directional
/// coefficients, so the screen function g is resolved within a step. The period starts when
/// tooth 0 enters the cut.
pub struct MillingSd {
    a0: DMatrix<f64>,
    c: DMatrix<f64>,
    /// Per step: M⁻¹Uᵀ·D̄_f (M×d), None while no tooth cuts.
    forcing: Vec<Option<DMatrix<f64>>>,
    free: Step,
    h: f64,
}

impl MillingSd {
    /// Prepares the milling SD of `system` at `speed_rpm` (validated first).
    pub fn new(
        system: &MillingSystem,
        speed_rpm: f64,
        settings: &SdSettings,
    ) -> Result<Self, StabilityError> {
        system.validate()?;
        if !(speed_rpm.is_finite() && speed_rpm > 0.0) {
            return Err(StabilityError::BadSetting {
                name: "spindle speed, rpm",
                value: speed_rpm,
                accepted: "a finite number greater than 0",
            });
        }
        if settings.steps < 2 {
            return Err(StabilityError::BadSetting {
                name: "steps per period",
                value: settings.steps as f64,
                accepted: "at least 2",
            });
        }
        let dirs: &[usize] = match system.flexibility {
            Flexibility::Both => &[0, 1],
            Flexibility::FeedOnly => &[0],
        };
        let modes: Vec<(usize, _)> = dirs
            .iter()
            .flat_map(|&dir| {
                let list = if dir == 0 {
                    &system.dynamics.x
                } else {
                    &system.dynamics.y
                };
                list.iter().map(move |md| (dir, *md))
            })
            .collect();
        let (nm, d) = (modes.len(), dirs.len());
        let mut a0 = DMatrix::zeros(2 * nm, 2 * nm);
        let mut u = DMatrix::zeros(d, nm);
        let mut minv_ut = DMatrix::zeros(nm, d);
        for (k, (dir, md)) in modes.iter().enumerate() {
            let w = md.omega();
            a0[(k, nm + k)] = 1.0;
            a0[(nm + k, k)] = -w * w;
            a0[(nm + k, nm + k)] = -2.0 * md.damping_ratio * w;
            let di = dirs.iter().position(|x| x == dir).unwrap_or(0);
            u[(di, k)] = 1.0;
            minv_ut[(k, di)] = 1.0 / md.mass();
        }
        let mut c = DMatrix::zeros(d, 2 * nm);
        c.view_mut((0, 0), (d, nm)).copy_from(&u);
        let m = settings.steps;
        let h = system.tool.tooth_period(speed_rpm) / m as f64;
        let forcing = step_directional_means(system, m)
            .into_iter()
            .map(|dm| {
                let sub = DMatrix::from_fn(d, d, |r, q| dm[(dirs[r], dirs[q])]);
                (sub.iter().any(|&v| v != 0.0)).then(|| &minv_ut * sub)
            })
            .collect();
        let free = Step::free(&a0, d, h);
        Ok(Self {
            a0,
            c,
            forcing,
            free,
            h,
        })
    }

    /// Spectral radius of the monodromy matrix at axial depth `depth_m` (m); below 1 is stable.
    pub fn spectral_radius(&self, depth_m: f64) -> Result<f64, StabilityError> {
        if !(depth_m.is_finite() && depth_m >= 0.0) {
            return Err(StabilityError::BadSetting {
                name: "axial depth, m",
                value: depth_m,
                accepted: "a finite number, 0 or greater",
            });
        }
        let (n, d) = (self.a0.nrows(), self.c.nrows());
        let nm = n / 2;
        let steps: Vec<Step> = self
            .forcing
            .iter()
            .map(|f| match f {
                None => self.free.clone(),
                Some(f) => {
                    let mut a = self.a0.clone();
                    let mut b = DMatrix::zeros(n, d);
                    let fu = f * self.c.view((0, 0), (d, nm)) * depth_m;
                    a.view_mut((nm, 0), (nm, nm)).add_assign(&fu);
                    b.view_mut((nm, 0), (nm, d)).copy_from(&(f * -depth_m));
                    Step::new(&a, &b, self.h)
                }
            })
            .collect();
        spectral_radius(&monodromy(&self.c, &steps)?)
    }
}

use std::ops::AddAssign;

/// D̄_i = (K_t/2)·(1/Δφ)·Σ_j ∫ g·[a](φ) dφ over step i of the tooth period (Δφ = 2π/(N·m)),
/// starting with tooth 0 at φ_st; 2×2 in (x, y), N/m².
fn step_directional_means(system: &MillingSystem, m: usize) -> Vec<nalgebra::Matrix2<f64>> {
    use std::f64::consts::TAU;
    let (st, ex) = system.engagement_angles();
    let (kr, kt) = (system.radial_ratio(), system.coefficients.tangential);
    let teeth = system.tool.teeth;
    let pitch = TAU / teeth as f64;
    let dphi = pitch / m as f64;
    (0..m)
        .map(|i| {
            let mut sum = nalgebra::Matrix2::zeros();
            for j in 0..teeth {
                let p0 = (st + j as f64 * pitch + i as f64 * dphi).rem_euclid(TAU);
                for shift in [0.0, TAU] {
                    let lo = p0.max(st + shift);
                    let hi = (p0 + dphi).min(ex + shift);
                    if hi > lo {
                        sum += directional_integral(lo, hi, kr);
                    }
                }
            }
            sum * (0.5 * kt / dphi)
        })
        .collect()
}

/// Spectral radii of the SD monodromy over a grid of speeds × depths.
#[derive(Clone, Debug, PartialEq)]
pub struct StabilityMap {
    pub speeds_rpm: Vec<f64>,
    pub depths_m: Vec<f64>,
    /// radius[s·depths + k] at speed s and depth k.
    pub radius: Vec<f64>,
}

impl StabilityMap {
    /// Spectral radius at speed index `s`, depth index `k`.
    pub fn at(&self, s: usize, k: usize) -> f64 {
        self.radius[s * self.depths_m.len() + k]
    }

    /// Per speed, the lowest depth where the radius reaches 1 (linear in the radius between
    /// grid depths); None where the whole column is stable.
    pub fn boundary(&self) -> Vec<Option<f64>> {
        (0..self.speeds_rpm.len())
            .map(|s| {
                let dm = &self.depths_m;
                let k = (0..dm.len()).find(|&k| self.at(s, k) >= 1.0)?;
                if k == 0 {
                    return Some(dm[0]);
                }
                let (r0, r1) = (self.at(s, k - 1), self.at(s, k));
                Some(dm[k - 1] + (dm[k] - dm[k - 1]) * (1.0 - r0) / (r1 - r0))
            })
            .collect()
    }
}

/// The SD stability map of `system` over `speeds_rpm` × `depths_m`.
pub fn stability_map(
    system: &MillingSystem,
    speeds_rpm: &[f64],
    depths_m: &[f64],
    settings: &SdSettings,
) -> Result<StabilityMap, StabilityError> {
    let mut radius = Vec::with_capacity(speeds_rpm.len() * depths_m.len());
    for &n in speeds_rpm {
        let sd = MillingSd::new(system, n, settings)?;
        for &a in depths_m {
            radius.push(sd.spectral_radius(a)?);
        }
    }
    Ok(StabilityMap {
        speeds_rpm: speeds_rpm.to_vec(),
        depths_m: depths_m.to_vec(),
        radius,
    })
}

/// The SD critical depth at `speed_rpm`: the lowest depth below `depth_max` (m) at which the
/// spectral radius reaches 1, found by a scan in `depth_max/64` steps and bisection to a
/// relative 1e-5; None when stable up to `depth_max`.
pub fn critical_depth(
    system: &MillingSystem,
    speed_rpm: f64,
    depth_max: f64,
    settings: &SdSettings,
) -> Result<Option<f64>, StabilityError> {
    let sd = MillingSd::new(system, speed_rpm, settings)?;
    let unstable = |a: f64| sd.spectral_radius(a).map(|r| r >= 1.0);
    let scan = 64;
    let mut lo = 0.0;
    for i in 1..=scan {
        let hi = depth_max * i as f64 / scan as f64;
        if unstable(hi)? {
            let mut hi = hi;
            while hi - lo > 1e-5 * hi {
                let mid = 0.5 * (lo + hi);
                if unstable(mid)? {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            return Ok(Some(0.5 * (lo + hi)));
        }
        lo = hi;
    }
    Ok(None)
}
