//! ISO 230-2 positioning runs with the laser interferometer on the simulated machine: an injected
//! scale error comes back in the mean deviations, the weather station's errors and a dead path
//! in warming air in the readings as their closed forms give them, and a screw backlash in the
//! reversal value read at rest.

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

/// A short X test at `feed_mm_min`: three targets 25 mm apart, three runs, 2 s dwells averaged
/// over the last 1 s (the carriage settles for a few tenths of a second after it stops).
fn test_at(feed_mm_min: f64) -> PositioningTest {
    PositioningTest {
        axis: Axis::X,
        targets_m: vec![0.1, 0.125, 0.15],
        line_m: Vector3::new(0.0, 0.2, 0.2),
        runs: 3,
        dwell_s: 2.0,
        feed_m_s: feed_mm_min / 60_000.0,
        overrun_m: 0.005,
    }
}

/// The short X test at 3000 mm/min.
fn test() -> PositioningTest {
    test_at(3000.0)
}

fn positioning_job(spec: LaserSpec) -> Job {
    positioning_job_at(spec, 3000.0)
}

fn positioning_job_at(spec: LaserSpec, feed_mm_min: f64) -> Job {
    let t = test_at(feed_mm_min);
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
    positioning_run_at(m, axes, spec, 3000.0)
}

fn positioning_run_at(
    m: &Machine,
    axes: [AxisDynamics; 3],
    spec: LaserSpec,
    feed_mm_min: f64,
) -> Run {
    let ipo = InterpolatorConfig::new(Limits::default());
    let job = positioning_job_at(spec, feed_mm_min);
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
/// mean deviations are ΔEXX + ε·(P − datum), ε = 2 K × 0.925 ppm/K = 1.85 ppm (by hand, not
/// from `scale_error`); the truth's error-chain deviations are ΔEXX exactly, its noise-free
/// deviations differ from the readings by the ε term only, and its drive share has no lost
/// motion.
///
/// Catches: an EXX that does not reach the tool point or the laser, a scale error of the wrong
/// sign or size on the readings, a truth chain that includes the drives, a truth that gives a
/// drive on a linear scale the screw's lost motion.
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
    // By hand: 2 K × 0.925 ppm/K (the weather test below derives the 0.925).
    let eps = 2.0 * 0.925e-6;
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
    // The linear scale holds the carriage itself: no lost motion at rest (the screw's would be
    // 2F/k, 0.7 µm), only where the loop leaves the carriage, a few nm, as the readings show.
    assert_eq!(
        truth["reversal_at_rest_bounds_um"],
        serde_json::json!([0.0, 0.0])
    );
    let drive_b = truth["iso230_2_drive"]["b_um"].as_f64().unwrap();
    assert!(drive_b < 0.02, "{drive_b}");
    assert!(
        (drive_b - iso.b_um).abs() < 0.003,
        "{drive_b} vs {}",
        iso.b_um
    );
}

/// A laser without noise or quantisation, to check its compensation at float precision.
fn exact_laser() -> LaserSpec {
    LaserSpec {
        noise_m: 0.0,
        resolution_m: 0.0,
        ..LaserSpec::default()
    }
}

/// Drives without backlash, X on a linear scale.
fn scale_axes() -> [AxisDynamics; 3] {
    let mut x = common::axis(250.0, 0.0, 33.0);
    x.drive.feedback = Feedback::LinearScale { resolution_m: 1e-9 };
    [
        x,
        common::axis(450.0, 0.0, 33.0),
        common::axis(180.0, 0.0, 33.0),
    ]
}

/// Reading minus noise-free deviation of every reading of `run`, µm, with its target (m) and
/// the noise-free deviation (µm).
fn instrument_error_um(run: &Run) -> Vec<(f64, f64, f64)> {
    let laser = run.laser.as_ref().unwrap();
    let exact = run.ground_truth["laser"]["exact_deviation_um"]
        .as_array()
        .unwrap();
    laser
        .readings
        .iter()
        .zip(exact)
        .map(|(r, e)| {
            let e = e.as_f64().unwrap();
            (r.target_mm * 1e-3, e, r.deviation_um - e)
        })
        .collect()
}

