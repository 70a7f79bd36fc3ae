//! The shipped scenarios, loaded from their files, through the model.

use nalgebra::Vector3;
use std::path::PathBuf;
use vmt_model::Direction;
use vmt_model::kinematics::AxisState;
use vmt_model::thermal::temperatures_at;

fn scenario_path(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("scenarios")
        .join(rel)
}

/// Rows of a compensation table in the file's units: X mm, then EXX, EYX, EZX µm, EAX, EBX, ECX µrad.
fn table_rows(rel: &str) -> Vec<Vec<f64>> {
    let mut r = csv::Reader::from_path(scenario_path(rel)).unwrap();
    r.records()
        .map(|rec| rec.unwrap().iter().map(|v| v.parse().unwrap()).collect())
        .collect()
}

/// On the gantry, the tool point is carried by X at the reference lever (Y = Z = 0, no tool):
/// the volumetric error at each table row is that row's EXX, EYX, EZX; with Y out at 600 mm the
/// yaw ECX adds its Abbe error -y·ECX to ΔX; reversing X switches to the backward table.
#[test]
fn gantry_table_rows_come_back_through_the_chain() {
    let s = vmt_scenario::load(&scenario_path("examples/gantry_x_table.toml")).unwrap();
    let m = &s.machine;
    assert_eq!(m.volumetric.kinematics.topology.to_string(), "WGXYZT");
    for (rel, dir) in [
        ("examples/x_forward.csv", Direction::Forward),
        ("examples/x_backward.csv", Direction::Backward),
    ] {
        for row in table_rows(rel) {
            let at = |y: f64| {
                let state = AxisState {
                    position: Vector3::new(row[0] * 1e-3, y, 0.0),
                    direction: [dir, Direction::Forward, Direction::Forward],
                };
                m.volumetric_error(&state, &[]).unwrap() * 1e6
            };
            let e = at(0.0);
            for k in 0..3 {
                assert!(
                    (e[k] - row[k + 1]).abs() < 1e-9,
                    "{rel} x = {}: {e:?}",
                    row[0]
                );
            }
            let abbe = at(0.6)[0] - e[0];
            let ecx = row[6] * 1e-6;
            // First order; the second-order products of the µrad angles over 0.6 m are ~1e-6 µm.
            assert!(
                (abbe - (-0.6 * ecx.sin()) * 1e6).abs() < 1e-5,
                "x = {}: {abbe}",
                row[0]
            );
        }
    }
}

/// A long warm-up of the built-in machine settles: the node temperatures reach the network's
/// steady state for the running condition, and the X scale has grown by α·ΔT·x.
#[test]
fn builtin_warm_up_reaches_the_steady_state_and_grows_the_x_scale() {
    let s = vmt_scenario::load(&scenario_path("vmc500.toml")).unwrap();
    let thermal = s.machine.thermal.as_ref().unwrap();
    let run = s.thermal_run.as_ref().unwrap();
    let warm_end = run.schedule.segments()[0].until_s;
    let op = run.schedule.segments()[0].op;
    // Hold the ambient at its value near the end of the warm-up: it drifts slowly (24 h period).
    let temps = temperatures_at(
        &thermal.network,
        &run.schedule,
        run.step_s,
        &[warm_end - 1.0],
    )
    .unwrap();
    let x_screw = thermal.network.node_index("x_screw").unwrap();
    let ambient = thermal.network.ambient().celsius_at(warm_end);
    let steady = thermal.network.steady_state_c(&op, ambient).unwrap();
    // The screw's own time constant is ~0.3 h, so after 4 h it is close to its steady state
    // (the bed it is tied to lags, with 5.5 h).
    assert!(
        (temps[0][x_screw] - steady[x_screw]).abs() < 0.5,
        "{} vs {}",
        temps[0][x_screw],
        steady[x_screw]
    );
    // Scale growth: the difference between x = 500 and x = 0 along X is α ΔT · 500 mm plus the
    // geometric part (taken out with the same points at 20 °C) plus the table yaw's Abbe term.
    let at = |x: f64, t: &[f64]| {
        let state = AxisState::new(Vector3::new(x, 0.0, 0.1), Direction::Forward);
        s.machine.volumetric_error(&state, t).unwrap()
    };
    let cold = vec![20.0; thermal.network.node_count()];
    let growth = (at(0.5, &temps[0]) - at(0.0, &temps[0])) - (at(0.5, &cold) - at(0.0, &cold));
    let expected = 11.5e-6 * (temps[0][x_screw] - 20.0) * 0.5;
    assert!(
        (growth.x - expected).abs() < 1e-9,
        "{} vs {}",
        growth.x,
        expected
    );
    assert!(
        growth.x > 5e-6,
        "a warm X screw grows several µm: {}",
        growth.x
    );
}
