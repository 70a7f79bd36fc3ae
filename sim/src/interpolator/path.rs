//! Path geometry: every motion block as a segment parameterised by its path length `s` (m).
//!
//! Lines are `p(s) = p₀ + s·d`. Arcs and helices are evaluated exactly from their centre, radius
//! and angle (no chords): with the plane basis `(u, v, n)` (right-handed, `n` the plane normal),
//! `σ = s / L`, `θ = θ₀ + φσ`, `e(θ) = cos θ·u + sin θ·v`,
//!
//! `p(σ) = c + r(σ)·e(θ) + n·hσ`, with `r(σ) = r₀ + Δr·σ`,
//!
//! where `φ` is the signed sweep (positive counter-clockwise seen from `+n`), `h` the helix rise
//! and `L = √((r̄φ)² + h² + Δr²)`. For a true arc or helix `Δr = 0` and `L` is its exact length.
//! `Δr ≠ 0` only absorbs a programmed end point off the circle by at most the arc radius
//! tolerance (Siemens' `CIRCLE_ERROR_CONST` 10 µm / `CIRCLE_ERROR_FACTOR` 0.1 %): the arc becomes
//! an Archimedean spiral that ends exactly on the programmed point.

use nalgebra::Vector3;

use super::InterpolatorError;
use crate::nc::program::{ArcDirection, Block, Motion, Plane, Program, SourceSpan, Spindle};

/// Blocks shorter than this (m) are skipped: no motion, no division by their length.
pub(crate) const MIN_SEGMENT_LENGTH_M: f64 = 1e-12;
/// An arc whose end point lies within this distance (m) of its start point in the arc plane is a
/// full turn (360°).
pub(crate) const FULL_CIRCLE_CHORD_M: f64 = 1e-9;
/// Absolute part of the accepted radius difference between arc start and end, m.
const ARC_RADIUS_TOLERANCE_M: f64 = 10e-6;
/// Relative part (of the start radius) of the accepted radius difference.
const ARC_RADIUS_TOLERANCE_REL: f64 = 1e-3;

/// A point of the path with its derivatives with respect to the path length.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PathPoint {
    /// Position, m.
    pub position: Vector3<f64>,
    /// `dp/ds`: the unit tangent (exactly unit on lines, arcs and helices).
    pub tangent: Vector3<f64>,
    /// `d²p/ds²`: the curvature vector, 1/m.
    pub curvature: Vector3<f64>,
}

/// A straight segment.
#[derive(Clone, Debug)]
pub(crate) struct Line {
    start: Vector3<f64>,
    end: Vector3<f64>,
    direction: Vector3<f64>,
    length: f64,
}

/// An arc, helix or (within the radius tolerance) spiral about an axis normal to a principal
/// plane.
#[derive(Clone, Debug)]
pub(crate) struct Helix {
    /// Centre in the plane through the start point, m.
    center: Vector3<f64>,
    /// In-plane basis and normal (right-handed: `u × v = n`).
    basis: [Vector3<f64>; 3],
    /// Indices of the axes along `u`, `v`, `n`.
    pub axes: [usize; 3],
    /// Start radius `r₀`, m.
    radius: f64,
    /// End radius minus start radius `Δr`, m.
    radius_change: f64,
    /// Start angle `θ₀` from `u` towards `v`, rad.
    start_angle: f64,
    /// Signed sweep `φ`, rad (positive counter-clockwise seen from `+n`).
    pub sweep: f64,
    /// Rise `h` along `n`, m.
    pub rise: f64,
    end: Vector3<f64>,
    length: f64,
}

/// The shape of one segment.
#[derive(Clone, Debug)]
pub(crate) enum Geometry {
    /// Straight line (G0, G1).
    Line(Line),
    /// Arc or helix (G2, G3).
    Helix(Helix),
}

/// How a segment is to be run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum MoveKind {
    /// G0 at the rapid rate.
    Rapid,
    /// G1/G2/G3 at the programmed feed, m/s.
    Feed(f64),
}

