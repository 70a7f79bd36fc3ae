//! Thermal deformation of the structure and the axes (Min & Chung 2013; ISO 230-3).
//!
//! Min & Chung's chain has, besides the geometric errors, temperature-dependent terms in every
//! link and joint matrix:
//!
//! - structural links `S(T) = [[R(ε_s(T)), (a, b, c) + (Δa, Δb, Δc)(T)], [0, 1]]`: thermal
//!   translations Δa, Δb, Δc (m) and thermal angular errors ε_s (rad) of the bed, column, table...
//! - joints `J(q, T)`: linear expansion of the axis scale `P_i(T)·(q - q_ref)` along the axis, and
//!   thermal angular errors ε_j(T) (rad) of the carriage; where a job simulates the screw's
//!   temperature along its length (`thermal::screw`), its growth `e(q)` in place of the linear
//!   expansion.
//!
//! Every term is modelled as linear in the temperature rises of the thermal network's nodes over
//! the reference temperature (20 °C, ISO 1): `Δ = Σ_k s_k (T_k - 20 °C)`, with sensitivities
//! `s_k` in m/K or rad/K, and `P_i = α_i (T_scale - 20 °C)` with α the expansion coefficient of
//! the scale or screw (1/K), `q_ref` the position where the scale is fixed. Linearity is the
//! standard assumption of thermal error models for the small temperature rises of machine tools
//! (a few K); the deformations are applied through exact rotations in the chain.

use crate::thermal::screw::ScrewGrowth;
use nalgebra::Vector3;
use thiserror::Error;

/// The reference temperature of dimensional metrology, ISO 1: 20 °C.
pub const REFERENCE_TEMPERATURE_C: f64 = 20.0;

/// Sensitivity of a deformation to the temperature rise of one node.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeSensitivity {
    /// Index of the thermal network node.
    pub node: usize,
    /// Deformation per kelvin: m/K for translations, rad/K for rotations, as (x, y, z).
    pub per_kelvin: Vector3<f64>,
}

/// Linear expansion of an axis' position measurement (scale or ball screw).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisExpansion {
    /// Node whose temperature the scale has.
    pub node: usize,
    /// Expansion coefficient, 1/K (steel 11.5e-6).
    pub alpha_per_k: f64,
    /// Axis position at which the scale is fixed and does not move when it grows, m.
    pub reference_m: f64,
}

/// Thermal sensitivities of one structural link.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct LinkThermalModel {
    /// Thermal translations (Δa, Δb, Δc).
    pub translation: Vec<NodeSensitivity>,
    /// Thermal angular errors ε_s.
    pub rotation: Vec<NodeSensitivity>,
}

/// Thermal sensitivities of one axis joint.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct JointThermalModel {
    /// Scale expansion, if modelled.
    pub expansion: Option<AxisExpansion>,
    /// Thermal angular errors ε_j of the carriage.
    pub rotation: Vec<NodeSensitivity>,
}

/// The machine's thermal deformation model: five structural links (in topology order from the
/// workpiece) and three joints (X, Y, Z).
#[derive(Clone, Debug, PartialEq, Default)]
pub struct ThermalDeformationModel {
    /// Links 0..5, link `k` between chain elements `k` and `k + 1`.
    pub links: [LinkThermalModel; 5],
    /// Joints of X, Y, Z.
    pub joints: [JointThermalModel; 3],
}

/// Deformation of a structural link at one thermal state.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct LinkDeformation {
    /// (Δa, Δb, Δc), m.
    pub translation: Vector3<f64>,
    /// ε_s, rad.
    pub rotation: Vector3<f64>,
}

/// Deformation of an axis joint at one thermal state.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct JointDeformation {
    /// `P_i(T)`: strain of the scale, dimensionless.
    pub strain: f64,
    /// Where the scale is fixed, m.
    pub reference_m: f64,
    /// ε_j, rad.
    pub rotation: Vector3<f64>,
    /// The growth of the axis' screw from its temperature field, added to the travel (a
    /// simulated job's distributed screw, `thermal::screw`, in place of the strain), if any.
    pub screw: Option<ScrewGrowth>,
}

/// The deformation of the whole machine at one thermal state.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct ThermalDeformation {
    /// Links in topology order.
    pub links: [LinkDeformation; 5],
    /// Joints of X, Y, Z.
    pub joints: [JointDeformation; 3],
}

/// Temperatures that do not fit the model.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum DeformationError {
    /// Fewer temperatures than the model's nodes.
    #[error("the thermal model uses node {node} but only {given} temperatures were given")]
    MissingNode {
        /// Node index.
        node: usize,
        /// Number of temperatures given.
        given: usize,
    },
    /// A temperature is NaN or infinite.
    #[error("temperature of node {node} is {value}; a finite °C value is needed")]
    NotFinite {
        /// Node index.
        node: usize,
        /// The value.
        value: f64,
    },
}

impl ThermalDeformationModel {
    /// The deformation when the nodes have temperatures `temps_c` (°C, by node index).
    pub fn deformation(&self, temps_c: &[f64]) -> Result<ThermalDeformation, DeformationError> {
        let rise = |node: usize| -> Result<f64, DeformationError> {
            let t = *temps_c.get(node).ok_or(DeformationError::MissingNode {
                node,
                given: temps_c.len(),
            })?;
            if t.is_finite() {
                Ok(t - REFERENCE_TEMPERATURE_C)
            } else {
                Err(DeformationError::NotFinite { node, value: t })
            }
        };
        let sum = |s: &[NodeSensitivity]| -> Result<Vector3<f64>, DeformationError> {
            s.iter().try_fold(Vector3::zeros(), |acc, k| {
                Ok(acc + k.per_kelvin * rise(k.node)?)
            })
        };
        let mut out = ThermalDeformation::default();
        for (d, m) in out.links.iter_mut().zip(&self.links) {
            d.translation = sum(&m.translation)?;
            d.rotation = sum(&m.rotation)?;
        }
        for (d, m) in out.joints.iter_mut().zip(&self.joints) {
            d.rotation = sum(&m.rotation)?;
            if let Some(e) = m.expansion {
                d.strain = e.alpha_per_k * rise(e.node)?;
                d.reference_m = e.reference_m;
            }
        }
        Ok(out)
    }
}
