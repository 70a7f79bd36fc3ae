//! The 21 geometric errors of a three-axis machine (ISO 230-1), direction dependent.
//!
//! Per axis six error motions, each a function of that axis' own position (ISO 230-1 names,
//! first letter the error direction, second the moving axis):
//!
//! | axis | positional | straightness | roll | pitch / yaw |
//! |------|-----------|--------------|------|-------------|
//! | X    | EXX       | EYX, EZX     | EAX  | EBX, ECX    |
//! | Y    | EYY       | EXY, EZY     | EBY  | EAY, ECY    |
//! | Z    | EZZ       | EXZ, EYZ     | ECZ  | EAZ, EBZ    |
//!
//! and three squareness errors: EC0Y (Y to X, about Z), EB0Z (Z to X, about Y), EA0Z (Z to Y,
//! about X). Every error is a motion of the tool relative to the workpiece, expressed in the
//! machine's reference frame (Ahn & Cho 2002, rules 1–5): translations in m along +X, +Y, +Z,
//! rotations in rad about +X, +Y, +Z by the right-hand rule, whatever assembly carries the axis.
//!
//! Direction dependence (Ahn & Cho 2002): every component has a forward and a backward function;
//! their difference is that component's backlash (EXX's is the positional backlash, ECX's the
//! yaw backlash, ...). Squareness depends on the approach directions of both of its axes, so it
//! has four values, whose differences are its two backlash components.
//!
//! Besides these smooth functions of position an axis may have local defects of its rails (a
//! bump, a rail-joint step: [`Guideway`]), which its carriage's blocks ride over; the chain
//! adds their error motion to the functions'.

mod compiled;
mod function;
mod guideway;

pub use function::{ErrorFunction, ErrorTable, FunctionError, Interpolation, LegendreSeries};
pub use guideway::{DefectShape, Guideway, RailDefect};

use crate::axis::{Axis, Direction};
use compiled::Compiled;
use nalgebra::Vector3;

/// One of the six error motions of an axis: a translation along or rotation about X, Y or Z.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Component {
    /// Translation along X (m).
    Tx,
    /// Translation along Y (m).
    Ty,
    /// Translation along Z (m).
    Tz,
    /// Rotation about X (rad), ISO letter A.
    Rx,
    /// Rotation about Y (rad), ISO letter B.
    Ry,
    /// Rotation about Z (rad), ISO letter C.
    Rz,
}

impl Component {
    /// The six components in the column order of compensation tables: EX?, EY?, EZ?, EA?, EB?, EC?.
    pub const ALL: [Component; 6] = [
        Component::Tx,
        Component::Ty,
        Component::Tz,
        Component::Rx,
        Component::Ry,
        Component::Rz,
    ];

    /// Index in [`Component::ALL`].
    pub const fn index(self) -> usize {
        self as usize
    }

    /// Whether this is an angular component (rad) rather than a translation (m).
    pub const fn is_angular(self) -> bool {
        matches!(self, Component::Rx | Component::Ry | Component::Rz)
    }

    /// ISO 230-1 letter of the error direction: X, Y, Z for translations, A, B, C for rotations.
    pub const fn letter(self) -> char {
        ['X', 'Y', 'Z', 'A', 'B', 'C'][self as usize]
    }

    /// The ISO 230-1 name of this component of `axis`, e.g. `EBX` (pitch of X).
    pub fn iso_name(self, axis: Axis) -> String {
        format!("E{}{}", self.letter(), axis.letter())
    }

    /// The component and axis of an ISO 230-1 name such as `EXX` or `ecz` (case-insensitive).
    pub fn parse_iso(name: &str) -> Option<(Component, Axis)> {
        let c: Vec<char> = name.to_ascii_uppercase().chars().collect();
        if c.len() != 3 || c[0] != 'E' {
            return None;
        }
        let component = Component::ALL.into_iter().find(|k| k.letter() == c[1])?;
        Some((component, Axis::from_letter(c[2])?))
    }
}

/// A component's functions for forward and backward approach; their difference is its backlash.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Directional {
    /// Function for forward approach.
    pub forward: ErrorFunction,
    /// Function for backward approach.
    pub backward: ErrorFunction,
}

impl Directional {
    /// The same function for both directions (no backlash).
    pub fn symmetric(f: ErrorFunction) -> Self {
        Self {
            forward: f.clone(),
            backward: f,
        }
    }

    /// The function for `direction`.
    #[inline]
    pub fn get(&self, direction: Direction) -> &ErrorFunction {
        match direction {
            Direction::Forward => &self.forward,
            Direction::Backward => &self.backward,
        }
    }

    /// The backlash of this component at `q`: backward minus forward value.
    pub fn backlash(&self, q: f64) -> f64 {
        self.backward.eval(q) - self.forward.eval(q)
    }
}

/// The error motion of one axis at one position: translation (m) and rotation vector (rad).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct ErrorMotion {
    /// (EX?, EY?, EZ?) in m.
    pub translation: Vector3<f64>,
    /// (EA?, EB?, EC?) in rad.
    pub rotation: Vector3<f64>,
}

/// The six direction-dependent error functions of one axis.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct AxisErrors {
    components: [Directional; 6],
    /// The functions of each direction arranged for joint evaluation.
    compiled: [Compiled; 2],
}

