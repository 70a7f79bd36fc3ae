//! Ground truth of a run: every injected parameter, and the derived figures a diagnosis reports,
//! in the same definitions and units.

use crate::laser::{DriveSample, LaserRun, LaserTruth};
use crate::nc::program::{ArcDirection, Motion, Plane, Program};
use crate::simulate::{AxisDynamics, BallbarSetup, Job};
use nalgebra::{Matrix2, Vector2, Vector3};
use serde_json::{Value, json};
use std::f64::consts::TAU;
use vmt_model::drive::Feedback;
use vmt_model::geometric::SquarenessError;
use vmt_model::kinematics::{AxisState, VolumetricEvaluator};
use vmt_model::machine::Machine;
use vmt_model::{Axis, Direction};

/// What the truth of a run is computed from: the machine with its drives, the job, and the error
/// chain at the machine's thermal state in the middle of each circular test (a test measures
/// the machine as it is then: the heat of the earlier tests has moved it).
pub struct TruthInputs<'a> {
    /// The machine.
    pub machine: &'a Machine,
    /// Its drives.
    pub axes: &'a [AxisDynamics; 3],
    /// The job.
    pub job: &'a Job,
    /// The error chain in the middle of each circular test of the job, in job order.
    pub at_tests: &'a [VolumetricEvaluator<'a>],
    /// The error chain at the start and end of each circular test's data, in job order (a test
    /// beyond the end of the slice has no `drift` in the truth; `simulate` gives every test
    /// one, a test without data a zero span).
    pub drifts: &'a [TestDrift<'a>],
}

/// The machine as a circular test's data starts and as it ends: what it drifted by over the
/// test (see [`test_drift`]).
pub struct TestDrift<'a> {
    /// From the start of the test's first data arc to the end of its last, s.
    pub span_s: f64,
    /// The error chain at the start.
    pub start: VolumetricEvaluator<'a>,
    /// The error chain at the end.
    pub end: VolumetricEvaluator<'a>,
    /// How much further each carriage stands from its command at the end than at the start
    /// (position less command, axis coordinates), m.
    pub drive_creep_m: Vector3<f64>,
}

/// The truth of a run of `job` on `machine` with drives `axes`, as JSON.
///
/// Derived figures (first order, ball-bar definitions):
/// - `backlash_seen_um`: in semi-closed loop a reversal *while moving* (a ball bar's) shifts the
///   carriage by the gap plus the screw's elastic change under the sliding guideway friction at
///   the test feed, `b + 2 F(v)/k` with `F(v)` the Stribeck curve plus the viscous `σ2 v`, or
///   by `2 F(v)/k` alone when a constant load larger than the friction (gravity on a Z head
///   without counterweight) keeps the nut on one flank; zero with a linear scale (the loop
///   closes on the carriage). A positioning test reads at rest, where no viscous friction acts:
///   its reversal is in the `laser` section (see `laser_truth`), not this figure.
/// - `static_deflection_um`: where that load holds the carriage from where its encoder puts
///   it, averaged over both directions: `F_load/k`, plus half the gap towards the load when the
///   nut stays on one flank.
/// - `servo_mismatch_ms`: `τ_a − τ_b` for the plane's axes (a, b) in ms, with the servo lag
///   `τ = (1 − k_vff)/K_v` at constant velocity; a ball bar sees `±(F Δτ / 2) sin 2θ` from it.
/// - `squareness.<ISO name>_urad` (`EC0Y_urad`, `EB0Z_urad`, `EA0Z_urad`): the injected
///   squareness errors, µrad, as `[reference axis direction][rotated axis direction]` (forward,
///   backward); the µm/m figure a ball bar reports in its plane is each test's
///   `figures.squareness_<plane>`.
/// - `figures.closing_error_<cw|ccw>` of a full-circle trace: the change of the bar's length at
///   the trace's start point from its first reading to its last, from the machine's thermal
///   drift there, the creep of the axis standing along the plane's normal (which an inclined
///   bar reads) and the pivot's creep (measured by the simulator as the trace runs).
///
/// `drives.<axis>.physics` is there only for an axis with optional physics: its motor's
/// cogging and ripple, its encoder's or scale's signal distortions with the error's
/// first-order harmonic amplitudes, its preloaded nut, its friction law, its rails' local
/// defects and its screw along its length (`in_effect` false with a linear scale, whose loop
/// takes the screw's growth out).
/// `drives.<axis>.backlash_seen_um` is taken at the job's test feed ([`Job::test_feed_m_s`]);
/// each circular test of `ballbar.tests` has its own at its feed, and a `figures` object with
/// every figure a ball-bar diagnosis reports, under the diagnosis' keys (see [`test_figures`]),
/// and a `drift` object with what the machine and the pivot drifted by over the test, which a
/// diagnosis of full circles run both ways fits and reports as closing errors, and any other
/// test leaves out and states the bias of (see [`test_drift`]).
/// A positioning test's
/// `laser` section holds the noise-free deviations (what a perfect laser would read), the error
/// chain's share, the drive's share at rest (the reversal a laser reads at standstill), and the
/// ISO 230-2 figures of each (see [`Iso230_2`](vmt_model::iso230_2::Iso230_2) and
/// `laser_truth`).
pub fn ground_truth(
    inputs: &TruthInputs,
    closing_um: &[Option<f64>],
    laser: Option<&(LaserRun, LaserTruth)>,
) -> Value {
    let TruthInputs {
        machine, axes, job, ..
    } = *inputs;
    let feed = job.test_feed_m_s();
    let loads = loads_n(machine);
    let mut drives = serde_json::Map::new();
    for a in Axis::ALL {
        let d = &axes[a.index()];
        let p = &d.drive;
        let seen = backlash_seen_m(d, feed, loads[a.index()]);
        let mut entry = json!({
                "backlash_um": p.screw.backlash_m * 1e6,
                "backlash_seen_um": seen * 1e6,
                "screw_cyclic_um": p.screw.cyclic_m.map(|v| v * 1e6),
                "cyclic_seen_um": cyclic_seen_m(p) * 1e6,
                "screw_lead_mm": p.screw.lead_m * 1e3,
                "screw_stiffness_n_per_um": p.screw.stiffness_n_per_m * 1e-6,
                "guide_coulomb_n": p.guide_friction.coulomb_n,
                "guide_static_n": p.guide_friction.static_n,
                "guide_stribeck_mm_s": p.guide_friction.stribeck_m_s * 1e3,
                "static_deflection_um": static_deflection_m(d, feed, loads[a.index()]) * 1e6,
                "kv_per_s": d.servo.kv_per_s,
                "velocity_ff": d.servo.velocity_ff,
                "moving_mass_kg": machine.axis(a).moving_mass_kg,
        });
        if let Some(extra) = physics(machine, d, a) {
            entry["physics"] = extra;
        }
        drives.insert(a.to_string().to_lowercase(), entry);
    }
    let lag = |a: Axis| lag_s(&axes[a.index()]);
    let mut squareness = serde_json::Map::new();
    for s in SquarenessError::ALL {
        let v = machine.volumetric.errors.squareness(s).values;
        let urad = v.map(|row| row.map(|rad| rad * 1e6));
        squareness.insert(format!("{}_urad", s.iso_name()), json!(urad));
    }
    let ballbar = job.ballbar.first().map(|b| {
        let mut closing = closing_um.iter();
        let tests: Vec<Value> = job
            .ballbar
            .iter()
            .zip(inputs.at_tests)
            .enumerate()
            .map(|(i, (t, chain))| {
                let mut v = ballbar_test(t, axes, &loads);
                if let Some(d) = inputs.drifts.get(i) {
                    v["drift"] = Value::Object(test_drift(inputs, t, d));
                }
                let mut figures = test_figures(inputs, t, chain);
                for (d, _) in &t.data {
                    let dir = match d {
                        ArcDirection::Cw => "cw",
                        ArcDirection::Ccw => "ccw",
                    };
                    if let Some(Some(c)) = closing.next() {
                        figures.insert(format!("closing_error_{dir}"), json!(c));
                    }
                }
                v["figures"] = Value::Object(figures);
                v
            })
            .collect();
        json!({
            "radius_mm": b.radius_m * 1e3,
            "feed_mm_min": b.feed_m_s * 60_000.0,
            "setup_eccentricity_um": [b.spec.setup_eccentricity_m.x * 1e6, b.spec.setup_eccentricity_m.y * 1e6, b.spec.setup_eccentricity_m.z * 1e6],
            "setup_drift_um_per_min": (b.spec.setup_drift_m_per_s * 6e7).as_slice(),
            "bar_temperature_c": b.spec.bar_temperature_c,
            "noise_um": b.spec.noise_m * 1e6,
            "resolution_um": b.spec.resolution_m * 1e6,
            "tests": tests,
        })
    });
    let laser = match (&job.laser, laser) {
        (Some(setup), Some((run, truth))) => {
            let a = setup.test.axis.index();
            laser_truth(setup, run, truth, &axes[a], loads[a])
        }
        _ => Value::Null,
    };
    json!({
        "machine": machine.name,
        "drives": drives,
        "servo_mismatch_ms": {
            "xy": (lag(Axis::X) - lag(Axis::Y)) * 1e3,
            "zx": (lag(Axis::Z) - lag(Axis::X)) * 1e3,
            "yz": (lag(Axis::Y) - lag(Axis::Z)) * 1e3,
        },
        "squareness": squareness,
        "ballbar": ballbar,
        "laser": laser,
    })
}

