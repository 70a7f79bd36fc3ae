//! Scenario loading: the built-in machine, tables, and one clear located error per bad input.

use std::path::Path;
use vmt_model::kinematics::AxisState;
use vmt_model::{Axis, Direction};
use vmt_scenario::{BUILTIN_DEFAULT, ScenarioError, builtin, load, parse};

fn with(replace: &str, by: &str) -> String {
    assert!(
        BUILTIN_DEFAULT.contains(replace),
        "test edit `{replace}` not found"
    );
    BUILTIN_DEFAULT.replacen(replace, by, 1)
}

fn error_of(text: &str) -> ScenarioError {
    parse(text, "machine.toml", None).expect_err("the scenario should be refused")
}

fn line_of(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).unwrap() + 1
}

fn scenarios() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios")
}

/// A shipped scenario (`scenarios/<name>`) with the first `replace` replaced by `by`.
fn shipped_with(name: &str, replace: &str, by: &str) -> String {
    let text = std::fs::read_to_string(scenarios().join(name)).unwrap();
    assert!(
        text.contains(replace),
        "test edit `{replace}` not in {name}"
    );
    text.replacen(replace, by, 1)
}

/// Asserts that `text`, read from the scenarios' folder, is refused at `key` on the line of
/// `at`, the message naming what is accepted.
fn assert_refused(text: &str, at: &str, key: &str, accepted: &str) {
    let e = parse(text, "s.toml", Some(&scenarios())).expect_err(at);
    assert_eq!(e.key.as_deref(), Some(key), "{e}");
    assert_eq!(e.position.map(|p| p.0), Some(line_of(text, at)), "{e}");
    assert!(e.message.contains(accepted), "{e}");
}

/// [`assert_refused`] for edits `(replace, by, key, accepted)` of shipped scenario `name`; the
/// refused value is on the last line of `by`.
fn assert_edits_refused(name: &str, edits: &[(&str, &str, &str, &str)]) {
    for (replace, by, key, accepted) in edits {
        let text = shipped_with(name, replace, by);
        assert_refused(&text, by.lines().last().unwrap(), key, accepted);
    }
}

#[test]
fn builtin_machine_loads_with_realistic_errors() {
    let s = builtin().unwrap();
    let m = &s.machine;
    assert_eq!(m.volumetric.kinematics.topology.to_string(), "WXYGZT");
    assert_eq!((m.axis(Axis::X).min_m, m.axis(Axis::X).max_m), (0.0, 0.5));
    let thermal = m.thermal.as_ref().unwrap();
    assert_eq!(thermal.network.node_count(), 6);
    // Volumetric error at 20 °C over the work zone: tens of µm, not nm and not mm.
    let temps = vec![20.0; 6];
    let mut worst: f64 = 0.0;
    for (x, y, z) in [
        (0.0, 0.0, 0.0),
        (0.5, 0.4, 0.4),
        (0.25, 0.2, 0.2),
        (0.5, 0.0, 0.4),
    ] {
        for d in [Direction::Forward, Direction::Backward] {
            let s = AxisState::new(nalgebra::Vector3::new(x, y, z), d);
            worst = worst.max(m.volumetric_error(&s, &temps).unwrap().amax());
        }
    }
    assert!((5e-6..100e-6).contains(&worst), "worst error {worst:e} m");
    // X backlash of the default: 2 µm on EXX.
    let exx = m
        .volumetric
        .errors
        .axis(Axis::X)
        .get(vmt_model::geometric::Component::Tx);
    assert!((exx.backlash(0.3) - 2e-6).abs() < 1e-15);
}

/// The drives, servos and ball bar of the built-in scenario in SI units, each expected value
/// converted by hand from scenarios/vmc500.toml.
#[test]
fn builtin_drive_servo_and_bar_values_arrive_in_si_units() {
    let s = builtin().unwrap();
    let exec = s
        .execution
        .as_ref()
        .expect("the built-in scenario has a job");
    // screw_stiffness_n_per_um 180, 200, 180 -> x 1e6 N/m; kv_per_s 33.0, 33.3, 33.0 (1/s as
    // written). velocity_bandwidth_hz 60 -> Kp = M·2π·60 with M the carriage plus the motor
    // inertia reflected through the 10 mm lead, J·(2π/0.010 m)² = J·394 784.176 1/m²:
    //   X: 0.003·394 784.176 = 1184.352 528 + 250 = 1434.352 528 kg -> Kp 540 738.163 804 N·s/m
    //   Y: 0.004·394 784.176 = 1579.136 704 + 450 = 2029.136 704 kg -> Kp 764 966.515 556 N·s/m
    //   Z: 0.003·394 784.176 = 1184.352 528 + 180 = 1364.352 528 kg -> Kp 514 348.785 514 N·s/m
    let expected = [
        (180e6, 33.0, 1_434.352_528_131, 540_738.163_804),
        (200e6, 33.3, 2_029.136_704_174, 764_966.515_556),
        (180e6, 33.0, 1_364.352_528_131, 514_348.785_514),
    ];
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-11 * b.abs();
    // Guide Coulomb forces 50, 70, 40 N as written; both frictions: stribeck_mm_s 1.0 ->
    // 1e-3 m/s, bristle_stiffness_n_per_um 20 -> 2e7 N/m.
    let coulomb = [50.0, 70.0, 40.0];
    for (k, (axis, (stiffness, kv, mass, kp))) in exec.axes.iter().zip(expected).enumerate() {
        let d = &axis.drive;
        assert!(close(d.screw.lead_m, 0.010), "{k}: lead {}", d.screw.lead_m);
        assert!(close(d.screw.stiffness_n_per_m, stiffness), "{k}: {d:?}");
        assert!(close(d.total_mass_kg(), mass), "{k}: {}", d.total_mass_kg());
        for f in [&d.guide_friction, &d.screw_friction] {
            assert!(close(f.stribeck_m_s, 1e-3), "{k}: {f:?}");
            assert!(close(f.sigma0_n_per_m, 2e7), "{k}: {f:?}");
        }
        assert_eq!(d.guide_friction.coulomb_n, coulomb[k]);
        assert!(close(axis.servo.kv_per_s, kv), "{k}: {:?}", axis.servo);
        assert!(
            close(axis.servo.velocity_kp_n_s_per_m, kp),
            "{k}: Kp {}",
            axis.servo.velocity_kp_n_s_per_m
        );
    }
    // The built-in bar has no set-up drift; one of [3.0, -1.2, 0.6] µm/min is
    // [3, -1.2, 0.6]·1e-6/60 = [5e-8, -2e-8, 1e-8] m/s.
    for b in &exec.job.ballbar {
        assert_eq!(b.spec.setup_drift_m_per_s, nalgebra::Vector3::zeros());
    }
    let text = with(
        "bar_alpha_per_k = 11.5e-6",
        "bar_alpha_per_k = 11.5e-6\nsetup_drift_um_per_min = [3.0, -1.2, 0.6]",
    );
    let s = parse(&text, "machine.toml", None).unwrap();
    let job = &s.execution.as_ref().unwrap().job;
    assert!(!job.ballbar.is_empty());
    for b in &job.ballbar {
        let v = b.spec.setup_drift_m_per_s;
        for (got, want) in v.iter().zip([5e-8, -2e-8, 1e-8]) {
            assert!(close(*got, want), "drift {v:?} m/s");
        }
    }
}

#[test]
fn unknown_topology_is_refused_with_the_accepted_form() {
    let text = with("topology = \"WXYGZT\"", "topology = \"WXXGZT\"");
    let e = error_of(&text);
    assert_eq!(e.key.as_deref(), Some("machine.topology"));
    assert_eq!(e.position.unwrap().0, line_of(&text, "topology ="));
    assert!(e.message.contains("unknown topology `WXXGZT`"), "{e}");
    assert!(e.message.contains("WGXYZT"), "{e}");
}

