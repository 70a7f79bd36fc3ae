//! Jobs the simulation refuses before it starts, each with one clear message.

mod common;

use nalgebra::Vector3;
use vmt_sim::interpolator::{InterpolatorConfig, Limits};
use vmt_sim::nc::parse;
use vmt_sim::plant::Fidelity;
use vmt_sim::simulate::{
    AxisDynamics, Job, SimError, SimSettings, check_servo, servo_warnings, simulate,
};

fn axes() -> [AxisDynamics; 3] {
    [
        common::axis(250.0, 0.0, 33.0),
        common::axis(450.0, 0.0, 33.0),
        common::axis(180.0, 0.0, 33.0),
    ]
}

/// Runs `program` from (100, 100, 100) mm on the built-in machine with `axes`; `progress` is
/// called as the run advances.
fn run(
    axes: &[AxisDynamics; 3],
    program: &str,
    substeps: usize,
    progress: &mut dyn FnMut(f64),
) -> Result<vmt_sim::run::Run, SimError> {
    let machine = vmt_scenario::builtin().unwrap().machine;
    let job = Job {
        program: parse(program, Vector3::new(0.1, 0.1, 0.1)).unwrap(),
        ballbar: vec![],
        laser: None,
    };
    let settings = SimSettings {
        fidelity: Fidelity::Reduced,
        plant_substeps: substeps,
        log_rate_hz: 1000.0,
        seed: 1,
    };
    let ipo = InterpolatorConfig::new(Limits::default());
    simulate(&machine, axes, &ipo, &job, &settings, "", progress)
}

/// [`run`], refused: the error and whether the run had begun.
fn refuse(axes: &[AxisDynamics; 3], program: &str, substeps: usize) -> (SimError, bool) {
    let mut started = false;
    let e = run(axes, program, substeps, &mut |_| started = true).unwrap_err();
    (e, started)
}

#[test]
fn travel_beyond_the_stroke_is_refused_before_the_run_naming_the_line() {
    let (e, started) = refuse(&axes(), "G1 X200 F1000\nG1 Y150\nG1 X600\n", 2);
    assert!(!started, "refused before the run");
    let m = e.to_string();
    // The block's farthest point (its target), not where it crosses the end of the stroke.
    assert!(
        m.starts_with("block at line 3: the X axis would reach 600.000 mm"),
        "{m}"
    );
    assert!(m.ends_with("mm, beyond its stroke 0 to 500 mm"), "{m}");
}

/// Semi-implicit Euler on a mode `m x'' = -k x - c x'` is stable for
/// h < (2/ω)(√(1+ζ²) - ζ), ω = √(k/m), ζ = c / (2√(k m)). Bristles of 1e11 N/m (a very stiff
/// contact) under the 250 kg X carriage with σ1 + σ2 = 3.02e4 N·s/m: 99.7 µs, of which half,
/// 49.85 µs, is accepted. The 125 µs step of one substep per servo period is refused, naming
/// the scenario key and the three substeps (41.7 µs) that are needed; two (62.5 µs, stable but
/// ringing 8 % fast) are refused too, and three are accepted.
#[test]
fn a_step_too_coarse_for_the_stiffest_mode_is_refused_stating_the_largest_stable_step() {
    let mut a = axes();
    a[0].drive.guide_friction.sigma0_n_per_m = 1e11;
    let (k, c, m): (f64, f64, f64) = (1e11, 3e4 + 200.0, 250.0);
    let (w, z) = ((k / m).sqrt(), c / (2.0 * (k * m).sqrt()));
    let limit_us = 2.0 / w * ((1.0 + z * z).sqrt() - z) * 1e6;
    assert!((limit_us - 99.7).abs() < 0.1, "{limit_us}");
    let (e, started) = refuse(&a, "G1 X101 F1000\n", 1);
    assert!(!started, "refused before the run");
    let msg = e.to_string();
    let expected = format!(
        "a plant step of 125.00 µs is too coarse for the guideway friction bristles of the X \
         drive: the largest stable step is {limit_us:.2} µs, and up to half of it ({:.2} µs) is \
         accepted, where the step keeps that mode's frequency within 5 %; raise plant_substeps \
         (scenario key controller.plant_substeps) to 3 or more",
        limit_us / 2.0
    );
    assert_eq!(msg, expected);
    // Two substeps (62.5 µs) are stable but beyond half the limit: refused, asking for three.
    let (e, _) = refuse(&a, "G1 X101 F1000\n", 2);
    assert!(e.to_string().ends_with("to 3 or more"), "{e}");
    // Three substeps are within it: the check passes and the (short) job runs.
    assert!(run(&a, "G1 X100.1 F1000\n", 3, &mut |_| {}).is_ok());
}

