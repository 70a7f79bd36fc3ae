//! The HTM chain against closed forms: Ahn & Cho's second-order model, hand-computed single
//! errors, the sign rules over all 24 topologies, and the thermal expansion of an axis.

use nalgebra::{Rotation3, Vector3, Vector4};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use vmt_model::geometric::{
    Component, Directional, ErrorFunction, GeometricErrors, LegendreSeries, SquarenessError,
    SquarenessValue,
};
use vmt_model::kinematics::{AxisState, Element, Kinematics, Topology, VolumetricModel};
use vmt_model::thermal_deformation::{
    AxisExpansion, JointThermalModel, NodeSensitivity, ThermalDeformation, ThermalDeformationModel,
};
use vmt_model::{Axis, Direction};

/// Rounding of a volumetric error taken as the difference of ~0.5 m coordinates (a few ulp).
const ROUNDING: f64 = 2e-16;

const STROKE: [(f64, f64); 3] = [(0.0, 0.5), (0.0, 0.4), (-0.4, 0.0)];

fn constant(v: f64) -> Directional {
    Directional::symmetric(ErrorFunction::Legendre(
        LegendreSeries::new(vec![v], -1.0, 1.0).unwrap(),
    ))
}

fn model_with(topology: &str, tool: Vector3<f64>, errors: GeometricErrors) -> VolumetricModel {
    let mut k = Kinematics::new(topology.parse().unwrap());
    k.tool_offset = tool;
    VolumetricModel::new(k, errors)
}

fn no_heat() -> ThermalDeformation {
    ThermalDeformation::default()
}

/// Random Legendre error functions of every axis (values up to `delta` m and `eps` rad) and
/// random squareness (up to `eps` rad, different for every direction pair).
fn random_errors(rng: &mut StdRng, delta: f64, eps: f64) -> GeometricErrors {
    let mut e = GeometricErrors::zero();
    for axis in Axis::ALL {
        let (lo, hi) = STROKE[axis.index()];
        for c in Component::ALL {
            let amp = if c.is_angular() { eps } else { delta };
            let mut series = || {
                let coeffs = (0..4).map(|_| rng.random_range(-amp..amp) / 2.0).collect();
                ErrorFunction::Legendre(LegendreSeries::new(coeffs, lo, hi).unwrap())
            };
            let functions = Directional {
                forward: series(),
                backward: series(),
            };
            e.axis_mut(axis).set(c, functions);
        }
    }
    for s in SquarenessError::ALL {
        let mut v = SquarenessValue::default();
        for row in &mut v.values {
            for x in row {
                *x = rng.random_range(-eps..eps);
            }
        }
        e.set_squareness(s, v);
    }
    e
}

fn random_state(rng: &mut StdRng) -> AxisState {
    let p = Vector3::from_fn(|i, _| rng.random_range(STROKE[i].0..STROKE[i].1));
    let mut d = || {
        if rng.random_range(0..2) == 0 {
            Direction::Forward
        } else {
            Direction::Backward
        }
    };
    let direction = [d(), d(), d()];
    AxisState {
        position: p,
        direction,
    }
}

/// Ahn & Cho (2002) eqs. (1)–(3) for their vertical machine, in their symbols.
struct AhnCho {
    /// δ[i][j]: error in direction i of axis j (δxx, δyx, ... in the paper).
    d: [[f64; 3]; 3],
    /// ε[i][j]: rotation about i of axis j.
    e: [[f64; 3]; 3],
    sxy: f64,
    sxz: f64,
    syz: f64,
}

