//! The machine's structure: each carriage a rigid body held on its guideway by its rolling
//! guide blocks.
//!
//! A carriage (table, saddle, spindle head) has its own mass `m`, centre of mass `c` and inertia
//! tensor `I_c` about it (from the scenario, or of a homogeneous box: `I = m/12·diag(b²+h², l²+h²,
//! l²+b²)` for edges l, b, h along X, Y, Z). It runs along its axis `u` on guide blocks, each at
//! `p_b` with a normal (load) direction `n_b` and a lateral direction `l_b = u × n_b`, stiff along
//! both and free along the rail (rolling elements). Positions are in the machine frame with every
//! axis at zero (the frame of the structural links' pivots), metres.
//!
//! Small motions of the carriage about its nominal place are taken at its **anchor** `a`, the
//! centroid of its blocks: a translation `t` and a rotation vector `θ` (rad) about `a`. A block
//! then deflects by `d_b = t + θ × r_b` (`r_b = p_b − a`) and pushes back with
//!
//! ```text
//! f_b = −(k_n n nᵀ + k_l l lᵀ)·d_b − (c_n n nᵀ + c_l l lᵀ)·ḋ_b        N, at p_b
//! ```
//!
//! so that on the coordinates `x = [t, θ]` the blocks act as `τ = −K x − C ẋ` with
//! `K = Σ_b B_bᵀ S_b B_b`, `B_b = [I | −[r_b]×]` (and `C` alike), the usual lumped model of
//! linear-guide joints (e.g. Altintas, Brecher, Weck & Witt, "Virtual machine tool", CIRP
//! Annals 54(2), 2005, §3; block stiffness from the guide makers' catalogues, hundreds of N/µm
//! per block of size 25–45). The translation along `u` is the axis' own coordinate, held by the
//! drive at the ball nut `p_n`, not by the blocks; the other five directions must be held by the
//! blocks ([`StructureError::Unheld`]).
//!
//! For a symmetric layout the closed forms follow: the pitch stiffness of blocks spread along
//! the axis by `±s/2` is `Σ k_n (s/2)²`, and a carriage accelerated at `a` by a nut lying `h`
//! below its centre of mass pitches by `m·a·h / Σ k_n (s/2)²` (the couple of the inertial and
//! the drive force over the angular stiffness); its pitch frequency is
//! `√(Σ k_n (s/2)² / I_pitch)/2π` with `I_pitch` about the anchor when the centre of mass lies
//! over it.

use crate::axis::Axis;
use nalgebra::{Matrix3, Matrix6, SMatrix, SymmetricEigen, Vector3};
use thiserror::Error;

/// One rolling guide block (carriage of a profile rail), SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GuideBlock {
    /// Where it is, machine frame with every axis at zero, m.
    pub position_m: Vector3<f64>,
    /// Unit normal (load) direction, perpendicular to the axis.
    pub normal: Vector3<f64>,
    /// Stiffness along the normal, N/m.
    pub normal_stiffness_n_per_m: f64,
    /// Stiffness across the rail (axis × normal), N/m.
    pub lateral_stiffness_n_per_m: f64,
    /// Damping along the normal, N·s/m.
    pub normal_damping_n_s_per_m: f64,
    /// Damping across the rail, N·s/m.
    pub lateral_damping_n_s_per_m: f64,
}

/// One carriage as a rigid body on its guide blocks.
#[derive(Clone, Debug, PartialEq)]
pub struct Carriage {
    /// The axis it moves along.
    pub axis: Axis,
    /// Its own mass (without the carriages it carries), kg.
    pub mass_kg: f64,
    /// Centre of mass, machine frame with every axis at zero, m.
    pub com_m: Vector3<f64>,
    /// Inertia tensor about the centre of mass, machine axes, kg·m².
    pub inertia_kg_m2: Matrix3<f64>,
    /// Centre of its box, m.
    pub box_center_m: Vector3<f64>,
    /// Edges of its box along X, Y, Z, m.
    pub box_size_m: Vector3<f64>,
    /// Where the drive's ball nut pushes it, m.
    pub nut_m: Vector3<f64>,
    /// Its guide blocks.
    pub blocks: Vec<GuideBlock>,
}

/// The compliant structure of the machine: the carriages of X, Y, Z.
#[derive(Clone, Debug, PartialEq)]
pub struct Structure {
    /// The carriages of X, Y, Z.
    pub carriages: [Carriage; 3],
}