#[test]
fn nan_is_refused_naming_the_key() {
    let text = with("moving_mass_kg = 250.0", "moving_mass_kg = nan");
    let e = error_of(&text);
    assert_eq!(e.key.as_deref(), Some("machine.axes.x.moving_mass_kg"));
    assert_eq!(
        e.position.unwrap().0,
        line_of(&text, "moving_mass_kg = nan")
    );
    assert!(e.message.contains("NaN is not accepted"), "{e}");
}

#[test]
fn errors_inside_tagged_tables_name_the_field_and_its_line() {
    // [job], [machine.thermal.ambient] and [[machine.thermal.sources]] carry a `kind` tag.
    for (replace, by, key, message) in [
        (
            "radius_mm = 150.0",
            "radius_mm = \"150\"",
            "job.radius_mm",
            "invalid type: string \"150\", expected f64",
        ),
        (
            "radius_mm = 150.0",
            "radius_typo = 150.0",
            "job.radius_typo",
            "unknown field `radius_typo`",
        ),
        (
            "w_per_mm_s = 0.5",
            "w_per_mm_s = \"a\"",
            "machine.thermal.sources[1].w_per_mm_s",
            "invalid type: string \"a\"",
        ),
        (
            "mean_c = 20.0",
            "mean_c = [20.0]",
            "machine.thermal.ambient.mean_c",
            "invalid type: sequence, expected f64",
        ),
    ] {
        let text = with(replace, by);
        let e = error_of(&text);
        assert_eq!(e.key.as_deref(), Some(key), "{e}");
        assert_eq!(e.position.map(|p| p.0), Some(line_of(&text, by)), "{e}");
        assert!(e.message.contains(message), "{e}");
    }
    // A missing field already names itself; it is placed at its table.
    let text = with("radius_mm = 150.0", "");
    let e = error_of(&text);
    assert_eq!(e.key.as_deref(), Some("job"), "{e}");
    assert_eq!(e.position.map(|p| p.0), Some(line_of(&text, "[job]")));
    assert!(e.message.contains("missing field `radius_mm`"), "{e}");
}

#[test]
fn missing_axis_is_refused() {
    // Drop every [machine.axes.z...] table.
    let mut skipping = false;
    let text: String = BUILTIN_DEFAULT
        .lines()
        .filter(|l| {
            if l.starts_with('[') {
                skipping = l.starts_with("[machine.axes.z");
            }
            !skipping
        })
        .map(|l| format!("{l}\n"))
        .collect();
    let e = error_of(&text);
    assert!(e.message.contains("missing field `z`"), "{e}");
    assert!(e.position.is_some());
}

#[test]
fn key_in_a_wrong_unit_is_refused_listing_the_accepted_keys() {
    let text = with("stroke_mm = [0.0, 500.0]", "stroke_in = [0.0, 19.7]");
    let e = error_of(&text);
    assert_eq!(e.position.unwrap().0, line_of(&text, "stroke_in"));
    assert!(e.message.contains("unknown field `stroke_in`"), "{e}");
    assert!(e.message.contains("stroke_mm"), "{e}");
    let text = with("EXX_um = [0.0, 4.0, -1.2, 0.5]", "EXX_mm = [0.0, 0.004]");
    let e = error_of(&text);
    assert_eq!(e.key.as_deref(), Some("machine.errors.x.forward.EXX_mm"));
    assert!(e.message.contains("EXX_um"), "{e}");
}

#[test]
fn out_of_range_values_are_refused() {
    let e = error_of(&with(
        "stroke_mm = [0.0, 400.0]",
        "stroke_mm = [400.0, 0.0]",
    ));
    assert_eq!(e.key.as_deref(), Some("machine.axes.y.stroke_mm"));
    assert!(e.message.contains("min < max"), "{e}");
    let e = error_of(&with(
        "capacity_j_per_k = 23000.0",
        "capacity_j_per_k = -1.0",
    ));
    assert_eq!(
        e.key.as_deref(),
        Some("machine.thermal.nodes[0].capacity_j_per_k")
    );
    let e = error_of(&with(
        "EBX_urad = [0.0, 6.0, -3.0]",
        "EBX_urad = [0.0, 60000.0]",
    ));
    assert!(e.message.contains("10000"), "{e}");
    let e = error_of(&with(
        "node = \"x_screw\"\nalpha_per_k",
        "node = \"x_scew\"\nalpha_per_k",
    ));
    assert!(e.message.contains("no thermal node `x_scew`"), "{e}");
    let e = error_of(&with(
        "[machine.thermal.links.\"Z-T\"]",
        "[machine.thermal.links.\"X-T\"]",
    ));
    assert!(e.message.contains("W-X, X-Y, Y-G, G-Z, Z-T"), "{e}");
    // Servo settings beyond any drive's are refused at their key with the range, the value as
    // typed (not 307 digits).
    let e = error_of(&with("kv_per_s = 33.0", "kv_per_s = 0.0"));
    assert_eq!(e.key.as_deref(), Some("machine.axes.x.servo.kv_per_s"));
    assert!(e.message.contains("from 0.1 to 1000"), "{e}");
    let e = error_of(&with(
        "velocity_bandwidth_hz = 60.0",
        "velocity_bandwidth_hz = 1e306",
    ));
    assert!(e.message.starts_with("1e306 is out of range"), "{e}");
    let e = error_of(&with(
        "current_time_constant_ms = 0.5",
        "current_time_constant_ms = 1e-47",
    ));
    assert_eq!(
        e.key.as_deref(),
        Some("machine.axes.x.servo.current_time_constant_ms")
    );
    // Drive and controller numbers beyond any machine's, which the step and loop checks could
    // not evaluate, are refused at their own keys.
    let e = error_of(&with("screw_lead_mm = 10.0", "screw_lead_mm = 1e-300"));
    assert_eq!(e.key.as_deref(), Some("machine.axes.x.drive.screw_lead_mm"));
    let e = error_of(&with(
        "servo_period_us = 125.0",
        "servo_period_us = 0.000001",
    ));
    assert_eq!(e.key.as_deref(), Some("controller.servo_period_us"));
    assert!(e.message.contains("from 10 to 10000"), "{e}");
}

