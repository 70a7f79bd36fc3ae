//! The compliant plant (carriages on their guide blocks) against closed forms of rigid bodies on
//! springs, written out here from the block layout and the carriages' boxes, not taken from the
//! code under test; and against the reduced plant in the stiff limit.

use nalgebra::Vector3;
use vmt_model::Axis;
use vmt_model::drive::{AxisCommand, Drive, LuGreParams};
use vmt_model::kinematics::{AxisState, Topology};
use vmt_model::structure::{Carriage, Structure, box_inertia};
use vmt_model::thermal_deformation::ThermalDeformation;
use vmt_sim::plant::{AxisLayout, CompliantPlant, Fidelity, Plant, PlantError, layout};
use vmt_sim::simulate::{AxisDynamics, SimError};

const SERVO: f64 = 125e-6;

/// The built-in machine's drives without friction (so that the blocks and the screw alone hold
/// the carriages), its structure and the layout of `topology`.
fn builtin(topology: &str) -> ([AxisDynamics; 3], Structure, [AxisLayout; 3], Vector3<f64>) {
    let s = vmt_scenario::builtin().unwrap();
    let mut axes = s.execution.unwrap().axes;
    for a in &mut axes {
        a.drive.guide_friction = LuGreParams::NONE;
        a.drive.screw_friction = LuGreParams::NONE;
        a.drive.screw.backlash_m = 0.0;
    }
    let moving = s.machine.axes.map(|a| a.moving_mass_kg);
    let l = layout(&topology.parse::<Topology>().unwrap(), moving).unwrap();
    let mut structure = s.machine.structure.unwrap();
    // The own masses of this topology's chain, with their boxes' inertias.
    for (c, l) in structure.carriages.iter_mut().zip(&l) {
        c.mass_kg = l.link_mass_kg;
        c.inertia_kg_m2 = box_inertia(c.mass_kg, &c.box_size_m);
    }
    (
        axes,
        structure,
        l,
        s.machine.volumetric.kinematics.tool_offset,
    )
}

fn plant(
    axes: &[AxisDynamics; 3],
    structure: &Structure,
    l: &[AxisLayout; 3],
    tcp: Vector3<f64>,
    q0: [f64; 3],
    substeps: usize,
) -> CompliantPlant {
    let drives = std::array::from_fn(|i| Drive::new(axes[i].drive, axes[i].servo, q0[i]));
    CompliantPlant::new(drives, l, structure, tcp, SERVO / substeps as f64).unwrap()
}

/// Holds every axis at `q0` for `seconds` in plant steps of `SERVO / substeps`, calling `each`
/// after every step.
fn hold(
    p: &mut CompliantPlant,
    q0: [f64; 3],
    seconds: f64,
    substeps: usize,
    mut each: impl FnMut(&CompliantPlant),
) {
    for _ in 0..(seconds / SERVO).round() as usize {
        let c = q0.map(|q| AxisCommand {
            position: q,
            ..Default::default()
        });
        p.control(&c, SERVO);
        for _ in 0..substeps {
            p.step(SERVO / substeps as f64);
            each(p);
        }
    }
}

/// The blocks' angular stiffness about `about` (0, 1, 2 for X, Y, Z) from the normal (or
/// lateral) stiffness times the squared distances from the blocks' centroid across that axis,
/// `Σ k r²`, N·m/rad: the textbook sum for springs at distances r.
fn angular_stiffness(c: &Carriage, about: usize, lateral: bool) -> f64 {
    let a = c.blocks.iter().map(|b| b.position_m).sum::<Vector3<f64>>() / c.blocks.len() as f64;
    c.blocks
        .iter()
        .map(|b| {
            let dir = if lateral {
                Vector3::ith(c.axis.index(), 1.0).cross(&b.normal)
            } else {
                b.normal
            };
            let k = if lateral {
                b.lateral_stiffness_n_per_m
            } else {
                b.normal_stiffness_n_per_m
            };
            // The lever of a force along `dir` at the block about the axis through the anchor.
            let r = b.position_m - a;
            let lever = r.cross(&dir)[about];
            k * lever * lever
        })
        .sum()
}

/// The frequency (Hz) of the oscillation in `x` sampled every `dt` (s), from its zero crossings
/// about its last value, linearly interpolated.
fn frequency(x: &[f64], dt: f64) -> f64 {
    let rest = x[x.len() - 1];
    let mut crossings = Vec::new();
    for k in 1..x.len() {
        let (a, b) = (x[k - 1] - rest, x[k] - rest);
        if a != 0.0 && a.signum() != b.signum() {
            crossings.push((k - 1) as f64 + a / (a - b));
        }
    }
    let n = crossings.len();
    assert!(n >= 10, "only {n} zero crossings");
    // Half periods between the first and the tenth-last crossing (the tail is at rounding).
    let (first, last) = (crossings[0], crossings[n - 5]);
    (n - 5) as f64 / 2.0 / ((last - first) * dt)
}