/// A carriage that is no rigid body on guide blocks.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum StructureError {
    /// A block lies outside the carriage's box.
    #[error(
        "block {block} of the {axis} carriage at ({:.1}, {:.1}, {:.1}) mm lies outside the carriage's box ({:.1} to {:.1}, {:.1} to {:.1}, {:.1} to {:.1} mm); a block is fixed to its carriage, within its box or on its faces",
        .at_mm[0], .at_mm[1], .at_mm[2], .lo_mm[0], .hi_mm[0], .lo_mm[1], .hi_mm[1], .lo_mm[2], .hi_mm[2]
    )]
    BlockOutside {
        /// The axis.
        axis: Axis,
        /// Index of the block.
        block: usize,
        /// Its position, mm.
        at_mm: [f64; 3],
        /// The box's lower corner, mm.
        lo_mm: [f64; 3],
        /// The box's upper corner, mm.
        hi_mm: [f64; 3],
    },
    /// A stiffness or damping that is not a positive (damping: non-negative) number.
    #[error(
        "the {axis} carriage's {what} is {value}: a stiffness must be a number > 0 (a damping ≥ 0)"
    )]
    NotPositive {
        /// The axis.
        axis: Axis,
        /// Which value.
        what: &'static str,
        /// The value.
        value: f64,
    },
    /// The inertia tensor is not symmetric positive definite.
    #[error(
        "the {axis} carriage's inertia tensor is not positive definite (eigenvalues {:.4}, {:.4}, {:.4} kg·m²): a rigid body's is symmetric with positive principal moments",
        .eigen[0], .eigen[1], .eigen[2]
    )]
    Inertia {
        /// The axis.
        axis: Axis,
        /// Its eigenvalues (of the symmetric part), kg·m².
        eigen: [f64; 3],
    },
    /// The blocks leave a direction other than the axis free.
    #[error(
        "the {axis} carriage's blocks do not hold it in all five directions across its axis (its guide stiffness has a free direction besides the axis: blocks on one line, or normals all along one direction); at least three blocks not on one line, with normals across the axis"
    )]
    Unheld {
        /// The axis.
        axis: Axis,
    },
    /// A block's normal is not perpendicular to the axis.
    #[error(
        "block {block} of the {axis} carriage has its normal along the axis; a block carries load across its rail"
    )]
    Normal {
        /// The axis.
        axis: Axis,
        /// Index of the block.
        block: usize,
    },
    /// A mass that is not positive.
    #[error("the {axis} carriage's own mass is {mass_kg} kg; a number > 0")]
    Mass {
        /// The axis.
        axis: Axis,
        /// The mass, kg.
        mass_kg: f64,
    },
}

/// The inertia tensor of a homogeneous box of `mass_kg` with edges `size_m` along X, Y, Z about
/// its centre, kg·m².
pub fn box_inertia(mass_kg: f64, size_m: &Vector3<f64>) -> Matrix3<f64> {
    let [l, b, h] = [size_m.x, size_m.y, size_m.z].map(|e| e * e);
    Matrix3::from_diagonal(&Vector3::new(b + h, l + h, l + b)) * (mass_kg / 12.0)
}

/// The skew matrix `[r]×` with `[r]× v = r × v`.
pub fn skew(r: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -r.z, r.y, r.z, 0.0, -r.x, -r.y, r.x, 0.0)
}

/// Tolerance of the box check, m: a block bolted to a face lies on it to within its rounding.
const ON_FACE_M: f64 = 1e-6;

impl GuideBlock {
    /// The lateral direction of a block on a carriage moving along `axis`: `u × n`.
    pub fn lateral(&self, axis: Axis) -> Vector3<f64> {
        axis_unit(axis).cross(&self.normal).normalize()
    }

    /// The block's stiffness (`damping = false`) or damping tensor along its normal and lateral
    /// directions, N/m or N·s/m.
    fn tensor(&self, axis: Axis, damping: bool) -> Matrix3<f64> {
        let (kn, kl) = if damping {
            (
                self.normal_damping_n_s_per_m,
                self.lateral_damping_n_s_per_m,
            )
        } else {
            (
                self.normal_stiffness_n_per_m,
                self.lateral_stiffness_n_per_m,
            )
        };
        let (n, l) = (self.normal, self.lateral(axis));
        n * n.transpose() * kn + l * l.transpose() * kl
    }
}

/// The unit vector of `axis`.
pub fn axis_unit(axis: Axis) -> Vector3<f64> {
    Vector3::ith(axis.index(), 1.0)
}

impl Carriage {
    /// The anchor: the centroid of the blocks, m (the point the small motions are taken at).
    pub fn anchor_m(&self) -> Vector3<f64> {
        let n = self.blocks.len().max(1) as f64;
        self.blocks
            .iter()
            .fold(Vector3::zeros(), |s, b| s + b.position_m)
            / n
    }

    /// The blocks' stiffness matrix `K` on `[t, θ]` at the anchor (module docs), N/m, N, N·m.
    pub fn stiffness(&self) -> Matrix6<f64> {
        self.assemble(false)
    }

