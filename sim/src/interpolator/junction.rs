//! The speed at which a corner between two segments may be passed without rounding it.
//!
//! With unit tangents `t₁` (end of the incoming segment) and `t₂` (start of the outgoing one),
//! `Δt = t₂ − t₁`, the direction of the velocity change `û = Δt/|Δt|`, and the largest
//! acceleration along `û` that keeps every axis within its limit, `A_û = min_i A_i / |û_i|`, the
//! junction speed is the smaller of
//!
//! - the **velocity-jump rule** (Siemens 840D, `MAX_AX_ACCEL · IPO cycle` with overload factor
//!   1): passing the corner at speed `v` steps each axis velocity by `v·|Δt_i|`, which may be at
//!   most what the axis gains in one interpolation period: `v ≤ min_i A_i T_ipo / |Δt_i|`
//!   (= `A_û T_ipo / |Δt|`);
//! - the **junction-deviation rule** (corner tolerance `δ`, as Grbl): the speed on the virtual
//!   arc tangent to both segments whose distance from the corner is `δ`, run at the acceleration
//!   `A_û`: `v ≤ √(A_û δ sin(θ/2) / (1 − sin(θ/2)))`, `θ` the angle between `−t₁` and `t₂`
//!   (`θ = π` straight on, `θ = 0` a reversal, which therefore stops).
//!
//! Tangent junctions (`Δt = 0`: a line into a tangent arc, an arc into an arc of the same or
//! another radius) have no corner limit: the speed carries through. The path itself is not
//! rounded: the axis velocities jump by at most `A_i T_ipo` at the corner.

use nalgebra::Vector3;

use super::config::Limits;

/// The largest speed (m/s) at which the corner from tangent `t_in` to `t_out` (unit vectors) may
/// be passed; infinity for a tangent junction.
pub(crate) fn corner_speed(
    t_in: &Vector3<f64>,
    t_out: &Vector3<f64>,
    limits: &Limits,
    ipo_period_s: f64,
) -> f64 {
    let change = t_out - t_in;
    let size = change.norm();
    if size.is_nan() || size <= 0.0 {
        return f64::INFINITY;
    }
    let accel = (0..3)
        .filter(|&i| change[i] != 0.0)
        .map(|i| limits.axis_accel_m_s2[i] * size / change[i].abs())
        .fold(f64::INFINITY, f64::min);
    let jump = accel * ipo_period_s / size;
    let sin_half = ((1.0 + t_in.dot(t_out).clamp(-1.0, 1.0)) / 2.0).sqrt();
    let deviation = if sin_half >= 1.0 {
        f64::INFINITY
    } else {
        (accel * limits.corner_tolerance_m * sin_half / (1.0 - sin_half)).sqrt()
    };
    jump.min(deviation)
}