impl AhnCho {
    fn from_model(m: &VolumetricModel, s: &AxisState) -> Self {
        let mut d = [[0.0; 3]; 3];
        let mut e = [[0.0; 3]; 3];
        for axis in Axis::ALL {
            let j = axis.index();
            let motion = m.errors.axis(axis).motion(s.position[j], s.direction[j]);
            for i in 0..3 {
                d[i][j] = motion.translation[i];
                e[i][j] = motion.rotation[i];
            }
        }
        let sq = |w: SquarenessError| {
            let (r, k) = w.axes();
            m.errors
                .squareness(w)
                .get(s.direction[r.index()], s.direction[k.index()])
        };
        // The paper's S_xy, S_xz, S_yz in terms of the ISO right-hand rotations of the axis lines.
        Self {
            d,
            e,
            sxy: sq(SquarenessError::C0Y),
            sxz: -sq(SquarenessError::B0Z),
            syz: sq(SquarenessError::A0Z),
        }
    }

    /// ΔV of eqs. (1)–(3), with the tool dimension Z4 along z.
    fn delta_v(&self, y: f64, z: f64, z4: f64) -> Vector3<f64> {
        let (d, e) = (&self.d, &self.e);
        let (x_, y_, z_) = (0, 1, 2);
        let dl = |i: usize, j: usize| d[i][j];
        let ep = |i: usize, j: usize| e[i][j];
        let (sxy, sxz, syz) = (self.sxy, self.sxz, self.syz);
        let dvx = dl(x_, x_) + dl(x_, y_) + dl(x_, z_) - y * ep(z_, x_) - y * sxy
            + z * ep(y_, x_)
            + z * ep(y_, y_)
            - z * sxz
            + z4 * ep(y_, x_)
            + z4 * ep(y_, y_)
            + z4 * ep(y_, z_)
            + dl(z_, y_) * ep(y_, x_)
            + dl(z_, z_) * ep(y_, x_)
            + dl(z_, z_) * ep(y_, y_)
            - dl(y_, y_) * ep(z_, x_)
            - dl(y_, z_) * ep(z_, x_)
            - dl(y_, z_) * ep(z_, y_)
            + z * ep(x_, y_) * ep(z_, x_)
            + z * ep(z_, x_) * syz
            + z * ep(z_, y_) * syz
            + z4 * ep(x_, y_) * ep(z_, x_)
            + z4 * ep(x_, z_) * ep(z_, x_)
            + z4 * ep(x_, z_) * ep(z_, y_);
        let dvy = dl(y_, x_) + dl(y_, y_) + dl(y_, z_)
            - z * ep(x_, x_)
            - z * ep(x_, y_)
            - z * syz
            - z4 * ep(x_, x_)
            - z4 * ep(x_, y_)
            - z4 * ep(x_, z_)
            - dl(z_, y_) * ep(x_, x_)
            - dl(z_, z_) * ep(x_, x_)
            - dl(z_, z_) * ep(x_, y_)
            + dl(x_, y_) * ep(z_, x_)
            + dl(x_, z_) * ep(z_, x_)
            + dl(x_, z_) * ep(z_, y_)
            + z * ep(y_, y_) * ep(z_, x_)
            - y * ep(z_, x_) * sxy
            - z * ep(z_, x_) * sxz
            - z * ep(z_, y_) * sxz
            + z4 * ep(y_, y_) * ep(z_, x_)
            + z4 * ep(y_, z_) * ep(z_, x_)
            + z4 * ep(y_, z_) * ep(z_, y_);
        let dvz = dl(z_, x_)
            + dl(z_, y_)
            + dl(z_, z_)
            + y * ep(x_, x_)
            + dl(y_, y_) * ep(x_, x_)
            + dl(y_, z_) * ep(x_, x_)
            + dl(y_, z_) * ep(x_, y_)
            - dl(x_, y_) * ep(y_, x_)
            - dl(x_, z_) * ep(y_, x_)
            - dl(x_, z_) * ep(y_, y_)
            + y * ep(y_, x_) * sxy
            - z * ep(x_, x_) * ep(x_, y_)
            - z * ep(y_, x_) * ep(y_, y_)
            + z * ep(y_, x_) * sxz
            + z * ep(y_, y_) * sxz
            - z * ep(x_, x_) * syz
            - z * ep(x_, y_) * syz
            - z4 * ep(x_, x_) * ep(x_, y_)
            - z4 * ep(x_, x_) * ep(x_, z_)
            - z4 * ep(x_, y_) * ep(x_, z_)
            - z4 * ep(y_, x_) * ep(y_, y_)
            - z4 * ep(y_, x_) * ep(y_, z_)
            - z4 * ep(y_, y_) * ep(y_, z_);
        Vector3::new(dvx, dvy, dvz)
    }

