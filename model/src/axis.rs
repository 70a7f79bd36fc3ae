//! The three linear axes of the machine and the direction state of each.
//!
//! Directions follow ISO 841: an axis moves "forward" when the tool moves in the positive
//! direction relative to the workpiece, whichever assembly actually moves. Ahn & Cho (2002)
//! evaluate every geometric error separately for forward and backward approach; the state that
//! selects between them is the direction of the axis' last motion, kept by [`DirectionTracker`].

use std::fmt;

/// One of the three linear axes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Axis {
    /// X axis.
    X,
    /// Y axis.
    Y,
    /// Z axis.
    Z,
}

impl Axis {
    /// The three axes in order X, Y, Z.
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

    /// Index 0, 1, 2 for X, Y, Z.
    pub const fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }

    /// Upper-case letter of the axis, as in ISO 230-1 error names.
    pub const fn letter(self) -> char {
        match self {
            Axis::X => 'X',
            Axis::Y => 'Y',
            Axis::Z => 'Z',
        }
    }

    /// The axis with the given letter (either case).
    pub fn from_letter(c: char) -> Option<Axis> {
        match c.to_ascii_uppercase() {
            'X' => Some(Axis::X),
            'Y' => Some(Axis::Y),
            'Z' => Some(Axis::Z),
            _ => None,
        }
    }
}

impl fmt::Display for Axis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.letter())
    }
}

/// Direction of approach of an axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Direction {
    /// Moving towards positive axis coordinates (ISO 230-2 "upward" approach).
    #[default]
    Forward,
    /// Moving towards negative axis coordinates.
    Backward,
}

impl Direction {
    /// +1 for forward, -1 for backward.
    pub const fn sign(self) -> i8 {
        match self {
            Direction::Forward => 1,
            Direction::Backward => -1,
        }
    }

    /// The direction of a sign: +1 forward, -1 backward, anything else none.
    pub const fn from_sign(sign: i64) -> Option<Direction> {
        match sign {
            1 => Some(Direction::Forward),
            -1 => Some(Direction::Backward),
            _ => None,
        }
    }

    /// Index 0 for forward, 1 for backward.
    pub const fn index(self) -> usize {
        match self {
            Direction::Forward => 0,
            Direction::Backward => 1,
        }
    }
}

/// Keeps the direction state of one axis from its motion.
///
/// The state changes only when the axis has moved more than `deadband_m` against it since the
/// last change, so that encoder-level jitter at a standstill does not toggle the direction; a
/// zero dead band follows every reversal.
#[derive(Clone, Copy, Debug)]
pub struct DirectionTracker {
    state: Direction,
    turn_point: f64,
    deadband_m: f64,
}

impl DirectionTracker {
    /// A tracker at `position_m` whose last motion was in `initial` direction.
    pub fn new(position_m: f64, initial: Direction, deadband_m: f64) -> Self {
        Self {
            state: initial,
            turn_point: position_m,
            deadband_m: deadband_m.abs(),
        }
    }

    /// The direction state after the axis has moved to `position_m`.
    pub fn update(&mut self, position_m: f64) -> Direction {
        match self.state {
            Direction::Forward => {
                if position_m > self.turn_point {
                    self.turn_point = position_m;
                } else if position_m < self.turn_point - self.deadband_m {
                    self.state = Direction::Backward;
                    self.turn_point = position_m;
                }
            }
            Direction::Backward => {
                if position_m < self.turn_point {
                    self.turn_point = position_m;
                } else if position_m > self.turn_point + self.deadband_m {
                    self.state = Direction::Forward;
                    self.turn_point = position_m;
                }
            }
        }
        self.state
    }

    /// The current direction state.
    pub fn direction(&self) -> Direction {
        self.state
    }
}