/// The optional physics of axis `a` (its drive's `effects`, its rails' local defects, its
/// screw along its length), in the scenario's units, or `None` when it has none (the truth of a
/// machine without them is as it was).
fn physics(machine: &Machine, d: &AxisDynamics, a: Axis) -> Option<Value> {
    let e = &d.effects;
    let mut out = serde_json::Map::new();
    if let Some(m) = &e.motor {
        out.insert(
            "motor".into(),
            json!({
                "cogging_n_m": m.cogging_n_m,
                "cogging_periods_per_rev": m.cogging_periods_per_rev,
                "pole_pairs": m.pole_pairs,
                "ripple_percent": m.ripple_fraction * 100.0,
                "ripple_harmonic": m.ripple_harmonic,
            }),
        );
    }
    let signals = |s: &vmt_model::drive::encoder::EncoderSignals| {
        json!({
            "signal_period_um": s.period_m * 1e6,
            "offsets_percent": [s.offset_cos * 100.0, s.offset_sin * 100.0],
            "amplitude_ratio": s.amplitude_ratio,
            "phase_error_deg": s.phase_error_rad.to_degrees(),
            "first_order_error_um": s.first_order_amplitudes_m().map(|v| v * 1e6),
        })
    };
    if let Some(s) = &e.motor_encoder_signals {
        out.insert("encoder_signals".into(), signals(s));
    }
    if let Some(s) = &e.scale_signals {
        out.insert("scale_signals".into(), signals(s));
    }
    if let Some(n) = &e.nut {
        out.insert(
            "nut".into(),
            json!({
                "preload_n": n.preload_n,
                "stiffness_n_per_um": n.stiffness_n_per_m * 1e-6,
                "remaining_preload_n": n.remaining_preload_n,
            }),
        );
    }
    for (key, gms) in [
        ("guide_friction_law", &e.guide_gms),
        ("screw_friction_law", &e.screw_gms),
    ] {
        if let Some(g) = gms {
            out.insert(key.into(), json!({"law": "gms", "elements": g.elements}));
        }
    }
    if let Some(g) = &machine.volumetric.errors.guideways[a.index()] {
        let defects: Vec<Value> = g
            .defects
            .iter()
            .map(|d| {
                let (shape, width) = match d.shape {
                    vmt_model::geometric::DefectShape::Bump { width_m } => {
                        ("bump", Some(width_m * 1e3))
                    }
                    vmt_model::geometric::DefectShape::Step => ("step", None),
                };
                json!({
                    "shape": shape,
                    "direction": d.direction.to_string().to_lowercase(),
                    "at_mm": d.at_m * 1e3,
                    "height_um": d.height_m * 1e6,
                    "width_mm": width,
                    "rail_offset_mm": d.rail_offset_m.map(|v| v * 1e3),
                })
            })
            .collect();
        out.insert(
            "guideway".into(),
            json!({
                "block_spacing_mm": g.block_spacing_m * 1e3,
                "block_length_mm": g.block_length_m * 1e3,
                "defects": defects,
            }),
        );
    }
    let screw = machine
        .thermal
        .as_ref()
        .and_then(|t| t.screws[a.index()].as_ref());
    if let Some(s) = screw {
        out.insert(
            "screw_thermal".into(),
            json!({
                "span_mm": s.span_m.map(|v| v * 1e3),
                "fixed_end": if s.fixed_at_high_end { "high" } else { "low" },
                "nut_w_per_mm_s": s.nut_w_per_m_s * 1e-3,
                "bearing_w_per_mm_s": s.bearing_w_per_m_s * 1e-3,
                "warm_rise_k": s.warm.map(|w| w.rise_k),
                "in_effect": matches!(d.drive.feedback, Feedback::MotorEncoder),
            }),
        );
    }
    (!out.is_empty()).then_some(Value::Object(out))
}

