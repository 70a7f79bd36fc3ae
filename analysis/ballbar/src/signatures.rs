//! The radial signature of each machine error on a circular test, to first order.
//!
//! The tool moves on a circle of radius R about the pivot, `p = R cos θ`, `q = R sin θ` in the
//! plane's axes `(p, q)`, with `dθ/dt = σ ω` (σ = +1 CCW, −1 CW). A small tool displacement
//! `(δp, δq)` changes the bar length by
//!
//! ```text
//! Δr = δp cos θ + δq sin θ                                  (µm)
//! ```
//!
//! Each error is a physical displacement law, and its signature follows from it (Kwon 1998;
//! Knapp 1983; ISO 230-4 Annex; the NOTES of this project):
//!
//! | error | displacement | Δr |
//! |-------|--------------|----|
//! | pivot offset e (set-up eccentricity) | bar = tool − (C + e) | −(e_p cos θ + e_q sin θ) |
//! | radius offset r₀ (bar length, temperature) | — | r₀ |
//! | scale mismatch m = ε_p − ε_q (ppm) | δp = ε_p p, δq = ε_q q | (R/2) m cos 2θ (+ a constant) |
//! | squareness γ (µrad, ISO EC0Y/EB0Z/EA0Z) | q-axis line rotated by γ | k (R/2) γ sin 2θ, k = −1 XY, +1 ZX, −1 YZ |
//! | servo mismatch Δτ = τ_p − τ_q (ms) | δp = −τ_p v_p, δq = −τ_q v_q | σ (F/2) Δτ sin 2θ |
//! | backlash b_p (µm) | δp = −(b_p/2) sign v_p | σ (b_p/2) sign(sin θ) cos θ |
//! | backlash b_q | δq = −(b_q/2) sign v_q | −σ (b_q/2) sign(cos θ) sin θ |
//! | lateral play l_p (play of p across, flips when p reverses) | δq = −(l_p/2) sign v_p | σ (l_p/2) \|sin θ\| |
//! | lateral play l_q | δp = −(l_q/2) sign v_q | −σ (l_q/2) \|cos θ\| |
//! | angular play ε_p (µrad: p's carriage turns about the plane's normal when p reverses) | δq = −(ε_p/2) sign v_p · p | σ (ε_p R/2) \|sin θ\| cos θ |
//! | angular play ε_q | δp = −(ε_q/2) sign v_q · q | −σ (ε_q R/2) \|cos θ\| sin θ |
//! | straightness S_p (bow of p towards +q, µm over 2R) | δq = S_p (1 − (p/R)²) | −S_p cos²θ sin θ (+ first harmonic) |
//! | straightness S_q (bow of q towards +p) | δp = S_q (1 − (q/R)²) | −S_q sin²θ cos θ (+ first harmonic) |
//! | drift over the test (progress s ∈ [−½, ½], 0 in its middle) | pivot moves by d·s, bar grows by g·s | g s − (d_p cos θ + d_q sin θ) s |
//!
//! with `v_p = −σ R ω sin θ`, `v_q = σ R ω cos θ`, F the feed (µm/ms) and the lags τ in ms.
//!
//! **Take-up of backlash.** The step of the table is the law away from a reversal. After the
//! axis reverses, a semi-closed loop drives the motor through the gap while friction holds the
//! carriage where it stopped (a play operator of width b: the carriage moves only when a flank
//! pushes it): δp runs from the old flank `+(b/2) d_new` to the new one `−(b/2) d_new` as the
//! motor's travel `u` from its turning point grows, `δp = d_new (b/2 − min(u, b))`. On the
//! circle `u = R − |p| = R (1 − |cos θ|)` (q: `R (1 − |sin θ|)`), so the flank takes
//! `√(2b/R)` rad after the reversal, 1.05° for 25 µm on a 150 mm bar: not a step nor a spike
//! but a parabola in θ ([`backlash_take_up`]). Where the step is the screw's elastic stretch
//! under friction rather than a gap, the carriage slides on its guides' presliding compliance
//! while the force reverses, and the flank is passed in less travel than the step: the law
//! takes the reach `a` (µm of motor travel from one flank to the other) as its own parameter,
//! `δp = d_new b (1/2 − min(u/a, 1))`, `a = b` for a gap held by friction, `a → 0` for a
//! sudden step. A compensation that overshoots the gap (a reading of negative backlash) is
//! passed over a reach too, as a controller spreads the compensation over a few milliseconds.
//! The servo lag τ of an axis is `(1 − k_vff)/K_v` for a position loop of gain K_v with
//! velocity feed-forward k_vff. The signs follow ISO 230-1: errors are tool-to-workpiece
//! displacements along +p, +q; backlash is "backward minus forward" (Ahn & Cho 2002).

