//! `scenarios/ringing.toml`: the built-in machine with X's velocity loop tuned too high, on its
//! compliant guide blocks. The loop is unstable by the sampled-loop analysis (its pole, the
//! reference here, is `least_damped_pole`: the closed-loop matrix of the two-mass drive under
//! the cascade, linearised without friction), so the scenario loads with a note and runs; the
//! motor rings at that pole's frequency, and what reaches the tool is measured from the run's
//! noise-free tool point. The ball bar's diagnosis is held to what the physics gives.

use vmt_ballbar::{Options, diagnose};
use vmt_model::drive::servo::least_damped_pole;

/// The largest amplitude (and its frequency) of `x` sampled at `fs` between `lo` and `hi` Hz,
/// by a direct DFT on a 0.25 Hz grid (the mean taken out).
fn line(x: &[f64], fs: f64, lo: f64, hi: f64) -> (f64, f64) {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let mut best = (0.0, 0.0);
    let mut f = lo;
    while f <= hi {
        let w = std::f64::consts::TAU * f / fs;
        let (mut re, mut im) = (0.0, 0.0);
        for (k, v) in x.iter().enumerate() {
            let (s, c) = (w * k as f64).sin_cos();
            re += (v - mean) * c;
            im += (v - mean) * s;
        }
        let a = 2.0 * (re * re + im * im).sqrt() / n;
        if a > best.1 {
            best = (f, a);
        }
        f += 0.25;
    }
    best
}

#[test]
fn a_velocity_loop_tuned_too_high_rings_at_its_pole_and_the_ball_bar_sees_what_reaches_the_tool() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/ringing.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let s = vmt_scenario::parse(&text, "ringing.toml", None).expect("loads, not refused");
    let e = s.execution.expect("a job");
    let x = &e.axes[0];
    let period = e.controller.servo_period_s;
    let (pole_hz, zeta) = least_damped_pole(&x.servo, &x.drive, period).expect("a pole");
    eprintln!(
        "pole {pole_hz:.1} Hz, damping ratio {zeta:.4}; notes {:?}",
        e.notes
    );
    assert!(zeta < 0.0, "the loop is unstable");
    assert!(
        e.notes.iter().any(|n| n.contains("velocity_bandwidth_hz")
            && n.contains("is unstable")
            && n.contains(&format!("rings at {pole_hz:.0} Hz"))),
        "{:?}",
        e.notes
    );
    let run = e.simulate(&s.machine, &text, &mut |_| {}).expect("runs");
    // The log is at 1 kHz: the ringing above 500 Hz shows at its alias.
    let fs = 1000.0;
    let alias = (pole_hz - fs * (pole_hz / fs).round()).abs();
    let servo = &run.streams[0];
    // Ten seconds of the first trace's steady motion.
    let t0 = run.ballbar[0].times_s[5000];
    let k0 = servo.times_s.iter().position(|&t| t >= t0).unwrap();
    let span = k0..k0 + 10_000;
    let force = &servo.channel("motor_force_x").unwrap().values[span.clone()];
    let (f_motor, a_motor) = line(force, fs, alias - 60.0, alias + 60.0);
    // The line back in the pole's band (the log's 1 kHz folds 633 Hz onto 367 Hz). The ring is
    // a limit cycle bounded by friction and the encoder's quantisation, whose frequency sits a
    // few per cent from the linear pole and moves by as much with a rounding of the state
    // (650–663 Hz measured across builds of the same physics), so it is held to the pole within
    // 5 % of the frequency itself, not of its alias.
    let k = (pole_hz / fs).round();
    let f_ring = k * fs + (pole_hz - k * fs).signum() * f_motor;
    eprintln!(
        "motor force line {a_motor:.1} N at {f_motor:.2} Hz, a ring at {f_ring:.1} Hz (pole's alias {alias:.2} Hz)"
    );
    assert!(
        (f_ring / pole_hz - 1.0).abs() < 0.05,
        "{f_ring} Hz against the pole's {pole_hz} Hz"
    );
    // A line, not the noise of the force (a few newtons a bin elsewhere).
    let (_, floor) = line(force, fs, 150.0, 250.0);
    assert!(a_motor > 2.0 * floor, "{a_motor} N against {floor} N");
    // What reaches the tool: the noise-free tool point along X, less the command, at that line.
    let tool = &servo.channel("tool_x").unwrap().values[span.clone()];
    let command = &servo.channel("command_x").unwrap().values[span];
    let error: Vec<f64> = tool.iter().zip(command).map(|(t, c)| t - c).collect();
    let (_, a_tool) = line(&error, fs, f_motor - 0.5, f_motor + 0.5);
    eprintln!("tool point along X at the line: {:.4} µm", a_tool * 1e6);
    let d = diagnose(&vmt_e2e::traces(&run), &Options::default()).expect("diagnosis");
    let v = d.finding("servo_vibration").expect("the vibration finding");
    eprintln!(
        "diagnosis: {:.4} ± {:.4} µm at {:?}, present {}",
        v.value, v.ci95, v.details, v.present
    );
    // The bar reads the tool's motion, a few nanometres: below what the diagnosis reports.
    assert!(a_tool * 1e6 < 0.05, "{a_tool}");
    assert!(!v.present, "a vibration reported: {v:?}");
    // The same machine tuned as built in: no note about its loops, no vibration.
    let nominal = vmt_scenario::builtin().unwrap();
    assert!(
        !nominal
            .execution
            .as_ref()
            .unwrap()
            .notes
            .iter()
            .any(|n| n.contains("velocity_bandwidth_hz"))
    );
}
