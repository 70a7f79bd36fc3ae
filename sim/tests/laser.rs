//! ISO 230-2 positioning runs with the laser interferometer on the simulated machine: an injected
//! scale error comes back in the mean deviations, and a screw backlash in the reversal value.

mod common;

use nalgebra::Vector3;
use vmt_model::Axis;
use vmt_model::drive::Feedback;
use vmt_model::geometric::{Component, Directional, ErrorFunction, LegendreSeries};
use vmt_model::machine::Machine;
use vmt_sim::interpolator::{InterpolatorConfig, Limits};
use vmt_sim::laser::{LaserSetup, LaserSpec, PositioningTest};
use vmt_sim::nc::parse;
use vmt_sim::plant::Fidelity;
use vmt_sim::run::Run;
use vmt_sim::simulate::{AxisDynamics, Job, SimSettings, simulate};

/// Linear EXX coefficient c1 (half the change over the 0–500 mm stroke), m: 40 µm/m.
const EXX_C1_M: f64 = 10e-6;

fn machine(exx_c1_m: f64) -> Machine {
    let mut m = vmt_scenario::builtin().unwrap().machine;
    m.volumetric.errors = vmt_model::geometric::GeometricErrors::zero();
    m.thermal = None;
    let series = LegendreSeries::new(vec![0.0, exx_c1_m], 0.0, 0.5).unwrap();
    m.volumetric.errors.axis_mut(Axis::X).set(
        Component::Tx,
        Directional::symmetric(ErrorFunction::Legendre(series)),
    );
    m
}

/// A short X test: three targets 25 mm apart, three runs, 2 s dwells averaged over the last 1 s
/// (after a reversal the carriage creeps for a few tenths of a second as the friction relaxes).
fn test() -> PositioningTest {
    PositioningTest {
        axis: Axis::X,
        targets_m: vec![0.1, 0.125, 0.15],
        line_m: Vector3::new(0.0, 0.2, 0.2),
        runs: 3,
        dwell_s: 2.0,
        feed_m_s: 3000.0 / 60_000.0,
        overrun_m: 0.005,
    }
}

fn positioning_job(spec: LaserSpec) -> Job {
    let t = test();
    let (text, datum_block, measurements) = t.gcode();
    let program = parse(&text, t.start_point()).unwrap();
    t.check_program(&program, datum_block, &measurements)
        .unwrap();
    Job {
        program,
        ballbar: Vec::new(),
        laser: Some(LaserSetup {
            spec,
            test: t,
            datum_block,
            measurements,
        }),
    }
}

const SETTINGS: SimSettings = SimSettings {
    fidelity: Fidelity::Reduced,
    plant_substeps: 2,
    log_rate_hz: 100.0,
    seed: 11,
};

fn positioning_run(m: &Machine, axes: [AxisDynamics; 3], spec: LaserSpec) -> Run {
    let ipo = InterpolatorConfig::new(Limits::default());
    let job = positioning_job(spec);
    simulate(m, &axes, &ipo, &job, &SETTINGS, "", &mut |_| {}).unwrap()
}

fn spec(air_temperature_error_k: f64) -> LaserSpec {
    LaserSpec {
        noise_m: 20e-9,
        averaging_s: 1.0,
        air_temperature_error_k,
        ..LaserSpec::default()
    }
}

/// With X on a linear scale and a linear EXX of 40 µm/m and a weather station reading the air 2 K warm, the forward
/// mean deviations are ΔEXX + ε·(P − datum), ε = 1.85 ppm; the truth's error-chain deviations
/// are ΔEXX exactly, and its noise-free deviations differ from the readings by the ε term only.
#[test]
fn scale_error_comes_back_in_the_mean_deviations() {
    let m = machine(EXX_C1_M);
    // A linear scale closes the X loop on the carriage, so the drive adds nothing at a stop.
    let mut x = common::axis(250.0, 0.0, 33.0);
    x.drive.feedback = Feedback::LinearScale { resolution_m: 1e-9 };
    let axes = [
        x,
        common::axis(450.0, 0.0, 33.0),
        common::axis(180.0, 0.0, 33.0),
    ];
    let spec = spec(2.0);
    let run = positioning_run(&m, axes, spec);
    let laser = run.laser.as_ref().unwrap();
    assert_eq!(laser.readings.len(), 3 * 2 * 3);
    let iso = laser.iso230_2();
    let t = test();
    let datum = t.datum_m();
    let exx = |x: f64| EXX_C1_M * (2.0 * x / 0.5 - 1.0);
    let eps = spec.scale_error();
    let truth = &run.ground_truth["laser"];
    let chain_iso = &truth["iso230_2_chain"];
    for (i, &p) in t.targets_m.iter().enumerate() {
        let injected_um = (exx(p) - exx(datum)) * 1e6;
        let expected_um = injected_um + eps * (p - datum) * 1e6;
        let got = iso.mean_forward_um[i];
        eprintln!(
            "target {:.0} mm: forward mean {got:.4} um, backward {:.4} um, expected {expected_um:.4} um (EXX part {injected_um:.4})",
            p * 1e3,
            iso.mean_backward_um[i]
        );
        assert!((got - expected_um).abs() < 0.01, "{got} vs {expected_um}");
        let chain = chain_iso["mean_forward_um"][i].as_f64().unwrap();
        assert!(
            (chain - injected_um).abs() < 1e-6,
            "{chain} vs {injected_um}"
        );
        let exact = truth["iso230_2_exact"]["mean_forward_um"][i]
            .as_f64()
            .unwrap();
        assert!(
            (got - exact - eps * (p - datum) * 1e6).abs() < 0.01,
            "{got} {exact}"
        );
    }
    // The ISO systematic error E↑ spans the injected slope over the targets (50 mm · 40 µm/m
    // plus the instrument's 1.85 ppm).
    let span = (40e-6 + eps) * 0.05 * 1e6;
    assert!(
        (iso.e_forward_um - span).abs() < 0.01,
        "{} vs {span}",
        iso.e_forward_um
    );
    // Without backlash the repeatability is the noise's and the servo's, a few nm.
    assert!(iso.r_forward_um < 0.01, "{}", iso.r_forward_um);
}