use crate::trace::{Plane, Sense};

/// One sample's place on the circle, in the units of the signatures.
#[derive(Clone, Copy, Debug)]
pub struct Point {
    /// cos θ, θ the angle from the plane's first axis.
    pub cos: f64,
    /// sin θ.
    pub sin: f64,
    /// Sense of travel.
    pub sense: Sense,
    /// Progress over the test, −½ at its start, 0 in its middle, ½ at its end.
    pub progress: f64,
    /// Nominal radius, µm.
    pub radius_um: f64,
    /// Feed, µm/ms.
    pub feed_um_per_ms: f64,
}

impl Point {
    /// The direction cosine of `axis` (0 p, 1 q) here: cos θ for p, sin θ for q. The axis
    /// stands at R times it, and a displacement along it moves Δr by as much times it.
    #[inline]
    pub fn own(&self, axis: usize) -> f64 {
        if axis == 0 { self.cos } else { self.sin }
    }

    /// The other cosine: sin θ for p, cos θ for q. It is 0 where `axis` turns and changes sign
    /// there, with the axis' direction of motion.
    #[inline]
    pub fn turning(&self, axis: usize) -> f64 {
        if axis == 0 { self.sin } else { self.cos }
    }
}

/// Sign of the squareness signature in each plane (see the module table).
pub const fn squareness_sign(plane: Plane) -> f64 {
    match plane {
        Plane::Xy | Plane::Yz => -1.0,
        Plane::Zx => 1.0,
    }
}

/// The sign of `x`, 0 at 0 (by selects, which the compiler keeps in vector registers).
#[inline]
pub(crate) fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Δr per µm of pivot offset along p and along q.
pub fn pivot_offset(pt: &Point) -> [f64; 2] {
    [-pt.cos, -pt.sin]
}

/// Δr per ppm of scale mismatch ε_p − ε_q (the constant half goes with the radius offset).
pub fn scale_mismatch(pt: &Point) -> f64 {
    0.5 * pt.radius_um * 1e-6 * (pt.cos * pt.cos - pt.sin * pt.sin)
}

/// Δr per µrad of the plane's ISO squareness.
pub fn squareness(pt: &Point, plane: Plane) -> f64 {
    squareness_sign(plane) * pt.radius_um * 1e-6 * pt.sin * pt.cos
}

/// Δr per ms of servo mismatch τ_p − τ_q.
pub fn servo_mismatch(pt: &Point) -> f64 {
    pt.sense.sign() * pt.feed_um_per_ms * pt.sin * pt.cos
}

/// Δr per µm of backlash of p and of q.
pub fn backlash(pt: &Point) -> [f64; 2] {
    [
        backlash_on_flank(pt, 0, sign(pt.sin)),
        backlash_on_flank(pt, 1, sign(pt.cos)),
    ]
}

/// Δr per µm of backlash of `axis` (0 p, 1 q) bearing on the flank `flank` (±1: the sign of
/// sin θ for p and of cos θ for q in [`backlash`], which the motion decides everywhere but at
/// the reversal itself).
pub fn backlash_on_flank(pt: &Point, axis: usize, flank: f64) -> f64 {
    let sg = pt.sense.sign();
    if axis == 0 {
        0.5 * sg * flank * pt.cos
    } else {
        -0.5 * sg * flank * pt.sin
    }
}

/// The motor's travel (µm) from the turning point of `axis` (0 p, 1 q) on the circle:
/// `R − |p|` for p, `R − |q|` for q.
pub fn travel_from_turn(pt: &Point, axis: usize) -> f64 {
    pt.radius_um * (1.0 - pt.own(axis).abs())
}