    /// The second-order terms that the paper's linearised error matrices leave out and the
    /// exact rotations contain: ½ θ×(θ×r) of each rotation θ acting on its lever r.
    fn self_terms(&self, y: f64, z: f64, z4: f64) -> Vector3<f64> {
        let col = |j: usize| Vector3::new(self.e[0][j], self.e[1][j], self.e[2][j]);
        let half_sq = |t: Vector3<f64>, r: Vector3<f64>| 0.5 * t.cross(&t.cross(&r));
        let tool = Vector3::new(0.0, 0.0, z4);
        half_sq(col(0), Vector3::new(0.0, y, z) + tool)
            + half_sq(col(1), Vector3::new(0.0, 0.0, z) + tool)
            + half_sq(col(2), tool)
            + half_sq(Vector3::new(0.0, 0.0, self.sxy), Vector3::new(0.0, y, 0.0))
            + half_sq(
                Vector3::new(self.syz, -self.sxz, 0.0),
                Vector3::new(0.0, 0.0, z),
            )
    }

    /// Largest angle and translation, for the bound of the third-order remainder.
    fn magnitudes(&self) -> (f64, f64) {
        let mut eps: f64 = self.sxy.abs().max(self.sxz.abs()).max(self.syz.abs());
        let mut delta: f64 = 0.0;
        for j in 0..3 {
            let e = Vector3::new(self.e[0][j], self.e[1][j], self.e[2][j]).norm();
            let d = Vector3::new(self.d[0][j], self.d[1][j], self.d[2][j]).norm();
            eps = eps.max(e);
            delta = delta.max(d);
        }
        (eps, delta)
    }
}

/// Ahn & Cho's vertical machine is the chain W-X-Y-G-Z-T (table X on saddle Y, head Z).
/// Their eqs. (1)–(3) are the chain with first-order error matrices, expanded to second order.
/// Adding the ½θ×(θ×r) terms of the exact rotations, the rest is third order: products of three
/// errors. Every third-order term is a product of at most three rotations (each below ε) with a
/// lever below L = |y| + |z| + |Z4|, or of two rotations with a translation (below δ); the
/// remainder of each exact rotation beyond second order is below |θ|³/6 |r|. With 5 rotations in
/// the chain there are at most 35 products of three and 15 of two, hence the bound
/// `B3 = 35 ε³ L + 15 ε² δ + 5 ε³ L / 6`, plus rounding of the 1 m-scale coordinates (1e-15 m).
#[test]
fn htm_chain_matches_ahn_cho_closed_form_within_third_order_bound() {
    let mut rng = StdRng::seed_from_u64(2002);
    for (delta, eps) in [(20e-6, 50e-6), (100e-6, 1e-3), (1e-3, 1e-2)] {
        let mut worst_ratio: f64 = 0.0;
        for _ in 0..500 {
            let z4 = rng.random_range(-0.25..0.25);
            let m = model_with(
                "WXYGZT",
                Vector3::new(0.0, 0.0, z4),
                random_errors(&mut rng, delta, eps),
            );
            let s = random_state(&mut rng);
            let a = AhnCho::from_model(&m, &s);
            let (y, z) = (s.position.y, s.position.z);
            let htm = m.volumetric_error(&s, &no_heat());
            let closed = a.delta_v(y, z, z4) + a.self_terms(y, z, z4);
            let (e, d) = a.magnitudes();
            let lever = y.abs() + z.abs() + z4.abs();
            let bound =
                35.0 * e.powi(3) * lever + 15.0 * e * e * d + 5.0 / 6.0 * e.powi(3) * lever + 1e-15;
            let diff = (htm - closed).amax();
            assert!(
                diff <= bound,
                "ΔV differs by {diff:e} m > bound {bound:e} (δ {delta}, ε {eps})"
            );
            worst_ratio = worst_ratio.max(diff / bound);
        }
        assert!(worst_ratio < 1.0);
    }
}