fn write_scenario_with_table(dir: &Path, rows: &str) -> std::path::PathBuf {
    std::fs::write(dir.join("x.csv"), rows).unwrap();
    let text = with(
        "[machine.errors.x.forward]\nEXX_um = [0.0, 4.0, -1.2, 0.5]\nEYX_um = [0.0, 0.0, 2.0]\nEZX_um = [0.0, 0.0, -3.0, 0.6]\nEAX_urad = [0.0, 3.0]\nEBX_urad = [0.0, 6.0, -3.0]\nECX_urad = [0.0, -4.0, 2.0]\n\n[machine.errors.x.backward]\nEXX_um = [2.0, 4.0, -1.2, 0.5]   # 2 um positional backlash\nECX_urad = [1.5, -4.0, 2.0]      # yaw backlash of the table\n",
        "[machine.errors.x.forward]\ntable = \"x.csv\"\ninterpolation = \"pchip\"\n",
    );
    let path = dir.join("m.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn compensation_tables_load_and_interpolate() {
    let dir = tempfile::tempdir().unwrap();
    let rows =
        "X, EXX, EYX, EZX, EAX, EBX, ECX\n0,0,0,0,0,0,0\n250,3.0,1,0,0,5,0\n500,4.0,0,0,0,10,0\n";
    let s = load(&write_scenario_with_table(dir.path(), rows)).unwrap();
    let x = s.machine.volumetric.errors.axis(Axis::X);
    let exx = x.get(vmt_model::geometric::Component::Tx);
    assert!((exx.forward.eval(0.25) - 3e-6).abs() < 1e-18);
    // No backward section: the backward functions are the forward ones.
    assert_eq!(exx.backlash(0.1), 0.0);
}

#[test]
fn table_positions_that_do_not_increase_are_refused_with_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let rows = "X,EXX,EYX,EZX,EAX,EBX,ECX\n0,0,0,0,0,0,0\n300,1,0,0,0,0,0\n250,2,0,0,0,0,0\n500,0,0,0,0,0,0\n";
    let e = load(&write_scenario_with_table(dir.path(), rows)).unwrap_err();
    assert!(e.file.ends_with("x.csv"), "{e}");
    assert_eq!(e.position, Some((4, 1)));
    assert!(e.message.contains("250 mm after 300 mm"), "{e}");
    let rows = "X,EXX,EYX,EAX,EBX,ECX\n0,0,0,0,0,0\n500,0,0,0,0,0\n";
    let e = load(&write_scenario_with_table(dir.path(), rows)).unwrap_err();
    assert!(e.message.contains("missing column EZX"), "{e}");
    let rows = "X,EXX,EYX,EZX,EAX,EBX,ECX\n0,0,0,0,0,0,0\n400,0,0,0,0,0,0\n";
    let e = load(&write_scenario_with_table(dir.path(), rows)).unwrap_err();
    assert!(e.message.contains("must cover the stroke"), "{e}");
    assert_eq!(e.key.as_deref(), Some("machine.errors.x.forward.table"));
    let rows = "X,EXX,EYX,EZX,EAX,EBX,ECX\n0,0,0,0,0,0,0\n500,0,0,0,0,0,2e4\n";
    let e = load(&write_scenario_with_table(dir.path(), rows)).unwrap_err();
    assert_eq!(e.position, Some((3, 7)));
    assert!(
        e.message
            .contains("ECX: 20000 µrad is beyond the accepted ±10000 µrad"),
        "{e}"
    );
}

#[test]
fn the_display_names_file_line_column_and_key() {
    let text = with("moving_mass_kg = 450.0", "moving_mass_kg = -450.0");
    let e = error_of(&text);
    let line = line_of(&text, "moving_mass_kg = -450.0");
    assert_eq!(
        e.to_string(),
        format!(
            "machine.toml:{line}:18: key `machine.axes.y.moving_mass_kg`: -450 is out of range; a mass in kg from 0 to 100000 is accepted"
        )
    );
}

#[test]
fn a_value_of_the_wrong_type_or_length_names_its_key() {
    let text = with("moving_mass_kg = 250.0", "moving_mass_kg = \"heavy\"");
    let e = error_of(&text);
    assert_eq!(
        e.key.as_deref(),
        Some("machine.axes.x.moving_mass_kg"),
        "{e}"
    );
    assert_eq!(e.position.unwrap().0, line_of(&text, "\"heavy\""));
    assert!(e.message.contains("expected f64"), "{e}");
    let text = with("stroke_mm = [0.0, 500.0]", "stroke_mm = [0.0, 500.0, 9.0]");
    let e = error_of(&text);
    assert_eq!(e.key.as_deref(), Some("machine.axes.x.stroke_mm"), "{e}");
    assert_eq!(e.position.unwrap().0, line_of(&text, "9.0]"));
    assert!(
        e.message
            .contains("invalid length 3, expected an array of 2 numbers"),
        "{e}"
    );
}

/// A controller clamps a programmed feed to its maximum, and samples the ball bar at servo
/// ticks: a test above either is refused at its key, not run slower than it is labelled.
#[test]
fn a_test_feed_or_sample_rate_beyond_the_controller_is_refused() {
    let text = with("feed_mm_min = 1000.0", "feed_mm_min = 50000.0");
    let e = error_of(&text);
    assert_eq!(e.key.as_deref(), Some("job.feed_mm_min"), "{e}");
    assert_eq!(
        e.position.map(|p| p.0),
        Some(line_of(&text, "feed_mm_min = 50000.0")),
        "{e}"
    );
    assert!(
        e.message
            .contains("largest feed is 10000 mm/min (controller.max_feed_mm_min)"),
        "{e}"
    );
    let text = with("sample_rate_hz = 1000.0", "sample_rate_hz = 1e9");
    let e = error_of(&text);
    assert_eq!(
        e.key.as_deref(),
        Some("instruments.ballbar.sample_rate_hz"),
        "{e}"
    );
    assert!(e.message.contains("at most 8000 Hz"), "{e}");
    // At the limits they run.
    let text = with("feed_mm_min = 1000.0", "feed_mm_min = 10000.0");
    assert!(parse(&text, "machine.toml", None).is_ok());
}

/// A generated test program that would leave a stroke is refused at load, at the job's keys,
/// with the axis and how far it would go.
#[test]
fn a_test_circle_beyond_a_stroke_is_refused_at_the_job() {
    let text = with("radius_mm = 150.0", "radius_mm = 300.0");
    let e = error_of(&text);
    assert_eq!(e.key.as_deref(), Some("job.center_mm"), "{e}");
    assert!(
        e.message.contains(
            "the test takes the Y axis from -100.000 to 500.000 mm, beyond its stroke 0 to 400 mm"
        ) && e
            .message
            .contains("move the centre or shorten job.radius_mm"),
        "{e}"
    );
}

/// A circular test's bad value is refused at its own key of [job].
#[test]
fn a_bad_test_value_is_refused_at_its_key() {
    let e = error_of(&with("radius_mm = 150.0", "radius_mm = -150.0"));
    assert_eq!(e.key.as_deref(), Some("job.radius_mm"), "{e}");
    let e = error_of(&with("arc_deg = 360.0", "arc_deg = 400.0"));
    assert_eq!(e.key.as_deref(), Some("job.arc_deg"), "{e}");
}

#[test]
fn an_implausible_bar_temperature_is_refused() {
    let e = error_of(&with(
        "bar_temperature_c = 20.0",
        "bar_temperature_c = 2000.0",
    ));
    assert_eq!(
        e.key.as_deref(),
        Some("instruments.ballbar.bar_temperature_c"),
        "{e}"
    );
    assert!(e.message.contains("from -50 to 150"), "{e}");
}

#[test]
fn an_empty_program_is_refused_naming_its_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("empty.nc"), "(nothing but a comment)\n").unwrap();
    let job = "kind = \"ballbar\"\nplane = \"XY\"\ncenter_mm = [250.0, 200.0, 200.0]\n\
               radius_mm = 150.0\nfeed_mm_min = 1000.0\narc_deg = 360.0\n\
               directions = [\"cw\", \"ccw\"]\n";
    let text = with(job, "kind = \"program\"\nprogram = \"empty.nc\"\n");
    let path = dir.path().join("s.toml");
    std::fs::write(&path, text).unwrap();
    let e = load(&path).expect_err("refused");
    assert!(e.file.ends_with("empty.nc"), "{e}");
    assert!(e.message.contains("no blocks to run"), "{e}");
}

/// A test feed the controller would slow down on the circle (v²/r at 90 % of the plane axes'
/// acceleration) is refused at load: 0.05 m/s² on 150 mm allows √(0.9 · 0.05 · 0.15) m/s,
/// 4929.5 mm/min.
#[test]
fn a_test_feed_beyond_the_circles_acceleration_limit_is_refused() {
    let text = with(
        "axis_accel_m_s2 = [5.0, 5.0, 5.0]",
        "axis_accel_m_s2 = [0.05, 0.05, 5.0]",
    )
    .replacen("feed_mm_min = 1000.0", "feed_mm_min = 5000.0", 1);
    let e = error_of(&text);
    assert_eq!(e.key.as_deref(), Some("job.feed_mm_min"), "{e}");
    assert!(e.message.contains("at most at 4929.5 mm/min"), "{e}");
}

