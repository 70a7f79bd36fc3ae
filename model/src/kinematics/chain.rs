//! The volumetric error: actual tool point relative to the workpiece, from the HTM chain.
//!
//! Following Min & Chung (2013, eq. 2) the tool point in workpiece coordinates is
//! `ᵂP_T = [workpiece branch]⁻¹ · [tool branch] · ˢP_T`. Read from the workpiece to the tool
//! through a topology `e0 e1 ... e5` (see [`Topology`]) this is the product
//!
//! ```text
//! ᵂP_T = L0 · J(e1) · L1 · J(e2) · L2 · J(e3) · L3 · J(e4) · L4 · ˢP_T
//! ```
//!
//! with one joint matrix `J` per axis element (the ground has none) and one structural link `Lk`
//! between elements `k` and `k+1`:
//!
//! - `J(q) = Trans(q·u + δ(q) + P(T)(q - q_ref)·u) · R(ε(q))`, where `u` is the unit vector of the
//!   axis' reference straight line (the nominal axis turned by the squareness errors), `δ` the
//!   translational errors (EX?, EY?, EZ?) and `ε` the angular errors (EA?, EB?, EC?) for the
//!   axis' direction state, with the error motion of the rails' local defects added to both
//!   (`geometric::Guideway`). The geometric errors are motions of the tool relative to the
//!   workpiece (ISO 230-1, Ahn & Cho's sign rules), so this form holds on both sides of the
//!   ground. The thermal rotation `ε_j` is a physical rotation of the carriage: on the tool side
//!   it turns what the carriage carries, `J·R(ε_j)`; on the workpiece side the carriage is the
//!   inverse of its motion in Min & Chung's chain, `(Trans(-q)·R(ε_j))⁻¹ = R(-ε_j)·Trans(q)`, so
//!   it turns the carriage's own travel as well, `R(-ε_j)·J`.
//! - `Lk = S_k` on the tool side and `S_k⁻¹` on the workpiece side, where
//!   `S_k = Trans(Δ(T)) · Trans(p_k) · R(ε_s(T)) · Trans(-p_k)` is the physical deformation of the
//!   link, rotating about its pivot `p_k` (e.g. the foot of the column) and translating by Δ.
//! - `ˢP_T` is the tool centre point in the spindle frame: TCP offset and tool length.
//!
//! The nominal tool point is `q + ˢP_T` (all errors zero). Every rotation is exact (see
//! [`crate::kinematics::htm`]); the product is evaluated right to left on the point, which equals
//! the 4x4 product applied to it ([`VolumetricModel::chain_factors`] returns the factors).

use super::htm::{Htm, rotation_matrix};
use super::topology::{Element, Side, Topology};
use crate::axis::{Axis, Direction};
use crate::geometric::GeometricErrors;
use crate::thermal_deformation::ThermalDeformation;
use nalgebra::{Matrix3, Vector3};

/// The nominal geometry of the kinematic chain.
#[derive(Clone, Debug, PartialEq)]
pub struct Kinematics {
    /// Order of workpiece, axes, ground and tool.
    pub topology: Topology,
    /// Tool centre point in the spindle frame, m: (TCP x, TCP y, -tool length).
    pub tool_offset: Vector3<f64>,
    /// Pivot of each structural link's thermal rotation, m, in the link's own frame: the
    /// machine frame as it is with every axis at zero (nominal links are identities, so the two
    /// coincide there); the pivot moves with the carriages that precede the link in the chain.
    pub link_pivots: [Vector3<f64>; 5],
}

impl Kinematics {
    /// A chain with zero tool offset and pivots at the origin.
    pub fn new(topology: Topology) -> Self {
        Self {
            topology,
            tool_offset: Vector3::zeros(),
            link_pivots: [Vector3::zeros(); 5],
        }
    }
}

/// Positions (m) and direction states of the three axes.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct AxisState {
    /// X, Y, Z commanded coordinates of the tool relative to the workpiece, m.
    pub position: Vector3<f64>,
    /// Direction state of X, Y, Z.
    pub direction: [Direction; 3],
}

impl AxisState {
    /// All axes at `position` (m), last moved in `direction`.
    pub fn new(position: Vector3<f64>, direction: Direction) -> Self {
        Self {
            position,
            direction: [direction; 3],
        }
    }
}