/// The constant force on each axis' carriage along its coordinate, N: gravity on Z's moving mass
/// (as the plant applies it, [`crate::plant::layout`]), none on the horizontal axes.
fn loads_n(machine: &Machine) -> [f64; 3] {
    let moving = machine.axes.map(|a| a.moving_mass_kg);
    // The plant was built from the same layout before the run, so it cannot fail here.
    crate::plant::layout(&machine.volumetric.kinematics.topology, moving)
        .map_or([0.0; 3], |l| l.map(|a| a.gravity_n))
}

/// Whether the constant load `load_n` (N) keeps the nut on one flank of the screw through a
/// reversal at `feed` (m/s): it does when it outweighs the guideway friction, `|F_load| > F(v)`
/// (a vertical axis without counterweight: the head hangs on its screw).
fn gap_stays_closed(d: &AxisDynamics, feed: f64, load_n: f64) -> bool {
    load_n.abs() > d.drive.guide_friction.steady_state_force(feed.max(1e-9))
}

/// The backlash a reversal at `feed` (m/s) shows at the tool, m (see [`ground_truth`]): in semi-closed
/// loop the screw's elastic change under the guideway friction, `2 F(v)/k`, plus the gap `b`
/// unless the constant load `load_n` (N) keeps the nut on one flank; zero with a linear scale.
/// The reversal at rest ([`reversal_at_rest_m`]) with the friction of sliding at `feed`
/// holding the carriage.
fn backlash_seen_m(d: &AxisDynamics, feed: f64, load_n: f64) -> f64 {
    let friction = d.drive.guide_friction.steady_state_force(feed.max(1e-9));
    reversal_at_rest_m(d, friction, load_n)
}

/// The carriage's displacement from where its motor encoder puts it, averaged over both
/// directions of travel, under the constant load `load_n` (N) along its coordinate, m: the
/// screw's stretch `F_load/k`, and half the gap towards the load when the load keeps the nut on
/// one flank (otherwise the gap is crossed symmetrically and averages out). Zero with a linear
/// scale (the loop closes on the carriage).
fn static_deflection_m(d: &AxisDynamics, feed: f64, load_n: f64) -> f64 {
    let p = &d.drive;
    let half_gap = if gap_stays_closed(d, feed, load_n) {
        0.5 * p.screw.backlash_m * load_n.signum()
    } else {
        0.0
    };
    match p.feedback {
        Feedback::MotorEncoder => load_n / p.screw.stiffness_n_per_m + half_gap,
        Feedback::LinearScale { .. } => 0.0,
    }
}

/// The amplitude of the screw's periodic lead error at the carriage, m: all of it under
/// semi-closed loop, none with a linear scale closing the loop on the carriage.
fn cyclic_seen_m(p: &vmt_model::drive::DriveParams) -> f64 {
    match p.feedback {
        Feedback::MotorEncoder => p.screw.cyclic_m[0].hypot(p.screw.cyclic_m[1]),
        Feedback::LinearScale { .. } => 0.0,
    }
}

