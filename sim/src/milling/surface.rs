//! The finished wall: surface location error and the profile along the feed, with Ra and Rz.
//!
//! The wall is generated where the teeth leave (down milling, φ = π, the wall on the -Y side)
//! or enter (up milling, φ = 0, the +Y side) the material, so its outward normal (from the
//! tool into the wall) is n_f = (sin φ_f, cos φ_f). Each time a tooth of an axial disk crosses
//! φ_f:
//! - surface location error SLE = u·n_f, m: the tool point's displacement along the normal at
//!   that instant (positive: the wall is cut deeper than nominal, an overcut), averaged over all
//!   crossings of all disks;
//! - the bottom disk stamps its arc on the wall profile: depth(x) = p·n_f + √(R_j² - (x - p_x)²)
//!   about the tool axis p at the crossing, the deepest stamp kept (a circle about the crossing
//!   point: the trochoid's departure from it is of order f_t/R over the arc that shapes the
//!   marks). The profile is sampled every f_t/64 along X.
//!
//! Roughness (ISO 4287/ISO 21920-2 parameters on the unfiltered profile, no λc cut-off): the
//! profile over the evaluation length (the stamped wall without its first and last 3·f_t) minus
//! its least-squares mean line z(x); Ra = mean |z|; Rz = mean over 5 equal sampling lengths of
//! the peak-to-valley height (max z - min z) in each. For a rigid tool Ra = f_t²/(18√3·R) and
//! Rz = f_t²/(8R) (scallops of radius R at pitch f_t).

use serde::Serialize;

/// Samples of the wall profile per feed per tooth.
const SAMPLES_PER_FEED: f64 = 64.0;
/// Half-width of a stamp, feeds per tooth.
const STAMP_HALF_WIDTH: f64 = 3.0;

/// Surface figures of a cut.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SurfaceReport {
    /// Mean surface location error over all crossings of the finishing angle, m (positive:
    /// overcut).
    pub sle_mean_m: f64,
    /// Largest |SLE| of a crossing, m.
    pub sle_max_abs_m: f64,
    /// Arithmetic mean roughness Ra, m.
    pub ra_m: f64,
    /// Mean peak-to-valley height Rz over 5 sampling lengths, m.
    pub rz_m: f64,
    /// Positions of the profile samples along the feed from the start of the cut, m.
    pub profile_x_m: Vec<f64>,
    /// Depth of the wall along its outward normal (from the tool's nominal radius), m.
    pub profile_depth_m: Vec<f64>,
}

impl SurfaceReport {
    /// (Ra, Rz), m, of the stretch of the profile from `from_m` to `to_m` along the feed (m from
    /// the start of the cut), about that stretch's own least-squares line: the roughness of a
    /// part of the wall, e.g. the part cut after a controller changed the spindle speed (the
    /// whole wall's figures also see the step in surface location error between the parts).
    /// Zero when the stretch holds fewer than five samples.
    pub fn roughness_between(&self, from_m: f64, to_m: f64) -> (f64, f64) {
        let (xs, zs): (Vec<f64>, Vec<f64>) = self
            .profile_x_m
            .iter()
            .zip(&self.profile_depth_m)
            .filter(|(x, _)| (from_m..=to_m).contains(*x))
            .map(|(x, z)| (*x, *z))
            .unzip();
        roughness(&xs, &zs)
    }
}

/// The wall being machined.
pub(crate) struct Wall {
    /// Outward normal's Y component (±1); the finishing angle is 0 (+1) or π (-1).
    normal_y: f64,
    x0: f64,
    dx: f64,
    half_width: f64,
    nominal_radius: f64,
    depth: Vec<f64>,
    sle_sum: f64,
    sle_count: usize,
    sle_max: f64,
}

impl Wall {
    pub(crate) fn new(down: bool, x0: f64, feed_per_tooth: f64, nominal_radius: f64) -> Self {
        Self {
            normal_y: if down { -1.0 } else { 1.0 },
            x0,
            dx: feed_per_tooth / SAMPLES_PER_FEED,
            half_width: STAMP_HALF_WIDTH * feed_per_tooth,
            nominal_radius,
            depth: Vec::new(),
            sle_sum: 0.0,
            sle_count: 0,
            sle_max: 0.0,
        }
    }

    /// The finishing angle in bin units of `bins` per revolution.
    pub(crate) fn finishing_angle_bins(&self, bins: f64) -> f64 {
        if self.normal_y < 0.0 { bins / 2.0 } else { 0.0 }
    }

    /// A tooth crossed the finishing angle with the tool displaced by `u`.
    pub(crate) fn record_sle(&mut self, u: [f64; 2]) {
        let sle = u[1] * self.normal_y;
        self.sle_sum += sle;
        self.sle_count += 1;
        self.sle_max = self.sle_max.max(sle.abs());
    }