/// Each weather-station error scales every reading about the datum by the sensitivity of the
/// air's refractive index to it, worked out here by hand from the refractivity of standard air
/// at 633 nm, 20 °C, 1013.25 hPa, `n − 1 = 2.71e-4` (Edlén 1966, Metrologia 2:71; Birch &
/// Downs 1993, Metrologia 30:155): the station's error makes the laser assume
/// `n + Δn` and read `L n/(n + Δn)`, a scale error `ε = −Δn`.
/// - +1 hPa: `Δn = (n − 1)/p = 2.71e-4/1013.25 hPa`, `ε = −0.2675 ppm`;
/// - +10 %RH: water vapour lowers n by `(3.7345 − 0.0401 σ²)·1e-10 = 3.634e-10` per Pa
///   (Birch & Downs, σ = 1/0.633 µm⁻¹) and 10 %RH at 20 °C is 233.9 Pa (saturation 2339 Pa),
///   so `ε = +0.0850 ppm`;
/// - +1 K: `Δn = −(n − 1)/T = −2.71e-4/293.15 K`, `ε = +0.9245 ppm`;
/// - a material sensor 1 K warm with α = 11.5e-6/K over-corrects: `ε = −11.5 ppm`;
/// - all four together: their sum.
///
/// With a noise-free, unquantised laser, reading minus noise-free deviation is
/// `ε (P − datum + x)` for every reading, checked to 0.1 % of ε (the implemented sensitivities
/// are these rounded to four digits).
///
/// Catches: a pressure or humidity term of the wrong sign (the pressure term flipped gives
/// +0.2675 ppm), in Pa instead of hPa, or in fractions instead of percent; the two swapped;
/// a scale error applied to the absolute position instead of the distance from the datum.
#[test]
fn weather_station_errors_scale_the_readings_by_the_air_sensitivities() {
    let m = machine(0.0);
    let n_minus_1 = 2.71e-4;
    let per_hpa = n_minus_1 / 1013.25;
    let per_percent = (3.7345 - 0.0401 / 0.633f64.powi(2)) * 1e-10 * 2339.0 / 100.0;
    let per_kelvin = n_minus_1 / 293.15;
    let cases = [
        (
            "+1 hPa",
            LaserSpec {
                air_pressure_error_hpa: 1.0,
                ..exact_laser()
            },
            -per_hpa,
        ),
        (
            "+10 %RH",
            LaserSpec {
                humidity_error_percent: 10.0,
                ..exact_laser()
            },
            10.0 * per_percent,
        ),
        (
            "+1 K air",
            LaserSpec {
                air_temperature_error_k: 1.0,
                ..exact_laser()
            },
            per_kelvin,
        ),
        (
            "+1 K material",
            LaserSpec {
                material_temperature_error_k: 1.0,
                ..exact_laser()
            },
            -11.5e-6,
        ),
        (
            "all four",
            LaserSpec {
                air_pressure_error_hpa: 1.0,
                humidity_error_percent: 10.0,
                air_temperature_error_k: 1.0,
                material_temperature_error_k: 1.0,
                ..exact_laser()
            },
            -per_hpa + 10.0 * per_percent + per_kelvin - 11.5e-6,
        ),
    ];
    assert!(
        (-per_hpa * 1e6 + 0.2675).abs() < 1e-3 && (10.0 * per_percent * 1e6 - 0.085).abs() < 1e-3
    );
    let datum = test().datum_m();
    for (name, spec, eps) in cases {
        let run = positioning_run(&m, scale_axes(), spec);
        for (target, x_um, got_um) in instrument_error_um(&run) {
            let expected_um = eps * (target - datum + x_um * 1e-6) * 1e6;
            assert!(
                (got_um - expected_um).abs() < 1e-3 * expected_um.abs(),
                "{name}: at {target} m the reading is {got_um} um off, {expected_um} um by hand (ε = {} ppm)",
                eps * 1e6
            );
        }
    }
}

