//! Jobs the simulation refuses before it starts, each with one clear message.

mod common;

use nalgebra::Vector3;
use vmt_sim::interpolator::{InterpolatorConfig, Limits};
use vmt_sim::nc::parse;
use vmt_sim::plant::Fidelity;
use vmt_sim::simulate::{AxisDynamics, Job, SimError, SimSettings, simulate};

fn axes() -> [AxisDynamics; 3] {
    [
        common::axis(250.0, 0.0, 33.0),
        common::axis(450.0, 0.0, 33.0),
        common::axis(180.0, 0.0, 33.0),
    ]
}

/// Runs `program` from (100, 100, 100) mm; the error and whether the run had begun.
fn refuse(axes: &[AxisDynamics; 3], program: &str, substeps: usize) -> (SimError, bool) {
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
    let mut started = false;
    let e = simulate(&machine, axes, &ipo, &job, &settings, "", &mut |_| {
        started = true
    })
    .unwrap_err();
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
/// contact) under the 250 kg X carriage with σ1 + σ2 = 3.02e4 N·s/m: 99.7 µs, so the 125 µs
/// step of one substep per servo period is refused, naming the scenario key and the two
/// substeps (62.5 µs) that are needed, and two substeps are accepted.
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
         drive: the largest stable step is {limit_us:.2} µs; raise plant_substeps (scenario key \
         controller.plant_substeps) to 2 or more"
    );
    assert_eq!(msg, expected);
    // Two substeps are within the limit: the check passes and the (short) job runs.
    let machine = vmt_scenario::builtin().unwrap().machine;
    let job = Job {
        program: parse("G1 X100.1 F1000\n", Vector3::new(0.1, 0.1, 0.1)).unwrap(),
        ballbar: vec![],
        laser: None,
    };
    let settings = SimSettings {
        fidelity: Fidelity::Reduced,
        plant_substeps: 2,
        log_rate_hz: 1000.0,
        seed: 1,
    };
    let ipo = InterpolatorConfig::new(Limits::default());
    assert!(simulate(&machine, &a, &ipo, &job, &settings, "", &mut |_| {}).is_ok());
}

/// A scenario file whose plant step is too coarse is refused when it loads, the error naming
/// the file, the line and the key `controller.plant_substeps` besides the largest stable step.
#[test]
fn a_scenario_with_a_step_too_coarse_names_the_file_and_the_substeps_key() {
    let text = vmt_scenario::BUILTIN_DEFAULT
        .replace("servo_period_us = 125.0", "servo_period_us = 2500.0")
        .replace("ipo_period_ms = 1.0", "ipo_period_ms = 2.5")
        .replace("plant_substeps = 2", "plant_substeps = 1");
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