/// One motion block as a path segment.
#[derive(Clone, Debug)]
pub(crate) struct Segment {
    /// Index of the block in the program.
    pub block: usize,
    /// Where the block was written.
    pub span: SourceSpan,
    /// Spindle state during the block.
    pub spindle: Spindle,
    /// Rapid or feed.
    pub kind: MoveKind,
    /// Shape.
    pub geometry: Geometry,
    /// Path length of the program at the start of this segment, m.
    pub s_start: f64,
}

/// A dwell block.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Dwell {
    /// Index of the block in the program.
    pub block: usize,
    /// Where the block was written.
    pub span: SourceSpan,
    /// Duration, s.
    pub seconds: f64,
    /// Spindle state during the dwell.
    pub spindle: Spindle,
}

/// The program as the planner sees it: segments and dwells in order (zero-length blocks gone).
#[derive(Clone, Debug)]
pub(crate) enum Step {
    /// A motion.
    Move(Box<Segment>),
    /// A dwell (forces a stop).
    Dwell(Dwell),
}

impl Line {
    fn new(start: Vector3<f64>, end: Vector3<f64>) -> Option<Line> {
        let length = (end - start).norm();
        (length >= MIN_SEGMENT_LENGTH_M).then(|| Line {
            start,
            end,
            direction: (end - start) / length,
            length,
        })
    }

    /// Unit direction.
    pub fn direction(&self) -> Vector3<f64> {
        self.direction
    }

    fn point(&self, s: f64) -> PathPoint {
        let position = if s >= self.length {
            self.end
        } else if s <= 0.0 {
            self.start
        } else {
            self.start + self.direction * s
        };
        PathPoint {
            position,
            tangent: self.direction,
            curvature: Vector3::zeros(),
        }
    }
}

/// Plane basis `(u, v, n)` and the indices of those axes.
fn plane_basis(plane: Plane) -> ([Vector3<f64>; 3], [usize; 3]) {
    let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
    match plane {
        Plane::Xy => ([x, y, z], [0, 1, 2]),
        Plane::Zx => ([z, x, y], [2, 0, 1]),
        Plane::Yz => ([y, z, x], [1, 2, 0]),
    }
}

/// Signed sweep from the in-plane radial vectors `a` (start) and `b` (end).
fn sweep_angle(a: Vector3<f64>, b: Vector3<f64>, n: Vector3<f64>, dir: ArcDirection) -> f64 {
    use std::f64::consts::TAU;
    let raw = a.cross(&b).dot(&n).atan2(a.dot(&b));
    let full = (b - a).norm() <= FULL_CIRCLE_CHORD_M;
    match dir {
        ArcDirection::Ccw if raw > 0.0 && !full => raw,
        ArcDirection::Ccw => raw + TAU,
        ArcDirection::Cw if raw < 0.0 && !full => raw,
        ArcDirection::Cw => raw - TAU,
    }
}

/// The arc of `motion` from `start`, checked.
struct ArcInput {
    start: Vector3<f64>,
    to: Vector3<f64>,
    center: Vector3<f64>,
    plane: Plane,
    direction: ArcDirection,
    span: SourceSpan,
}

impl Helix {
    fn new(arc: &ArcInput) -> Result<Helix, InterpolatorError> {
        let (basis, axes) = plane_basis(arc.plane);
        let n = basis[2];
        let center = arc.center + n * (arc.start - arc.center).dot(&n);
        let a = arc.start - center;
        let rise = (arc.to - center).dot(&n);
        let b = arc.to - center - n * rise;
        let (radius, end_radius) = (a.norm(), b.norm());
        if radius < MIN_SEGMENT_LENGTH_M {
            return Err(InterpolatorError::ArcRadiusZero {
                line: arc.span.line,
                column: arc.span.column,
            });
        }
        let tolerance_m = ARC_RADIUS_TOLERANCE_M.max(ARC_RADIUS_TOLERANCE_REL * radius);
        if (end_radius - radius).abs() > tolerance_m {
            return Err(InterpolatorError::ArcRadiusMismatch {
                line: arc.span.line,
                column: arc.span.column,
                start_radius_m: radius,
                end_radius_m: end_radius,
                tolerance_m,
            });
        }
        let sweep = sweep_angle(a, b, n, arc.direction);
        let radius_change = end_radius - radius;
        let mean_radius = 0.5 * (radius + end_radius);
        let length = ((mean_radius * sweep).powi(2) + rise * rise + radius_change.powi(2)).sqrt();
        Ok(Helix {
            center,
            basis,
            axes,
            radius,
            radius_change,
            start_angle: a.dot(&basis[1]).atan2(a.dot(&basis[0])),
            sweep,
            rise,
            end: arc.to,
            length,
        })
    }