/// Dead path: the 100 mm of beam between the interferometer and the reflector at the datum is
/// not in the displacement the compensation scales, so when the air warms after the laser is
/// zeroed, the optical path of the dead path shortens by `(∂n/∂T) D ΔT` unseen (the deadpath
/// error of displacement interferometry, Bobroff 1993, Meas. Sci. Technol. 4:907) and every
/// later reading is short by `0.925e-6/K · D · drift · (t − t0)`, t the middle of its
/// averaging window and t0 the zeroing (the end of the datum's window, when the axis leaves
/// the datum). With D = 0.1 m and the air warming at 0.6 K/min (far more than a shop's, so that
/// the term stands out) that is 0.925 nm per second, 0.035 µm at the last reading, 40.6 s in.
/// With a noise-free, unquantised laser and no weather error, reading minus noise-free
/// deviation is that offset alone, checked to 1e-5 µm (the zeroing instant is taken from the
/// 1 kHz log of the command, within a millisecond: 1e-6 µm).
///
/// Catches: a dead-path term of the wrong sign or size, on the distance from the datum instead
/// of D, or with the drift counted from the start of the run instead of from the zeroing (the
/// datum reading would drift too: 4.6e-4 µm off).
#[test]
fn a_dead_path_in_warming_air_shortens_the_readings_by_the_closed_form() {
    let m = machine(0.0);
    let drift_k_per_s = 0.6 / 60.0;
    let dead_path_m = 0.1;
    let spec = LaserSpec {
        dead_path_m,
        air_drift_k_per_s: drift_k_per_s,
        ..exact_laser()
    };
    let ipo = InterpolatorConfig::new(Limits::default());
    let settings = SimSettings {
        log_rate_hz: 1000.0,
        ..SETTINGS
    };
    let job = positioning_job(spec);
    let run = simulate(&m, &scale_axes(), &ipo, &job, &settings, "", &mut |_| {}).unwrap();
    // The zeroing: the datum dwell ends when the command sets off for the first target.
    let servo = run.streams.iter().find(|s| s.name == "servo").unwrap();
    let command = &servo.channel("command_x").unwrap().values;
    let datum = test().datum_m();
    let leave = command.iter().position(|&c| c > datum + 1e-9).unwrap();
    let zeroed_s = servo.times_s[leave] - 0.5e-3;
    let laser = run.laser.as_ref().unwrap();
    let errors = instrument_error_um(&run);
    let last = laser.readings.last().unwrap().time_s;
    assert!(last > 40.0, "the test runs {last} s");
    for (r, (_, _, got_um)) in laser.readings.iter().zip(errors) {
        let middle_s = r.time_s - 0.5 * spec.averaging_s;
        let expected_um = -0.925e-6 * dead_path_m * drift_k_per_s * (middle_s - zeroed_s) * 1e6;
        assert!(
            (got_um - expected_um).abs() < 1e-5,
            "reading at {} s: {got_um} um off, {expected_um} um by hand",
            r.time_s
        );
    }
}

