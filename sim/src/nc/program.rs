//! An NC program as the interpolator sees it: motion blocks in SI units, absolute coordinates.
//!
//! Coordinates are the commanded tool position relative to the workpiece (m), as in the model
//! crate's `AxisState::position`. Feeds are path speeds in m/s. Every block keeps the line and
//! column of the G-code it came from, so later stages (stroke checks, the controller) can name it.

use nalgebra::Vector3;
use vmt_model::Axis;

/// Where a block came from in its source file (1-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct SourceSpan {
    /// Line, 1-based.
    pub line: usize,
    /// Column, 1-based.
    pub column: usize,
}

/// The plane of circular interpolation (G17, G18, G19).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Plane {
    /// G17: XY, arcs about +Z.
    #[default]
    Xy,
    /// G18: ZX, arcs about +Y.
    Zx,
    /// G19: YZ, arcs about +X.
    Yz,
}

impl Plane {
    /// The unit normal of the plane (the arc axis; CCW is right-handed about it).
    pub fn normal(self) -> Vector3<f64> {
        match self {
            Plane::Xy => Vector3::z(),
            Plane::Zx => Vector3::y(),
            Plane::Yz => Vector3::x(),
        }
    }

    /// The plane's axes (p, q), in the order of its angle (from p towards q).
    pub fn axes(self) -> (Axis, Axis) {
        match self {
            Plane::Xy => (Axis::X, Axis::Y),
            Plane::Zx => (Axis::Z, Axis::X),
            Plane::Yz => (Axis::Y, Axis::Z),
        }
    }
}

/// Direction of circular interpolation seen from the positive end of the plane's normal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArcDirection {
    /// G2, clockwise.
    Cw,
    /// G3, counter-clockwise.
    Ccw,
}

/// Spindle state (M3, M4, M5 with S).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum Spindle {
    /// M5 (or never started).
    #[default]
    Stopped,
    /// M3 at the given speed, rpm.
    Clockwise(f64),
    /// M4 at the given speed, rpm.
    CounterClockwise(f64),
}

/// One motion of the program.
#[derive(Clone, Debug, PartialEq)]
pub enum Motion {
    /// G0: positioning at the rapid rate to `to` (m).
    Rapid {
        /// End point, m.
        to: Vector3<f64>,
    },
    /// G1: straight line to `to` (m) at `feed` (m/s).
    Linear {
        /// End point, m.
        to: Vector3<f64>,
        /// Path speed, m/s (> 0).
        feed: f64,
    },
    /// G2/G3: arc (helix if `to` leaves the plane) about `center` (m) to `to` at `feed` (m/s).
    /// A full circle has `to` equal to the start point and is swept as 360°; multi-turn arcs
    /// (a P word on G2/G3) are refused by the parser.
    Arc {
        /// End point, m.
        to: Vector3<f64>,
        /// Centre, m (in the plane through the start point).
        center: Vector3<f64>,
        /// Plane of the arc.
        plane: Plane,
        /// Clockwise or counter-clockwise.
        direction: ArcDirection,
        /// Path speed, m/s (> 0).
        feed: f64,
    },
    /// G4: dwell for `seconds`.
    Dwell {
        /// Duration, s (>= 0).
        seconds: f64,
    },
}

/// One block: a motion and the state it runs in.
#[derive(Clone, Debug, PartialEq)]
pub struct Block {
    /// What moves.
    pub motion: Motion,
    /// Spindle state during the block.
    pub spindle: Spindle,
    /// Where in the source the block was written.
    pub span: SourceSpan,
}

/// A program: its blocks in order, starting from `start` (m).
#[derive(Clone, Debug, PartialEq)]
pub struct Program {
    /// Position of the tool before the first block, m.
    pub start: Vector3<f64>,
    /// The motion blocks; M30 ends the list.
    pub blocks: Vec<Block>,
}