/// An ISO 230-2 job's targets and runs, a ball-bar job's directions and a Kwon job's steps are
/// bounded before their program is generated (10^8 targets or runs, or 150 circles, took all
/// memory).
#[test]
fn test_programs_are_bounded_before_they_are_generated() {
    let targets = "a number of targets (ISO 230-2 asks for 5 per metre, at least 5) from 2 to 10000 is accepted";
    let runs = "a number of runs (ISO 230-2 asks for 5) from 2 to 100 is accepted";
    let list: Vec<String> = (0..10_001).map(|i| format!("{}.0", i + 1)).collect();
    let list = format!("targets_mm = [{}]", list.join(", "));
    assert_edits_refused(
        "iso230_2_x.toml",
        &[
            ("count = 11", "count = 100000000", "job.count", targets),
            ("count = 11", "count = 10001", "job.count", targets),
            ("count = 11", "count = 1", "job.count", targets),
            ("runs = 5", "runs = 100000000", "job.runs", runs),
            ("runs = 5", "runs = 1", "job.runs", runs),
            (
                "range_mm = [25.0, 475.0]       # or targets_mm = [...] (ISO recommends uneven spacing)\ncount = 11",
                &list,
                "job.targets_mm",
                "10001 targets are not accepted; a list of up to 10000 targets is accepted",
            ),
        ],
    );
    let cw = vec!["\"cw\""; 150].join(", ");
    let text = with(
        "directions = [\"cw\", \"ccw\"]",
        &format!("directions = [{cw}]"),
    );
    assert_refused(
        &text,
        "directions = [",
        "job.directions",
        "150 directions are not accepted; a list of up to 8 directions (cw, ccw) is accepted",
    );
    assert_edits_refused(
        "kwon_seven_step.toml",
        &[(
            "steps = [1, 2, 3, 4, 5, 6, 7]",
            "steps = [1, 2, 3, 4, 5, 6, 7, 1, 2, 3, 4, 5, 6, 7, 1, 2, 3, 4, 5, 6, 7, 1, 2, 3, 4, 5, 6, 7, 1]",
            "job.steps",
            "29 steps are not accepted; a list of up to 28 steps (each of 1 to 7) is accepted",
        )],
    );
}

/// Milling values that hung or took all memory (a sample rate, cut step or mode frequency that
/// makes the cut step tiny) or that no tool or sensor has are refused at their keys.
#[test]
fn milling_values_beyond_any_tool_or_sensor_are_refused_at_their_keys() {
    let rate = "a sample rate in Hz from 100 to 1000000 is accepted";
    let step = "a cut step in µs from 0.1 to 10000 is accepted";
    let window = "a supervisor window in ms (at least one accelerometer sample) from 0.05 to 10000 is accepted";
    assert_edits_refused(
        "milling_slot.toml",
        &[
            (
                "sample_rate_hz = 20000.0",
                "sample_rate_hz = 1e308",
                "instruments.accelerometer.sample_rate_hz",
                rate,
            ),
            (
                "sample_rate_hz = 20000.0",
                "sample_rate_hz = 1e7",
                "instruments.accelerometer.sample_rate_hz",
                rate,
            ),
            (
                "direction = \"down\"",
                "direction = \"down\"\nstep_us = 1e-6",
                "job.step_us",
                step,
            ),
            (
                "frequency_hz = 922.0",
                "frequency_hz = 1e9",
                "tools.T1.modes_x[0].frequency_hz",
                "a natural frequency in Hz from 0 to 100000 is accepted",
            ),
            (
                "stiffness_n_per_um = 1.340",
                "stiffness_n_per_um = 0.0",
                "tools.T1.modes_x[0].stiffness_n_per_um",
                "a stiffness in N/µm must be > 0",
            ),
            (
                "diameter_mm = 20.0",
                "diameter_mm = 1e308",
                "tools.T1.diameter_mm",
                "a diameter in mm from 0 to 1000 is accepted",
            ),
            (
                "flute_length_mm = 30.0",
                "flute_length_mm = 1e308",
                "tools.T1.flute_length_mm",
                "a flute length in mm from 0 to 1000 is accepted",
            ),
            (
                "teeth = 2",
                "teeth = 1000",
                "tools.T1.teeth",
                "a number of teeth from 1 to 500 is accepted",
            ),
            (
                "helix_deg = 0.0",
                "helix_deg = 0.0\nrunout_um = 1e308",
                "tools.T1.runout_um",
                "a run-out in µm from 0 to 1000 is accepted",
            ),
            (
                "noise_m_s2 = 0.05",
                "noise_m_s2 = 1e308",
                "instruments.accelerometer.noise_m_s2",
                "a noise RMS in m/s² from 0 to 1000 is accepted",
            ),
            (
                "supervisor_window_ms = 25.0",
                "supervisor_window_ms = 1e308",
                "job.supervisor_window_ms",
                window,
            ),
            (
                "supervisor_window_ms = 25.0",
                "supervisor_window_ms = 1e-9",
                "job.supervisor_window_ms",
                window,
            ),
        ],
    );
    // The sensor's other values, which were all reported at job.tool, at their own keys.
    assert_edits_refused(
        "milling_slot.toml",
        &[
            (
                "sample_rate_hz = 20000.0",
                "sample_rate_hz = 1",
                "instruments.accelerometer.sample_rate_hz",
                rate,
            ),
            (
                "noise_m_s2 = 0.05",
                "noise_m_s2 = -1",
                "instruments.accelerometer.noise_m_s2",
                "-1 is out of range; a noise RMS in m/s² from 0 to 1000 is accepted",
            ),
            (
                "noise_m_s2 = 0.05",
                "noise_m_s2 = 0.05\nadc_bits = 0",
                "instruments.accelerometer.adc_bits",
                "0 is out of range; a resolution in bits from 1 to 32 is accepted",
            ),
            (
                "noise_m_s2 = 0.05",
                "noise_m_s2 = 0.05\nparticipation = [nan, 0.2]",
                "instruments.accelerometer.participation[0]",
                "NaN is not accepted; a participation factor from -10 to 10 is accepted",
            ),
            (
                "noise_m_s2 = 0.05",
                "noise_m_s2 = 0.05\nparticipation = [0.2]",
                "instruments.accelerometer.participation",
                "none (0.2 for every mode) or one per mode of the tool, 2 here",
            ),
            (
                "noise_m_s2 = 0.05",
                "noise_m_s2 = 0.05\nresonance_hz = 0",
                "instruments.accelerometer.resonance_hz",
                "a resonance in Hz from 100 to 1000000 is accepted",
            ),
            (
                "noise_m_s2 = 0.05",
                "noise_m_s2 = 0.05\nanti_alias_hz = 12000.0",
                "instruments.accelerometer.anti_alias_hz",
                "an anti-alias corner in Hz (below half of sample_rate_hz) above 0 and below 10000 is accepted",
            ),
            (
                "direction = \"down\"",
                "direction = \"down\"\nstep_us = nan",
                "job.step_us",
                step,
            ),
        ],
    );
}

/// A micro end mill loads: the cut is checked with a feed per tooth within its radius.
#[test]
fn a_micro_end_mill_loads() {
    let text = shipped_with(
        "milling_slot.toml",
        "diameter_mm = 20.0",
        "diameter_mm = 0.1",
    )
    .replacen("axial_depth_mm = 0.5", "axial_depth_mm = 0.05", 1)
    .replacen("radial_depth_mm = 20.0", "radial_depth_mm = 0.1", 1);
    // The tool itself is accepted; the shipped program's 0.1 mm per tooth is too coarse for
    // it, and that is refused at the program's line, not at the tool.
    let e = parse(&text, "s.toml", Some(&scenarios())).unwrap_err();
    assert!(
        e.file.ends_with("slot.nc") && e.position == Some((5, 1)),
        "{e}"
    );
    assert!(
        e.message
            .contains("= 0.1 mm is not accepted: from 0 to the tool radius 0.05 mm"),
        "{e}"
    );
}

