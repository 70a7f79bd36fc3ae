//! Ground truth of a run: every injected parameter, and the derived figures a diagnosis reports,
//! in the same definitions and units.

use crate::simulate::{AxisDynamics, Job};
use serde_json::{Value, json};
use vmt_model::Axis;
use vmt_model::drive::Feedback;
use vmt_model::geometric::SquarenessError;
use vmt_model::machine::Machine;

/// The truth of a run of `job` on `machine` with drives `axes`, as JSON.
///
/// Derived figures (first order, ball-bar definitions):
/// - `backlash_seen_um`: in semi-closed loop a reversal shifts the carriage by the gap plus the
///   screw's elastic change under the guideway friction at the test feed, `b + 2 F(v)/k`;
///   zero with a linear scale (the loop closes on the carriage).
/// - `servo_mismatch_ms`: `1/Kv_a - 1/Kv_b` for the test plane's axes (a, b) in ms; a ball bar
///   sees `±(F Δτ / 2) sin 2θ` from it.
/// - `squareness_um_per_m`: the ISO squareness of the plane, µm/m.
pub fn ground_truth(machine: &Machine, axes: &[AxisDynamics; 3], job: &Job) -> Value {
    let feed = job.ballbar.as_ref().map_or(0.0, |b| b.feed_m_s);
    let mut drives = serde_json::Map::new();
    for a in Axis::ALL {
        let d = &axes[a.index()];
        let p = &d.drive;
        let friction = p.guide_friction.steady_state_force(feed.max(1e-9));
        let seen = match p.feedback {
            Feedback::MotorEncoder => {
                p.screw.backlash_m + 2.0 * friction / p.screw.stiffness_n_per_m
            }
            Feedback::LinearScale { .. } => 0.0,
        };
        drives.insert(
            a.to_string().to_lowercase(),
            json!({
                "backlash_um": p.screw.backlash_m * 1e6,
                "backlash_seen_um": seen * 1e6,
                "screw_stiffness_n_per_um": p.screw.stiffness_n_per_m * 1e-6,
                "guide_coulomb_n": p.guide_friction.coulomb_n,
                "guide_static_n": p.guide_friction.static_n,
                "guide_stribeck_mm_s": p.guide_friction.stribeck_m_s * 1e3,
                "kv_per_s": d.servo.kv_per_s,
                "velocity_ff": d.servo.velocity_ff,
                "moving_mass_kg": machine.axis(a).moving_mass_kg,
            }),
        );
    }
    let kv = |a: Axis| axes[a.index()].servo.kv_per_s;
    let mut squareness = serde_json::Map::new();
    for s in SquarenessError::ALL {
        let v = machine.volumetric.errors.squareness(s).values;
        squareness.insert(format!("{}_urad", s.iso_name()), json!(v));
    }
    let ballbar = job.ballbar.as_ref().map(|b| {
        json!({
            "radius_mm": b.radius_m * 1e3,
            "feed_mm_min": b.feed_m_s * 60_000.0,
            "setup_eccentricity_um": [b.spec.setup_eccentricity_m.x * 1e6, b.spec.setup_eccentricity_m.y * 1e6, b.spec.setup_eccentricity_m.z * 1e6],
            "bar_temperature_c": b.spec.bar_temperature_c,
            "noise_um": b.spec.noise_m * 1e6,
            "resolution_um": b.spec.resolution_m * 1e6,
        })
    });
    json!({
        "machine": machine.name,
        "drives": drives,
        "servo_mismatch_ms": {
            "xy": (1.0 / kv(Axis::X) - 1.0 / kv(Axis::Y)) * 1e3,
            "zx": (1.0 / kv(Axis::Z) - 1.0 / kv(Axis::X)) * 1e3,
            "yz": (1.0 / kv(Axis::Y) - 1.0 / kv(Axis::Z)) * 1e3,
        },
        "squareness": squareness,
        "ballbar": ballbar,
    })
}