/// The closed form without its second-order cross terms is measurably worse than with them:
/// the cross terms are really produced by the chain (not just hidden inside the bound).
#[test]
fn ahn_cho_cross_terms_are_resolved_by_the_test() {
    let mut rng = StdRng::seed_from_u64(7);
    let (delta, eps) = (1e-3, 1e-2);
    let mut with_cross = 0.0;
    let mut without = 0.0;
    for _ in 0..200 {
        let z4 = rng.random_range(-0.25..0.25);
        let m = model_with(
            "WXYGZT",
            Vector3::new(0.0, 0.0, z4),
            random_errors(&mut rng, delta, eps),
        );
        let s = random_state(&mut rng);
        let a = AhnCho::from_model(&m, &s);
        let (y, z) = (s.position.y, s.position.z);
        let htm = m.volumetric_error(&s, &no_heat());
        let full = a.delta_v(y, z, z4) + a.self_terms(y, z, z4);
        let first = first_order(&a, y, z, z4);
        with_cross += (htm - full).norm();
        without += (htm - first - a.self_terms(y, z, z4)).norm();
    }
    assert!(
        without > 100.0 * with_cross,
        "cross terms: {without:e} vs {with_cross:e}"
    );
}

/// The first-order part of eqs. (1)–(3).
fn first_order(a: &AhnCho, y: f64, z: f64, z4: f64) -> Vector3<f64> {
    let (d, e) = (&a.d, &a.e);
    Vector3::new(
        d[0][0] + d[0][1] + d[0][2] - y * e[2][0] - y * a.sxy + z * e[1][0] + z * e[1][1]
            - z * a.sxz
            + z4 * (e[1][0] + e[1][1] + e[1][2]),
        d[1][0] + d[1][1] + d[1][2]
            - z * e[0][0]
            - z * e[0][1]
            - z * a.syz
            - z4 * (e[0][0] + e[0][1] + e[0][2]),
        d[2][0] + d[2][1] + d[2][2] + y * e[0][0],
    )
}

/// A pure pitch of X (EBX = θ) with tool length L: the Abbe error of the lever z - L, exactly.
#[test]
fn pure_pitch_with_tool_offset_is_the_abbe_error() {
    let theta = 40e-6;
    let length = 0.15;
    let mut e = GeometricErrors::zero();
    e.axis_mut(Axis::X).set(Component::Ry, constant(theta));
    let m = model_with("WXYGZT", Vector3::new(0.0, 0.0, -length), e);
    let s = AxisState::new(Vector3::new(0.3, 0.2, -0.1), Direction::Forward);
    let h = s.position.z - length;
    let expected = Vector3::new(h * theta.sin(), 0.0, h * (theta.cos() - 1.0));
    let got = m.volumetric_error(&s, &no_heat());
    assert!(
        (got - expected).amax() < ROUNDING,
        "{got:?} vs {expected:?}"
    );
    // 40 µrad over 250 mm: 10 µm of Abbe error towards -X (first order: θ·h).
    assert!((got.x + 10e-6).abs() < theta * theta * h.abs());
}