/// One circular test: where and how it ran (`radius_mm` is the bar length, `center_mm` the
/// centre ball), and the backlash each axis shows at its feed.
fn ballbar_test(b: &BallbarSetup, axes: &[AxisDynamics; 3], loads: &[f64; 3]) -> Value {
    let plane = match b.plane {
        crate::nc::Plane::Xy => "XY",
        crate::nc::Plane::Zx => "ZX",
        crate::nc::Plane::Yz => "YZ",
    };
    let seen: serde_json::Map<String, Value> = Axis::ALL
        .into_iter()
        .map(|a| {
            let s = backlash_seen_m(&axes[a.index()], b.feed_m_s, loads[a.index()]);
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

/// The screw's lost motion at rest, m: where the carriage stands from the nut when the guideway
/// friction `holding_n` (N, against forward motion) holds it still against the screw under the
/// constant load `load_n` (N, along the axis). At rest the screw carries `S = F_h − F_load`
/// (no inertia, no viscous or bristle-damping force without velocity) and the carriage sits
/// `−(S/k + sign(S) b/2)` from the nut: the screw's stretch, and half the gap on the flank `S`
/// pushes on. Zero with a linear scale, whose loop holds the carriage itself.
fn lost_motion_at_rest_m(d: &AxisDynamics, holding_n: f64, load_n: f64) -> f64 {
    let p = &d.drive;
    let screw = holding_n - load_n;
    match p.feedback {
        Feedback::MotorEncoder => {
            -(screw / p.screw.stiffness_n_per_m + 0.5 * p.screw.backlash_m * screw.signum())
        }
        Feedback::LinearScale { .. } => 0.0,
    }
}

/// The reversal a positioning test reads at rest when the guideways hold the carriage with
/// `holding_n` (N, magnitude) after either approach, m: backward minus forward lost motion,
/// `b + 2 F_h/k` in semi-closed loop (`2 F_h/k` when the load keeps the nut on one flank, 0
/// with a linear scale).
fn reversal_at_rest_m(d: &AxisDynamics, holding_n: f64, load_n: f64) -> f64 {
    lost_motion_at_rest_m(d, -holding_n, load_n) - lost_motion_at_rest_m(d, holding_n, load_n)
}

/// The laser section: instrument settings, the compensation scale error, and per measurement
/// the noise-free deviation (`exact_deviation_um`, the tool point), the error chain's share
/// (`chain_deviation_um`: geometric and thermal errors at the commanded positions, without the
/// drives) and the drive's share at rest (`drive_deviation_um`), with the ISO 230-2 figures of
/// each (`iso230_2_exact`, `iso230_2_chain`, `iso230_2_drive`).
///
/// The drive's share of a reading, relative to the datum's (the same share of the datum
/// reading, whose `datum_holding_force_n` and `datum_servo_residual_um` are given), is where the
/// servo left what the drive positions (`servo_residual_um`, position minus command, the
/// opposite sign of the `following_error` channel: the nut, that is the motor through the
/// screw's lead with its cyclic error, or the carriage on a linear scale; within about a count
/// of the encoder) plus the screw's lost motion at rest ([`lost_motion_at_rest_m`]) under the
/// guideway friction that held the carriage while it was read (`holding_force_n`, N, signed,
/// positive after a forward approach; each averaged over the reading's window). The noise-free
/// deviation is then the chain's share plus the drive's, reading by reading. A laser reads after
/// a dwell, with the carriage at rest, so its reversal is
///
/// `B = b + (F_h↑ + F_h↓)/k` (plus the servo residuals' difference, about a count),
///
/// with no viscous share and so independent of the feed, unlike the moving
/// `backlash_seen_um`'s `b + 2 F(v)/k`. `F_h` is the LuGre bristles' `σ0 z` at rest, set by
/// how the carriage came to rest: the position loop's exponential approach (time constant
/// `1/K_v`) slows through the Stribeck range over the last `v_s/K_v` of travel, many times the
/// bristles' deflection `F_s/σ0`, so the bristles stop loaded near `F_s`; the position loop's
/// hunting by an encoder count at standstill then relaxes them (LuGre's drift under small
/// oscillations), the more the longer the dwell, so B depends on the dwell though not on the
/// feed. `reversal_at_rest_bounds_um` is the range of `B` for `F_c ≤ F_h ≤ F_s`,
/// `[b + 2 F_c/k, b + 2 F_s/k]` (`[2 F_c/k, 2 F_s/k]` when the load keeps the nut on one flank,
/// `[0, 0]` with a linear scale; see [`reversal_at_rest_m`]), less about a count: the upper
/// bound is strict (the bristles never hold more than `F_s`), the lower one holds for dwells of
/// a few seconds, not for half a minute of hunting.
fn laser_truth(
    setup: &crate::laser::LaserSetup,
    run: &LaserRun,
    truth: &LaserTruth,
    drive: &AxisDynamics,
    load_n: f64,
) -> Value {
    let s = &setup.spec;
    let t = &setup.test;
    let share =
        |d: DriveSample| d.servo_residual_m + lost_motion_at_rest_m(drive, d.holding_n, load_n);
    let datum = share(truth.datum_drive);
    let drive_um: Vec<f64> = truth
        .holding_force_n
        .iter()
        .zip(&truth.servo_residual_m)
        .map(|(&holding_n, &servo_residual_m)| {
            let d = DriveSample {
                holding_n,
                servo_residual_m,
            };
            (share(d) - datum) * 1e6
        })
        .collect();
    let friction = &drive.drive.guide_friction;
    let bounds_um =
        [friction.coulomb_n, friction.static_n].map(|f| reversal_at_rest_m(drive, f, load_n) * 1e6);
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
        "drive_deviation_um": drive_um,
        "holding_force_n": truth.holding_force_n,
        "servo_residual_um": truth.servo_residual_m.iter().map(|m| m * 1e6).collect::<Vec<_>>(),
        "datum_holding_force_n": truth.datum_drive.holding_n,
        "datum_servo_residual_um": truth.datum_drive.servo_residual_m * 1e6,
        "reversal_at_rest_bounds_um": bounds_um,
        "iso230_2_exact": setup.iso230_2(&truth.exact_um),
        "iso230_2_chain": setup.iso230_2(&truth.chain_um),
        "iso230_2_drive": setup.iso230_2(&drive_um),
    })
}

/// Servo lag of an axis at constant velocity, `(1 - k_vff)/K_v`, s.
fn lag_s(d: &AxisDynamics) -> f64 {
    (1.0 - d.servo.velocity_ff) / d.servo.kv_per_s
}

/// The amplitude ratio of an axis' position to its command at `omega` (rad/s): a P position loop
/// of gain `K_v` with velocity feed-forward `k` over an ideal velocity loop,
/// `ẋ = K_v (x_c − x) + k ẋ_c`, has `X/X_c = (K_v + k s)/(s + K_v)`, so
/// `|X/X_c| = √((K_v² + k²ω²)/(K_v² + ω²)) ≈ 1 − (1 − k²) ω²/(2 K_v²)`.
fn amplitude_gain(d: &AxisDynamics, omega: f64) -> f64 {
    let (kv, k) = (d.servo.kv_per_s, d.servo.velocity_ff);
    ((kv * kv + k * k * omega * omega) / (kv * kv + omega * omega)).sqrt()
}

/// The figures a ball-bar diagnosis of circular test `b` reports, in its keys and units.
///
/// From the error chain `chain` in the middle of the test (the tool-point error field `δ` on the nominal
/// circle, averaged over the approach directions of the two plane axes, the third axis in the
/// direction of its last move before the test): its component along
/// the bar `δ·u(θ)` (u from the pivot to the tool; in the plane unless the link is inclined)
/// is expanded in Fourier series `A_k cos kθ + B_k sin kθ` over the full circle, and
/// the signatures of the diagnosis read off it (see `vmt-ballbar`'s signatures):
/// straightness `S_p = -4 B_3`, `S_q = 4 A_3` (µm over the diameter); scale mismatch
/// `2 A_2 / R` (ppm) plus the dynamic share `|H_p| − |H_q|` of the position loops' amplitude
/// ratios at ω = F/r (`amplitude_gain`, about `-(ω²/2)(τ_p² − τ_q²)` without feed-forward,
/// τ = 1/K_v); squareness `2 B_2 / (k R)` (µm/m, k = -1 XY and YZ, +1 ZX); the pivot
/// offset equivalent `e_p = -A_1 - S_q/4 - d_p`, `e_q = -B_1 - S_p/4 - d_q`, added to the bar's set-up
/// eccentricity, with `d` the drives' static deflection under their constant load (a hanging
/// Z head sits `m g / k` plus half its gap lower than its encoder says). Backlash and lateral
/// play of an axis: the change of `δ` along and across the axis when it reverses (backward minus
/// forward), at the circle's centre of lines fitted over the data arcs as the signatures
/// weigh them (see `reversal_change`),
/// the growth of those changes across and along the axis its angular play (µrad: a table's
/// yaw backlash turns it about the plane's normal); the backlash adds the drive's lost motion
/// along the circle (`drive_share`: the gap and the screw's stretch under the guideway
/// friction, the Stribeck hump at the reversals included).
/// Servo mismatch: `(1 - k_vff,p)/K_v,p - (1 - k_vff,q)/K_v,q` (ms) plus the drives' apparent
/// lag difference (`drive_share`: `σ2/k` of the viscous friction, less the hump's lead).
pub fn test_figures(
    inputs: &TruthInputs,
    b: &BallbarSetup,
    chain: &VolumetricEvaluator,
) -> serde_json::Map<String, Value> {
    let (pa, qa) = b.plane.axes();
    let (ep, eq) = (unit(pa), unit(qa));
    let r_um = b.radius_m * 1e6;
    let (centre, radius) = b.tool_circle();
    let base = base_directions(inputs.job, b);
    let field = |th: f64| mean_error(inputs, chain, b, th, base);
    let n = 720;
    let (mut a, mut bb) = ([0.0; 4], [0.0; 4]);
    for i in 0..n {
        let th = TAU * i as f64 / n as f64;
        // Along the bar, from the pivot to the tool on its circle.
        let tool = centre + (ep * th.cos() + eq * th.sin()) * radius;
        let u = (tool - b.center).normalize();
        let dr = field(th).dot(&u) * 1e6;
        for k in 1..4 {
            a[k] += 2.0 / n as f64 * dr * (k as f64 * th).cos();
            bb[k] += 2.0 / n as f64 * dr * (k as f64 * th).sin();
        }
    }
    let s_p = -4.0 * bb[3];
    let s_q = 4.0 * a[3];
    let sign = if b.plane == Plane::Zx { 1.0 } else { -1.0 };
    // An inclined bar reads in-plane displacements (the pivot's, the lags', the drives') times
    // its in-plane share; the chain's share is already projected on the bar.
    let k = radius / b.radius_m;
    let axes = inputs.axes;
    let loads = loads_n(inputs.machine);
    let deflection_um =
        |a: Axis| static_deflection_m(&axes[a.index()], b.feed_m_s, loads[a.index()]) * 1e6 * k;
    // The pivot where it is in the middle of the test (it creeps from the first reading on).
    let pivot =
        b.spec.setup_eccentricity_m + b.spec.setup_drift_m_per_s * half_span_s(inputs.job, b);
    let e = pivot * 1e6 * k;
    let (lp, lq) = (pa.to_string().to_lowercase(), qa.to_string().to_lowercase());
    let pl = format!("{lp}{lq}");
    let mut m = serde_json::Map::new();
    let mut put = |key: String, v: f64| {
        m.insert(key, json!(v));
    };
    put(
        format!("eccentricity_{lp}"),
        e[pa.index()] - a[1] - s_q / 4.0 - deflection_um(pa),
    );
    put(
        format!("eccentricity_{lq}"),
        e[qa.index()] - bb[1] - s_p / 4.0 - deflection_um(qa),
    );
    put(format!("straightness_{lp}"), s_p);
    put(format!("straightness_{lq}"), s_q);
    // A position loop following a circle at ω = F/r lets each axis' amplitude fall short
    // (`amplitude_gain`): unequal shortfalls read as a scale mismatch on the bar.
    let omega = b.feed_m_s / radius;
    let dynamic = |a: Axis| amplitude_gain(&inputs.axes[a.index()], omega) - 1.0;
    let dynamic_ppm = (dynamic(pa) - dynamic(qa)) * 1e6 * k * k;
    put(
        format!("scale_mismatch_{pl}"),
        2.0 * a[2] / r_um * 1e6 + dynamic_ppm,
    );
    put(
        format!("squareness_{pl}"),
        2.0 * bb[2] / (sign * r_um) * 1e6,
    );
    let arcs = data_arcs(inputs.job, b);
    let share = drive_share(axes, &loads, b, &arcs);
    put(
        format!("servo_mismatch_{pl}"),
        (lag_s(&axes[pa.index()]) - lag_s(&axes[qa.index()]) + share.lag_s) * 1e3 * k,
    );
    for (i, (axis, other)) in [(pa, qa), (qa, pa)].into_iter().enumerate() {
        let change = reversal_change(inputs, chain, b, (axis, other), &arcs, base);
        let drive = share.lost_motion_m[i] * 1e6;
        let l = axis.to_string().to_lowercase();
        put(format!("backlash_{l}"), (drive + change.along_um) * k);
        put(format!("lateral_play_{l}"), change.across_um * k);
        // The bar reads the in-plane position along the axis times k, and the play across it
        // times k again.
        put(format!("angular_play_{l}"), change.angular_urad * k * k);
        put(
            format!("cyclic_{l}"),
            cyclic_seen_m(&axes[axis.index()].drive) * 1e6 * k,
        );
    }
    m
}

/// The drift of circular test `b` over its data, as the drift terms of a ball-bar diagnosis
/// read it (keys `radial_drift` and `pivot_drift_<axis>`, µm over the test; see `vmt-ballbar`'s
/// signatures: `Δr = g s − (d_p cos θ + d_q sin θ) s` with the progress s from −½ to ½).
///
/// The change of the bar's reading over the test at each angle, `δr(θ) = (δ_end(θ) −
/// δ_start(θ) + Δs n − Δc)·u(θ)`, from the tool-point error fields `δ` of the chain at the
/// start and the end of the data (the machine's thermal drift, averaged over the plane axes'
/// approach directions as in [`test_figures`]), the creep `Δs` of the axis that stands
/// through the test along the plane's normal `n` (its carriage's position less its command:
/// a hanging Z head that sinks as its friction relaxes, which an inclined bar reads) and the
/// pivot's creep `Δc` over the span, is expanded over the full circle: `g` is its mean,
/// `d_p = −A_1`, `d_q = −B_1`. A warm-up is not linear in time; these are the changes from
/// the first reading to the last, which is what the fit's linear terms and a closing error
/// measure. The moving axes' own creep is not told from their following error here, and is
/// left out.
pub fn test_drift(
    inputs: &TruthInputs,
    b: &BallbarSetup,
    d: &TestDrift,
) -> serde_json::Map<String, Value> {
    let (pa, qa) = b.plane.axes();
    let (centre, radius) = b.tool_circle();
    let base = base_directions(inputs.job, b);
    let creep = b.spec.setup_drift_m_per_s * d.span_s;
    let n_axis = b.plane.normal();
    let standing = n_axis * n_axis.dot(&d.drive_creep_m);
    let n = 720;
    let (mut g, mut a1, mut b1) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let th = TAU * i as f64 / n as f64;
        let tool = centre + (unit(pa) * th.cos() + unit(qa) * th.sin()) * radius;
        let u = (tool - b.center).normalize();
        let change = mean_error(inputs, &d.end, b, th, base)
            - mean_error(inputs, &d.start, b, th, base)
            + standing
            - creep;
        let dr = change.dot(&u) * 1e6;
        g += dr / n as f64;
        a1 += 2.0 / n as f64 * dr * th.cos();
        b1 += 2.0 / n as f64 * dr * th.sin();
    }
    let mut m = serde_json::Map::new();
    m.insert("radial_drift".into(), json!(g));
    for (axis, v) in [(pa, -a1), (qa, -b1)] {
        m.insert(
            format!("pivot_drift_{}", axis.to_string().to_lowercase()),
            json!(v),
        );
    }
    m
}

