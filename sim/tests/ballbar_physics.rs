//! Ball-bar signatures emerging from the physics of the simulated machine.

mod common;

use nalgebra::Vector3;
use vmt_model::machine::Machine;
use vmt_sim::ballbar::BallbarSpec;
use vmt_sim::interpolator::{InterpolatorConfig, Limits};
use vmt_sim::nc::{CircularTest, Plane, parse};
use vmt_sim::plant::Fidelity;
use vmt_sim::run::{BallbarTrace, Run};
use vmt_sim::simulate::{AxisDynamics, BallbarSetup, Job, SimSettings, simulate};

fn machine() -> Machine {
    let mut m = vmt_scenario::builtin().unwrap().machine;
    // A geometrically perfect machine, so that only the drives make the signature.
    m.volumetric.errors = vmt_model::geometric::GeometricErrors::zero();
    m.thermal = None;
    m
}

fn circle_run(axes: [AxisDynamics; 3], feed_mm_min: f64, fidelity: Fidelity) -> Run {
    let m = machine();
    let center = Vector3::new(0.25, 0.2, 0.2);
    let test = CircularTest::iso230_4(Plane::Xy, center, 0.15, feed_mm_min / 60_000.0);
    let start = test.start_point();
    let program = parse(&test.gcode(), start).unwrap();
    let data = test.data_blocks(&program).unwrap();
    let job = Job {
        program,
        ballbar: vec![BallbarSetup {
            name: None,
            spec: BallbarSpec::default(),
            center,
            radius_m: 0.15,
            plane: Plane::Xy,
            feed_m_s: test.feed_m_s,
            data,
            circle: None,
        }],
        laser: None,
    };
    let settings = SimSettings {
        fidelity,
        plant_substeps: 2,
        log_rate_hz: 1000.0,
        seed: 7,
    };
    let ipo = InterpolatorConfig::new(Limits::default());
    simulate(&m, &axes, &ipo, &job, &settings, "", &mut |_| {}).unwrap()
}

/// Mean deviation (µm) of a trace over the angles within `half_width` degrees of `at` (mod 360).
fn mean_near(t: &BallbarTrace, at: f64, half_width: f64) -> f64 {
    let sel: Vec<f64> = t
        .angle_deg
        .iter()
        .zip(&t.deviation_um)
        .filter(|(a, _)| {
            ((*a - at).rem_euclid(360.0) + 180.0).rem_euclid(360.0) - 180.0 < half_width
                && ((*a - at).rem_euclid(360.0) + 180.0).rem_euclid(360.0) - 180.0 > -half_width
        })
        .map(|(_, d)| *d)
        .collect();
    sel.iter().sum::<f64>() / sel.len() as f64
}

fn trace<'a>(run: &'a Run, dir: &str) -> &'a BallbarTrace {
    run.ballbar.iter().find(|t| t.direction == dir).unwrap()
}

/// With backlash on X only, the trace steps at the X reversals (0° and 180°) by about the
/// backlash the ball bar sees, b + 2F/k, and not at the Y reversals (90°, 270°).
#[test]
fn x_backlash_steps_at_0_and_180_degrees_only() {
    let b = 4e-6;
    let axes = [
        common::axis(250.0, b, 33.0),
        common::axis(450.0, 0.0, 33.0),
        common::axis(180.0, 0.0, 33.0),
    ];
    let run = circle_run(axes, 1000.0, Fidelity::Reduced);
    let seen = run.ground_truth["drives"]["x"]["backlash_seen_um"]
        .as_f64()
        .unwrap();
    for dir in ["cw", "ccw"] {
        let t = trace(&run, dir);
        assert!(t.angle_deg.len() > 50_000, "{} samples", t.angle_deg.len());
        let sweep = (t.angle_deg[t.angle_deg.len() - 1] - t.angle_deg[0]).abs();
        assert!((sweep - 360.0).abs() < 1.0, "sweep {sweep}");
        // Step across a reversal: mean 5-15° after minus mean 5-15° before, in the run's sense.
        let s = if dir == "ccw" { 1.0 } else { -1.0 };
        let step = |at: f64| mean_near(t, at + s * 10.0, 5.0) - mean_near(t, at - s * 10.0, 5.0);
        for at in [0.0, 180.0] {
            assert!(
                (step(at).abs() - seen).abs() < 0.3 * seen,
                "{dir} at {at}: step {} vs {seen}",
                step(at)
            );
        }
        for at in [90.0, 270.0] {
            assert!(
                step(at).abs() < 0.2 * seen,
                "{dir} at {at}: step {}",
                step(at)
            );
        }
    }
}

/// Unequal Kv on X and Y: the trace is an ellipse at 45° whose sign flips between CW and CCW,
/// of half-amplitude F·Δτ/2 (first order), Δτ = 1/Kv_x - 1/Kv_y.
#[test]
fn servo_mismatch_ellipse_flips_between_cw_and_ccw() {
    let axes = [
        common::axis(250.0, 0.0, 30.0),
        common::axis(450.0, 0.0, 36.0),
        common::axis(180.0, 0.0, 33.0),
    ];
    let feed = 2000.0;
    let run = circle_run(axes, feed, Fidelity::Reduced);
    let dtau = 1.0 / 30.0 - 1.0 / 36.0;
    let expected = feed / 60_000.0 * dtau / 2.0 * 1e6; // µm
    let sin2 = |t: &BallbarTrace| {
        // Least-squares amplitude of sin 2θ.
        let (num, den) =
            t.angle_deg
                .iter()
                .zip(&t.deviation_um)
                .fold((0.0, 0.0), |(n, d), (a, v)| {
                    let s = (2.0 * a.to_radians()).sin();
                    (n + s * v, d + s * s)
                });
        num / den
    };
    let (cw, ccw) = (sin2(trace(&run, "cw")), sin2(trace(&run, "ccw")));
    assert!(cw * ccw < 0.0, "the ellipse flips: cw {cw}, ccw {ccw}");
    for a in [cw.abs(), ccw.abs()] {
        assert!(
            (a - expected).abs() < 0.15 * expected,
            "amplitude {a} vs {expected} µm"
        );
    }
}