/// Single errors with exact closed forms: positional, yaw over the Y lever, squareness, roll
/// of Z with a TCP offset.
#[test]
fn single_errors_match_hand_computation_exactly() {
    let p = Vector3::new(0.25, 0.3, -0.2);
    let s = AxisState::new(p, Direction::Forward);
    let tool = Vector3::new(0.01, -0.02, -0.1);
    let run = |f: &dyn Fn(&mut GeometricErrors)| {
        let mut e = GeometricErrors::zero();
        f(&mut e);
        model_with("WXYGZT", tool, e).volumetric_error(&s, &no_heat())
    };
    let v = 7e-6;
    // EXX: +X by exactly v.
    let got = run(&|e| e.axis_mut(Axis::X).set(Component::Tx, constant(v)));
    assert!((got - Vector3::new(v, 0.0, 0.0)).amax() < ROUNDING);
    // ECX (yaw of X): everything after X (y, z, tool) turns about +Z.
    let got = run(&|e| e.axis_mut(Axis::X).set(Component::Rz, constant(v)));
    let lever = Vector3::new(0.0, p.y, p.z) + tool;
    let expected = Rotation3::new(Vector3::z() * v) * lever - lever;
    assert!((got - expected).amax() < ROUNDING);
    // EC0Y: the Y travel turns about +Z: (-y sin s, y (cos s - 1), 0).
    let got = run(&|e| e.set_squareness(SquarenessError::C0Y, SquarenessValue::constant(v)));
    let expected = Vector3::new(-p.y * v.sin(), p.y * (v.cos() - 1.0), 0.0);
    assert!((got - expected).amax() < ROUNDING);
    // ECZ (roll of Z): only the tool offset turns.
    let got = run(&|e| e.axis_mut(Axis::Z).set(Component::Rz, constant(v)));
    let expected = Rotation3::new(Vector3::z() * v) * tool - tool;
    assert!((got - expected).amax() < ROUNDING);
}

/// With every error zero the chain gives the nominal tool point, in all 24 topologies.
#[test]
fn zero_errors_give_the_nominal_point_in_every_topology() {
    let mut rng = StdRng::seed_from_u64(24);
    let all = Topology::all();
    assert_eq!(all.len(), 24);
    for t in all {
        let mut k = Kinematics::new(t);
        k.tool_offset = Vector3::new(0.02, -0.01, -0.18);
        k.link_pivots = std::array::from_fn(|i| Vector3::new(0.1 * i as f64, -0.3, 0.7));
        let m = VolumetricModel::new(k, GeometricErrors::zero());
        for _ in 0..100 {
            let s = random_state(&mut rng);
            let got = m.tool_point(&s, &no_heat());
            let nominal = s.position + m.kinematics.tool_offset;
            assert!((got - nominal).amax() < 1e-12, "{t}: {got:?}");
        }
    }
}

/// The lever of an axis' angular errors: everything after it in the chain from the workpiece.
fn lever_after(t: &Topology, axis: Axis, p: &Vector3<f64>, tool: &Vector3<f64>) -> Vector3<f64> {
    let i = t.axis_index(axis);
    let mut r = *tool;
    for e in &t.chain()[i + 1..] {
        if let Element::Axis(a) = e {
            r[a.index()] += p[a.index()];
        }
    }
    r
}