/// The ball bar's noise and resolution within its ±1 mm range (10^308 µm gave inf or all-zero
/// traces).
#[test]
fn ballbar_noise_and_resolution_beyond_its_range_are_refused() {
    for (replace, by, key, accepted) in [
        (
            "noise_um = 0.1",
            "noise_um = 1e308",
            "instruments.ballbar.noise_um",
            "1e308 is out of range; a noise (µm) from 0 to 100 is accepted",
        ),
        (
            "resolution_um = 0.1",
            "resolution_um = 1e308",
            "instruments.ballbar.resolution_um",
            "1e308 is out of range; a resolution (µm) from 0 to 100 is accepted",
        ),
        (
            "setup_eccentricity_um = [3.0, -2.0, 0.0]",
            "setup_eccentricity_um = [3.0, -1e308, 0.0]",
            "instruments.ballbar.setup_eccentricity_um[1]",
            "-1e308 is out of range; an offset of the pivot within the bar's range (µm) from -1000 to 1000",
        ),
        (
            "setup_eccentricity_um = [3.0, -2.0, 0.0]",
            "setup_eccentricity_um = [3.0, -2.0, 0.0]\nsetup_drift_um_per_min = [0.0, 0.0, 101.0]",
            "instruments.ballbar.setup_drift_um_per_min[2]",
            "101 is out of range; a drift of the pivot (µm/min) from -100 to 100",
        ),
    ] {
        let at = by.lines().last().unwrap();
        assert_refused(&with(replace, by), at, key, accepted);
    }
}

/// Drive values beyond any drive (traces spanning millimetres, NaN temperatures) and encoder
/// counts that are not whole are refused at their keys; friction forces that were refused at
/// the whole friction table are refused at theirs.
#[test]
fn drive_values_beyond_any_drive_are_refused_at_their_keys() {
    let drive = "machine.axes.x.drive";
    let backlash = "a backlash (µm) from 0 to 1000 is accepted";
    let counts = "a whole number of counts per revolution from 4 to 4294967296 is accepted";
    let force = "a force (N) from 0 to 100000 is accepted";
    let friction = |k: &str| format!("{drive}.guide_friction.{k}");
    for (replace, by, key, accepted) in [
        (
            "backlash_um = 1.0",
            "backlash_um = 1e308",
            format!("{drive}.backlash_um"),
            backlash,
        ),
        (
            "backlash_um = 1.0",
            "backlash_um = 5000",
            format!("{drive}.backlash_um"),
            backlash,
        ),
        (
            "encoder_counts_per_rev = 1048576",
            "encoder_counts_per_rev = 1e308",
            format!("{drive}.encoder_counts_per_rev"),
            counts,
        ),
        (
            "encoder_counts_per_rev = 1048576",
            "encoder_counts_per_rev = 0.5",
            format!("{drive}.encoder_counts_per_rev"),
            counts,
        ),
        (
            "encoder_counts_per_rev = 1048576",
            "encoder_counts_per_rev = 1048576.5",
            format!("{drive}.encoder_counts_per_rev"),
            "1048576.5 is not accepted; a whole number of counts per revolution from 4 to 4294967296 is accepted",
        ),
        (
            "torque_constant_n_m_per_a = 1.2",
            "torque_constant_n_m_per_a = 1e-300",
            format!("{drive}.torque_constant_n_m_per_a"),
            "a torque constant (N·m/A) from 0.001 to 1000 is accepted",
        ),
        (
            "feedback = \"motor_encoder\"",
            "feedback = \"linear_scale\"\nscale_resolution_nm = 1e308",
            format!("{drive}.scale_resolution_nm"),
            "a resolution (nm) from 0.001 to 10000 is accepted",
        ),
        (
            "static_n = 65.0",
            "static_n = 1e308",
            friction("static_n"),
            force,
        ),
        (
            "coulomb_n = 50.0",
            "coulomb_n = 1e308",
            friction("coulomb_n"),
            force,
        ),
        (
            "static_n = 65.0",
            "static_n = 45.0",
            friction("static_n"),
            "the static force 45 N is below the Coulomb force 50 N",
        ),
        (
            "viscous_n_s_per_m = 200.0",
            "viscous_n_s_per_m = 1e308",
            friction("viscous_n_s_per_m"),
            "a viscous coefficient (N·s/m) from 0 to 1000000 is accepted",
        ),
        (
            "bristle_damping_n_s_per_m = 3.0e4",
            "bristle_damping_n_s_per_m = 1e308",
            friction("bristle_damping_n_s_per_m"),
            "a damping (N·s/m) from 0 to 100000000 is accepted",
        ),
        (
            "bristle_stiffness_n_per_um = 20.0",
            "bristle_stiffness_n_per_um = 1e308",
            friction("bristle_stiffness_n_per_um"),
            "a bristle stiffness (N/µm) from 0.01 to 100000 is accepted",
        ),
        (
            "stribeck_mm_s = 1.0",
            "stribeck_mm_s = 1e308",
            friction("stribeck_mm_s"),
            "a Stribeck velocity (mm/s) from 0.001 to 1000 is accepted",
        ),
        (
            "stribeck_mm_s = 1.0,",
            "stribeck_mm_s = 1.0, stribeck_exponent = 1e308,",
            friction("stribeck_exponent"),
            "a Stribeck exponent from 0.1 to 10 is accepted",
        ),
    ] {
        assert_refused(
            &with(replace, by),
            by.lines().last().unwrap(),
            &key,
            accepted,
        );
    }
}

