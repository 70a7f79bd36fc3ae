//! Ground truth of a run: every injected parameter, and the derived figures a diagnosis reports,
//! in the same definitions and units.

use crate::laser::{Iso230_2, LaserRun, LaserTruth};
use crate::simulate::{AxisDynamics, BallbarSetup, Job};
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
///
/// `drives.<axis>.backlash_seen_um` is taken at the job's test feed ([`Job::test_feed_m_s`]);
/// each circular test of `ballbar.tests` has its own at its feed. A positioning test's
/// `laser` section holds the noise-free deviations (what a perfect laser would read), the error
/// chain's share, and the ISO 230-2 figures of both (see [`Iso230_2`]).
pub fn ground_truth(
    machine: &Machine,
    axes: &[AxisDynamics; 3],
    job: &Job,
    laser: Option<&(LaserRun, LaserTruth)>,
) -> Value {
    let feed = job.test_feed_m_s();
    let mut drives = serde_json::Map::new();
    for a in Axis::ALL {
        let d = &axes[a.index()];
        let p = &d.drive;
        let seen = backlash_seen_m(d, feed);
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
    let ballbar = job.ballbar.first().map(|b| {
        let tests: Vec<Value> = job.ballbar.iter().map(|t| ballbar_test(t, axes)).collect();
        json!({
            "radius_mm": b.radius_m * 1e3,
            "feed_mm_min": b.feed_m_s * 60_000.0,
            "setup_eccentricity_um": [b.spec.setup_eccentricity_m.x * 1e6, b.spec.setup_eccentricity_m.y * 1e6, b.spec.setup_eccentricity_m.z * 1e6],
            "bar_temperature_c": b.spec.bar_temperature_c,
            "noise_um": b.spec.noise_m * 1e6,
            "resolution_um": b.spec.resolution_m * 1e6,
            "tests": tests,
        })
    });
    let laser = match (&job.laser, laser) {
        (Some(setup), Some((run, truth))) => laser_truth(setup, run, truth),
        _ => Value::Null,
    };
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
        "laser": laser,
    })
}

/// The backlash a reversal at `feed` (m/s) shows at the tool, m (see [`ground_truth`]).
fn backlash_seen_m(d: &AxisDynamics, feed: f64) -> f64 {
    let p = &d.drive;
    let friction = p.guide_friction.steady_state_force(feed.max(1e-9));
    match p.feedback {
        Feedback::MotorEncoder => p.screw.backlash_m + 2.0 * friction / p.screw.stiffness_n_per_m,
        Feedback::LinearScale { .. } => 0.0,
    }
}

/// One circular test: where and how it ran (`radius_mm` is the bar length, `center_mm` the
/// centre ball), and the backlash each axis shows at its feed.
fn ballbar_test(b: &BallbarSetup, axes: &[AxisDynamics; 3]) -> Value {
    let plane = match b.plane {
        crate::nc::Plane::Xy => "XY",
        crate::nc::Plane::Zx => "ZX",
        crate::nc::Plane::Yz => "YZ",
    };
    let seen: serde_json::Map<String, Value> = Axis::ALL
        .into_iter()
        .map(|a| {
            let s = backlash_seen_m(&axes[a.index()], b.feed_m_s);
            (a.to_string().to_lowercase(), json!(s * 1e6))
        })
        .collect();
    json!({
        "name": b.name,
        "plane": plane,
        "center_mm": [b.center.x * 1e3, b.center.y * 1e3, b.center.z * 1e3],
        "radius_mm": b.radius_m * 1e3,
        "feed_mm_min": b.feed_m_s * 60_000.0,
        "backlash_seen_um": seen,
    })
}

/// The laser section: instrument settings, the compensation scale error, and per measurement
/// the noise-free deviation (`exact_deviation_um`, the tool point) and the error chain's share
/// (`chain_deviation_um`: geometric and thermal errors at the commanded positions, without the
/// drives), with the ISO 230-2 figures of each.
fn laser_truth(setup: &crate::laser::LaserSetup, run: &LaserRun, truth: &LaserTruth) -> Value {
    let s = &setup.spec;
    let t = &setup.test;
    let ms = &setup.measurements;
    json!({
        "axis": run.axis,
        "feed_mm_min": t.feed_m_s * 60_000.0,
        "dwell_s": t.dwell_s,
        "overrun_mm": t.overrun_m * 1e3,
        "datum_mm": t.datum_m() * 1e3,
        "resolution_nm": s.resolution_m * 1e9,
        "noise_nm": s.noise_m * 1e9,
        "averaging_s": s.averaging_s,
        "scale_error_ppm": s.scale_error() * 1e6,
        "dead_path_mm": s.dead_path_m * 1e3,
        "air_drift_k_per_h": s.air_drift_k_per_s * 3600.0,
        "exact_deviation_um": truth.exact_um,
        "chain_deviation_um": truth.chain_um,
        "iso230_2_exact": Iso230_2::evaluate(&t.targets_m, ms, &truth.exact_um),
        "iso230_2_chain": Iso230_2::evaluate(&t.targets_m, ms, &truth.chain_um),
    })
}