/// Ahn & Cho's sign rules in every topology: a positive translation moves the tool relative to
/// the workpiece along +X/+Y/+Z; a positive angular error turns it right-handed about +X/+Y/+Z
/// (first order: θ × lever); a positive squareness turns the axis' travel right-handed.
#[test]
fn positive_errors_follow_the_sign_rules_in_every_topology() {
    let p = Vector3::new(0.31, 0.17, -0.23);
    let tool = Vector3::new(0.015, 0.01, -0.12);
    let v = 1e-6;
    for t in Topology::all() {
        for axis in Axis::ALL {
            for c in Component::ALL {
                let mut e = GeometricErrors::zero();
                e.axis_mut(axis).set(c, constant(v));
                let m = model_with(&t.to_string(), tool, e);
                let got = m.volumetric_error(&AxisState::new(p, Direction::Forward), &no_heat());
                let unit = Vector3::ith(c.index() % 3, 1.0);
                let expected = if c.is_angular() {
                    (unit * v).cross(&lever_after(&t, axis, &p, &tool))
                } else {
                    unit * v
                };
                assert!(
                    (got - expected).amax() < v * v + 1e-18,
                    "{t} {}: {got:?} vs {expected:?}",
                    c.iso_name(axis)
                );
            }
        }
        for sq in SquarenessError::ALL {
            let mut e = GeometricErrors::zero();
            e.set_squareness(sq, SquarenessValue::constant(v));
            let m = model_with(&t.to_string(), tool, e);
            let got = m.volumetric_error(&AxisState::new(p, Direction::Forward), &no_heat());
            let (_, moved) = sq.axes();
            let k = match sq {
                SquarenessError::C0Y => Vector3::z(),
                SquarenessError::B0Z => Vector3::y(),
                SquarenessError::A0Z => Vector3::x(),
            };
            let expected = (k * v).cross(&(Vector3::ith(moved.index(), 1.0) * p[moved.index()]));
            assert!((got - expected).amax() < v * v, "{t} {}", sq.iso_name());
        }
    }
}

/// Backward approach uses the backward functions; the difference is the backlash. Squareness
/// uses the value of its pair of directions.
#[test]
fn direction_state_selects_forward_or_backward_values() {
    let b = 3e-6;
    let mut e = GeometricErrors::zero();
    e.axis_mut(Axis::X).set(
        Component::Tx,
        Directional {
            forward: ErrorFunction::Zero,
            backward: constant(b).forward,
        },
    );
    let sq = SquarenessValue {
        values: [[10e-6, 12e-6], [14e-6, 16e-6]],
    };
    e.set_squareness(SquarenessError::C0Y, sq);
    let m = model_with("WXYGZT", Vector3::zeros(), e);
    let p = Vector3::new(0.1, 0.2, -0.1);
    // X and Y approached in directions dx and dy (Z forward).
    let at = |dx, dy| {
        let s = AxisState {
            position: p,
            direction: [dx, dy, Direction::Forward],
        };
        m.volumetric_error(&s, &no_heat())
    };
    use Direction::{Backward as B, Forward as F};
    // X reversed: EXX's backlash b, and EC0Y's value for (X backward, Y forward) acting on -y.
    let expected = b - p.y * (f64::sin(14e-6) - f64::sin(10e-6));
    assert!((at(B, F).x - at(F, F).x - expected).abs() < ROUNDING);
    for (dx, dy, s) in [(F, F, 10e-6), (F, B, 12e-6), (B, F, 14e-6), (B, B, 16e-6)] {
        let expected_y = p.y * (f64::cos(s) - 1.0);
        assert!(
            (at(dx, dy).y - expected_y).abs() < ROUNDING,
            "{dx:?} {dy:?}"
        );
    }
}

/// The chain evaluated on the point equals the explicit product of its 4x4 matrices.
#[test]
fn point_evaluation_equals_the_product_of_4x4_matrices() {
    let mut rng = StdRng::seed_from_u64(44);
    for t in Topology::all() {
        let mut k = Kinematics::new(t);
        k.tool_offset = Vector3::new(0.0, 0.01, -0.1);
        k.link_pivots = std::array::from_fn(|i| Vector3::new(0.0, 0.1 * i as f64, 0.5));
        let m = VolumetricModel::new(k, random_errors(&mut rng, 50e-6, 100e-6));
        let mut thermal = ThermalDeformation::default();
        for (i, l) in thermal.links.iter_mut().enumerate() {
            l.translation = Vector3::new(1e-6, -2e-6, 3e-6) * i as f64;
            l.rotation = Vector3::new(-2e-6, 1e-6, 4e-6) * i as f64;
        }
        thermal.joints[1].rotation = Vector3::new(3e-6, 0.0, -1e-6);
        let s = random_state(&mut rng);
        let product = m
            .chain_factors(&s, &thermal)
            .iter()
            .fold(nalgebra::Matrix4::identity(), |acc, f| acc * f.to_matrix4());
        let tool = m.kinematics.tool_offset;
        let by_matrix = product * Vector4::new(tool.x, tool.y, tool.z, 1.0);
        let by_point = m.tool_point(&s, &thermal);
        assert!((by_matrix.xyz() - by_point).amax() < 1e-15, "{t}");
    }
}