/// A velocity loop too fast for the servo period (2 kHz at 125 µs behind a 0.5 ms current loop)
/// is warned of before the run, stating the stable bandwidths (the upper end is the limit: 1 %
/// below it is stable, 1 % above not) and where it will ring; the run goes on, as a machine
/// tuned so would (the loop rings, bounded by the force limit).
#[test]
fn a_servo_loop_unstable_at_the_servo_period_is_warned_of_stating_the_stable_bandwidths() {
    let mut a = axes();
    let per_hz = a[1].drive.total_mass_kg() * std::f64::consts::TAU;
    a[1].servo.velocity_kp_n_s_per_m = per_hz * 2000.0;
    let period = 125e-6;
    let warnings = servo_warnings(&a, period);
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    let (axis, msg) = &warnings[0];
    assert_eq!(*axis, vmt_model::Axis::Y);
    assert!(
        msg.starts_with(
            "the Y axis' velocity loop of 2000.0 Hz is unstable at the servo period of 125.0 µs"
        ),
        "{msg}"
    );
    assert!(msg.contains("The run goes on: the loop rings at "), "{msg}");
    let range = msg.split("stable from ").nth(1).expect(msg);
    let ends: Vec<f64> = range
        .split(" Hz")
        .next()
        .unwrap()
        .split(" to ")
        .map(|v| v.parse().unwrap())
        .collect();
    // The tests' 60 Hz (377 rad/s) loops lie inside.
    assert!(
        ends[0] < 60.0 && 60.0 < ends[1] && ends[1] < 2000.0,
        "{msg}"
    );
    for (factor, ok) in [(0.99, true), (1.01, false)] {
        a[1].servo.velocity_kp_n_s_per_m = per_hz * ends[1] * factor;
        assert_eq!(
            check_servo(&a, period).is_ok(),
            ok,
            "{factor} × {} Hz",
            ends[1]
        );
    }
    // The run is not refused.
    a[1].servo.velocity_kp_n_s_per_m = per_hz * 2000.0;
    assert!(run(&a, "G1 X100.1 F1000\n", 2, &mut |_| {}).is_ok());
    // An integral time as short as the current loop's lag leaves no stable bandwidth at all:
    // the message says which settings to change instead.
    a[1].servo.velocity_kp_n_s_per_m = per_hz * 60.0;
    a[1].servo.velocity_ti_s = 0.5e-3;
    let msg = check_servo(&a, period).unwrap_err().to_string();
    assert!(
        msg.ends_with("no velocity bandwidth is stable with this position gain, integral time and current loop at this servo period; lengthen velocity_integral_ms, shorten current_time_constant_ms or servo_period_us, or lower kv_per_s"),
        "{msg}"
    );
    // The built-in tuning gives no warning.
    assert!(servo_warnings(&axes(), period).is_empty());
}