/// A 4 µm screw backlash under semi-closed loop, read at rest after each dwell: the carriage
/// lags behind the nut in both directions, so every backward reading lies higher than the
/// forward ones (B_i = x̄↑ − x̄↓ < 0) by the screw's lost motion at standstill,
/// `B = b + (F_h↑ + F_h↓)/k`, where `F_h` is the guideway friction that holds the carriage
/// still. No viscous friction acts at rest, so B is the same at 1000, 3000 and 6000 mm/min
/// (within 0.01 µm), and the LuGre bristles hold the resting carriage between the Coulomb and
/// the static force (they stop near F_s, and the servo's hunting by an encoder count relaxes
/// them to about 62.6 N over the 2 s dwells), so
/// `b + 2 F_c/k <= B <= b + 2 F_s/k`: 4.5556 to 4.7222 µm with b = 4 µm, k = 180 N/µm,
/// F_c = 50 N, F_s = 65 N (the drives of `common::axis`), worked out here by hand. The moving
/// figure `b + 2 (F_c + σ2 v)/k` would be 4.593, 4.667 and 4.778 µm at those feeds.
///
/// Catches: a truth that reads the reversal at the feed (with the viscous `σ2 v`, as the
/// ball bar's `backlash_seen_um` does: off by 0.09 µm at 1000 and 6000 mm/min, 0.02 at 3000) or drops
/// the gap or the factor 2 of the stretch; a drive that does not take up the gap or the
/// stretch at a reversal, or a friction that holds a resting carriage outside [F_c, F_s].
#[test]
fn backlash_gives_the_reversal_value_at_rest_whatever_the_feed() {
    let m = machine(0.0);
    let axes = || {
        [
            common::axis(250.0, 4e-6, 33.0),
            common::axis(450.0, 0.0, 33.0),
            common::axis(180.0, 0.0, 33.0),
        ]
    };
    // By hand, from common::axis: b = 4 µm, k = 1.8e8 N/m, F_c = 50 N, F_s = 65 N.
    let (b_um, k_n_per_um, coulomb_n, static_n) = (4.0, 180.0, 50.0, 65.0);
    let lowest = b_um + 2.0 * coulomb_n / k_n_per_um;
    let highest = b_um + 2.0 * static_n / k_n_per_um;
    let mut reversals = Vec::new();
    for feed in [1000.0, 3000.0, 6000.0] {
        let run = positioning_run_at(&m, axes(), spec(0.0), feed);
        let iso = run.laser.as_ref().unwrap().iso230_2();
        let truth = &run.ground_truth["laser"];
        let f = |v: &serde_json::Value| v.as_f64().unwrap();
        let drive = f(&truth["iso230_2_drive"]["b_um"]);
        let bounds = [
            f(&truth["reversal_at_rest_bounds_um"][0]),
            f(&truth["reversal_at_rest_bounds_um"][1]),
        ];
        let holding: Vec<f64> = truth["holding_force_n"]
            .as_array()
            .unwrap()
            .iter()
            .map(f)
            .collect();
        eprintln!(
            "{feed} mm/min: B = {:.4} um, B_i = {:?}, truth at rest {drive:.4} um, bounds {bounds:?}, holding {:.1} to {:.1} N, R = {:.4} um",
            iso.b_um,
            iso.reversal_um,
            holding
                .iter()
                .map(|h| h.abs())
                .fold(f64::INFINITY, f64::min),
            holding.iter().map(|h| h.abs()).fold(0.0, f64::max),
            iso.r_um
        );
        assert!(
            (bounds[0] - lowest).abs() < 1e-9 && (bounds[1] - highest).abs() < 1e-9,
            "{bounds:?} vs [{lowest}, {highest}]"
        );
        assert!(
            lowest <= iso.b_um && iso.b_um <= highest,
            "B {} outside [{lowest}, {highest}]",
            iso.b_um
        );
        // The closed form by hand from the truth's holding forces and the motor's rest
        // positions (servo residuals s): x↑ − x↓ = (s↑ − s↓) − b − (F↑ + |F↓|)/k, averaged
        // over the runs.
        let servo = truth["servo_residual_um"].as_array().unwrap();
        let readings = &run.laser.as_ref().unwrap().readings;
        let mut by_hand = [0.0; 3];
        for ((r, h), s) in readings.iter().zip(&holding).zip(servo) {
            assert!(
                (coulomb_n..=static_n).contains(&h.abs()),
                "holding force {h} N outside [{coulomb_n}, {static_n}]"
            );
            let sign = if r.direction == "forward" { 1.0 } else { -1.0 };
            let share = f(s) - sign * (b_um / 2.0 + h.abs() / k_n_per_um);
            by_hand[r.target - 1] += sign * share / 3.0;
        }
        for (b, t) in iso
            .reversal_um
            .iter()
            .zip(truth["iso230_2_drive"]["reversal_um"].as_array().unwrap())
        {
            // Forward minus backward: the carriage lags behind the nut in both directions.
            assert!(*b < -lowest, "B_i {b}");
            assert!((b - f(t)).abs() < 0.003, "B_i {b} vs truth {t}");
        }
        for (b, hand) in iso.reversal_um.iter().zip(by_hand) {
            assert!((b - hand).abs() < 0.003, "B_i {b} vs {hand} by hand");
        }
        assert!((drive - iso.b_um).abs() < 0.003, "{drive} vs {}", iso.b_um);
        // The noise-free tool point has no other share of the reversal (no error chain here).
        let exact = f(&truth["iso230_2_exact"]["b_um"]);
        assert!((exact - drive).abs() < 1e-4, "{exact} vs {drive}");
        reversals.push((iso.b_um, drive));
    }
    for (b, drive) in &reversals[1..] {
        assert!((b - reversals[0].0).abs() < 0.01, "{reversals:?}");
        assert!((drive - reversals[0].1).abs() < 0.01, "{reversals:?}");
    }
}