/// The direction state of each axis through test `b`: forward for the plane axes (the field
/// is averaged over theirs), the third axis as its last move before the test left it.
fn base_directions(job: &Job, b: &BallbarSetup) -> [Direction; 3] {
    let (pa, qa) = b.plane.axes();
    let mut base = [Direction::Forward; 3];
    if let Some(t) = Axis::ALL.into_iter().find(|a| *a != pa && *a != qa) {
        base[t.index()] = out_of_plane_direction(job, b, t);
    }
    base
}

fn unit(a: Axis) -> Vector3<f64> {
    Vector3::from_fn(|i, _| if i == a.index() { 1.0 } else { 0.0 })
}

/// Where each block of `program` ends, m (a dwell ends where it starts).
fn block_ends(program: &Program) -> Vec<Vector3<f64>> {
    let mut at = program.start;
    program
        .blocks
        .iter()
        .map(|block| {
            if let Motion::Rapid { to } | Motion::Linear { to, .. } | Motion::Arc { to, .. } =
                block.motion
            {
                at = to;
            }
            at
        })
        .collect()
}

/// The direction state of `axis` during test `b`: that of its last commanded move before the
/// test's first data arc (the axis stands still through a test in the other two, and its
/// direction-dependent errors, e.g. a squareness that differs by direction, stay as that move
/// left them); forward if it has not moved, as the machine starts.
fn out_of_plane_direction(job: &Job, b: &BallbarSetup, axis: Axis) -> Direction {
    let first = b.data.first().map_or(0, |(_, r)| r.start);
    let ends = block_ends(&job.program);
    let i = axis.index();
    let points: Vec<Vector3<f64>> = std::iter::once(job.program.start)
        .chain(ends.into_iter().take(first))
        .collect();
    points
        .windows(2)
        .rev()
        .map(|w| w[1][i] - w[0][i])
        .find(|d| d.abs() > 1e-9)
        .map_or(Direction::Forward, |d| {
            if d > 0.0 {
                Direction::Forward
            } else {
                Direction::Backward
            }
        })
}