    /// Largest radius along the arc, m.
    pub fn max_radius(&self) -> f64 {
        self.radius.max(self.radius + self.radius_change)
    }

    /// End radius minus start radius `Δr`, m (zero for a true arc or helix).
    pub fn radius_change(&self) -> f64 {
        self.radius_change
    }

    /// Length, m.
    pub fn length(&self) -> f64 {
        self.length
    }

    fn point(&self, s: f64) -> PathPoint {
        let sigma = (s / self.length).clamp(0.0, 1.0);
        let [u, v, n] = self.basis;
        let (sin, cos) = (self.start_angle + self.sweep * sigma).sin_cos();
        let radial = u * cos + v * sin;
        let across = v * cos - u * sin;
        let r = self.radius + self.radius_change * sigma;
        let position = if sigma >= 1.0 {
            self.end
        } else {
            self.center + radial * r + n * (self.rise * sigma)
        };
        let d1 = radial * self.radius_change + across * (r * self.sweep) + n * self.rise;
        let d2 =
            across * (2.0 * self.radius_change * self.sweep) - radial * (r * self.sweep.powi(2));
        PathPoint {
            position,
            tangent: d1 / self.length,
            curvature: d2 / self.length.powi(2),
        }
    }
}

impl Geometry {
    /// Path length, m.
    pub fn length(&self) -> f64 {
        match self {
            Geometry::Line(line) => line.length,
            Geometry::Helix(helix) => helix.length,
        }
    }

    /// The point at path length `s` (m) from the segment start, `s` clamped to the segment.
    pub fn point(&self, s: f64) -> PathPoint {
        match self {
            Geometry::Line(line) => line.point(s),
            Geometry::Helix(helix) => helix.point(s),
        }
    }

    /// Bounds on `|p⁽ᵏ⁾(s)|`, the 2nd, 3rd and 4th derivatives of the position by path length
    /// over the segment, 1/m, 1/m², 1/m³. Zero on a line. On a helix `p = c + r(σ)·e(θ) + n·h·σ`
    /// (`σ = s/L`, `r = r₀ + Δr·σ`, `θ = θ₀ + φσ`, angle rate `ω = |φ|/L`), Leibniz' rule with
    /// `r″ = 0` and `|e⁽ʲ⁾| = 1` gives `|p⁽ᵏ⁾| ≤ r_max ω^k + k (|Δr|/L) ω^(k−1)`.
    pub fn derivative_bounds(&self) -> [f64; 3] {
        match self {
            Geometry::Line(_) => [0.0; 3],
            Geometry::Helix(helix) => {
                let omega = helix.sweep.abs() / helix.length;
                let growth = helix.radius_change.abs() / helix.length;
                let r = helix.max_radius();
                [2, 3, 4].map(|k| r * omega.powi(k) + f64::from(k) * growth * omega.powi(k - 1))
            }
        }
    }

    /// Unit tangent at the start.
    pub fn start_tangent(&self) -> Vector3<f64> {
        self.point(0.0).tangent.normalize()
    }

    /// Unit tangent at the end.
    pub fn end_tangent(&self) -> Vector3<f64> {
        self.point(self.length()).tangent.normalize()
    }

    /// A box (lower and upper corner, m) holding every point of the segment: the segment's
    /// own box for a line; for an arc or helix the in-plane square of its largest radius about
    /// the centre, and its rise, with the end point.
    pub fn bounds(&self) -> (Vector3<f64>, Vector3<f64>) {
        match self {
            Geometry::Line(line) => (line.start.inf(&line.end), line.start.sup(&line.end)),
            Geometry::Helix(h) => {
                let [u, v, n] = h.basis;
                let half = (u.abs() + v.abs()) * h.max_radius();
                let (a, b) = (h.center, h.center + n * h.rise);
                let (lo, hi) = (a.inf(&b) - half, a.sup(&b) + half);
                (lo.inf(&h.end), hi.sup(&h.end))
            }
        }
    }