/// ISO 230-3 arithmetic: a 500 mm steel scale (α = 11.5e-6 /K) 1 K above 20 °C grows 5.75 µm.
#[test]
fn scale_expansion_of_500_mm_at_one_kelvin_is_5_75_um() {
    let m = model_with("WXYGZT", Vector3::zeros(), GeometricErrors::zero());
    let mut thermal_model = ThermalDeformationModel::default();
    thermal_model.joints[0] = JointThermalModel {
        expansion: Some(AxisExpansion {
            node: 0,
            alpha_per_k: 11.5e-6,
            reference_m: 0.0,
        }),
        rotation: vec![],
    };
    let d = thermal_model.deformation(&[21.0]).unwrap();
    let s = AxisState::new(Vector3::new(0.5, 0.0, 0.0), Direction::Forward);
    let e = m.volumetric_error(&s, &d);
    assert!((e.x - 5.75e-6).abs() < 1e-15, "{e:?}");
    assert_eq!((e.y, e.z), (0.0, 0.0));
}

/// Thermal deformation is physical: a table (workpiece side) that rises lowers the tool
/// relative to the workpiece, a head (tool side) that rises raises it; a carriage's thermal tilt
/// turns the tool the other way when the carriage carries the workpiece.
#[test]
fn thermal_deformations_act_with_the_physical_sign_on_each_side() {
    let m = model_with(
        "WXYGZT",
        Vector3::new(0.0, 0.0, -0.1),
        GeometricErrors::zero(),
    );
    let s = AxisState::new(Vector3::new(0.2, 0.1, -0.1), Direction::Forward);
    let rise = Vector3::new(0.0, 0.0, 4e-6);
    for (link, sign) in [(0, -1.0), (1, -1.0), (2, -1.0), (3, 1.0), (4, 1.0)] {
        let mut d = ThermalDeformation::default();
        d.links[link].translation = rise;
        let e = m.volumetric_error(&s, &d);
        assert!((e - rise * sign).amax() < ROUNDING, "link {link}: {e:?}");
    }
    let tilt = Vector3::new(0.0, 5e-6, 0.0);
    let mut d = ThermalDeformation::default();
    d.joints[0].rotation = tilt; // X carries the workpiece in WXYGZT
    let e = m.volumetric_error(&s, &d);
    // The table turns with its own travel: the lever is the whole x + y + z + tool.
    let lever = Vector3::new(0.2, 0.1, -0.2);
    assert!((e - (-tilt).cross(&lever)).amax() < tilt.norm_squared() * lever.norm());
    // On the tool side (Z head) the tilt turns only what the head carries: the tool.
    let mut d = ThermalDeformation::default();
    d.joints[2].rotation = tilt;
    let e = m.volumetric_error(&s, &d);
    let tool = Vector3::new(0.0, 0.0, -0.1);
    assert!((e - tilt.cross(&tool)).amax() < tilt.norm_squared() * tool.norm());
    // A node-temperature model drives the same terms linearly.
    let mut tm = ThermalDeformationModel::default();
    tm.links[3].translation.push(NodeSensitivity {
        node: 1,
        per_kelvin: Vector3::new(0.0, 1e-6, 2e-6),
    });
    let d = tm.deformation(&[20.0, 22.5]).unwrap();
    assert!((d.links[3].translation - Vector3::new(0.0, 2.5e-6, 5e-6)).amax() < ROUNDING);
}