/// What an axis' carriage adds to its geometric errors while it deflects on its guide blocks
/// (the dynamic part of its ISO 230-1 errors: straightness, positioning, pitch, yaw, roll), in
/// the form of the joint's errors: a translation δ (m) and a rotation vector ε (rad) of the tool
/// relative to the workpiece, added to the geometric ones (`Trans(q·u + δ_g + δ_d)·R(ε_g +
/// ε_d)`: first order in the µrad-sized rotations, whose products are below 1e-10).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Deflection {
    /// Translation, m.
    pub translation: Vector3<f64>,
    /// Rotation vector, rad.
    pub rotation: Vector3<f64>,
}

/// Geometric errors on a kinematic chain: the machine's quasi-static error model.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumetricModel {
    /// Nominal chain.
    pub kinematics: Kinematics,
    /// The 21 direction-dependent geometric errors.
    pub errors: GeometricErrors,
}

/// A [`VolumetricModel`] prepared for one thermal state: link matrices and joint thermal
/// rotations are computed once, so that each point costs only its own joint matrices.
#[derive(Clone, Debug)]
pub struct VolumetricEvaluator<'a> {
    model: &'a VolumetricModel,
    thermal: ThermalDeformation,
    links: [Htm; 5],
    link_identity: [bool; 5],
    joint_thermal: [Option<Matrix3<f64>>; 3],
    /// Unit vectors of the axes' reference straight lines (squareness), for each of the eight
    /// combinations of direction states, indexed by [`direction_index`].
    axis_lines: [[Vector3<f64>; 3]; 8],
    /// Whether each axis' carriage moves the tool (else the workpiece).
    moves_tool: [bool; 3],
}

/// Index 0..8 of a combination of the three direction states.
fn direction_index(d: &[Direction; 3]) -> usize {
    d[0].index() | d[1].index() << 1 | d[2].index() << 2
}

impl VolumetricModel {
    /// A model of `kinematics` with `errors`.
    pub fn new(kinematics: Kinematics, errors: GeometricErrors) -> Self {
        Self { kinematics, errors }
    }

    /// The nominal tool point relative to the workpiece at `position` (m).
    pub fn nominal_tool_point(&self, position: &Vector3<f64>) -> Vector3<f64> {
        position + self.kinematics.tool_offset
    }

    /// Prepares evaluation at one thermal state.
    pub fn evaluator(&self, thermal: &ThermalDeformation) -> VolumetricEvaluator<'_> {
        let topology = &self.kinematics.topology;
        let links = std::array::from_fn(|k| {
            let d = thermal.links[k];
            let s = Htm::rotation_about(d.rotation, self.kinematics.link_pivots[k], d.translation);
            match topology.link_side(k) {
                Side::Workpiece => s.inverse(),
                Side::Tool => s,
            }
        });
        let link_identity = std::array::from_fn(|k| thermal.links[k] == Default::default());
        let joint_thermal = std::array::from_fn(|i| {
            let eps = thermal.joints[i].rotation;
            (eps != Vector3::zeros()).then(|| match topology.axis_side(Axis::ALL[i]) {
                Side::Workpiece => rotation_matrix(-eps),
                Side::Tool => rotation_matrix(eps),
            })
        });
        let axis_lines = std::array::from_fn(|combo| {
            let dirs = std::array::from_fn(|i| match combo >> i & 1 {
                0 => Direction::Forward,
                _ => Direction::Backward,
            });
            let turns = self.errors.axis_line_rotations(&dirs);
            std::array::from_fn(|i| rotation_matrix(turns[i]).column(i).into_owned())
        });
        let moves_tool = Axis::ALL.map(|a| topology.axis_side(a) == Side::Tool);
        VolumetricEvaluator {
            model: self,
            axis_lines,
            moves_tool,
            thermal: *thermal,
            links,
            link_identity,
            joint_thermal,
        }
    }

    /// The actual tool point relative to the workpiece, m.
    pub fn tool_point(&self, state: &AxisState, thermal: &ThermalDeformation) -> Vector3<f64> {
        self.evaluator(thermal).tool_point(state)
    }

    /// The volumetric error (actual minus nominal tool point), m.
    pub fn volumetric_error(
        &self,
        state: &AxisState,
        thermal: &ThermalDeformation,
    ) -> Vector3<f64> {
        self.evaluator(thermal).volumetric_error(state)
    }

    /// The nine factors `L0, J(e1), L1, ..., L4` of the chain in order from the workpiece, for
    /// checking the chain against explicit 4x4 products. The tool point is their product applied
    /// to the tool offset.
    pub fn chain_factors(&self, state: &AxisState, thermal: &ThermalDeformation) -> Vec<Htm> {
        let ev = self.evaluator(thermal);
        let chain = self.kinematics.topology.chain();
        let mut out = vec![ev.links[0]];
        for (element, link) in chain[1..5].iter().zip(&ev.links[1..]) {
            out.push(match element {
                Element::Axis(a) => ev.joint(*a, state),
                _ => Htm::identity(),
            });
            out.push(*link);
        }
        out
    }
}