/// How far (µm) the take-up of backlash `b` µm of `axis` (0 p, 1 q) over a reach of `reach`
/// µm of motor travel moves Δr from the step of [`backlash`] at a sample after the axis'
/// reversal (see the module notes): `2 u_b b (t/a − 1)` while the travel `t` from the turn is
/// below the reach `a` (the carriage still on its old flank at `t = 0`), 0 beyond it and for
/// `b = 0`; `u_b` is [`backlash_on_flank`] on the new flank.
pub fn backlash_take_up(pt: &Point, axis: usize, b: f64, reach: f64) -> f64 {
    let unit = backlash_on_flank(pt, axis, sign(pt.turning(axis)));
    take_up_at(unit, travel_from_turn(pt, axis), b, reach)
}

/// [`backlash_take_up`] at a sample whose Δr per µm of backlash on its flank is `unit` and
/// whose motor has travelled `travel` µm from the turn: `2 u_b b (t/a − 1)` for `t < a`, 0
/// beyond the reach and for `b = 0` or `a ≤ 0` (a sudden step).
#[inline]
pub fn take_up_at(unit: f64, travel: f64, b: f64, reach: f64) -> f64 {
    if b == 0.0 || reach <= 0.0 || travel >= reach {
        return 0.0;
    }
    2.0 * unit * b * (travel / reach - 1.0)
}

/// |sin θ| (p) or |cos θ| (q) at or below which a sample lies on the axis' turn itself, with
/// no direction of motion to say which flank of its backlash it bears on: rounding leaves
/// 1e-16 where the angle is a multiple of 90°, a recorded 0.0001° is 2e-6.
pub const ON_TURN: f64 = 1e-9;

/// |sin θ| (p) or |cos θ| (q) of a run's first (or last) sample at or below which the run
/// starts (ends) on the axis' turn, within 0.006° (a start recorded as 0.0001° is 1.7e-6):
/// its approach is not known, so neither is the flank its first samples bear on.
pub const STARTS_ON_TURN: f64 = 1e-4;

/// Δr per µm of lateral play of p and of q.
pub fn lateral_play(pt: &Point) -> [f64; 2] {
    let (s, c) = (pt.sin, pt.cos);
    let sg = pt.sense.sign();
    [0.5 * sg * s.abs(), -0.5 * sg * c.abs()]
}

/// Δr per µrad of angular play of p and of q: the lateral play growing along the axis, `ε`
/// times the distance from the circle's centre (a carriage that turns by `ε` about the
/// plane's normal when it reverses, a table's yaw backlash).
pub fn angular_play(pt: &Point) -> [f64; 2] {
    let (s, c) = (pt.sin, pt.cos);
    let half = 0.5 * pt.sense.sign() * pt.radius_um * 1e-6;
    [half * s.abs() * c, -half * c.abs() * s]
}

/// Δr per µm of straightness (bow over the diameter) of p and of q.
pub fn straightness(pt: &Point) -> [f64; 2] {
    let (s, c) = (pt.sin, pt.cos);
    [-c * c * s, -s * s * c]
}