/// The laser: a rate above the servo rate was clamped to it and an averaging window with no
/// sample read 0; both are refused like the ball bar's rate. Its other values are bounded to
/// what an interferometer and its sensors can be.
#[test]
fn laser_values_it_cannot_have_are_refused_at_their_keys() {
    let laser = "instruments.laser";
    let key = |k: &str| format!("{laser}.{k}");
    let window = "the averaging window holds no sample";
    for (replace, by, key, accepted) in [
        (
            "sample_rate_hz = 1000.0",
            "sample_rate_hz = 1e308",
            key("sample_rate_hz"),
            "1e308 Hz is not accepted: the laser is sampled at servo ticks, at most 8000 Hz (1 / controller.servo_period_us)",
        ),
        (
            "averaging_s = 1.0 ",
            "averaging_s = 1e-9 ",
            key("averaging_s"),
            "1e-9 s is not accepted: the averaging window holds no sample; the laser samples every 0.001 s (every 8 servo ticks at instruments.laser.sample_rate_hz = 1000 Hz), so at least 0.001 s is accepted",
        ),
        (
            "averaging_s = 1.0 ",
            "averaging_s = 0.0009 ",
            key("averaging_s"),
            window,
        ),
        (
            "sample_rate_hz = 1000.0",
            "sample_rate_hz = 1e-9",
            key("sample_rate_hz"),
            "1e-9 is out of range; a sample rate in Hz from 1 to the servo rate (1 / controller.servo_period_us) is accepted",
        ),
        (
            "resolution_nm = 1.0",
            "resolution_nm = 1e308",
            key("resolution_nm"),
            "a resolution (nm) from 0 to 1000 is accepted",
        ),
        (
            "noise_nm = 20.0",
            "noise_nm = 1e308",
            key("noise_nm"),
            "a noise (nm) from 0 to 1000 is accepted",
        ),
        (
            "dead_path_mm = 100.0",
            "dead_path_mm = 1e308",
            key("dead_path_mm"),
            "a dead path (mm) from 0 to 100000 is accepted",
        ),
        (
            "air_temperature_error_k = 0.5",
            "air_temperature_error_k = 1e308",
            key("air_temperature_error_k"),
            "a temperature error (K) from -30 to 30 is accepted",
        ),
        (
            "air_pressure_error_hpa = 0.0",
            "air_pressure_error_hpa = 1e308",
            key("air_pressure_error_hpa"),
            "a pressure error (hPa) from -300 to 300 is accepted",
        ),
        (
            "humidity_error_percent = 0.0",
            "humidity_error_percent = 1e308",
            key("humidity_error_percent"),
            "a humidity error (%RH) from -100 to 100 is accepted",
        ),
        (
            "material_temperature_error_k = 0.0",
            "material_temperature_error_k = -1e308",
            key("material_temperature_error_k"),
            "a temperature error (K) from -30 to 30 is accepted",
        ),
        (
            "material_alpha_per_k = 11.5e-6",
            "material_alpha_per_k = 1e308",
            key("material_alpha_per_k"),
            "an expansion coefficient (1/K) from -0.00001 to 0.0001 is accepted",
        ),
        (
            "air_drift_k_per_h = 0.2",
            "air_drift_k_per_h = 1e308",
            key("air_drift_k_per_h"),
            "an air temperature drift (K/h) from -10 to 10 is accepted",
        ),
    ] {
        let text = shipped_with("iso230_2_x.toml", replace, by);
        assert_refused(&text, by, &key, accepted);
    }
    // A window of one sample is accepted.
    let text = shipped_with(
        "iso230_2_x.toml",
        "averaging_s = 1.0 ",
        "averaging_s = 0.001 ",
    );
    parse(&text, "s.toml", None).unwrap();
}

/// The log rate is checked at load, as the run checks it; controller limits near zero, which
/// stretched a program beyond the interpolator and were blamed on [job], and a phase of the
/// ambient beyond any period are refused at their keys.
#[test]
fn log_rate_controller_limits_and_ambient_phase_are_refused_at_their_keys() {
    let log = "a log rate in Hz above 0 and up to the servo rate, 8000 (1 / controller.servo_period_us), is accepted";
    let accel = "an acceleration (m/s²) from 0.01 to 1000 is accepted";
    for (replace, by, key, accepted) in [
        (
            "log_rate_hz = 1000.0",
            "log_rate_hz = 1e308",
            "simulation.log_rate_hz",
            log,
        ),
        (
            "log_rate_hz = 1000.0",
            "log_rate_hz = 8001",
            "simulation.log_rate_hz",
            log,
        ),
        (
            "log_rate_hz = 1000.0",
            "log_rate_hz = 0.0",
            "simulation.log_rate_hz",
            log,
        ),
        (
            "path_jerk_m_s3 = 20.0",
            "path_jerk_m_s3 = 1e-300",
            "controller.path_jerk_m_s3",
            "a jerk (m/s³) from 0.1 to 1000000 is accepted",
        ),
        (
            "path_jerk_m_s3 = 20.0",
            "path_jerk_m_s3 = 1e5",
            "controller.path_jerk_m_s3",
            "is shorter than one interpolation period (0.001 s)",
        ),
        (
            "path_accel_m_s2 = 2.0",
            "path_accel_m_s2 = 1e-300",
            "controller.path_accel_m_s2",
            accel,
        ),
        (
            "axis_accel_m_s2 = [5.0, 5.0, 5.0]",
            "axis_accel_m_s2 = [1e-300, 5.0, 5.0]",
            "controller.axis_accel_m_s2[0]",
            accel,
        ),
        (
            "rapid_mm_min = 30000.0",
            "rapid_mm_min = 1e308",
            "controller.rapid_mm_min",
            "a rapid rate (mm/min) from 1 to 1000000 is accepted",
        ),
        (
            "max_feed_mm_min = 10000.0",
            "max_feed_mm_min = 1e-300",
            "controller.max_feed_mm_min",
            "a feed (mm/min) from 1 to 1000000 is accepted",
        ),
        (
            "corner_tolerance_um = 10.0",
            "corner_tolerance_um = 1e308",
            "controller.corner_tolerance_um",
            "a tolerance (µm) from 0.001 to 10000 is accepted",
        ),
        (
            "phase_h = 0.0",
            "phase_h = 1e300",
            "machine.thermal.ambient.phase_h",
            "1e300 is out of range; a phase in h from -10000 to 10000 is accepted",
        ),
    ] {
        assert_refused(&with(replace, by), by, key, accepted);
    }
    // At the servo rate the log is accepted.
    parse(
        &with("log_rate_hz = 1000.0", "log_rate_hz = 8000"),
        "s.toml",
        None,
    )
    .unwrap();
}

/// Table errors name the file's line, counting blank and `#` lines the csv reader skips; a
/// column given twice is refused naming both.
#[test]
fn table_errors_name_the_line_after_blank_and_comment_lines_and_duplicate_columns() {
    let dir = tempfile::tempdir().unwrap();
    for (rows, position, message) in [
        (
            "X,EXX,EYX,EZX,EAX,EBX,ECX\n0,0,0,0,0,0,0\n\n\n500,abc,1,1,1,1,1\n",
            (5, 2),
            "column EXX: `abc` is not a finite number",
        ),
        (
            "# X table\nX,EXX,EYX,EZX,EAX,EBX,ECX\r\n# the start\r\n0,0,0,0,0,0,0\r\n\r\n# the end\r\n500,1,1,1,1,1,2e4\r\n",
            (7, 7),
            "ECX: 20000 µrad is beyond the accepted ±10000 µrad",
        ),
        (
            "X,EXX,EYX,EZX,EAX,EBX,ECX\n0,0,0,0,0,0,0\n\n# short\n500,1,1,1,1,1\n",
            (5, 1),
            "malformed row: 6 fields, the rows before have 7",
        ),
        (
            "# X table\nX,EXX,EYX,EZX,EAX,EBX\n0,0,0,0,0,0\n500,0,0,0,0,0\n",
            (2, 1),
            "missing column ECX",
        ),
        (
            "X,EXX,EYX,EZX,EAX,EBX,ECX,exx\n0,0,0,0,0,0,0,1\n500,0,0,0,0,0,0,1\n",
            (1, 8),
            "column EXX is given twice, as columns 2 and 8; give each column once",
        ),
    ] {
        let e = load(&write_scenario_with_table(dir.path(), rows)).unwrap_err();
        assert!(e.file.ends_with("x.csv"), "{e}");
        assert_eq!(e.key.as_deref(), Some("machine.errors.x.forward.table"));
        assert_eq!(e.position, Some(position), "{rows:?}: {e}");
        assert!(e.message.contains(message), "{e}");
    }
}

/// A test job too long for the interpolator is refused at the job, without the line of a
/// program its author never wrote; targets closer than the evaluation accepts are refused too.
#[test]
fn a_test_job_too_long_or_too_dense_is_refused_at_its_keys() {
    let text = shipped_with("iso230_2_x.toml", "count = 11", "count = 5000").replacen(
        "runs = 5",
        "runs = 100",
        1,
    );
    let e = parse(&text, "s.toml", Some(&scenarios())).expect_err("too long");
    assert_eq!(e.key.as_deref(), Some("job"), "{e}");
    assert_eq!(
        e.position.map(|p| p.0),
        Some(line_of(&text, "[job]")),
        "{e}"
    );
    assert!(
        e.message.contains("the test lasts about") && !e.message.contains("line"),
        "{e}"
    );
    let text = shipped_with(
        "iso230_2_x.toml",
        "range_mm = [25.0, 475.0]",
        "range_mm = [25.0, 25.5]",
    )
    .replacen("count = 11", "count = 1000", 1);
    let e = parse(&text, "s.toml", Some(&scenarios())).expect_err("too dense");
    assert_eq!(e.key.as_deref(), Some("job.count"), "{e}");
    assert!(e.message.contains("at least 0.001 mm apart"), "{e}");
    // A feed its program would write as F0.0.
    let at = "feed_mm_min = 0.01";
    let text = shipped_with("iso230_2_x.toml", "feed_mm_min = 3000.0", at);
    assert_refused(
        &text,
        at,
        "job.feed_mm_min",
        "a feed in mm/min from 0.1 to 100000",
    );
}

