//! Local defects of an axis' guideway: a bump or a rail-joint step at one place on the rails,
//! which the carriage's blocks ride over.
//!
//! A profiled rail guide carries its carriage on four blocks, two along the axis at spacing
//! `L` on each of two rails. A rail deviation `h(s)` (m, at rail coordinate `s`, along a
//! direction `n` across the axis: vertical or lateral) lifts each block by the deviation
//! averaged over the block's loaded length `b` (its rows of balls share it):
//!
//! ```text
//! bump (raised cosine):   h(s) = H/2 (1 + cos(2π s / w))   for |s| <= w/2, else 0
//! step (rail joint):      h(s) = H                          for s >= 0, else 0
//! block:                  δ_j  = 1/b ∫ h(s) ds over [s_j − b/2, s_j + b/2]   (h(s_j) for b = 0)
//! ```
//!
//! The carriage is rigid and its blocks equally stiff, so it takes the least-squares rigid
//! motion of the four block displacements (blocks at `±L/2` along the axis direction `u` and
//! at `±a` across, along the third machine axis `w`):
//!
//! ```text
//! translation  t = mean(δ_j) n
//! pitch / yaw  θ_p = (mean of front − mean of rear) / L       about u × n
//! roll         θ_r = Σ e_j δ_j / Σ e_j²                        about w × n
//! ```
//!
//! so a bump narrower than `L` tilts the carriage by `H/L` and lifts it by `H/2` as one block
//! passes, and one wider than `L` lifts it almost whole without tilt. A defect on one rail only
//! (at across offset `a`) lifts by half and rolls by `H/2a`. Several defects add.
//!
//! The carriage turns about its blocks' centre `c`, not about the chain's joint origin, so
//! the angle reaches the tool with the Abbe offset from there: in the chain's joint form
//! (`J = Trans(q u + δ) R(ε)`, `kinematics::chain`) the error motion of the tool relative to
//! the workpiece is `ε = s θ`, `δ = s (t − θ × c(q))`, with `s = +1` and `c = c0` for a
//! carriage that moves the tool, and `s = −1` and `c = c0 − q u` for one that moves the
//! workpiece (the joint turns the tool point given in the carriage's parent frame, where the
//! blocks' centre moves by `−q u`); `c0` is the blocks' centre in machine coordinates with every
//! axis at 0. The rail coordinate of the blocks' centre is `s (q − q_d)`, `q_d` the axis
//! position at which the blocks' centre is over the defect. This term is separate from the
//! axis' error functions (Legendre series or tables): it is evaluated where the chain
//! evaluates them, and added.
//!
//! Plausible sizes on a machine of 500 × 400 × 400 mm (rails of size 35–45): rail-joint steps
//! of 1–5 µm (butt joints ground together are specified to a few µm), bumps of 1–3 µm over
//! 10–50 mm (a chip or burr under the rail, a mounting-surface flaw), block spacing 150–350 mm,
//! block lengths 80–120 mm, rail spacing 250–500 mm.

use super::ErrorMotion;
use crate::axis::Axis;
use nalgebra::Vector3;
use std::f64::consts::TAU;

/// The shape of a rail defect.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DefectShape {
    /// A raised cosine of full width `width_m` (m, > 0).
    Bump {
        /// Full width along the rail, m.
        width_m: f64,
    },
    /// A step at a rail joint: the rail is higher by the height beyond the joint (towards +
    /// rail coordinate, the direction the carriage moves for increasing axis position on the
    /// tool side).
    Step,
}

/// One local defect of an axis' rails.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RailDefect {
    /// Its shape.
    pub shape: DefectShape,
    /// The machine axis along which the rail displaces the blocks (across the moving axis).
    pub direction: Axis,
    /// The axis position at which the blocks' centre is over the defect (its middle, or the
    /// joint), m.
    pub at_m: f64,
    /// Height H along `direction`, m (signed).
    pub height_m: f64,
    /// Across offset (along the third machine axis, from the blocks' centre) of the one rail
    /// that has the defect, m; `None`: every rail has it at the same place.
    pub rail_offset_m: Option<f64>,
}

impl RailDefect {
    /// The rail's antiderivative `∫ h ds` from far before the defect to `s` (m²).
    fn integral(&self, s: f64) -> f64 {
        match self.shape {
            DefectShape::Bump { width_m } => {
                let u = s.clamp(-0.5 * width_m, 0.5 * width_m);
                0.5 * self.height_m * (u + width_m / TAU * (TAU * u / width_m).sin())
            }
            DefectShape::Step => self.height_m * s.max(0.0),
        }
    }