    /// End point, m.
    pub fn end(&self) -> Vector3<f64> {
        match self {
            Geometry::Line(line) => line.end,
            Geometry::Helix(helix) => helix.end,
        }
    }
}

impl Segment {
    /// Path length of the program at the end of this segment, m.
    pub fn s_end(&self) -> f64 {
        self.s_start + self.geometry.length()
    }
}

fn invalid(
    span: SourceSpan,
    what: &'static str,
    value: f64,
    reason: &'static str,
) -> InterpolatorError {
    InterpolatorError::InvalidBlock {
        line: span.line,
        column: span.column,
        what,
        value,
        reason,
    }
}

fn check_point(
    span: SourceSpan,
    what: &'static str,
    p: &Vector3<f64>,
) -> Result<(), InterpolatorError> {
    match p.iter().find(|c| !c.is_finite()) {
        Some(&c) => Err(invalid(span, what, c, "coordinates must be finite")),
        None => Ok(()),
    }
}

fn check_feed(span: SourceSpan, feed: f64) -> Result<MoveKind, InterpolatorError> {
    if feed.is_finite() && feed > 0.0 {
        Ok(MoveKind::Feed(feed))
    } else {
        Err(invalid(
            span,
            "feed (m/s)",
            feed,
            "the feed must be a finite number > 0",
        ))
    }
}

/// Turns the program into segments and dwells, skipping zero-length blocks.
pub(crate) fn build_steps(program: &Program) -> Result<Vec<Step>, InterpolatorError> {
    check_point(SourceSpan::default(), "program start (m)", &program.start)?;
    let mut steps = Vec::with_capacity(program.blocks.len());
    let mut position = program.start;
    let mut s = 0.0;
    for (index, block) in program.blocks.iter().enumerate() {
        if let Some(step) = build_step(index, block, position, s)? {
            if let Step::Move(segment) = &step {
                position = segment.geometry.end();
                s = segment.s_end();
                if !s.is_finite() {
                    let length = segment.geometry.length();
                    return Err(invalid(
                        block.span,
                        "length (m)",
                        length,
                        "the path is too long",
                    ));
                }
            }
            steps.push(step);
        }
    }
    Ok(steps)
}

fn build_step(
    block: usize,
    b: &Block,
    start: Vector3<f64>,
    s_start: f64,
) -> Result<Option<Step>, InterpolatorError> {
    let span = b.span;
    let (kind, geometry) = match &b.motion {
        Motion::Dwell { seconds } => {
            if !(seconds.is_finite() && *seconds >= 0.0) {
                return Err(invalid(
                    span,
                    "dwell (s)",
                    *seconds,
                    "a dwell must be finite and >= 0",
                ));
            }
            let dwell = Dwell {
                block,
                span,
                seconds: *seconds,
                spindle: b.spindle,
            };
            return Ok(Some(Step::Dwell(dwell)));
        }
        Motion::Rapid { to } => {
            check_point(span, "end point (m)", to)?;
            (MoveKind::Rapid, Line::new(start, *to).map(Geometry::Line))
        }
        Motion::Linear { to, feed } => {
            check_point(span, "end point (m)", to)?;
            (
                check_feed(span, *feed)?,
                Line::new(start, *to).map(Geometry::Line),
            )
        }
        Motion::Arc {
            to,
            center,
            plane,
            direction,
            feed,
        } => {
            check_point(span, "end point (m)", to)?;
            check_point(span, "centre (m)", center)?;
            let kind = check_feed(span, *feed)?;
            let arc = ArcInput {
                start,
                to: *to,
                center: *center,
                plane: *plane,
                direction: *direction,
                span,
            };
            (kind, Some(Geometry::Helix(Helix::new(&arc)?)))
        }
    };
    let Some(geometry) = geometry else {
        return Ok(None);
    };
    let length = geometry.length();
    if !length.is_finite() {
        return Err(invalid(span, "length (m)", length, "the block is too long"));
    }
    Ok(Some(Step::Move(Box::new(Segment {
        block,
        span,
        spindle: b.spindle,
        kind,
        geometry,
        s_start,
    }))))
}