/// The laser's window is compared with its sample interval exactly, as the run compares them:
/// three ticks of a 62.5 µs servo (187.5 µs, which rounds to 188 µs) are accepted.
#[test]
fn a_laser_window_of_whole_servo_ticks_is_accepted_exactly() {
    let text = shipped_with(
        "iso230_2_x.toml",
        "servo_period_us = 125.0",
        "servo_period_us = 62.5",
    )
    .replacen(
        "sample_rate_hz = 1000.0",
        "sample_rate_hz = 5333.333333333333",
        1,
    )
    .replacen("averaging_s = 1.0 ", "averaging_s = 0.0001875 ", 1);
    parse(&text, "s.toml", Some(&scenarios())).expect("a window of exactly one sample");
    let shorter = text.replacen("averaging_s = 0.0001875 ", "averaging_s = 0.000187 ", 1);
    let e = parse(&shorter, "s.toml", Some(&scenarios())).expect_err("no sample");
    assert_eq!(
        e.key.as_deref(),
        Some("instruments.laser.averaging_s"),
        "{e}"
    );
}

/// Without a log rate the log follows the servo when the servo is slower than 1 kHz, rather
/// than refusing a key the file does not have.
#[test]
fn the_default_log_rate_follows_a_slow_servo() {
    let text = with("servo_period_us = 125.0", "servo_period_us = 1250.0")
        .replacen("ipo_period_ms = 1.0", "ipo_period_ms = 2.5", 1)
        .replacen("plant_substeps = 1 ", "plant_substeps = 10 ", 1)
        .replacen("sample_rate_hz = 1000.0", "sample_rate_hz = 800.0", 1)
        .replacen("log_rate_hz = 1000.0", "", 1);
    let s = parse(&text, "s.toml", None).expect("a slow servo without a log rate");
    let rate = s.execution.expect("a job").settings.log_rate_hz;
    assert!((rate - 800.0).abs() < 1e-9, "{rate}");
    let e = error_of(&text.replacen("[simulation]", "[simulation]\nlog_rate_hz = 1000.0", 1));
    assert_eq!(e.key.as_deref(), Some("simulation.log_rate_hz"), "{e}");
}

/// The ISO 230-2 dwell and the servo's peak torque were only checked for being finite and
/// positive: a dwell of 10^308 s was refused as a test too long at [job], and a torque of
/// 10^308 N·m was accepted. Both are bounded at their keys.
#[test]
fn a_dwell_or_peak_torque_beyond_any_test_or_motor_is_refused_at_its_key() {
    let dwell = "a dwell (s) from 0 to 3600 is accepted";
    assert_edits_refused(
        "iso230_2_x.toml",
        &[
            ("dwell_s = 2.0", "dwell_s = 1e308", "job.dwell_s", dwell),
            ("dwell_s = 2.0", "dwell_s = 7200.0", "job.dwell_s", dwell),
            (
                "dwell_s = 2.0",
                "dwell_s = 0.0",
                "job.dwell_s",
                "0 is not accepted; a dwell (s) must be > 0",
            ),
        ],
    );
    let torque = "a peak torque (N·m) from 0 to 100000 is accepted";
    for (by, accepted) in [
        ("peak_torque_n_m = 1e308", torque),
        ("peak_torque_n_m = 2e5", torque),
        ("peak_torque_n_m = -12.0", torque),
        (
            "peak_torque_n_m = 0.0",
            "0 is not accepted; a peak torque (N·m) must be > 0",
        ),
    ] {
        assert_refused(
            &with("peak_torque_n_m = 12.0", by),
            by,
            "machine.axes.x.servo.peak_torque_n_m",
            accepted,
        );
    }
    // The hour itself is accepted as a dwell (the job is then too long for the interpolator,
    // which is refused at [job]), and so is a large torque motor.
    let hour = shipped_with("iso230_2_x.toml", "dwell_s = 2.0", "dwell_s = 3600.0");
    let e = parse(&hour, "s.toml", Some(&scenarios())).expect_err("too long");
    assert_eq!(e.key.as_deref(), Some("job"), "{e}");
    builtin_with("peak_torque_n_m = 12.0", "peak_torque_n_m = 1e5");
}

/// The excess-error limit is optional (the control's default), and one that is given must be a
/// length from 0 to 10 m, refused at its key otherwise.
#[test]
fn a_following_error_limit_is_a_positive_length_at_its_key() {
    let torque = "peak_torque_n_m = 12.0";
    builtin_with(
        torque,
        "peak_torque_n_m = 12.0\nfollowing_error_limit_mm = 20.0",
    );
    let accepted = "a following-error limit (mm) from 0 to 10000 is accepted";
    for (limit, why) in [
        ("-1.0", accepted),
        ("2e4", accepted),
        (
            "0.0",
            "0 is not accepted; a following-error limit (mm) must be > 0",
        ),
    ] {
        let by = format!("{torque}\nfollowing_error_limit_mm = {limit}");
        assert_refused(
            &with(torque, &by),
            &format!("following_error_limit_mm = {limit}"),
            "machine.axes.x.servo.following_error_limit_mm",
            why,
        );
    }
}

/// Instruments and the log are sampled at servo ticks (8 kHz on the built-in machine): a rate
/// that is no whole number of ticks per sample (3 kHz would have been taken every 3 ticks, at
/// 2.667 kHz, with no word) is refused at its key, naming the nearest rates; 4 kHz and 2 kHz
/// are accepted.
#[test]
fn rates_off_the_servo_ticks_are_refused_naming_the_nearest() {
    let nearest = "the nearest are 4000 Hz (every 2 ticks) and 2666.667 Hz (every 3)";
    for (replace, by, key) in [
        (
            "log_rate_hz = 1000.0",
            "log_rate_hz = 3000.0",
            "simulation.log_rate_hz",
        ),
        (
            "sample_rate_hz = 1000.0",
            "sample_rate_hz = 3000.0",
            "instruments.ballbar.sample_rate_hz",
        ),
    ] {
        assert_refused(&with(replace, by), by, key, nearest);
        for fine in ["4000.0", "2000.0"] {
            builtin_with(replace, &by.replace("3000.0", fine));
        }
    }
    assert_edits_refused(
        "iso230_2_x.toml",
        &[(
            "sample_rate_hz = 1000.0",
            "sample_rate_hz = 3000.0",
            "instruments.laser.sample_rate_hz",
            nearest,
        )],
    );
}

/// The ball bar's measuring range is ±1 µm to ±2 mm (bars read ±1 mm), refused at its key.
#[test]
fn a_ball_bar_range_beyond_any_bar_is_refused_at_its_key() {
    let alpha = "bar_alpha_per_k = 11.5e-6";
    builtin_with(alpha, "bar_alpha_per_k = 11.5e-6\nrange_um = 2000.0");
    for range in ["0.5", "3000.0"] {
        let by = format!("{alpha}\nrange_um = {range}");
        assert_refused(
            &with(alpha, &by),
            &format!("range_um = {range}"),
            "instruments.ballbar.range_um",
            "a measuring range (± µm; ball bars read ±1000) from 1 to 2000",
        );
    }
}