/// A scenario file whose plant step is too coarse is refused when it loads, the error naming
/// the file, the line and the key `controller.plant_substeps` besides the largest stable step.
#[test]
fn a_scenario_with_a_step_too_coarse_names_the_file_and_the_substeps_key() {
    let text = vmt_scenario::BUILTIN_DEFAULT
        .replace("servo_period_us = 125.0", "servo_period_us = 2500.0")
        .replace("ipo_period_ms = 1.0", "ipo_period_ms = 2.5");
    let line = 1 + text
        .lines()
        .position(|l| l.starts_with("plant_substeps = 1"))
        .unwrap();
    // The position is the value's.
    let column = "plant_substeps = ".len() + 1;
    let e = match vmt_scenario::parse(&text, "coarse.toml", None) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("a 2.5 ms step was accepted"),
    };
    assert!(
        e.starts_with(&format!(
            "coarse.toml:{line}:{column}: key `controller.plant_substeps`: a plant step of 2500.00 µs \
             is too coarse for the screw axial mode of the X drive: the largest stable step is"
        )),
        "{e}"
    );
    assert!(
        e.contains("; raise plant_substeps (scenario key controller.plant_substeps) to "),
        "{e}"
    );
}

/// A scenario whose velocity loop is unstable at its servo period loads, with a note for the
/// run naming the axis' `velocity_bandwidth_hz` key.
#[test]
fn a_scenario_with_an_unstable_servo_is_noted_naming_the_bandwidth_key() {
    let x_servo = vmt_scenario::BUILTIN_DEFAULT
        .find("[machine.axes.x.servo]")
        .unwrap();
    let (head, tail) = vmt_scenario::BUILTIN_DEFAULT.split_at(x_servo);
    let text = format!(
        "{head}{}",
        tail.replacen(
            "velocity_bandwidth_hz = 60.0",
            "velocity_bandwidth_hz = 2000.0",
            1
        )
    );
    let s = vmt_scenario::parse(&text, "fast.toml", None).expect("loads");
    let notes = s.execution.unwrap().notes;
    assert!(
        notes.iter().any(|n| n.starts_with(
            "key `machine.axes.x.servo.velocity_bandwidth_hz`: the X axis' velocity loop of 2000.0 Hz is unstable"
        )),
        "{notes:?}"
    );
}

/// The excess-error alarm: an X drive whose peak force (60 N) cannot overcome its guideway and
/// screw friction (80 N at breakaway) does not move, so its following error grows with the
/// command until it passes the default limit, twice the lag at the axis' velocity limit
/// (2 · 0.5 m/s / 33 s⁻¹ = 30.303 mm), and the run stops there naming the block, the axis and
/// the limit. A limit set below the lag of a sound drive at 1000 mm/min
/// (1000/60 mm/s / 33 s⁻¹ = 0.505 mm) stops it too; one above lets it run.
#[test]
fn a_drive_that_cannot_follow_stops_the_run_at_its_excess_error_limit() {
    let mut weak = axes();
    weak[0].servo.force_limit_n = 60.0;
    let (e, started) = refuse(&weak, "G1 X400 F5000\n", 2);
    assert!(started, "an alarm of the running job");
    let SimError::ExcessError {
        line,
        axis,
        error_mm,
        limit_mm,
        ..
    } = e
    else {
        panic!("{e}")
    };
    assert_eq!((line, axis), (1, vmt_model::Axis::X));
    assert!((limit_mm - 2.0 * 500.0 / 33.0).abs() < 1e-9, "{limit_mm}");
    assert!(
        error_mm > limit_mm && error_mm < limit_mm + 0.01,
        "{error_mm}"
    );
    let mut strict = axes();
    strict[0].servo.following_error_limit_m = Some(0.4e-3);
    let (e, _) = refuse(&strict, "G1 X105 F1000\n", 2);
    let m = e.to_string();
    assert!(
        m.starts_with("block at line 1: the X axis' following error reached 0.400")
            && m.contains("beyond its excess-error limit of 0.400 mm")
            && m.contains("machine.axes.x.servo.following_error_limit_mm"),
        "{m}"
    );
    strict[0].servo.following_error_limit_m = Some(0.6e-3);
    run(&strict, "G1 X105 F1000\n", 2, &mut |_| {}).expect("0.505 mm of lag");
}