/// Δr per µm of radial growth over the trace, and per µm of pivot drift along p and q.
pub fn drift(pt: &Point) -> [f64; 3] {
    let (s, c) = (pt.sin, pt.cos);
    [pt.progress, -c * pt.progress, -s * pt.progress]
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn pt(theta: f64, sense: Sense) -> Point {
        Point {
            cos: theta.cos(),
            sin: theta.sin(),
            sense,
            progress: 0.0,
            radius_um: 150e3,
            feed_um_per_ms: 1000.0 / 60.0,
        }
    }

    /// The table's signatures are `δp cos θ + δq sin θ` of their displacement laws: check them
    /// against the laws evaluated by finite differences of the nominal path.
    #[test]
    fn signatures_follow_from_their_displacement_laws() {
        for sense in [Sense::Cw, Sense::Ccw] {
            for k in 0..360 {
                let th = (k as f64 + 0.37) * PI / 180.0;
                let p = pt(th, sense);
                let (r, omega) = (p.radius_um, 1.0);
                let vp = -sense.sign() * r * omega * th.sin();
                let vq = sense.sign() * r * omega * th.cos();
                let radial = |dp: f64, dq: f64| dp * th.cos() + dq * th.sin();
                let b = backlash(&p);
                assert!((b[0] - radial(-0.5 * vp.signum(), 0.0)).abs() < 1e-12);
                assert!((b[1] - radial(0.0, -0.5 * vq.signum())).abs() < 1e-12);
                let l = lateral_play(&p);
                assert!((l[0] - radial(0.0, -0.5 * vp.signum())).abs() < 1e-12);
                assert!((l[1] - radial(-0.5 * vq.signum(), 0.0)).abs() < 1e-12);
                // Lags in ms at feed F (µm/ms): v in µm/ms is F times the unit direction.
                let f = p.feed_um_per_ms;
                let (up, uq) = (vp / r * f, vq / r * f);
                assert!((servo_mismatch(&p) - radial(-up, 0.0)).abs() < 1e-9);
                assert!((servo_mismatch(&p) + radial(0.0, -uq)).abs() < 1e-9);
                let (pp, qq) = (r * th.cos(), r * th.sin());
                assert!((scale_mismatch(&p) - radial(pp * 0.5e-6, -qq * 0.5e-6)).abs() < 1e-9);
                let s = straightness(&p);
                let bow = radial(0.0, 1.0 - (pp / r).powi(2)) - th.sin();
                assert!((s[0] - bow).abs() < 1e-12);
            }
        }
    }

    /// The take-up is the play operator of the module notes: a carriage left at its old flank
    /// until the motor has travelled the reach `a` from its turn, its offset moving `b/a` times
    /// as fast as the motor (`a = b`: a gap held by friction), then on the step of
    /// [`backlash`]. Checked against the operator run on the nominal circle after each reversal
    /// of p and of q, in both senses, for reaches shorter than, equal to and longer than `b`.
    #[test]
    fn the_take_up_is_a_play_operator_on_the_nominal_path() {
        let b = 25.0;
        for reach in [5.0, 25.0, 60.0] {
            for sense in [Sense::Cw, Sense::Ccw] {
                for (axis, turn_deg) in [(0, 0.0), (0, 180.0), (1, 90.0), (1, 270.0)] {
                    check_play(b, reach, sense, axis, turn_deg);
                }
            }
        }
    }

    fn check_play(b: f64, reach: f64, sense: Sense, axis: usize, turn_deg: f64) {
        let sg = sense.sign();
        let axis_at = |deg: f64| {
            let th = f64::to_radians(deg);
            150e3 * if axis == 0 { th.cos() } else { th.sin() }
        };
        // The carriage's offset δ from the motor, on the flank the approach left it.
        let start = turn_deg - sg * 2.0;
        let approach = axis_at(start + sg * 1e-3) - axis_at(start);
        let mut delta = -0.5 * b * approach.signum();
        let mut last = axis_at(start);
        for k in 1..4000 {
            let deg = start + sg * k as f64 * 1e-3;
            let now = axis_at(deg);
            delta = (delta - b / reach * (now - last)).clamp(-0.5 * b, 0.5 * b);
            last = now;
            let p = pt(deg.to_radians(), sense);
            let radial = delta * p.own(axis);
            if (deg - turn_deg).abs() < 1e-6 {
                continue; // on the turn: no direction of motion, no flank
            }
            let after = sg * (deg - turn_deg) > 0.0;
            let take_up = if after {
                backlash_take_up(&p, axis, b, reach)
            } else {
                0.0
            };
            let model = b * backlash(&p)[axis] + take_up;
            assert!(
                (radial - model).abs() < 1e-6,
                "{sense:?} axis {axis}, reach {reach}, at {deg}°: {radial} against {model}"
            );
        }
    }

    /// ISO 230-1 squareness rotates the second axis' line: XY rotates Y about +Z (δx = −γ y),
    /// ZX rotates Z about +Y (δx = +β z, X is q there), YZ rotates Z about +X (δy = −α z).
    #[test]
    fn squareness_signs_match_the_rotations_of_iso_230_1() {
        let th = 0.3_f64;
        let p = pt(th, Sense::Ccw);
        let (r, gamma) = (p.radius_um, 1e-6);
        let (pp, qq) = (r * th.cos(), r * th.sin());
        let xy = -gamma * qq * th.cos();
        let zx = gamma * pp * th.sin();
        let yz = -gamma * qq * th.cos();
        assert!((squareness(&p, Plane::Xy) - xy).abs() < 1e-12);
        assert!((squareness(&p, Plane::Zx) - zx).abs() < 1e-12);
        assert!((squareness(&p, Plane::Yz) - yz).abs() < 1e-12);
    }
}