/// Half the time from the start of test `b`'s first data arc to the end of its last, s: the
/// blocks in between at their programmed feeds (the acceleration at their joins, a few tens of
/// ms in all, is not counted; nor are rapids, which a circular test does not hold between its
/// data arcs).
fn half_span_s(job: &Job, b: &BallbarSetup) -> f64 {
    let (Some((_, first)), Some((_, last))) = (b.data.first(), b.data.last()) else {
        return 0.0;
    };
    let ends = block_ends(&job.program);
    let from = |k: usize| {
        if k == 0 {
            job.program.start
        } else {
            ends[k - 1]
        }
    };
    let seconds: f64 = (first.start..last.end)
        .map(|k| match &job.program.blocks[k].motion {
            Motion::Linear { to, feed } => (to - from(k)).norm() / feed,
            Motion::Arc { feed, .. } => {
                arc_sweep(job, &ends, b, k).abs() * b.tool_circle().1 / feed
            }
            Motion::Dwell { seconds } => *seconds,
            Motion::Rapid { .. } => 0.0,
        })
        .sum();
    0.5 * seconds
}

/// The signed sweep of arc block `k` of the job's program (its blocks ending at `ends`) about
/// test `b`'s circle, rad (CCW positive; an arc ending where it starts is a full turn); 0 for
/// any other block.
fn arc_sweep(job: &Job, ends: &[Vector3<f64>], b: &BallbarSetup, k: usize) -> f64 {
    let Motion::Arc { to, direction, .. } = job.program.blocks[k].motion else {
        return 0.0;
    };
    let from = if k == 0 {
        job.program.start
    } else {
        ends[k - 1]
    };
    let (a, z) = (circle_angle(b, from), circle_angle(b, to));
    let full_if_none = |turn: f64| if turn < 1e-9 { TAU } else { turn };
    match direction {
        ArcDirection::Ccw => full_if_none((z - a).rem_euclid(TAU)),
        ArcDirection::Cw => -full_if_none((a - z).rem_euclid(TAU)),
    }
}