/// Pitch and yaw natural frequencies of the table on its four blocks: `√(Σ k r² / I)/2π`, with
/// `I` the table box's moment about its centre of mass, put over the blocks' centroid and the
/// nut at the same height so that tilting couples to no translation (the table on the ground,
/// topology WXGYZT). A 1 ms force on the tool sets it ringing; measured within 0.2 %.
#[test]
fn pitch_and_yaw_frequencies_of_the_table_are_the_closed_forms() {
    let (axes, mut structure, l, tcp) = builtin("WXGYZT");
    let table = &mut structure.carriages[0];
    let anchor = table
        .blocks
        .iter()
        .map(|b| b.position_m)
        .sum::<Vector3<f64>>()
        / 4.0;
    table.com_m = anchor;
    table.nut_m = anchor;
    let table = structure.carriages[0].clone();
    let q0 = [0.1, 0.2, 0.3];
    // This topology hangs the head on the saddle-shaped Y carriage, whose stiffest modes ring
    // at a few kHz: eight plant steps per servo period.
    let n = 8;
    let mut p = plant(&axes, &structure, &l, tcp, q0, n);
    let (mut pitch, mut yaw) = (Vec::new(), Vec::new());
    p.set_tool_force(Vector3::new(2000.0, 2000.0, 0.0));
    hold(&mut p, q0, 1e-3, n, |_| {});
    p.set_tool_force(Vector3::zeros());
    hold(&mut p, q0, 0.08, n, |p| {
        let (_, th) = p.motions()[0];
        pitch.push(th.y);
        yaw.push(th.z);
    });
    let i = box_inertia(table.mass_kg, &table.box_size_m);
    let f = |k: f64, i: f64| (k / i).sqrt() / std::f64::consts::TAU;
    let want_pitch = f(angular_stiffness(&table, 1, false), i[(1, 1)]);
    let want_yaw = f(angular_stiffness(&table, 2, true), i[(2, 2)]);
    let dt = SERVO / n as f64;
    let (got_pitch, got_yaw) = (frequency(&pitch, dt), frequency(&yaw, dt));
    eprintln!(
        "pitch {got_pitch:.2} Hz (closed form {want_pitch:.2}), yaw {got_yaw:.2} Hz ({want_yaw:.2})"
    );
    assert!((got_pitch / want_pitch - 1.0).abs() < 0.02);
    assert!((got_yaw / want_yaw - 1.0).abs() < 0.02);
    // The plant's own modal analysis finds them too.
    let modes: Vec<f64> = p.modes().iter().map(|m| m.0).collect();
    for want in [want_pitch, want_yaw] {
        assert!(
            modes.iter().any(|m| (m / want - 1.0).abs() < 0.02),
            "{want} Hz not among {modes:?}"
        );
    }
}

/// Quasi-static pitch under a constant acceleration: the table of mass m accelerated at a by
/// its nut h below its centre of mass pitches by `m·a·h / Σ k_n r²` (the couple of the inertial
/// and the drive force over the blocks' angular stiffness), on the built-in machine (the table
/// on its saddle); measured within 0.5 % at 2 m/s².
#[test]
fn table_pitches_by_the_inertial_couple_over_the_block_stiffness() {
    let (axes, structure, l, tcp) = builtin("WXYGZT");
    let table = structure.carriages[0].clone();
    let q0 = [0.05, 0.2, 0.3];
    let mut p = plant(&axes, &structure, &l, tcp, q0, 1);
    hold(&mut p, q0, 0.05, 1, |_| {});
    let rest = p.motions()[0].1.y;
    // A constant acceleration of the X coordinate from rest; the table moves along -X.
    let a = 2.0;
    let n = (0.3 / SERVO) as usize;
    let mut velocities = Vec::new();
    for k in 0..n {
        let t = k as f64 * SERVO;
        let cmd = [
            AxisCommand {
                position: q0[0] + 0.5 * a * t * t,
                velocity: a * t,
                acceleration: a,
            },
            AxisCommand {
                position: q0[1],
                ..Default::default()
            },
            AxisCommand {
                position: q0[2],
                ..Default::default()
            },
        ];
        p.control(&cmd, SERVO);
        p.step(SERVO);
        velocities.push(p.carriages()[0].velocity_m_s);
    }
    // The acceleration the table really has at the end (over the last 20 ms), physical sign.
    let k = velocities.len() - 1;
    let span = (0.02 / SERVO) as usize;
    let accel = -(velocities[k] - velocities[k - span]) / (span as f64 * SERVO);
    let pitch = p.motions()[0].1.y - rest;
    let h = table.com_m.z - table.nut_m.z;
    let k_theta = angular_stiffness(&table, 1, false);
    // A couple m·a·h turning the table about +Y when it accelerates along -X with the nut
    // below: r × F of the drive force at the nut, about the centre of mass.
    let want = -table.mass_kg * accel * h / k_theta;
    eprintln!("pitch {pitch:e} rad at {accel:.4} m/s², closed form {want:e}");
    assert!(
        (accel + a).abs() < 0.05 * a,
        "the table accelerates at {accel}"
    );
    assert!(
        (pitch / want - 1.0).abs() < 0.02,
        "pitch {pitch:e}, want {want:e}"
    );
}

