//! The ball bar: a telescoping linear transducer between a ball on the table (the pivot) and a
//! ball in the spindle (the tool point), ISO 230-4 circular tests.
//!
//! ```text
//! L_true = |P_tool - (C + e + v (t - t₀))|        bar length, m (C nominal centre, e set-up
//!                                                  eccentricity of the pivot, m; v the creep of
//!                                                  the pivot's mount, m/s, from the bar's first
//!                                                  reading t₀: a magnetic base warming up)
//! r      = L_true - R - α_bar R (T_bar - 20 °C)    transducer reading: the bar body grows with its
//!                                                  temperature and the reading drops by as much
//! d      = q·round((r + n) / q),  n ~ N(0, σ²)     noise σ, resolution q (0.1 µm)
//! ```
//!
//! sampled at the instrument's rate (1 kHz by default) on the run's clock. The angle is the
//! bar's direction in the test plane from the plane's first axis (X for XY, Z for ZX, Y for YZ).

use crate::nc::program::Plane;
use nalgebra::Vector3;
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};

/// Ball-bar instrument settings, SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BallbarSpec {
    /// Transducer resolution, m (0.1 µm).
    pub resolution_m: f64,
    /// Standard deviation of the reading noise, m.
    pub noise_m: f64,
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Set-up eccentricity of the pivot from the nominal centre, m.
    pub setup_eccentricity_m: Vector3<f64>,
    /// Drift of the pivot after set-up, m/s.
    pub setup_drift_m_per_s: Vector3<f64>,
    /// Temperature of the bar, °C.
    pub bar_temperature_c: f64,
    /// Expansion coefficient of the bar body, 1/K.
    pub bar_alpha_per_k: f64,
    /// Measuring range of the transducer about the nominal length, ± m (±1 mm for the
    /// Renishaw QC20-W and the Heidenhain DBB): a reading beyond it stops the capture.
    pub range_m: f64,
}

impl Default for BallbarSpec {
    fn default() -> Self {
        Self {
            resolution_m: 0.1e-6,
            noise_m: 0.0,
            sample_rate_hz: 1000.0,
            setup_eccentricity_m: Vector3::zeros(),
            setup_drift_m_per_s: Vector3::zeros(),
            bar_temperature_c: 20.0,
            bar_alpha_per_k: 11.5e-6,
            range_m: 1e-3,
        }
    }
}

/// A ball bar set up for one test: nominal centre, length and plane.
#[derive(Debug)]
pub struct Ballbar {
    spec: BallbarSpec,
    center: Vector3<f64>,
    radius_m: f64,
    plane: Plane,
    rng: StdRng,
    /// Time of the first reading, s.
    set_up_s: Option<f64>,
}

impl Ballbar {
    /// A bar of nominal length `radius_m` about `center` (m) in `plane`; `seed` drives the noise.
    pub fn new(
        spec: BallbarSpec,
        center: Vector3<f64>,
        radius_m: f64,
        plane: Plane,
        seed: u64,
    ) -> Self {
        Self {
            spec,
            center,
            radius_m,
            plane,
            rng: StdRng::seed_from_u64(seed),
            set_up_s: None,
        }
    }

    /// The settings.
    pub fn spec(&self) -> &BallbarSpec {
        &self.spec
    }

    /// Where the pivot is at `time_s` (s), m.
    pub fn pivot(&self, time_s: f64) -> Vector3<f64> {
        let since = time_s - self.set_up_s.unwrap_or(time_s);
        self.center + self.spec.setup_eccentricity_m + self.spec.setup_drift_m_per_s * since
    }

    /// The reading (length minus nominal, m) and the bar's angle (rad, wrapped to (-π, π]) for
    /// a tool point `tool` (m, relative to the workpiece) at `time_s` (s).
    pub fn read(&mut self, tool: &Vector3<f64>, time_s: f64) -> (f64, f64) {
        self.set_up_s.get_or_insert(time_s);
        let bar = tool - self.pivot(time_s);
        let growth =
            self.spec.bar_alpha_per_k * self.radius_m * (self.spec.bar_temperature_c - 20.0);
        let r = bar.norm() - self.radius_m - growth;
        let n: f64 = StandardNormal.sample(&mut self.rng);
        let noisy = r + self.spec.noise_m * n;
        let q = self.spec.resolution_m;
        let reading = if q > 0.0 {
            (noisy / q).round() * q
        } else {
            noisy
        };
        (reading, plane_angle(self.plane, &bar))
    }
}

/// The angle of `v` in `plane` from the plane's first axis, rad.
pub fn plane_angle(plane: Plane, v: &Vector3<f64>) -> f64 {
    match plane {
        Plane::Xy => v.y.atan2(v.x),
        Plane::Zx => v.x.atan2(v.z),
        Plane::Yz => v.z.atan2(v.y),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A noise-free bar without quantisation, 100 mm about the origin in XY.
    fn bar(spec: BallbarSpec) -> Ballbar {
        let exact = BallbarSpec {
            resolution_m: 0.0,
            noise_m: 0.0,
            ..spec
        };
        Ballbar::new(exact, Vector3::zeros(), 0.1, Plane::Xy, 1)
    }

    /// The point of the bar's 100 mm circle at `deg` in XY, m.
    fn on(deg: f64) -> Vector3<f64> {
        Vector3::new(deg.to_radians().cos(), deg.to_radians().sin(), 0.0) * 0.1
    }

    /// A bar 1.5 K warm reads short by α·R·ΔT = 11.5e-6 · 100 mm · 1.5 K = 1.725 µm at every
    /// angle; a cold one long by as much.
    #[test]
    fn a_warm_bar_reads_short_by_its_expansion() {
        for deg in [0.0f64, 37.0, 90.0, 211.0] {
            let tool = on(deg);
            let at = |c: f64| {
                bar(BallbarSpec {
                    bar_temperature_c: c,
                    ..Default::default()
                })
                .read(&tool, 0.0)
                .0
            };
            assert!(at(20.0).abs() < 1e-15);
            assert!((at(21.5) + 1.725e-6).abs() < 1e-12, "{}", at(21.5));
            assert!((at(18.5) - 1.725e-6).abs() < 1e-12, "{}", at(18.5));
        }
    }

    /// A pivot set 5 µm off along +X reads -5 µm at 0° and +5 µm at 180° (first order: the
    /// projection of the offset on the bar), none at 90°; a pivot creeping 2 µm/s along +Y
    /// reads -2 µm at 90° one second after the first reading.
    #[test]
    fn eccentricity_and_drift_of_the_pivot_project_on_the_bar() {
        let mut b = bar(BallbarSpec {
            setup_eccentricity_m: Vector3::new(5e-6, 0.0, 0.0),
            ..Default::default()
        });
        let (r0, a0) = b.read(&on(0.0), 0.0);
        assert!((r0 + 5e-6).abs() < 1e-12 && a0.abs() < 1e-9, "{r0} {a0}");
        assert!((b.read(&on(180.0), 0.0).0 - 5e-6).abs() < 1e-12);
        assert!(b.read(&on(90.0), 0.0).0.abs() < 1e-9);
        let mut d = bar(BallbarSpec {
            setup_drift_m_per_s: Vector3::new(0.0, 2e-6, 0.0),
            ..Default::default()
        });
        assert!(d.read(&on(0.0), 10.0).0.abs() < 1e-15);
        let (r, a) = d.read(&on(90.0), 11.0);
        assert!((r + 2e-6).abs() < 1e-12, "{r}");
        assert!((a - std::f64::consts::FRAC_PI_2).abs() < 1e-6, "{a}");
    }
}