/// The built-in machine with `replace` replaced by `by`, which must load.
fn builtin_with(replace: &str, by: &str) {
    let text = with(replace, by);
    parse(&text, "machine.toml", None).unwrap_or_else(|e| panic!("{by}: {e}"));
}

/// The material's coefficients were checked by the model only (positive, not negative) and
/// the error named `job.material`, not the key; each is now bounded at its key to what real
/// materials and edges take.
#[test]
fn cutting_coefficients_beyond_any_material_are_refused_at_their_keys() {
    let material = "job.material";
    let key = |k: &str| format!("{material}.{k}");
    let cutting = "a specific cutting force in N/mm² from 0 to 100000 is accepted";
    let edge = "an edge force in N/mm from 0 to 10000 is accepted";
    let kr = "kr_n_per_mm2 = 200.0";
    for (replace, by, key, accepted) in [
        (
            "kt_n_per_mm2 = 600.0",
            "kt_n_per_mm2 = 1e308",
            key("kt_n_per_mm2"),
            cutting,
        ),
        (
            "kt_n_per_mm2 = 600.0",
            "kt_n_per_mm2 = 2e5",
            key("kt_n_per_mm2"),
            cutting,
        ),
        (
            "kt_n_per_mm2 = 600.0",
            "kt_n_per_mm2 = 0.0",
            key("kt_n_per_mm2"),
            "0 is not accepted; a specific cutting force in N/mm² must be > 0",
        ),
        (kr, "kr_n_per_mm2 = 1e308", key("kr_n_per_mm2"), cutting),
        (kr, "kr_n_per_mm2 = -200.0", key("kr_n_per_mm2"), cutting),
        (
            kr,
            "kr_n_per_mm2 = 200.0\nka_n_per_mm2 = 1e6",
            key("ka_n_per_mm2"),
            cutting,
        ),
        (
            kr,
            "kr_n_per_mm2 = 200.0\nkte_n_per_mm = 1e308",
            key("kte_n_per_mm"),
            edge,
        ),
        (
            kr,
            "kr_n_per_mm2 = 200.0\nkre_n_per_mm = 2e4",
            key("kre_n_per_mm"),
            edge,
        ),
        (
            kr,
            "kr_n_per_mm2 = 200.0\nkae_n_per_mm = -1.0",
            key("kae_n_per_mm"),
            edge,
        ),
    ] {
        let text = shipped_with("milling_slot.toml", replace, by);
        assert_refused(&text, by.lines().last().unwrap(), &key, accepted);
    }
    // Real coefficients load: titanium's (Budak et al.) with its edge forces.
    let titanium = "kt_n_per_mm2 = 1319.0\nkr_n_per_mm2 = 1025.0\nka_n_per_mm2 = 225.0\n\
                    kte_n_per_mm = 24.0\nkre_n_per_mm = 43.0\nkae_n_per_mm = 2.0";
    let text = shipped_with("milling_slot.toml", "kt_n_per_mm2 = 600.0", titanium).replacen(
        "kr_n_per_mm2 = 200.0\n",
        "",
        1,
    );
    parse(&text, "s.toml", Some(&scenarios())).expect("titanium's coefficients");
}

/// The number of axial disks follows from the helix lag a_p·tan β / R; a helix near 90°
/// made it unbounded (82 071 disks of surface memory at 89.999°, more than memory holds
/// closer to 90°). More than 1000 disks are refused at the depth of cut.
#[test]
fn a_cut_needing_more_axial_disks_than_accepted_is_refused_at_its_depth() {
    // 0.5 mm deep with a 20 mm tool: 89.9° needs 821 disks, 89.999° about 82 000.
    let steep = shipped_with("milling_slot.toml", "helix_deg = 0.0", "helix_deg = 89.999");
    assert_refused(
        &steep,
        "axial_depth_mm = 0.5",
        "job.axial_depth_mm",
        "at most 1000 disks are accepted",
    );
    let e = parse(&steep, "s.toml", Some(&scenarios())).unwrap_err();
    assert!(
        e.message.contains("the cut needs 82071 axial disks")
            && e.message
                .contains("tools.T1.helix_deg = 89.999, tools.T1.diameter_mm = 20)"),
        "{e}"
    );
    let text = shipped_with("milling_slot.toml", "helix_deg = 0.0", "helix_deg = 89.9");
    parse(&text, "s.toml", Some(&scenarios())).expect("821 disks");
}

/// A positioning test beyond a stroke is refused at the key at fault: the beam line's
/// coordinate for an axis the test holds still (it was blamed on `job.axis`), the targets for
/// the test's own axis.
#[test]
fn a_positioning_test_beyond_a_stroke_is_refused_at_the_key_at_fault() {
    let beam = "beam_line_mm = [900.0, 200.0]";
    let text = shipped_with("iso230_2_x.toml", "beam_line_mm = [200.0, 200.0]", beam);
    let e = parse(&text, "s.toml", Some(&scenarios())).expect_err("beam line off the stroke");
    assert_eq!(e.key.as_deref(), Some("job.beam_line_mm[0]"), "{e}");
    assert_eq!(e.position.map(|p| p.0), Some(line_of(&text, beam)), "{e}");
    assert!(
        e.message.contains(
            "the test takes the Y axis from 900.000 to 900.000 mm, beyond its stroke 0 to 400 mm"
        ) && e.message.contains("put the beam line within the strokes"),
        "{e}"
    );
    let range = "range_mm = [25.0, 498.0]";
    let text = shipped_with("iso230_2_x.toml", "range_mm = [25.0, 475.0]", range);
    let e = parse(&text, "s.toml", Some(&scenarios())).expect_err("overrun off the stroke");
    assert_eq!(e.key.as_deref(), Some("job.range_mm"), "{e}");
    assert!(
        e.message.contains("the test takes the X axis from")
            && e.message.contains("beyond its stroke 0 to 500 mm")
            && e.message.contains("job.overrun_mm"),
        "{e}"
    );
    let text = shipped_with(
        "iso230_2_x.toml",
        "range_mm = [25.0, 475.0]",
        "targets_mm = [25.0, 250.0, 498.0]",
    )
    .replacen("count = 11\n", "", 1);
    let e = parse(&text, "s.toml", Some(&scenarios())).expect_err("targets off the stroke");
    assert_eq!(e.key.as_deref(), Some("job.targets_mm"), "{e}");
}

/// An instrument table the job does not read is noted, naming the job kinds that do: a ball
/// bar beside an ISO 230-2 laser run records nothing. The shipped scenarios give none.
#[test]
fn an_instrument_the_job_does_not_use_is_noted() {
    let laser = "[instruments.laser]";
    let text = shipped_with(
        "iso230_2_x.toml",
        laser,
        "[instruments.ballbar]\n\n[instruments.laser]",
    );
    let s = parse(&text, "s.toml", Some(&scenarios())).expect("loads");
    let notes = s.execution.expect("a job").notes;
    assert_eq!(
        notes,
        [
            "[instruments.ballbar] records nothing: a `iso230_2` job does not use it (a job of kind ballbar, kwon_seven_step or program does)"
        ]
    );
    for name in [
        "vmc500.toml",
        "kwon_seven_step.toml",
        "iso230_2_x.toml",
        "milling_slot.toml",
        "dataset_xy.toml",
        "dataset_zx.toml",
    ] {
        let text = std::fs::read_to_string(scenarios().join(name)).unwrap();
        let s = parse(&text, name, Some(&scenarios())).expect("loads");
        assert!(s.execution.expect("a job").notes.is_empty(), "{name}");
    }
}