/// The deflection at the tool under a static force across the machine (Y, 1 kN) is the sum of
/// the compliances along the load path, each the closed form of a rigid body on springs: the
/// saddle's screw `1/k_s` and its pitch on its blocks about the nut line `(z_p − z_n)²/Σk_n r²`,
/// the table's lateral `1/Σk_l` and roll `(z_p − z_a)²/Σk_n r²`, the head's normal `1/Σk_n`
/// and tilt `(z_p − z_a)²/Σk_n r²`; measured within 0.5 %.
#[test]
fn static_deflection_at_the_tool_is_the_sum_of_the_load_paths_compliances() {
    let s = vmt_scenario::builtin().unwrap();
    let (axes, structure, l, tcp) = builtin("WXYGZT");
    let q0 = [0.25, 0.2, 0.3];
    let tool_at = |p: &CompliantPlant| {
        let ev = s
            .machine
            .volumetric
            .evaluator(&ThermalDeformation::default());
        let q = Vector3::from_fn(|i, _| p.carriages()[i].position_m);
        let state = AxisState::new(q, vmt_model::Direction::Forward);
        ev.tool_point_deflected(&state, &p.deflections().unwrap())
    };
    let mut p = plant(&axes, &structure, &l, tcp, q0, 1);
    hold(&mut p, q0, 0.6, 1, |_| {});
    let before = tool_at(&p);
    let f = 1000.0;
    p.set_tool_force(Vector3::new(0.0, f, 0.0));
    hold(&mut p, q0, 0.6, 1, |_| {});
    let after = tool_at(&p);
    let got = after.y - before.y;

    let [table, saddle, head] = &structure.carriages;
    let anchor = |c: &Carriage| {
        c.blocks.iter().map(|b| b.position_m).sum::<Vector3<f64>>() / c.blocks.len() as f64
    };
    // The tool point's height (the workpiece side moves only in X and Y, the head in Z).
    let z_p = tcp.z + q0[2];
    let k_screw = axes[1].drive.screw.stiffness_n_per_m;
    let saddle_path =
        1.0 / k_screw + (z_p - saddle.nut_m.z).powi(2) / angular_stiffness(saddle, 0, false);
    let lateral: f64 = table
        .blocks
        .iter()
        .map(|b| b.lateral_stiffness_n_per_m)
        .sum();
    let table_path =
        1.0 / lateral + (z_p - anchor(table).z).powi(2) / angular_stiffness(table, 0, false);
    let normal: f64 = head.blocks.iter().map(|b| b.normal_stiffness_n_per_m).sum();
    // The head's anchor and the tool move together along Z: their heights with Z at zero.
    let head_path =
        1.0 / normal + (tcp.z - anchor(head).z).powi(2) / angular_stiffness(head, 0, false);
    // The tool moves with the force on it (+Y under +Y), the workpiece with its reaction.
    let want = f * (saddle_path + table_path + head_path);
    eprintln!(
        "deflection {:.4} µm, closed form {:.4} µm (saddle {:.3}, table {:.3}, head {:.3})",
        got * 1e6,
        want * 1e6,
        f * saddle_path * 1e6,
        f * table_path * 1e6,
        f * head_path * 1e6
    );
    assert!(
        (got / want - 1.0).abs() < 0.02,
        "got {got:e}, want {want:e}"
    );
}