impl AxisErrors {
    /// No errors.
    pub fn zero() -> Self {
        Self::default()
    }

    /// Sets a component's functions.
    pub fn set(&mut self, component: Component, functions: Directional) {
        self.components[component.index()] = functions;
        for d in [Direction::Forward, Direction::Backward] {
            let f = std::array::from_fn(|k| self.components[k].get(d));
            self.compiled[d.index()] = Compiled::new(f);
        }
    }

    /// A component's functions.
    pub fn get(&self, component: Component) -> &Directional {
        &self.components[component.index()]
    }

    /// The error motion at axis position `q` (m) approached in `direction`.
    #[inline]
    pub fn motion(&self, q: f64, direction: Direction) -> ErrorMotion {
        let v = self.compiled[direction.index()].eval(q);
        ErrorMotion {
            translation: Vector3::new(v[0], v[1], v[2]),
            rotation: Vector3::new(v[3], v[4], v[5]),
        }
    }
}

/// One of the three squareness errors of ISO 230-1.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SquarenessError {
    /// EC0Y: squareness of Y to X, a rotation of Y's reference straight line about +Z.
    C0Y,
    /// EB0Z: squareness of Z to X, a rotation of Z's reference straight line about +Y.
    B0Z,
    /// EA0Z: squareness of Z to Y, a rotation of Z's reference straight line about +X.
    A0Z,
}

impl SquarenessError {
    /// The three squareness errors.
    pub const ALL: [SquarenessError; 3] = [
        SquarenessError::C0Y,
        SquarenessError::B0Z,
        SquarenessError::A0Z,
    ];

    /// ISO 230-1 name.
    pub const fn iso_name(self) -> &'static str {
        match self {
            SquarenessError::C0Y => "EC0Y",
            SquarenessError::B0Z => "EB0Z",
            SquarenessError::A0Z => "EA0Z",
        }
    }

    /// The reference axis (whose direction is taken as exact) and the axis that is rotated.
    pub const fn axes(self) -> (Axis, Axis) {
        match self {
            SquarenessError::C0Y => (Axis::X, Axis::Y),
            SquarenessError::B0Z => (Axis::X, Axis::Z),
            SquarenessError::A0Z => (Axis::Y, Axis::Z),
        }
    }

    /// The unit vector of the rotation.
    fn rotation_axis(self) -> Vector3<f64> {
        match self {
            SquarenessError::C0Y => Vector3::z(),
            SquarenessError::B0Z => Vector3::y(),
            SquarenessError::A0Z => Vector3::x(),
        }
    }
}

/// A squareness value (rad) for each pair of approach directions of its two axes.
///
/// `values[r][m]` is the value with the reference axis approached in direction `r` and the
/// rotated axis in direction `m` (index 0 forward, 1 backward). Ahn & Cho's two squareness
/// backlash components are `values[0][1] - values[0][0]` and `values[1][0] - values[0][0]`.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct SquarenessValue {
    /// Values indexed by [reference direction][rotated-axis direction], rad.
    pub values: [[f64; 2]; 2],
}

impl SquarenessValue {
    /// The same value for every direction.
    pub fn constant(rad: f64) -> Self {
        Self {
            values: [[rad; 2]; 2],
        }
    }

    /// The value for the given directions of the reference and rotated axes.
    #[inline]
    pub fn get(&self, reference: Direction, rotated: Direction) -> f64 {
        self.values[reference.index()][rotated.index()]
    }
}

/// The complete set of geometric errors: 18 axis error motions and 3 squareness errors, and
/// the local defects of the axes' rails.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct GeometricErrors {
    /// Error functions of X, Y, Z.
    pub axes: [AxisErrors; 3],
    /// EC0Y, EB0Z, EA0Z.
    pub squareness: [SquarenessValue; 3],
    /// The carriages of X, Y, Z on their rails, where the rails have local defects.
    pub guideways: [Option<Guideway>; 3],
}

impl GeometricErrors {
    /// No errors at all.
    pub fn zero() -> Self {
        Self::default()
    }

    /// The errors of `axis`.
    pub fn axis(&self, axis: Axis) -> &AxisErrors {
        &self.axes[axis.index()]
    }

    /// Mutable errors of `axis`.
    pub fn axis_mut(&mut self, axis: Axis) -> &mut AxisErrors {
        &mut self.axes[axis.index()]
    }

    /// The squareness value of `which`.
    pub fn squareness(&self, which: SquarenessError) -> &SquarenessValue {
        &self.squareness[which as usize]
    }

    /// Sets the squareness value of `which`.
    pub fn set_squareness(&mut self, which: SquarenessError, value: SquarenessValue) {
        self.squareness[which as usize] = value;
    }

    /// The rotation vectors (rad) that turn the nominal directions of X, Y and Z into the
    /// reference straight lines of the actual axes for the given direction states.
    #[inline]
    pub fn axis_line_rotations(&self, directions: &[Direction; 3]) -> [Vector3<f64>; 3] {
        let mut rot = [Vector3::zeros(); 3];
        for s in SquarenessError::ALL {
            let (r, m) = s.axes();
            let angle =
                self.squareness[s as usize].get(directions[r.index()], directions[m.index()]);
            rot[m.index()] += s.rotation_axis() * angle;
        }
        rot
    }
}