/// The Z head hangs on its screw (no counterweight): its weight, 180 kg · 9.81 m/s² = 1765 N,
/// outweighs any friction the guideways can hold (65 N), so the nut stays on its lower flank in
/// both directions and a reversal at rest shows the stretch alone, `(F_h↑ + F_h↓)/k`, between
/// `2 F_c/k` = 0.5556 and `2 F_s/k` = 0.7222 µm (by hand), however large the gap (4 µm here).
///
/// Catches: a truth that adds the gap whatever the load (4.6 µm instead of 0.7), or takes the
/// load's stretch as a reversal; a plant that lets a hanging head cross its gap.
#[test]
fn a_hanging_z_head_reverses_at_rest_without_its_gap() {
    let m = machine(0.0);
    let axes = [
        common::axis(250.0, 0.0, 33.0),
        common::axis(450.0, 0.0, 33.0),
        common::axis(180.0, 4e-6, 33.0),
    ];
    let t = PositioningTest {
        axis: Axis::Z,
        line_m: Vector3::new(0.25, 0.2, 0.0),
        ..test()
    };
    let (text, datum_block, measurements) = t.gcode();
    let program = parse(&text, t.start_point()).unwrap();
    let job = Job {
        program,
        ballbar: Vec::new(),
        laser: Some(LaserSetup {
            spec: spec(0.0),
            test: t,
            datum_block,
            measurements,
        }),
    };
    let ipo = InterpolatorConfig::new(Limits::default());
    let run = simulate(&m, &axes, &ipo, &job, &SETTINGS, "", &mut |_| {}).unwrap();
    let iso = run.laser.as_ref().unwrap().iso230_2();
    let truth = &run.ground_truth["laser"];
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    let drive = f(&truth["iso230_2_drive"]["b_um"]);
    let (lowest, highest) = (2.0 * 50.0 / 180.0, 2.0 * 65.0 / 180.0);
    eprintln!("Z: B = {:.4} um, truth at rest {drive:.4} um", iso.b_um);
    assert!((f(&truth["reversal_at_rest_bounds_um"][0]) - lowest).abs() < 1e-9);
    assert!((f(&truth["reversal_at_rest_bounds_um"][1]) - highest).abs() < 1e-9);
    assert!(
        lowest <= iso.b_um && iso.b_um <= highest,
        "B {} outside [{lowest}, {highest}]",
        iso.b_um
    );
    assert!((drive - iso.b_um).abs() < 0.003, "{drive} vs {}", iso.b_um);
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

/// The shipped positioning run of X (`scenarios/iso230_2_x.toml`): its reversal is the error
/// chain's (a 2 µm EXX backlash and the table's yaw backlash at the beam's height) plus the
/// drive's at rest, target by target, and the drive's lies between `b + 2 F_c/k` = 1.5556 and
/// `b + 2 F_s/k` = 1.7222 µm with the scenario's b = 1 µm, k = 180 N/µm, F_c = 50 N,
/// F_s = 65 N (by hand); the readings' B is the truth's within the noise.
///
/// Catches: a drive share that counts the chain's reversal again or has the wrong sign, a
/// truth that reads the shipped drive's reversal at the feed (1.6667 µm), a chain share
/// that includes the drives.
#[test]
fn shipped_positioning_reversal_is_the_chain_s_plus_the_drive_s_at_rest() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/iso230_2_x.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let s = vmt_scenario::parse(&text, "iso230_2_x.toml", None).unwrap();
    let exec = s.execution.as_ref().unwrap();
    let run = exec.simulate(&s.machine, &text, &mut |_| {}).unwrap();
    let truth = &run.ground_truth["laser"];
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    let reversals = |key: &str| -> Vec<f64> {
        truth[key]["reversal_um"]
            .as_array()
            .unwrap()
            .iter()
            .map(f)
            .collect()
    };
    let (exact, chain, drive) = (
        reversals("iso230_2_exact"),
        reversals("iso230_2_chain"),
        reversals("iso230_2_drive"),
    );
    assert_eq!(exact.len(), 11);
    let (lowest, highest) = (1.0 + 2.0 * 50.0 / 180.0, 1.0 + 2.0 * 65.0 / 180.0);
    for i in 0..exact.len() {
        assert!(
            (exact[i] - chain[i] - drive[i]).abs() < 1e-3,
            "target {i}: {} = {} + {}?",
            exact[i],
            chain[i],
            drive[i]
        );
        assert!(chain[i] < -1.5, "target {i}: the chain's {}", chain[i]);
        assert!(
            lowest <= -drive[i] && -drive[i] <= highest,
            "target {i}: the drive's {} outside [{lowest}, {highest}]",
            -drive[i]
        );
    }
    let iso = run.laser.as_ref().unwrap().iso230_2();
    let b = f(&truth["iso230_2_exact"]["b_um"]);
    assert!((iso.b_um - b).abs() < 0.005, "{} vs {b}", iso.b_um);
    readings_are_the_chain_s_plus_the_drive_s(&run);
    // With a 2 µm cyclic lead error on X's screw (the first screw of the file), still reading by
    // reading: the drive's share holds the nut's cyclic error.
    let cyclic = text.replacen(
        "screw_cyclic_um = [0.0, 0.0]",
        "screw_cyclic_um = [2.0, 0.0]",
        1,
    );
    let s = vmt_scenario::parse(&cyclic, "iso230_2_x.toml", None).unwrap();
    let exec = s.execution.as_ref().unwrap();
    let run = exec.simulate(&s.machine, &cyclic, &mut |_| {}).unwrap();
    readings_are_the_chain_s_plus_the_drive_s(&run);
}

/// Every reading's noise-free deviation is the chain's share plus the drive's (both relative
/// to the datum), to 1e-3 µm. Catches: a drive share without the datum's (a constant offset,
/// which the reversals cancel), one that leaves out the screw's cyclic lead error.
fn readings_are_the_chain_s_plus_the_drive_s(run: &vmt_sim::run::Run) {
    let truth = &run.ground_truth["laser"];
    let values = |key: &str| -> Vec<f64> {
        truth[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect()
    };
    let (exact, chain, drive) = (
        values("exact_deviation_um"),
        values("chain_deviation_um"),
        values("drive_deviation_um"),
    );
    assert_eq!(exact.len(), run.laser.as_ref().unwrap().readings.len());
    for i in 0..exact.len() {
        let rest = exact[i] - chain[i] - drive[i];
        assert!(rest.abs() < 1e-3, "reading {i}: {rest} µm left over");
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