/// A 4 µm screw backlash under semi-closed loop: every backward reading lies lower than the
/// forward ones by the backlash the tool sees, b + 2F/k (truth's `backlash_seen_um` at the
/// test feed), and the ISO reversal value B equals it.
#[test]
fn backlash_gives_the_reversal_value() {
    let m = machine(0.0);
    let axes = [
        common::axis(250.0, 4e-6, 33.0),
        common::axis(450.0, 0.0, 33.0),
        common::axis(180.0, 0.0, 33.0),
    ];
    let run = positioning_run(&m, axes, spec(0.0));
    let laser = run.laser.as_ref().unwrap();
    let iso = laser.iso230_2();
    let seen = run.ground_truth["drives"]["x"]["backlash_seen_um"]
        .as_f64()
        .unwrap();
    eprintln!(
        "B = {:.4} um, B_i = {:?}, seen {seen:.4} um, R = {:.4} um",
        iso.b_um, iso.reversal_um, iso.r_um
    );
    for b in &iso.reversal_um {
        // Forward minus backward: the carriage lags behind the motor in both directions.
        assert!((b + seen).abs() < 0.05, "B_i {b} vs -{seen}");
    }
    assert!((iso.b_um - seen).abs() < 0.05, "{} vs {seen}", iso.b_um);
    let truth = &run.ground_truth["laser"]["iso230_2_exact"]["b_um"];
    assert!((truth.as_f64().unwrap() - iso.b_um).abs() < 0.01);
}

/// A laser sampled faster than the servo ticks it is read at (it was clamped to the servo rate)
/// or averaging over less than its sample interval (no sample: it read 0) is refused before
/// the run.
#[test]
fn a_laser_faster_than_the_servo_or_with_an_empty_window_is_refused_before_the_run() {
    let m = machine(0.0);
    let axes = [
        common::axis(250.0, 0.0, 33.0),
        common::axis(450.0, 0.0, 33.0),
        common::axis(180.0, 0.0, 33.0),
    ];
    let ipo = InterpolatorConfig::new(Limits::default());
    for (spec, message) in [
        (
            LaserSpec {
                sample_rate_hz: 10_000.0,
                ..spec(0.0)
            },
            "laser sample rate 10000 Hz: from 0 to the servo rate 8000 Hz is accepted",
        ),
        (
            LaserSpec {
                averaging_s: 0.5e-3,
                ..spec(0.0)
            },
            "laser averaging time 0.0005 s: it holds no sample at one sample every 0.001 s; at least 0.001 s is accepted",
        ),
    ] {
        let mut started = false;
        let job = positioning_job(spec);
        let e = simulate(&m, &axes, &ipo, &job, &SETTINGS, "", &mut |_| {
            started = true
        })
        .unwrap_err();
        assert!(!started, "refused before the run");
        assert_eq!(e.to_string(), message);
    }
}

/// The shipped positioning scenario loads, and bad values are refused naming their key.
#[test]
fn positioning_scenario_loads_and_names_bad_keys() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/iso230_2_x.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let s = vmt_scenario::parse(&text, "iso230_2_x.toml", None).unwrap();
    let laser = s.execution.unwrap().job.laser.unwrap();
    assert_eq!(laser.test.targets_m.len(), 11);
    assert_eq!(laser.measurements.len(), 11 * 2 * 5);
    assert!((laser.test.targets_m[1] - 0.07).abs() < 1e-12);
    for (from, to, key) in [
        ("count = 11", "count = 1", "job.count"),
        ("axis = \"X\"", "axis = \"W\"", "job.axis"),
        (
            "averaging_s = 1.0",
            "averaging_s = 3.0",
            "instruments.laser.averaging_s",
        ),
        ("overrun_mm = 5.0", "overrun_mm = -5.0", "job.overrun_mm"),
        (
            "noise_nm = 20.0",
            "noise_nm = -1.0",
            "instruments.laser.noise_nm",
        ),
    ] {
        assert!(text.contains(from), "{from}");
        let e = vmt_scenario::parse(&text.replace(from, to), "f.toml", None).unwrap_err();
        assert_eq!(e.key.as_deref(), Some(key), "{e}");
        assert!(e.position.is_some(), "{e}");
    }
}