impl VolumetricEvaluator<'_> {
    /// The joint matrix of `axis` at `state`.
    pub fn joint(&self, axis: Axis, state: &AxisState) -> Htm {
        let (geometric, thermal) = self.joint_parts(axis, state, None);
        match (thermal, self.model.kinematics.topology.axis_side(axis)) {
            (None, _) => geometric,
            (Some(r), Side::Tool) => Htm {
                rotation: geometric.rotation * r,
                translation: geometric.translation,
            },
            (Some(r), Side::Workpiece) => Htm {
                rotation: r * geometric.rotation,
                translation: r * geometric.translation,
            },
        }
    }

    /// The joint matrix as `geometric · R(±ε_j)`: the geometric part `Trans(q·u + δ) · R(ε)`
    /// and the thermal rotation, if any, kept apart so a point can go through them in turn.
    #[inline]
    fn joint_parts(
        &self,
        axis: Axis,
        state: &AxisState,
        deflection: Option<&Deflection>,
    ) -> (Htm, Option<&Matrix3<f64>>) {
        let i = axis.index();
        let q = state.position[i];
        let mut motion = self.model.errors.axis(axis).motion(q, state.direction[i]);
        if let Some(g) = &self.model.errors.guideways[i] {
            let local = g.error_motion(q, self.moves_tool[i]);
            motion.translation += local.translation;
            motion.rotation += local.rotation;
        }
        if let Some(d) = deflection {
            motion.translation += d.translation;
            motion.rotation += d.rotation;
        }
        let u = self.axis_lines[direction_index(&state.direction)][i];
        let jt = &self.thermal.joints[i];
        let mut travel = q + jt.strain * (q - jt.reference_m);
        if let Some(screw) = &jt.screw {
            travel += screw.at(q);
        }
        let geometric = Htm {
            rotation: rotation_matrix(motion.rotation),
            translation: u * travel + motion.translation,
        };
        (geometric, self.joint_thermal[i].as_ref())
    }

    /// The actual tool point relative to the workpiece, m.
    #[inline]
    pub fn tool_point(&self, state: &AxisState) -> Vector3<f64> {
        self.tool_point_with(state, None)
    }

    /// The actual tool point relative to the workpiece with the carriages deflected by
    /// `deflections` (X, Y, Z; see [`Deflection`]), m.
    #[inline]
    pub fn tool_point_deflected(
        &self,
        state: &AxisState,
        deflections: &[Deflection; 3],
    ) -> Vector3<f64> {
        self.tool_point_with(state, Some(deflections))
    }

    #[inline]
    fn tool_point_with(
        &self,
        state: &AxisState,
        deflections: Option<&[Deflection; 3]>,
    ) -> Vector3<f64> {
        let chain = self.model.kinematics.topology.chain();
        let mut p = self.model.kinematics.tool_offset;
        for k in (0..5).rev() {
            if !self.link_identity[k] {
                p = self.links[k].transform_point(&p);
            }
            if k > 0
                && let Element::Axis(a) = chain[k]
            {
                let d = deflections.map(|d| &d[a.index()]);
                let (geometric, thermal) = self.joint_parts(a, state, d);
                p = match (thermal, self.model.kinematics.topology.axis_side(a)) {
                    (None, _) => geometric.transform_point(&p),
                    (Some(r), Side::Tool) => geometric.transform_point(&(r * p)),
                    (Some(r), Side::Workpiece) => r * geometric.transform_point(&p),
                };
            }
        }
        p
    }

    /// The volumetric error (actual minus nominal tool point), m.
    #[inline]
    pub fn volumetric_error(&self, state: &AxisState) -> Vector3<f64> {
        self.tool_point(state) - self.model.nominal_tool_point(&state.position)
    }
}