    /// The blocks' damping matrix `C` on `[ṫ, θ̇]` at the anchor.
    pub fn damping(&self) -> Matrix6<f64> {
        self.assemble(true)
    }

    fn assemble(&self, damping: bool) -> Matrix6<f64> {
        let a = self.anchor_m();
        let mut k = Matrix6::zeros();
        for b in &self.blocks {
            let mut bm = SMatrix::<f64, 3, 6>::zeros();
            bm.fixed_view_mut::<3, 3>(0, 0)
                .copy_from(&Matrix3::identity());
            bm.fixed_view_mut::<3, 3>(0, 3)
                .copy_from(&(-skew(&(b.position_m - a))));
            k += bm.transpose() * b.tensor(self.axis, damping) * bm;
        }
        k
    }

    /// The carriage's rigid-body mass matrix on `[t, θ]` at the anchor: `[[m I, −m[c]×],
    /// [m[c]×, I_c − m[c]×²]]` with `c` the centre of mass from the anchor.
    pub fn mass_matrix(&self) -> Matrix6<f64> {
        let c = skew(&(self.com_m - self.anchor_m()));
        let m = self.mass_kg;
        let mut out = Matrix6::zeros();
        out.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(Matrix3::identity() * m));
        out.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-c * m));
        out.fixed_view_mut::<3, 3>(3, 0).copy_from(&(c * m));
        out.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(self.inertia_kg_m2 - c * c * m));
        out
    }

    /// Checks the carriage: a positive mass, a positive definite inertia tensor, positive
    /// stiffnesses (non-negative dampings), normals across the axis, blocks within the box, and
    /// the five directions across the axis held.
    pub fn validate(&self) -> Result<(), StructureError> {
        let axis = self.axis;
        if !(self.mass_kg > 0.0 && self.mass_kg.is_finite()) {
            return Err(StructureError::Mass {
                axis,
                mass_kg: self.mass_kg,
            });
        }
        let i = self.inertia_kg_m2;
        let eig = SymmetricEigen::new((i + i.transpose()) * 0.5).eigenvalues;
        let symmetric = (i - i.transpose()).amax() <= 1e-9 * i.amax().max(1e-300);
        if !symmetric || !eig.iter().all(|&e| e > 0.0 && e.is_finite()) {
            return Err(StructureError::Inertia {
                axis,
                eigen: [eig[0], eig[1], eig[2]],
            });
        }
        let lo = self.box_center_m - self.box_size_m / 2.0;
        let hi = self.box_center_m + self.box_size_m / 2.0;
        for (k, b) in self.blocks.iter().enumerate() {
            for (what, v, strict) in [
                ("normal stiffness", b.normal_stiffness_n_per_m, true),
                ("lateral stiffness", b.lateral_stiffness_n_per_m, true),
                ("normal damping", b.normal_damping_n_s_per_m, false),
                ("lateral damping", b.lateral_damping_n_s_per_m, false),
            ] {
                let ok = v.is_finite() && if strict { v > 0.0 } else { v >= 0.0 };
                if !ok {
                    return Err(StructureError::NotPositive {
                        axis,
                        what,
                        value: v,
                    });
                }
            }
            if b.normal.cross(&axis_unit(axis)).norm() < 1e-6 {
                return Err(StructureError::Normal { axis, block: k });
            }
            let p = b.position_m;
            let outside = (0..3).any(|j| p[j] < lo[j] - ON_FACE_M || p[j] > hi[j] + ON_FACE_M);
            if outside {
                let mm = |v: Vector3<f64>| [v.x * 1e3, v.y * 1e3, v.z * 1e3];
                return Err(StructureError::BlockOutside {
                    axis,
                    block: k,
                    at_mm: mm(p),
                    lo_mm: mm(lo),
                    hi_mm: mm(hi),
                });
            }
        }
        // The five directions across the axis: K without the axis' row and column is
        // positive definite, judged relative to its largest eigenvalue.
        let across = self.across_axis(&self.stiffness());
        let eig = SymmetricEigen::new(across).eigenvalues;
        let top = eig.amax();
        // NaN (unevaluable) counts as free too.
        let held = eig.min() > 1e-9 * top;
        if self.blocks.is_empty() || !held {
            return Err(StructureError::Unheld { axis });
        }
        Ok(())
    }

    /// `m` without the row and column of the axis' translation: the five directions the
    /// blocks hold.
    pub fn across_axis(&self, m: &Matrix6<f64>) -> SMatrix<f64, 5, 5> {
        let keep: Vec<usize> = (0..6).filter(|&j| j != self.axis.index()).collect();
        SMatrix::<f64, 5, 5>::from_fn(|r, c| m[(keep[r], keep[c])])
    }
}