/// In the stiff limit the compliant plant is the reduced one: with every block 100 times
/// stiffer (its deflections 100 times smaller, its modes 10 times faster, so eight plant steps
/// per servo period for both plants), the built-in ball-bar test's readings agree with the
/// reduced plant's within 0.05 µm (the bound; measured 0.03 µm, the head's droop).
/// The bar reads without noise and quantisation here, so that the plants are compared, not the
/// instrument; the samples at which one run's direction-dependent geometric errors (X's 2 µm
/// positional backlash) have switched at an axis' reversal and the other's not yet (a
/// sub-nanometre difference moves a switch by one sample) are counted apart.
#[test]
fn stiff_blocks_give_the_reduced_plant_on_the_builtin_ballbar_test() {
    let s = vmt_scenario::builtin().unwrap();
    let mut exec = s.execution.unwrap();
    let mut machine = s.machine;
    for c in &mut machine.structure.as_mut().unwrap().carriages {
        for b in &mut c.blocks {
            b.normal_stiffness_n_per_m *= 100.0;
            b.lateral_stiffness_n_per_m *= 100.0;
            b.normal_damping_n_s_per_m *= 10.0;
            b.lateral_damping_n_s_per_m *= 10.0;
        }
    }
    exec.settings.plant_substeps = 8;
    for b in &mut exec.job.ballbar {
        b.spec.noise_m = 0.0;
        b.spec.resolution_m = 0.0;
    }
    let run = |fidelity| {
        let mut settings = exec.settings;
        settings.fidelity = fidelity;
        vmt_sim::simulate::simulate(
            &machine,
            &exec.axes,
            &exec.controller,
            &exec.job,
            &settings,
            "",
            &mut |_| {},
        )
        .unwrap()
    };
    let reduced = run(Fidelity::Reduced);
    let compliant = run(Fidelity::Compliant);
    // A switch of the geometric errors is a step of a micrometre or more between samples
    // (noise-free readings otherwise change by under 0.2 µm per sample at this feed).
    let step = |r: &[f64], k: usize| k > 0 && (r[k] - r[k - 1]).abs() > 1.0;
    let (mut worst, mut same_sample, mut switches): (f64, f64, usize) = (0.0, 0.0, 0);
    for (a, b) in reduced.ballbar.iter().zip(&compliant.ballbar) {
        let (a, b) = (&a.deviation_um, &b.deviation_um);
        assert_eq!(a.len(), b.len());
        for k in 0..a.len() {
            let d = (a[k] - b[k]).abs();
            same_sample = same_sample.max(d);
            // The sample between the two runs' switches: one has switched, the other not yet.
            let apart = |j: usize| j < a.len() && step(a, j) != step(b, j);
            if apart(k) || apart(k + 1) {
                switches += 1;
                continue;
            }
            worst = worst.max(d);
        }
    }
    eprintln!(
        "largest difference {worst:.4} µm ({same_sample:.4} µm at {switches} samples between \
         the two runs' switches of the direction-dependent errors)"
    );
    assert!(switches <= 8, "{switches} samples between switches");
    assert!(worst < 0.05, "largest difference {worst} µm");
}

/// A plant step too coarse for the stiffest mode of the carriages is refused with the mode and
/// the accepted step, naming the key to change.
#[test]
fn a_step_too_coarse_for_the_blocks_is_refused() {
    let (axes, mut structure, l, tcp) = builtin("WXYGZT");
    for b in &mut structure.carriages[2].blocks {
        b.normal_stiffness_n_per_m *= 100.0;
    }
    let drives = std::array::from_fn(|i| Drive::new(axes[i].drive, axes[i].servo, 0.2));
    let err = CompliantPlant::new(drives, &l, &structure, tcp, SERVO)
        .err()
        .expect("refused");
    let msg = err.to_string();
    eprintln!("{msg}");
    assert!(
        matches!(err, PlantError::StepTooCoarse { axis: Axis::Z, .. }),
        "{err:?}"
    );
    assert!(msg.contains("controller.plant_substeps"), "{msg}");
    // And through a run: the same error, as a plant error.
    let s = vmt_scenario::builtin().unwrap();
    let mut machine = s.machine;
    machine.structure = Some(structure);
    let exec = s.execution.unwrap();
    let mut settings = exec.settings;
    settings.fidelity = Fidelity::Compliant;
    let e = vmt_sim::simulate::simulate(
        &machine,
        &exec.axes,
        &exec.controller,
        &exec.job,
        &settings,
        "",
        &mut |_| {},
    )
    .expect_err("refused");
    assert!(
        matches!(e, SimError::Plant(PlantError::StepTooCoarse { .. })),
        "{e}"
    );
}