/// The angle of point `p` (m) on test `b`'s circle, rad, from the plane's first axis towards
/// its second.
fn circle_angle(b: &BallbarSetup, p: Vector3<f64>) -> f64 {
    let (pa, qa) = b.plane.axes();
    let v = p - b.tool_circle().0;
    v[qa.index()].atan2(v[pa.index()])
}

/// Each data arc of `b` as (start angle, signed sweep), rad, in the angle convention of the
/// plane (from its first axis towards its second; CCW positive).
fn data_arcs(job: &Job, b: &BallbarSetup) -> Vec<(f64, f64)> {
    let ends = block_ends(&job.program);
    b.data
        .iter()
        .map(|(_, range)| {
            let start = if range.start == 0 {
                job.program.start
            } else {
                ends[range.start - 1]
            };
            let sweep = range.clone().map(|k| arc_sweep(job, &ends, b, k)).sum();
            (circle_angle(b, start), sweep)
        })
        .collect()
}

fn state(
    inputs: &TruthInputs,
    tool: Vector3<f64>,
    base: [Direction; 3],
    dirs: [(Axis, Direction); 2],
) -> AxisState {
    let mut direction = base;
    for (a, d) in dirs {
        direction[a.index()] = d;
    }
    AxisState {
        position: tool - inputs.machine.volumetric.kinematics.tool_offset,
        direction,
    }
}

/// The tool-point error (m) at angle `th` of the circle, averaged over the four approach
/// directions of the plane's axes, the third axis in its direction of `base`.
fn mean_error(
    inputs: &TruthInputs,
    chain: &VolumetricEvaluator,
    b: &BallbarSetup,
    th: f64,
    base: [Direction; 3],
) -> Vector3<f64> {
    let (pa, qa) = b.plane.axes();
    let (centre, radius) = b.tool_circle();
    let tool = centre + (unit(pa) * th.cos() + unit(qa) * th.sin()) * radius;
    let dirs = [Direction::Forward, Direction::Backward];
    let mut sum = Vector3::zeros();
    for dp in dirs {
        for dq in dirs {
            sum += chain.volumetric_error(&state(inputs, tool, base, [(pa, dp), (qa, dq)]));
        }
    }
    sum / 4.0
}

/// What the feed drives add to a circular test's backlash and servo-mismatch figures: the lost
/// motion of each plane axis (`[p, q]`, m) and the apparent lag of `p` less that of `q` (s),
/// beyond the servos'.
struct DriveShare {
    lost_motion_m: [f64; 2],
    lag_s: f64,
}

/// Samples per full turn of [`drive_share`]'s projection: 0.01°, so that a Stribeck hump of
/// `v_s / F` rad (0.03° for 0.5 mm/s at 1000 mm/min) spans a few of them.
const SHARE_SAMPLES_PER_TURN: f64 = 36_000.0;

/// The drives' share of test `b` over its data arcs `arcs` (start angle, signed sweep, rad), as
/// the diagnosis' least squares read it.
///
/// In semi-closed loop an axis sliding at `v` stands `e(v)` from where its encoder puts it:
/// half its gap and the screw's stretch under the guideway friction `F(v)` (Stribeck curve
/// plus viscous `σ2 v`, [`lost_motion_at_rest_m`] with that friction holding it). Along the
/// circle the axis' speed runs from 0 at its reversals to the feed, so `e` is not a step: the
/// Stribeck excess `(F_s − F_c) e^{−(v/v_s)²}` adds a hump at each reversal, and the viscous
/// term is a lag `σ2/k`. Its radial reading `e_p cos θ + e_q sin θ` (in-plane displacements)
/// is fitted over the data arcs, sampled evenly in angle as a constant feed samples them, with
/// what the diagnosis fits it with: radius and centre (1, cos θ, sin θ), each axis' lost
/// motion `l` (`−½ l sign(v) cos θ` for p, `sin θ` for q, when the axis runs both ways) and,
/// when both senses were run, a lag difference `Δτ` (`−Δτ v_p cos θ`; a lag common to both
/// axes leaves the radius unchanged). An axis that runs one way only (the test cannot show its
/// lost motion) gets that of a reversal at the test feed under the Stribeck force, and with
/// one sense only the lag stays the servos'. At the test feed far above `v_s` the lost motion is
/// `b + 2 F_c/k` and the lag `σ2/k` per axis; with a wide Stribeck range the hump raises the
/// lost motion and lowers the lag (a 250 N static peak over 50 N Coulomb with `v_s` = 5 mm/s,
/// at 1000 mm/min on 150 mm: +1.9 µm and −0.08 ms on a 180 N/µm screw). The take-up of the
/// gap just after a reversal is not part of this projection.
fn drive_share(
    axes: &[AxisDynamics; 3],
    loads: &[f64; 3],
    b: &BallbarSetup,
    arcs: &[(f64, f64)],
) -> DriveShare {
    let (pa, qa) = b.plane.axes();
    let offset = |a: Axis, v: f64| {
        let d = &axes[a.index()];
        lost_motion_at_rest_m(
            d,
            d.drive.guide_friction.steady_state_force(v),
            loads[a.index()],
        )
    };
    let mut normal = nalgebra::SMatrix::<f64, 6, 6>::zeros();
    let mut rhs = nalgebra::SVector::<f64, 6>::zeros();
    let (mut ways, mut senses) = ([[false; 2]; 2], [false; 2]);
    for &(start, sweep) in arcs {
        let n = (sweep.abs() / TAU * SHARE_SAMPLES_PER_TURN).ceil().max(1.0) as usize;
        let sense = sweep.signum();
        senses[usize::from(sense > 0.0)] = true;
        for j in 0..n {
            // Mid-interval samples: an axis' reversal (v = 0) falls between them.
            let th = start + sweep * (j as f64 + 0.5) / n as f64;
            let (sin, cos) = th.sin_cos();
            let v = [-sense * b.feed_m_s * sin, sense * b.feed_m_s * cos];
            for (w, v) in ways.iter_mut().zip(v) {
                w[usize::from(v > 0.0)] = true;
            }
            let row = nalgebra::SVector::<f64, 6>::from([
                1.0,
                cos,
                sin,
                -0.5 * v[0].signum() * cos,
                -0.5 * v[1].signum() * sin,
                -v[0] * cos,
            ]);
            let r = offset(pa, v[0]) * cos + offset(qa, v[1]) * sin;
            normal += row * row.transpose();
            rhs += row * r;
        }
    }
    let both = |w: [bool; 2]| w[0] && w[1];
    let fitted: Vec<usize> = (0..6)
        .filter(|&c| match c {
            3 | 4 => both(ways[c - 3]),
            5 => both(senses),
            _ => true,
        })
        .collect();
    let sub = normal.select_rows(&fitted).select_columns(&fitted);
    let sub_rhs = rhs.select_rows(&fitted);
    let x = sub.cholesky().map(|c| c.solve(&sub_rhs));
    let coef = |c: usize| {
        let i = fitted.iter().position(|&f| f == c)?;
        x.as_ref().map(|x| x[i])
    };
    let at_feed = |a: Axis| {
        let d = &axes[a.index()];
        let friction = d.drive.guide_friction.stribeck_force(b.feed_m_s);
        reversal_at_rest_m(d, friction, loads[a.index()])
    };
    DriveShare {
        lost_motion_m: [
            coef(3).unwrap_or_else(|| at_feed(pa)),
            coef(4).unwrap_or_else(|| at_feed(qa)),
        ],
        lag_s: coef(5).unwrap_or(0.0),
    }
}

