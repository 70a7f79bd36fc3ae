//! Errors local to a place along an axis: a rail defect under the carriage's blocks
//! (`geometric::Guideway`) and the growth of a screw warm along part of its length
//! (`thermal::screw`), each against closed forms and through the kinematic chain against the
//! rigid-body motion written out here.

use nalgebra::Vector3;
use vmt_model::Axis;
use vmt_model::Direction;
use vmt_model::geometric::{DefectShape, GeometricErrors, Guideway, RailDefect};
use vmt_model::kinematics::{AxisState, Kinematics, VolumetricModel};
use vmt_model::thermal::screw::{ScrewThermal, ScrewThermalParams};
use vmt_model::thermal_deformation::ThermalDeformation;

const H: f64 = 2e-6;
const L: f64 = 0.3;

fn bump(width_m: f64, at_m: f64, direction: Axis) -> RailDefect {
    RailDefect {
        shape: DefectShape::Bump { width_m },
        direction,
        at_m,
        height_m: H,
        rail_offset_m: None,
    }
}

fn guideway(axis: Axis, centre: [f64; 3], defect: RailDefect) -> Guideway {
    Guideway {
        axis,
        block_spacing_m: L,
        block_length_m: 0.0,
        blocks_centre_m: Vector3::from(centre),
        defects: vec![defect],
    }
}

fn close(a: Vector3<f64>, b: Vector3<f64>, tol: f64) -> bool {
    (a - b).norm() <= tol
}

/// Against the closed forms of two point blocks L apart on a raised cosine of height H and
/// width w: narrower than L, one block at a time lifts the carriage by H/2 and tilts it by
/// H/L; wider, both ride it, the carriage rises by `H/2 (1 + cos(π L/w))` at the middle without
/// tilt, and tilts by `(h(L) − H)/L` when the rear block is on the top.
#[test]
fn narrow_and_wide_bumps_under_two_blocks() {
    let at = 0.33;
    // The pitch axis of an X carriage lifted along Z: u × n = x × z = −y.
    let pitch = -Vector3::y();
    let narrow = guideway(Axis::X, [0.25, 0.2, -0.25], bump(0.04, at, Axis::Z));
    let (t, theta) = narrow.carriage_motion(at - L / 2.0, true);
    assert!(close(t, Vector3::z() * H / 2.0, 1e-18), "{t}");
    assert!(close(theta, pitch * H / L, 1e-18), "{theta}");
    let (t, theta) = narrow.carriage_motion(at, true);
    assert!(t.norm() == 0.0 && theta.norm() == 0.0);
    // On the workpiece side the carriage moves −q: the front block meets it at q = at + L/2.
    let (t, theta) = narrow.carriage_motion(at + L / 2.0, false);
    assert!(close(t, Vector3::z() * H / 2.0, 1e-18), "{t}");
    assert!(close(theta, pitch * H / L, 1e-18), "{theta}");

    let w = 1.2;
    let wide = guideway(Axis::X, [0.25, 0.2, -0.25], bump(w, at, Axis::Z));
    let (t, theta) = wide.carriage_motion(at, true);
    let both = H / 2.0 * (1.0 + (std::f64::consts::PI * L / w).cos());
    assert!(close(t, Vector3::z() * both, 1e-18), "{t}");
    assert!(theta.norm() < 1e-20, "{theta}");
    let (_, theta) = wide.carriage_motion(at + L / 2.0, true);
    let front = H / 2.0 * (1.0 + (std::f64::consts::TAU * L / w).cos());
    assert!(close(theta, pitch * (front - H) / L, 1e-18), "{theta}");
}

/// A defect on one rail only (at across offset a): the four blocks' rigid fit lifts by half
/// the rail's lift and rolls by it over 2a; a step under a block of length b lifts it by H/2
/// at the joint and 3H/4 a quarter block past it (the block's mean over its balls).
#[test]
fn one_rail_rolls_and_a_block_averages_a_step() {
    let at = 0.2;
    let a = 0.2;
    let defect = RailDefect {
        rail_offset_m: Some(a),
        ..bump(1.2, at, Axis::Z)
    };
    let g = guideway(Axis::X, [0.25, 0.2, -0.25], defect);
    let (t, theta) = g.carriage_motion(at, true);
    let on_rail = H / 2.0 * (1.0 + (std::f64::consts::PI * L / 1.2).cos());
    assert!(close(t, Vector3::z() * on_rail / 2.0, 1e-18), "{t}");
    // Roll about w × n = y × z = +x.
    assert!(
        close(theta, Vector3::x() * on_rail / (2.0 * a), 1e-18),
        "{theta}"
    );

    let step = RailDefect {
        shape: DefectShape::Step,
        ..bump(1.0, at, Axis::Y)
    };
    let b = 0.1;
    for (s, expected) in [
        (0.0, 0.5),
        (b / 4.0, 0.75),
        (-b / 4.0, 0.25),
        (b, 1.0),
        (-b, 0.0),
    ] {
        assert!((step.under_block(s, b) - expected * H).abs() < 1e-18, "{s}");
    }
}