    /// The rail's deviation at rail coordinate `s` (m from the defect), m.
    pub fn height_at(&self, s: f64) -> f64 {
        match self.shape {
            DefectShape::Bump { width_m } if s.abs() <= 0.5 * width_m => {
                0.5 * self.height_m * (1.0 + (TAU * s / width_m).cos())
            }
            DefectShape::Bump { .. } => 0.0,
            DefectShape::Step if s >= 0.0 => self.height_m,
            DefectShape::Step => 0.0,
        }
    }

    /// A block of loaded length `b` (m) centred at rail coordinate `s`: the mean deviation
    /// under it, m.
    pub fn under_block(&self, s: f64, b: f64) -> f64 {
        if b <= 0.0 {
            return self.height_at(s);
        }
        (self.integral(s + 0.5 * b) - self.integral(s - 0.5 * b)) / b
    }
}

/// An axis' carriage on its rails, and the local defects of the rails.
#[derive(Clone, Debug, PartialEq)]
pub struct Guideway {
    /// The moving axis.
    pub axis: Axis,
    /// Distance between the front and rear blocks' centres along the axis, m (> 0).
    pub block_spacing_m: f64,
    /// Loaded length of each block, over which it averages the rail, m (>= 0).
    pub block_length_m: f64,
    /// The blocks' centre in machine coordinates with every axis at 0, m.
    pub blocks_centre_m: Vector3<f64>,
    /// The defects.
    pub defects: Vec<RailDefect>,
}

impl Guideway {
    /// A description of the first value that is not a guideway's, if any.
    pub fn check(&self) -> Result<(), String> {
        if !(self.block_spacing_m.is_finite() && self.block_spacing_m > 0.0) {
            return Err("the block spacing must be a finite length > 0".into());
        }
        if !(self.block_length_m.is_finite() && self.block_length_m >= 0.0) {
            return Err("the block length must be a finite length >= 0".into());
        }
        for (i, d) in self.defects.iter().enumerate() {
            if d.direction == self.axis {
                return Err(format!(
                    "defect {i}: its direction must be across the axis {}, not along it",
                    self.axis
                ));
            }
            if let DefectShape::Bump { width_m } = d.shape
                && !(width_m.is_finite() && width_m > 0.0)
            {
                return Err(format!("defect {i}: a bump's width must be > 0"));
            }
            if d.rail_offset_m
                .is_some_and(|a| !(a.is_finite() && a != 0.0))
            {
                return Err(format!(
                    "defect {i}: a rail's offset must be finite and not 0"
                ));
            }
        }
        Ok(())
    }

    /// The carriage's rigid motion (translation, m, and rotation vector, rad, in the machine
    /// frame) at axis position `q` (m); `moves_tool`: whether the carriage carries the tool
    /// (it moves `+q` along the axis) or the workpiece (`−q`).
    pub fn carriage_motion(&self, q: f64, moves_tool: bool) -> (Vector3<f64>, Vector3<f64>) {
        let side = if moves_tool { 1.0 } else { -1.0 };
        let u = Vector3::ith(self.axis.index(), 1.0);
        let (mut t, mut theta) = (Vector3::zeros(), Vector3::zeros());
        let half = 0.5 * self.block_spacing_m;
        for d in &self.defects {
            let centre = side * (q - d.at_m);
            let front = d.under_block(centre + half, self.block_length_m);
            let rear = d.under_block(centre - half, self.block_length_m);
            let n = Vector3::ith(d.direction.index(), 1.0);
            let (lift, roll) = match d.rail_offset_m {
                None => (0.5 * (front + rear), Vector3::zeros()),
                Some(a) => {
                    // Only the blocks on the rail at across offset a rise: of four blocks at
                    // ±|a| along w, the mean is half theirs and the roll Σeδ/Σe² = on/(2a).
                    let w = Vector3::ith(3 - self.axis.index() - d.direction.index(), 1.0);
                    let on_rail = 0.5 * (front + rear);
                    (0.5 * on_rail, w.cross(&n) * (on_rail / (2.0 * a)))
                }
            };
            t += n * lift;
            // Pitch or yaw: the front and rear rise differently. With the defect on one rail
            // only, half the blocks carry the difference.
            let share = if d.rail_offset_m.is_some() { 0.5 } else { 1.0 };
            theta += u.cross(&n) * (share * (front - rear) / self.block_spacing_m) + roll;
        }
        (t, theta)
    }

    /// The error motion of the tool relative to the workpiece that the defects add at axis
    /// position `q` (m), in the chain's joint form (module docs).
    pub fn error_motion(&self, q: f64, moves_tool: bool) -> ErrorMotion {
        let (t, theta) = self.carriage_motion(q, moves_tool);
        let u = Vector3::ith(self.axis.index(), 1.0);
        let (side, centre) = if moves_tool {
            (1.0, self.blocks_centre_m)
        } else {
            (-1.0, self.blocks_centre_m - u * q)
        };
        ErrorMotion {
            translation: (t - theta.cross(&centre)) * side,
            rotation: theta * side,
        }
    }
}
