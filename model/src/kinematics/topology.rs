//! The 24 topologies of a three-axis machine (Ahn & Cho 2002, Fig. 4).
//!
//! A topology is the order of the elements along the kinematic chain from the workpiece (W) to
//! the tool (T): the three axes X, Y, Z and the ground (G, the bed) in any of 4! = 24 orders.
//! Axes between W and G carry the workpiece (tables, saddles); axes between G and T carry the
//! tool (columns, heads, rams). It is written as six letters, e.g. `WXYGZT`: a vertical
//! machining centre whose table X rides on saddle Y on the bed, with the spindle head Z on the
//! column; `WGXYZT`: a gantry machine with a fixed table.

use crate::axis::Axis;
use std::fmt;
use std::str::FromStr;
use thiserror::Error;

/// One element of the kinematic chain.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Element {
    /// The workpiece.
    Workpiece,
    /// A linear axis.
    Axis(Axis),
    /// The ground (machine bed).
    Ground,
    /// The tool.
    Tool,
}

impl Element {
    /// The letter of the element in a topology name.
    pub const fn letter(self) -> char {
        match self {
            Element::Workpiece => 'W',
            Element::Axis(a) => a.letter(),
            Element::Ground => 'G',
            Element::Tool => 'T',
        }
    }
}

/// Which assembly an axis or structural link belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// Between the workpiece and the ground: it moves the workpiece.
    Workpiece,
    /// Between the ground and the tool: it moves the tool.
    Tool,
}

/// A topology name that is not one of the 24.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
#[error(
    "unknown topology `{name}`: a topology is W, then X, Y, Z and G (ground) each once in any \
     order, then T, e.g. WXYGZT (table X on saddle Y, spindle head Z on the column), WYXGZT, \
     WGXYZT (gantry), WZGXYT"
)]
pub struct TopologyError {
    /// The name given.
    pub name: String,
}

/// The order of workpiece, axes, ground and tool along the chain.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Topology {
    chain: [Element; 6],
}

impl Topology {
    /// All 24 topologies.
    pub fn all() -> Vec<Topology> {
        let middle = [
            Element::Axis(Axis::X),
            Element::Axis(Axis::Y),
            Element::Axis(Axis::Z),
            Element::Ground,
        ];
        let mut out = Vec::with_capacity(24);
        for a in 0..4 {
            for b in (0..4).filter(|&b| b != a) {
                for c in (0..4).filter(|&c| c != a && c != b) {
                    let d = 6 - a - b - c;
                    out.push(Topology {
                        chain: [
                            Element::Workpiece,
                            middle[a],
                            middle[b],
                            middle[c],
                            middle[d],
                            Element::Tool,
                        ],
                    });
                }
            }
        }
        out
    }

    /// The six elements from workpiece to tool.
    pub fn chain(&self) -> &[Element; 6] {
        &self.chain
    }

    /// Position of the ground in the chain (1..=4).
    pub fn ground_index(&self) -> usize {
        self.chain
            .iter()
            .position(|e| *e == Element::Ground)
            .unwrap_or(5)
    }

    /// Position of `axis` in the chain (1..=4).
    pub fn axis_index(&self, axis: Axis) -> usize {
        self.chain
            .iter()
            .position(|e| *e == Element::Axis(axis))
            .unwrap_or(0)
    }

    /// The axes in order from workpiece to tool.
    pub fn axis_order(&self) -> [Axis; 3] {
        let mut out = [Axis::X; 3];
        let axes = self.chain.iter().filter_map(|e| match e {
            Element::Axis(a) => Some(*a),
            _ => None,
        });
        for (slot, a) in out.iter_mut().zip(axes) {
            *slot = a;
        }
        out
    }

    /// Whether `axis` moves the workpiece or the tool.
    pub fn axis_side(&self, axis: Axis) -> Side {
        if self.axis_index(axis) < self.ground_index() {
            Side::Workpiece
        } else {
            Side::Tool
        }
    }

    /// Whether structural link `k` (between chain elements `k` and `k + 1`) is on the workpiece
    /// or the tool side of the ground.
    pub fn link_side(&self, k: usize) -> Side {
        if k < self.ground_index() {
            Side::Workpiece
        } else {
            Side::Tool
        }
    }

    /// The names of the five structural links, e.g. `W-X`, `X-Y`, `Y-G`, `G-Z`, `Z-T`.
    pub fn link_names(&self) -> [String; 5] {
        std::array::from_fn(|k| {
            format!("{}-{}", self.chain[k].letter(), self.chain[k + 1].letter())
        })
    }
}

impl FromStr for Topology {
    type Err = TopologyError;

    /// Parses six letters (any case; `-` and spaces between them are ignored).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let letters: String = s
            .chars()
            .filter(|c| *c != '-' && !c.is_whitespace())
            .map(|c| c.to_ascii_uppercase())
            .collect();
        Topology::all()
            .into_iter()
            .find(|t| t.to_string() == letters)
            .ok_or_else(|| TopologyError {
                name: s.to_string(),
            })
    }
}

impl fmt::Display for Topology {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.chain
            .iter()
            .try_for_each(|e| write!(f, "{}", e.letter()))
    }
}