    /// Stamps the arc of a tooth of radius `radius` about the tool axis `p` on the profile.
    pub(crate) fn stamp(&mut self, p: [f64; 2], radius: f64) {
        let centre = (p[0] - self.x0) / self.dx;
        let half = (self.half_width.min(0.99 * radius) / self.dx).floor();
        let lo = (centre - half).ceil().max(0.0) as usize;
        let hi = (centre + half).floor();
        if hi < 0.0 {
            return;
        }
        let hi = hi as usize;
        if self.depth.len() <= hi {
            self.depth.resize(hi + 1, f64::NEG_INFINITY);
        }
        let base = p[1] * self.normal_y - self.nominal_radius;
        for i in lo..=hi {
            let x = (i as f64 - centre) * self.dx;
            let d = base + (radius * radius - x * x).sqrt();
            if d > self.depth[i] {
                self.depth[i] = d;
            }
        }
    }

    pub(crate) fn report(&self) -> SurfaceReport {
        let skip = (self.half_width / self.dx).ceil() as usize;
        let (xs, zs): (Vec<f64>, Vec<f64>) = self
            .depth
            .iter()
            .enumerate()
            .filter(|(_, d)| d.is_finite())
            .map(|(i, &d)| (i as f64 * self.dx, d))
            .unzip();
        let eval = if zs.len() > 2 * skip + 10 {
            skip..zs.len() - skip
        } else {
            0..zs.len()
        };
        let (ra_m, rz_m) = roughness(&xs[eval.clone()], &zs[eval]);
        let n = self.sle_count.max(1) as f64;
        SurfaceReport {
            sle_mean_m: self.sle_sum / n,
            sle_max_abs_m: self.sle_max,
            ra_m,
            rz_m,
            profile_x_m: xs,
            profile_depth_m: zs,
        }
    }
}

/// (Ra, Rz) of a profile z(x) about its least-squares line; Rz over 5 sampling lengths.
pub(crate) fn roughness(x: &[f64], z: &[f64]) -> (f64, f64) {
    let n = z.len();
    if n < 5 {
        return (0.0, 0.0);
    }
    let nf = n as f64;
    let (mx, mz) = (x.iter().sum::<f64>() / nf, z.iter().sum::<f64>() / nf);
    let sxx: f64 = x.iter().map(|v| (v - mx) * (v - mx)).sum();
    let sxz: f64 = x.iter().zip(z).map(|(a, b)| (a - mx) * (b - mz)).sum();
    let slope = if sxx > 0.0 { sxz / sxx } else { 0.0 };
    let r: Vec<f64> = x
        .iter()
        .zip(z)
        .map(|(a, b)| b - mz - slope * (a - mx))
        .collect();
    let ra = r.iter().map(|v| v.abs()).sum::<f64>() / nf;
    let rz = r
        .chunks(n / 5)
        .take(5)
        .map(|c| {
            let (lo, hi) = c
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
                    (l.min(v), h.max(v))
                });
            hi - lo
        })
        .sum::<f64>()
        / 5.0;
    (ra, rz)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A wall cut 5 µm deeper over its first half, then with a sinusoidal profile of amplitude
    /// A: over the second half alone Ra = 2A/π about its mean line, whatever the step.
    #[test]
    fn roughness_of_a_stretch_ignores_the_rest_of_the_wall() {
        let a = 1e-6;
        let x: Vec<f64> = (0..2000).map(|i| i as f64 * 1e-6).collect();
        let z: Vec<f64> = x
            .iter()
            .map(|&x| {
                if x < 1e-3 {
                    5e-6
                } else {
                    a * (std::f64::consts::TAU * x / 1e-4).sin()
                }
            })
            .collect();
        let (ra_all, _) = roughness(&x, &z);
        let report = SurfaceReport {
            sle_mean_m: 0.0,
            sle_max_abs_m: 0.0,
            ra_m: ra_all,
            rz_m: 0.0,
            profile_x_m: x,
            profile_depth_m: z,
        };
        let (ra, rz) = report.roughness_between(1e-3, 2e-3);
        assert!(
            (ra - 2.0 * a / std::f64::consts::PI).abs() < 0.02 * a,
            "{ra}"
        );
        assert!((rz - 2.0 * a).abs() < 0.02 * a, "{rz}");
        assert!(
            ra_all > 1.5 * ra,
            "the step dominates the whole wall: {ra_all}"
        );
        assert_eq!(report.roughness_between(3e-3, 4e-3), (0.0, 0.0));
    }
}