/// What changes when an axis reverses: along it and across it (µm), and how much those changes
/// grow across and along the axis (µrad, summed: the bar reads both as one angular play).
struct ReversalChange {
    along_um: f64,
    across_um: f64,
    angular_urad: f64,
}

/// A weighted least-squares line `c ≈ c₀ + g·x` through points `(x, c)`.
#[derive(Default)]
struct Line {
    ata: Matrix2<f64>,
    aty: Vector2<f64>,
}

impl Line {
    fn add(&mut self, w: f64, x: f64, c: f64) {
        let row = Vector2::new(1.0, x);
        self.ata += w * row * row.transpose();
        self.aty += w * c * row;
    }

    /// The weighted mean of `c`.
    fn mean(&self) -> f64 {
        self.aty[0] / self.ata[(0, 0)]
    }

    /// The line's value at `x = 0`, `c₀`; the weighted mean without spread in `x`.
    fn at_zero(&self) -> f64 {
        self.ata.lu().solve(&self.aty).map_or(self.mean(), |v| v[0])
    }

    /// The slope `g`; 0 without spread in `x`.
    fn slope(&self) -> f64 {
        self.ata.lu().solve(&self.aty).map_or(0.0, |v| v[1])
    }
}

/// The change of the tool-point error when `axis` reverses (backward minus forward), along it
/// and along `other`, over the data arcs `arcs` (start angle, signed sweep, rad) and the
/// directions of `other`, the third axis in its direction of `base`: each change is a
/// weighted least-squares line in the position from the circle's centre (across the axis for
/// the change along it, along the axis for the change across it), and the backlash and lateral
/// play are the lines' values at the centre, the angular play the sum of their slopes. Each
/// point weighs as the signature's least squares weigh it: the change along `axis` (the
/// backlash, `± cos θ` from the axis) by the square of the axis' share of the radius, the
/// change along `other` (the lateral play, `± |sin θ|`) by the square of `other`'s share. Both
/// slopes read `σ (εR/2) |sin θ| cos θ` on the bar (for p), so a carriage turning about the
/// plane's normal shows only where the two differ (a turn about the circle's centre moves
/// nothing radially). These are the diagnosis' parameters: its lateral play is the change at
/// the centre and its angular play the growth from there. On a full circle the weights are
/// symmetric about the centre and the values at it are the weighted means; on a half circle
/// over the top, which cannot fit the angular play, a line's mean lies a slope times the
/// weighted mean position away (0.42 R for Z's lateral play in YZ), and the diagnosis reads the
/// value at the centre plus the angular play's bias that it states.
fn reversal_change(
    inputs: &TruthInputs,
    chain: &VolumetricEvaluator,
    b: &BallbarSetup,
    (axis, other): (Axis, Axis),
    arcs: &[(f64, f64)],
    base: [Direction; 3],
) -> ReversalChange {
    let (pa, qa) = b.plane.axes();
    let (centre, radius) = b.tool_circle();
    let full = [(0.0, TAU)];
    let arcs = if arcs.is_empty() { &full[..] } else { arcs };
    let n = 360;
    let (mut along_line, mut across_line) = (Line::default(), Line::default());
    for &(start, sweep) in arcs {
        for j in 0..=n {
            let th = start + sweep * j as f64 / n as f64;
            let radial = unit(pa) * th.cos() + unit(qa) * th.sin();
            let tool = centre + radial * radius;
            let mut change = Vector3::zeros();
            for d in [Direction::Forward, Direction::Backward] {
                let at = |dir| {
                    chain.volumetric_error(&state(inputs, tool, base, [(axis, dir), (other, d)]))
                };
                change += 0.5 * (at(Direction::Backward) - at(Direction::Forward));
            }
            let (wa, wc) = (radial[axis.index()].powi(2), radial[other.index()].powi(2));
            let (x_along, x_across) = (
                radius * radial[axis.index()],
                radius * radial[other.index()],
            );
            along_line.add(wa, x_across, change[axis.index()]);
            across_line.add(wc, x_along, change[other.index()]);
        }
    }
    ReversalChange {
        along_um: along_line.at_zero() * 1e6,
        across_um: across_line.at_zero() * 1e6,
        angular_urad: (across_line.slope() + along_line.slope()) * 1e6,
    }
}
