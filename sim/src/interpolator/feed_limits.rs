//! The speed and tangential acceleration each segment may be run at.
//!
//! Lines (unit direction `d`): `v ≤ min(F, V_i / |d_i|)`, `a_t ≤ min(a_max, A_i / |d_i|)`.
//!
//! Arcs and helices (in-plane tangent share `q = r_max|φ|/L`, an upper bound on a spiral, axial
//! share `w = |h|/L`, curvature `κ = (r_max φ² + 2|Δr φ|) / L²`): `v ≤ min(F, V_in-plane / q, V_normal / w, √(c·A_plane / κ))`,
//! where `A_plane` is the smaller acceleration limit of the two in-plane axes and
//! `c` = [`CENTRIPETAL_SHARE`] the part of it granted to the centripetal acceleration `v²κ`. The
//! tangential acceleration on the arc takes what is left: the acceleration of an in-plane axis is
//! `a_t·t_i + v²·κ_i` with `t ⟂ κ`, whose size is at most `√((a_t q)² + (v²κ)²)`, so
//! `a_t ≤ min(a_max, √(A_plane² − (v²κ)²) / q, A_normal / w)`.

use super::config::Limits;
use super::path::{Geometry, MoveKind, Segment};

/// Share of the in-plane axis acceleration limit the centripetal acceleration `v²/r` may use on
/// an arc (the rest, at least `√(1 − 0.9²)` = 44 %, is left for tangential acceleration). As
/// Siemens' `CURV_EFFECT_ON_PATH_ACCEL`.
pub const CENTRIPETAL_SHARE: f64 = 0.9;

/// Speed and tangential acceleration limits of a stretch of path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct FeedLimits {
    /// Largest path speed, m/s.
    pub speed: f64,
    /// Largest tangential path acceleration, m/s².
    pub accel: f64,
}

/// `limit / component`, or infinity for a zero component.
fn ratio(limit: f64, component: f64) -> f64 {
    if component > 0.0 {
        limit / component
    } else {
        f64::INFINITY
    }
}

/// The commanded path speed of a segment, m/s.
pub(crate) fn commanded_speed(kind: MoveKind, limits: &Limits) -> f64 {
    match kind {
        MoveKind::Rapid => limits.rapid_m_s,
        MoveKind::Feed(feed) => feed.min(limits.max_feed_m_s),
    }
}

/// The fastest a circle of radius `radius_m` in the plane of axes `plane` can be run, m/s:
/// what `segment_limits` grants a helix without rise (`q = 1`, `κ = 1/r`), the slower plane
/// axis' velocity and `√(c a r)` for its acceleration `a`, with the path feed's own maximum.
pub fn circle_speed_limit(limits: &Limits, plane: [usize; 2], radius_m: f64) -> f64 {
    let [iu, iv] = plane;
    let a_plane = limits.axis_accel_m_s2[iu].min(limits.axis_accel_m_s2[iv]);
    let v_plane = limits.axis_velocity_m_s[iu].min(limits.axis_velocity_m_s[iv]);
    limits
        .max_feed_m_s
        .min(v_plane)
        .min((CENTRIPETAL_SHARE * a_plane * radius_m).sqrt())
}

/// The limits of one segment.
pub(crate) fn segment_limits(segment: &Segment, limits: &Limits) -> FeedLimits {
    let commanded = commanded_speed(segment.kind, limits);
    match &segment.geometry {
        Geometry::Line(line) => {
            let d = line.direction();
            let mut speed = commanded;
            let mut accel = limits.path_accel_m_s2;
            for i in 0..3 {
                speed = speed.min(ratio(limits.axis_velocity_m_s[i], d[i].abs()));
                accel = accel.min(ratio(limits.axis_accel_m_s2[i], d[i].abs()));
            }
            FeedLimits { speed, accel }
        }
        Geometry::Helix(helix) => {
            let [iu, iv, inormal] = helix.axes;
            let length = helix.length();
            let q = helix.max_radius() * helix.sweep.abs() / length;
            let w = helix.rise.abs() / length;
            let kappa = (helix.max_radius() * helix.sweep.powi(2)
                + 2.0 * (helix.radius_change() * helix.sweep).abs())
                / length.powi(2);
            let a_plane = limits.axis_accel_m_s2[iu].min(limits.axis_accel_m_s2[iv]);
            let v_plane = limits.axis_velocity_m_s[iu].min(limits.axis_velocity_m_s[iv]);
            let speed = commanded
                .min(ratio(v_plane, q))
                .min(ratio(limits.axis_velocity_m_s[inormal], w))
                .min(ratio(CENTRIPETAL_SHARE * a_plane, kappa).sqrt());
            let centripetal = speed * speed * kappa;
            let left = (a_plane * a_plane - centripetal * centripetal)
                .max(0.0)
                .sqrt();
            let accel = limits
                .path_accel_m_s2
                .min(ratio(left, q))
                .min(ratio(limits.axis_accel_m_s2[inormal], w));
            FeedLimits { speed, accel }
        }
    }
}