/// Through the kinematic chain, against the rigid-body motion of the carriage about its
/// blocks' centre written out: a table (X, carrying the workpiece) lifted at its front block
/// tilts the workpiece under the tool, whose error is `−t − θ × (P_T − c)` with `P_T` the tool
/// point and `c` the blocks' centre where the table has moved it; a head (Z, carrying the tool)
/// gives `t + θ × (tool − c)`. The Abbe offsets of a few hundred millimetres turn 7 µrad into
/// micrometres. The chain turns by exact rotations: it differs from these first-order forms by
/// the second-order remainder, `θ² |r| / 2` (a few 1e-12 m here).
#[test]
fn the_chain_carries_the_tilt_with_its_abbe_offsets() {
    let tool = Vector3::new(0.0, 0.0, -0.1);
    let at = 0.33;
    let (qx, qy, qz) = (at + L / 2.0, 0.18, 0.2);
    let state = AxisState::new(Vector3::new(qx, qy, qz), Direction::Forward);
    let model = |axis: Axis, centre: [f64; 3], direction: Axis| {
        let mut e = GeometricErrors::zero();
        e.guideways[axis.index()] = Some(guideway(axis, centre, bump(0.04, at, direction)));
        let mut k = Kinematics::new("WXYGZT".parse().unwrap());
        k.tool_offset = tool;
        VolumetricModel::new(k, e)
    };
    // The table: front block on the bump's top (q = at + L/2 on the workpiece side).
    let b0 = Vector3::new(0.25, 0.2, -0.25);
    let x = model(Axis::X, b0.into(), Axis::Z);
    let error = x.volumetric_error(&state, &ThermalDeformation::default());
    let (t, theta) = (Vector3::z() * H / 2.0, -Vector3::y() * H / L);
    let table_shift = Vector3::new(-qx, -qy, 0.0);
    let tool_point = Vector3::new(0.0, 0.0, qz) + tool;
    let expected = -t - theta.cross(&(tool_point - (b0 + table_shift)));
    let second_order = (H / L).powi(2);
    assert!(
        close(error, expected, second_order),
        "{error} against {expected}"
    );
    assert!(
        error.x.abs() > 1e-6,
        "an Abbe error of micrometres: {error}"
    );
    // The head: the tool side moves +q, the front block on the top at q = at − L/2, lifted
    // along Y (away from the column face), pitching about z × y = −x.
    let z_state = AxisState::new(Vector3::new(0.1, 0.1, at - L / 2.0), Direction::Forward);
    let c0 = Vector3::new(0.0, 0.4, 0.2);
    let z = model(Axis::Z, c0.into(), Axis::Y);
    let error = z.volumetric_error(&z_state, &ThermalDeformation::default());
    let (t, theta) = (Vector3::y() * H / 2.0, -Vector3::x() * H / L);
    let expected = t + theta.cross(&(tool - c0));
    assert!(
        close(error, expected, second_order),
        "{error} against {expected}"
    );
}

/// Through the chain, against `α ΔT (q − q_f)` of a uniformly warm screw and, for a screw warm
/// only between two positions, the growth of that part alone: `α ΔT (min(q, b) − a)` beyond `a`.
#[test]
fn a_screw_warm_in_part_grows_the_axis_there() {
    let p = ScrewThermalParams {
        span_m: [-0.1, 0.6],
        fixed_at_high_end: false,
        diameter_m: 0.028,
        conductivity_w_per_m_k: 46.0,
        heat_capacity_j_per_m3_k: 3.6e6,
        convection_w_per_m2_k: 15.0,
        end_conductance_w_per_k: [2.0, 0.5],
        nut_w_per_m_s: 300.0,
        nut_length_m: 0.1,
        bearing_w_per_m_s: 200.0,
        alpha_per_k: 11.5e-6,
        cells: 35,
        warm: None,
    };
    let screw = ScrewThermal::new(&p, 1.0).unwrap();
    let mut k = Kinematics::new("WXYGZT".parse().unwrap());
    k.tool_offset = Vector3::new(0.0, 0.0, -0.1);
    let model = VolumetricModel::new(k, GeometricErrors::zero());
    // Cells of 20 mm: warm (+3 K) over the cells from 0.1 to 0.3 m.
    let temps: Vec<f64> = (0..35)
        .map(|i| {
            let c = p.centre_m(i);
            if (0.1..0.3).contains(&c) { 23.0 } else { 20.0 }
        })
        .collect();
    let mut d = ThermalDeformation::default();
    d.joints[0].screw = Some(screw.growth(&temps));
    for q in [0.0, 0.05, 0.1, 0.15, 0.2, 0.3, 0.45] {
        let state = AxisState::new(Vector3::new(q, 0.2, 0.2), Direction::Forward);
        let error = model.volumetric_error(&state, &d);
        let grown = 11.5e-6 * 3.0 * (q.min(0.3) - 0.1).max(0.0);
        assert!(
            close(error, Vector3::x() * grown, 1e-15),
            "{q}: {error} against {grown}"
        );
    }
}
