//! Circular test programs for a ball bar: ISO 230-4 circles and Kwon's seven-step procedure.
//!
//! A [`CircularTest`] describes the circle (plane, centre, radius), the feed, the data arc and
//! how the machine gets onto and off the circle; [`CircularTest::gcode`] writes it as a readable
//! G-code program that [`parse`](super::parse::parse) reads, and
//! [`CircularTest::data_blocks`] says which blocks of the parsed program are the data arcs.
//!
//! # Angles
//!
//! Angles on the circle are measured in the plane from its first axis towards its second, so
//! that G3 (CCW about the plane's normal, [`Plane::normal`]) increases them:
//!
//! | plane | 0° on | 90° on | normal |
//! |---|---|---|---|
//! | XY (G17) | +X | +Y | +Z |
//! | ZX (G18) | +Z | +X | +Y |
//! | YZ (G19) | +Y | +Z | +X |
//!
//! The data arc covers the angles from `start_deg` to `start_deg + arc_deg`; by default
//! ([`default_start_deg`]) a full circle starts at 0° and a partial arc in a vertical plane lies
//! over the top, symmetric about +Z (the spindle side, away from the table, as ISO 230-4 and
//! ball-bar practice run them): in ZX from −arc/2 to +arc/2, in YZ from 90° − arc/2 to
//! 90° + arc/2 (a 180° arc from one horizontal over the top to the other, 220° from 20° below
//! one horizontal to 20° below the other). A CCW run travels
//! it from `start_deg` upwards, a CW run from `start_deg + arc_deg` downwards, so both
//! directions measure the same part of the circle (for a partial arc, e.g. the upper half of a
//! vertical circle, the machine never leaves it).
//!
//! # Program layout
//!
//! For each direction in [`CircularTest::directions`], in order, one *run*:
//!
//! 1. feed-in: a G1 move along the radius, from `feed_in_m` outside the circle onto it;
//! 2. run-in overshoot: an arc of `overshoot_deg` before the data arc;
//! 3. the data arc, between the comment lines `(DATA CW START)` and `(DATA CW END)` (or `CCW`);
//! 4. run-out overshoot: an arc of `overshoot_deg` after it;
//! 5. feed-out: a G1 move along the radius to `feed_in_m` outside the circle.
//!
//! The program starts with a G0 to the first run's feed-in start (where the ball bar is fitted),
//! preceded, when [`CircularTest::approach_from_above_m`] is set, by a G0 in Z alone to that
//! height above it, a G0 over the start at that height and the G0 down onto it, and ends with M30 at the last run's feed-out end. Runs in opposite directions join up: each
//! starts where the previous one ended. Between two runs in the same direction the machine
//! returns over the arc it has just travelled, at the feed-in radius. A data arc of 360° is one
//! full-circle block; every other arc longer than 180° is split into equal blocks of at most
//! 180°, so that no block's end point comes near its start. Coordinates are written in mm with
//! four decimals (0.1 µm), feeds in mm/min, centres as I/J/K offsets.

use super::parse::NcError;
use super::program::{ArcDirection, Motion, Plane, Program};
use nalgebra::Vector3;
use std::ops::Range;
use thiserror::Error;

/// Smallest circle radius a ball bar measures, m (50 mm).
pub const BALLBAR_MIN_RADIUS_M: f64 = 0.05;
/// Largest circle radius a ball bar measures, m (600 mm).
pub const BALLBAR_MAX_RADIUS_M: f64 = 0.6;
/// Radial feed-in and feed-out distance of commercial ball bars, m (1.5 mm).
pub const DEFAULT_FEED_IN_M: f64 = 1.5e-3;
/// Largest accepted feed-in distance, m (10 mm; a ball bar's travel is a few mm).
pub const MAX_FEED_IN_M: f64 = 10e-3;
/// Shortest data arc, deg: the shortest the diagnosis fits (scale and squareness need 90°).
pub const MIN_ARC_DEG: f64 = 90.0;
/// Largest accepted approach from above, m (10 mm: a lift clear of the bar's seat, not a move).
pub const MAX_APPROACH_M: f64 = 10e-3;
/// Feeds a test program may ask for, mm/min: from a creep the program still writes with four
/// decimals to beyond any machine tool's rapid traverse.
pub const FEED_RANGE_MM_MIN: (f64, f64) = (0.1, 100_000.0);
/// Largest centre coordinate, m (10 m: beyond the working space of any machining centre).
pub const MAX_CENTRE_M: f64 = 10.0;
/// Run-in and run-out overshoot of [`CircularTest::iso230_4`], degrees.
pub const DEFAULT_OVERSHOOT_DEG: f64 = 45.0;
/// Centre-ball position of the programs in `scenarios/kwon_seven_step/`, mm: the middle of the
/// built-in machine's X and Y strokes (500 x 400 mm), 60 mm above Z = 0: with the 100 mm tool
/// the Z carriage stands 100 mm above the tool point, so the raised and inclined steps (up to
/// 269 mm) stay within its 400 mm Z stroke.
pub const KWON_SCENARIO_PIVOT_MM: [f64; 3] = [250.0, 200.0, 60.0];

/// A circular test (ISO 230-4): the machine runs a circle at a constant feed, one or more
/// times, while a ball bar between the tool and a centre ball records the radius.
#[derive(Clone, Debug, PartialEq)]
pub struct CircularTest {
    /// Plane of the circle.
    pub plane: Plane,
    /// Centre of the circle (tool position, absolute), m.
    pub center: Vector3<f64>,
    /// Radius of the circle, m (a ball bar: 0.05 to 0.6 m).
    pub radius_m: f64,
    /// Path speed, m/s (> 0).
    pub feed_m_s: f64,
    /// Angle of the data arc, degrees, in (0, 360]: 360 for a full circle, or a partial arc
    /// (e.g. 220 or 180 in a vertical plane).
    pub arc_deg: f64,
    /// Angle where the data arc begins (see the module docs for the angle convention), degrees.
    pub start_deg: f64,
    /// The runs, in order; not empty.
    pub directions: Vec<ArcDirection>,
    /// Radial approach onto and away from the circle, m (0 to 10 mm; default 1.5 mm).
    pub feed_in_m: f64,
    /// Run-in and run-out arcs before and after the data arc, degrees (>= 0;
    /// `arc_deg + 2 * overshoot_deg <= 720`).
    pub overshoot_deg: f64,
    /// Height above the first run's feed-in start from which the program comes down onto it, m
    /// (0 to 10 mm; 0: one rapid straight there). A test approached from above starts with Z
    /// last moved down, whatever the machine did before it: a unidirectional approach, for
    /// errors that depend on the direction Z last moved.
    pub approach_from_above_m: f64,
}

/// The parameter of a [`CircularTest`] an [`InvalidTest`] is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TestParameter {
    /// [`CircularTest::center`].
    Center,
    /// [`CircularTest::radius_m`].
    Radius,
    /// [`CircularTest::feed_m_s`].
    Feed,
    /// [`CircularTest::arc_deg`].
    Arc,
    /// [`CircularTest::start_deg`].
    Start,
    /// [`CircularTest::overshoot_deg`].
    Overshoot,
    /// [`CircularTest::directions`].
    Directions,
    /// [`CircularTest::feed_in_m`].
    FeedIn,
    /// [`CircularTest::approach_from_above_m`].
    Approach,
}

impl TestParameter {
    /// The parameter's name in messages.
    pub fn name(self) -> &'static str {
        match self {
            TestParameter::Center => "centre",
            TestParameter::Radius => "radius",
            TestParameter::Feed => "feed",
            TestParameter::Arc => "data arc",
            TestParameter::Start => "start angle",
            TestParameter::Overshoot => "overshoot",
            TestParameter::Directions => "directions",
            TestParameter::FeedIn => "feed-in",
            TestParameter::Approach => "approach from above",
        }
    }
}

/// A circular test that cannot be run: which parameter, its value (in engineering units) and
/// what is accepted.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
#[error("{} {value}: {accepted}", parameter.name())]
pub struct InvalidTest {
    /// The offending parameter.
    pub parameter: TestParameter,
    /// Its value with unit, e.g. `20 mm`.
    pub value: String,
    /// What would be accepted.
    pub accepted: String,
}

fn invalid(parameter: TestParameter, value: String, accepted: &str) -> InvalidTest {
    InvalidTest {
        parameter,
        value,
        accepted: accepted.to_string(),
    }
}

/// Where one run lies on the circle, degrees in the plane's angle convention, unwrapped in the
/// direction of travel (a CW run's angles decrease).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunAngles {
    /// Direction of the run.
    pub direction: ArcDirection,
    /// Angle of the feed-in move (start of the run-in overshoot), degrees.
    pub feed_in_deg: f64,
    /// Angle where the data arc begins, degrees.
    pub data_start_deg: f64,
    /// Angle where the data arc ends, degrees.
    pub data_end_deg: f64,
    /// Angle of the feed-out move (end of the run-out overshoot), degrees.
    pub feed_out_deg: f64,
}

/// Where a data arc of `arc_deg` (degrees) starts when no start is given, degrees: 0 for a
/// full circle or a partial arc in XY; in ZX and YZ the arc centred on the upward vertical,
/// +Z, at 0° in ZX and 90° in YZ (see the module docs), so that it never runs under the centre
/// ball into the table.
pub fn default_start_deg(plane: Plane, arc_deg: f64) -> f64 {
    let up_deg = match plane {
        Plane::Xy => return 0.0,
        Plane::Zx => 0.0,
        Plane::Yz => 90.0,
    };
    if arc_deg >= 360.0 {
        0.0
    } else {
        up_deg - arc_deg / 2.0
    }
}

/// The unit vectors of the plane's first and second axis (see the module docs).
pub fn plane_axes(plane: Plane) -> (Vector3<f64>, Vector3<f64>) {
    match plane {
        Plane::Xy => (Vector3::x(), Vector3::y()),
        Plane::Zx => (Vector3::z(), Vector3::x()),
        Plane::Yz => (Vector3::y(), Vector3::z()),
    }
}

fn sign(direction: ArcDirection) -> f64 {
    match direction {
        ArcDirection::Ccw => 1.0,
        ArcDirection::Cw => -1.0,
    }
}

fn direction_name(direction: ArcDirection) -> &'static str {
    match direction {
        ArcDirection::Cw => "CW",
        ArcDirection::Ccw => "CCW",
    }
}

fn plane_label(plane: Plane) -> (&'static str, &'static str, [&'static str; 2]) {
    match plane {
        Plane::Xy => ("XY", "G17", ["+X", "+Y"]),
        Plane::Zx => ("ZX", "G18", ["+Z", "+X"]),
        Plane::Yz => ("YZ", "G19", ["+Y", "+Z"]),
    }
}

impl CircularTest {
    /// An ISO 230-4 circular test with the usual ball-bar settings: a full 360° data arc starting
    /// at 0°, a CW run then a CCW run, 1.5 mm feed-in and 45° overshoots.
    ///
    /// `center` and `radius_m` in m, `feed_m_s` in m/s. Not validated: see
    /// [`CircularTest::validate`].
    pub fn iso230_4(plane: Plane, center: Vector3<f64>, radius_m: f64, feed_m_s: f64) -> Self {
        CircularTest {
            plane,
            center,
            radius_m,
            feed_m_s,
            arc_deg: 360.0,
            start_deg: 0.0,
            directions: vec![ArcDirection::Cw, ArcDirection::Ccw],
            feed_in_m: DEFAULT_FEED_IN_M,
            overshoot_deg: DEFAULT_OVERSHOOT_DEG,
            approach_from_above_m: 0.0,
        }
    }

    /// Checks that the test can be run with a ball bar: a finite centre, a radius of 50 to
    /// 600 mm, a feed > 0, a data arc in (0, 360]°, a finite start angle, an overshoot >= 0 with
    /// `arc + 2 * overshoot <= 720°`, at least one direction, a feed-in of 0 to 10 mm and an
    /// approach from 0 to 10 mm above the start.
    pub fn validate(&self) -> Result<(), InvalidTest> {
        use TestParameter as P;
        if !self.center.iter().all(|c| c.abs() <= MAX_CENTRE_M) {
            let c = self.center * 1e3;
            return Err(invalid(
                P::Center,
                format!("({}, {}, {}) mm", num(c.x), num(c.y), num(c.z)),
                "every coordinate must be a number from -10000 to 10000 mm",
            ));
        }
        let r = self.radius_m;
        let eps = 1e-12;
        if !(r >= BALLBAR_MIN_RADIUS_M - eps && r <= BALLBAR_MAX_RADIUS_M + eps) {
            return Err(invalid(
                P::Radius,
                format!("{} mm", num(r * 1e3)),
                "a ball bar measures circles of 50 to 600 mm radius",
            ));
        }
        let (lo, hi) = FEED_RANGE_MM_MIN;
        if !(lo..=hi).contains(&(self.feed_m_s * 6e4)) {
            return Err(invalid(
                P::Feed,
                format!("{} mm/min", num(self.feed_m_s * 6e4)),
                &format!("the feed must be from {lo} to {hi} mm/min"),
            ));
        }
        if !(self.arc_deg >= MIN_ARC_DEG && self.arc_deg <= 360.0) {
            return Err(invalid(
                P::Arc,
                format!("{} deg", num(self.arc_deg)),
                "the data arc must be from 90 to 360 deg (a shorter arc cannot tell the circle's centre from its radius)",
            ));
        }
        if !(-360.0..=360.0).contains(&self.start_deg) {
            return Err(invalid(
                P::Start,
                format!("{} deg", num(self.start_deg)),
                "the start angle must be from -360 to 360 deg",
            ));
        }
        if !(self.overshoot_deg >= 0.0 && self.arc_deg + 2.0 * self.overshoot_deg <= 720.0) {
            return Err(invalid(
                P::Overshoot,
                format!("{} deg", num(self.overshoot_deg)),
                &format!(
                    "the overshoot must be >= 0 deg, and the data arc ({} deg) plus both \
                     overshoots at most 720 deg",
                    num(self.arc_deg)
                ),
            ));
        }
        if self.directions.is_empty() {
            return Err(invalid(
                P::Directions,
                "(none)".to_string(),
                "give at least one direction, CW or CCW",
            ));
        }
        if !(self.feed_in_m >= 0.0 && self.feed_in_m <= MAX_FEED_IN_M) {
            return Err(invalid(
                P::FeedIn,
                format!("{} mm", num(self.feed_in_m * 1e3)),
                "the feed-in must be 0 to 10 mm (commercial ball bars use 1.5 mm)",
            ));
        }
        if !(self.approach_from_above_m >= 0.0 && self.approach_from_above_m <= MAX_APPROACH_M) {
            return Err(invalid(
                P::Approach,
                format!("{} mm", num(self.approach_from_above_m * 1e3)),
                "the approach must start 0 to 10 mm above the start point",
            ));
        }
        Ok(())
    }

    /// The point at `angle_deg` on the circle of `radius_m` (m) about the centre, m.
    pub fn point(&self, angle_deg: f64, radius_m: f64) -> Vector3<f64> {
        let (u, v) = plane_axes(self.plane);
        let a = angle_deg.to_radians();
        self.center + radius_m * (a.cos() * u + a.sin() * v)
    }

    /// Where the run in `direction` lies on the circle (see [`RunAngles`]).
    pub fn run_angles(&self, direction: ArcDirection) -> RunAngles {
        let s = sign(direction);
        let data_start_deg = match direction {
            ArcDirection::Ccw => self.start_deg,
            ArcDirection::Cw => self.start_deg + self.arc_deg,
        };
        let data_end_deg = data_start_deg + s * self.arc_deg;
        RunAngles {
            direction,
            feed_in_deg: data_start_deg - s * self.overshoot_deg,
            data_start_deg,
            data_end_deg,
            feed_out_deg: data_end_deg + s * self.overshoot_deg,
        }
    }

    /// Where the program starts: the first run's feed-in start, `feed_in_m` outside the
    /// circle, m. The ball bar is fitted here.
    pub fn start_point(&self) -> Vector3<f64> {
        let first = self.directions.first().copied().unwrap_or(ArcDirection::Cw);
        self.point(
            self.run_angles(first).feed_in_deg,
            self.radius_m + self.feed_in_m,
        )
    }

    /// Where the program ends: the last run's feed-out end, `feed_in_m` outside the circle, m.
    pub fn end_point(&self) -> Vector3<f64> {
        let last = self.directions.last().copied().unwrap_or(ArcDirection::Cw);
        self.point(
            self.run_angles(last).feed_out_deg,
            self.radius_m + self.feed_in_m,
        )
    }

    /// The test as a G-code program (see the module docs for its layout), headed by a comment
    /// naming it an ISO 230-4 ball-bar test. Meant for a test that passes
    /// [`CircularTest::validate`]; another may give a program the parser refuses.
    pub fn gcode(&self) -> String {
        self.gcode_with_header(&["vmt circular test: ISO 230-4 ball bar"])
    }

    /// [`CircularTest::gcode`] headed by `header`, one comment line each (parentheses in it are
    /// replaced by brackets).
    pub fn gcode_with_header(&self, header: &[&str]) -> String {
        let mut w = Writer::new(self);
        for line in header {
            w.comment(line);
        }
        w.program();
        w.text
    }

    /// The data arcs of `program`, parsed from [`CircularTest::gcode`] of this test: for each
    /// run, its direction and the indices of its data-arc blocks in `program.blocks`.
    ///
    /// `None` if `program` does not have this test's layout (a different block count, or a
    /// data block that is not an arc in the run's direction).
    pub fn data_blocks(&self, program: &Program) -> Option<Vec<(ArcDirection, Range<usize>)>> {
        let mut w = Writer::new(self);
        w.program();
        if w.roles.len() != program.blocks.len() {
            return None;
        }
        let mut runs: Vec<(usize, ArcDirection, Range<usize>)> = Vec::new();
        for (k, (role, block)) in w.roles.iter().zip(&program.blocks).enumerate() {
            let Role::Data { run, direction } = *role else {
                continue;
            };
            match block.motion {
                Motion::Arc { direction: d, .. } if d == direction => {}
                _ => return None,
            }
            match runs.last_mut() {
                Some((r, _, range)) if *r == run => range.end = k + 1,
                _ => runs.push((run, direction, k..k + 1)),
            }
        }
        Some(runs.into_iter().map(|(_, d, r)| (d, r)).collect())
    }
}

/// The data arcs of any program marked as [`CircularTest::gcode`] marks them: the blocks between
/// a `(DATA CW START)` line and the next `(DATA CW END)` line (or `CCW`), as indices into
/// `program.blocks` (parsed from `text`).
///
/// Markers are matched case-insensitively on lines of their own. A marker out of order (an END
/// without its START, a START inside a data arc, or a START never ended) is an error naming its
/// line.
pub fn marked_data_blocks(
    text: &str,
    program: &Program,
) -> Result<Vec<(ArcDirection, Range<usize>)>, NcError> {
    let mut arcs = Vec::new();
    let mut open: Option<(usize, ArcDirection)> = None;
    for (k, line) in text.lines().enumerate() {
        let Some((direction, is_start)) = marker(line) else {
            continue;
        };
        let line_no = k + 1;
        let fail = |message: &str| NcError {
            line: line_no,
            column: 1,
            message: message.to_string(),
        };
        match (open, is_start) {
            (None, true) => open = Some((line_no, direction)),
            (Some((from, d)), false) if d == direction => {
                let inside: Vec<usize> = (0..program.blocks.len())
                    .filter(|&b| (from..line_no).contains(&program.blocks[b].span.line))
                    .collect();
                if let (Some(&a), Some(&b)) = (inside.first(), inside.last()) {
                    arcs.push((direction, a..b + 1));
                }
                open = None;
            }
            (Some(_), true) => return Err(fail("a DATA START inside a data arc: end it first")),
            _ => return Err(fail("a DATA END without the matching DATA START")),
        }
    }
    match open {
        Some((line, _)) => Err(NcError {
            line,
            column: 1,
            message: "this DATA START has no matching DATA END".to_string(),
        }),
        None => Ok(arcs),
    }
}

/// One circle a program measures between DATA markers: where the ball bar is set up, and the
/// runs on it.
#[derive(Clone, Debug, PartialEq)]
pub struct MarkedCircle {
    /// Plane of its arcs.
    pub plane: Plane,
    /// Centre of its arcs (the tool point, absolute), m.
    pub center: Vector3<f64>,
    /// Radius of its arcs, m, rounded to 0.1 µm (a program in mm with four decimals gives its
    /// end points to that, so a 150 mm circle's blocks end 150 mm ± 0.07 µm from the centre).
    pub radius_m: f64,
    /// Programmed feed of its arcs, m/s.
    pub feed_m_s: f64,
    /// Its runs in program order: the marker's direction and the data blocks.
    pub runs: Vec<(ArcDirection, Range<usize>)>,
}

/// Arcs further apart than this in centre or radius are different circles (the bar remounted),
/// m: ten times the 0.1 µm a four-decimal program resolves.
const SAME_CIRCLE_M: f64 = 1e-6;

/// The circles measured by the data arcs of a marked program ([`marked_data_blocks`]): every
/// block between a pair of markers must be an arc in the marker's direction, in its plane (no
/// helix), on one circle at one feed; consecutive runs on the same circle at the same feed make
/// one circle (one ball-bar set-up, as [`CircularTest::gcode`] runs CW then CCW). An error names
/// the line of the block at fault.
pub fn marked_circles(text: &str, program: &Program) -> Result<Vec<MarkedCircle>, NcError> {
    let starts = block_starts(program);
    let mut circles: Vec<MarkedCircle> = Vec::new();
    for (direction, range) in marked_data_blocks(text, program)? {
        let run = marked_run(program, &starts, direction, range)?;
        match circles.last_mut() {
            Some(c) if same_circle(c, &run) => c.runs.extend(run.runs),
            _ => circles.push(run),
        }
    }
    Ok(circles)
}

/// Where each block of `program` starts, m.
fn block_starts(program: &Program) -> Vec<Vector3<f64>> {
    let mut at = program.start;
    program
        .blocks
        .iter()
        .map(|b| {
            let start = at;
            if let Motion::Rapid { to } | Motion::Linear { to, .. } | Motion::Arc { to, .. } =
                b.motion
            {
                at = to;
            }
            start
        })
        .collect()
}

fn same_circle(a: &MarkedCircle, b: &MarkedCircle) -> bool {
    a.plane == b.plane
        && (a.center - b.center).norm() <= SAME_CIRCLE_M
        && (a.radius_m - b.radius_m).abs() <= SAME_CIRCLE_M
        && a.feed_m_s == b.feed_m_s
}

/// One marked run (a non-empty `range`, as [`marked_data_blocks`] gives) as a circle of its
/// own, every block checked against its first.
fn marked_run(
    program: &Program,
    starts: &[Vector3<f64>],
    direction: ArcDirection,
    range: Range<usize>,
) -> Result<MarkedCircle, NcError> {
    let circle_of = |k: usize| data_arc(program, starts[k], k, direction, range.clone());
    let first = circle_of(range.start)?;
    for k in range.clone().skip(1) {
        if !same_circle(&first, &circle_of(k)?) {
            return Err(block_error(
                program,
                k,
                format!(
                    "the arcs between one pair of DATA {} markers lie on one circle at one \
                     feed: this one has another plane, centre, radius or feed than the first",
                    direction_name(direction)
                ),
            ));
        }
    }
    Ok(first)
}

fn block_error(program: &Program, k: usize, message: String) -> NcError {
    let span = program.blocks[k].span;
    NcError {
        line: span.line,
        column: span.column,
        message,
    }
}

/// Block `k` (starting at `start`, m) of a run marked `direction` as the circle it lies on.
fn data_arc(
    program: &Program,
    start: Vector3<f64>,
    k: usize,
    direction: ArcDirection,
    range: Range<usize>,
) -> Result<MarkedCircle, NcError> {
    let name = direction_name(direction);
    let Motion::Arc {
        to,
        center,
        plane,
        direction: d,
        feed,
    } = program.blocks[k].motion
    else {
        let msg = format!(
            "a ball bar's data arc holds only arcs: this block between the DATA {name} markers \
             is not a G2/G3 move"
        );
        return Err(block_error(program, k, msg));
    };
    if d != direction {
        let msg = format!("this arc runs the other way than its DATA {name} markers say");
        return Err(block_error(program, k, msg));
    }
    let n = plane.normal();
    if (to - start).dot(&n).abs() > SAME_CIRCLE_M {
        let msg = "a ball bar's data arc lies in its plane: this arc is a helix".to_string();
        return Err(block_error(program, k, msg));
    }
    let r = start - center;
    let radius_m = (r - n * r.dot(&n)).norm();
    Ok(MarkedCircle {
        plane,
        center,
        radius_m: (radius_m * 1e7).round() / 1e7,
        feed_m_s: feed,
        runs: vec![(direction, range)],
    })
}

fn marker(line: &str) -> Option<(ArcDirection, bool)> {
    let t = line.trim().to_ascii_uppercase();
    match t.as_str() {
        "(DATA CW START)" => Some((ArcDirection::Cw, true)),
        "(DATA CW END)" => Some((ArcDirection::Cw, false)),
        "(DATA CCW START)" => Some((ArcDirection::Ccw, true)),
        "(DATA CCW END)" => Some((ArcDirection::Ccw, false)),
        _ => None,
    }
}

// ---------------------------------------------------------------------------------------------
// Writing the program

/// What a motion block of the generated program is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Role {
    Approach,
    FeedIn,
    RunIn,
    Data { run: usize, direction: ArcDirection },
    RunOut,
    FeedOut,
    Transit,
}

/// mm rounded to the written 4 decimals.
fn round4(x: f64) -> f64 {
    (x * 1e4).round() / 1e4
}

fn fmt4(x: f64) -> String {
    let r = round4(x);
    if r == 0.0 {
        "0.0000".to_string()
    } else {
        format!("{r:.4}")
    }
}

/// A value for a message: up to 4 decimals without trailing zeros, or scientific when tiny.
fn num(x: f64) -> String {
    if x != 0.0 && (x.abs() < 1e-3 || x.abs() >= 1e9) {
        format!("{x:e}")
    } else {
        fmt_short(x)
    }
}

/// A number with up to 4 decimals, trailing zeros dropped.
fn fmt_short(x: f64) -> String {
    let s = fmt4(x);
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s.is_empty() || s == "-" {
        "0".to_string()
    } else {
        s.to_string()
    }
}

struct Writer<'t> {
    test: &'t CircularTest,
    text: String,
    /// The last written position, mm (as written).
    last_mm: [f64; 3],
    roles: Vec<Role>,
}

impl<'t> Writer<'t> {
    fn new(test: &'t CircularTest) -> Self {
        Writer {
            test,
            text: String::new(),
            last_mm: [0.0; 3],
            roles: Vec::new(),
        }
    }

    fn line(&mut self, s: &str) {
        self.text.push_str(s);
        self.text.push('\n');
    }

    fn comment(&mut self, s: &str) {
        let clean: String = s
            .chars()
            .map(|c| match c {
                '(' => '[',
                ')' => ']',
                '\n' | '\r' => ' ',
                c => c,
            })
            .collect();
        self.line(&format!("({clean})"));
    }

    fn xyz(p_mm: [f64; 3]) -> String {
        format!("X{} Y{} Z{}", fmt4(p_mm[0]), fmt4(p_mm[1]), fmt4(p_mm[2]))
    }

    fn to_mm(p: Vector3<f64>) -> [f64; 3] {
        [round4(p.x * 1e3), round4(p.y * 1e3), round4(p.z * 1e3)]
    }

    fn straight(&mut self, code: &str, p: Vector3<f64>, role: Role) {
        let mm = Self::to_mm(p);
        self.line(&format!("{code} {}", Self::xyz(mm)));
        self.last_mm = mm;
        self.roles.push(role);
    }

    /// One arc block ending at `end_mm` about the test's centre.
    fn arc_block(&mut self, direction: ArcDirection, end_mm: [f64; 3], role: Role) {
        let c = Self::to_mm(self.test.center);
        let offset = |k: usize| fmt4(round4(c[k] - self.last_mm[k]));
        let ijk = match self.test.plane {
            Plane::Xy => format!("I{} J{}", offset(0), offset(1)),
            Plane::Zx => format!("I{} K{}", offset(0), offset(2)),
            Plane::Yz => format!("J{} K{}", offset(1), offset(2)),
        };
        let code = match direction {
            ArcDirection::Cw => "G2",
            ArcDirection::Ccw => "G3",
        };
        self.line(&format!("{code} {} {ijk}", Self::xyz(end_mm)));
        self.last_mm = end_mm;
        self.roles.push(role);
    }

    /// An arc of `sweep_deg` (>= 0) from `from_deg` at `radius_m`; a 360° sweep is one
    /// full-circle block, other sweeps over 180° are split.
    fn arc(
        &mut self,
        direction: ArcDirection,
        from_deg: f64,
        sweep_deg: f64,
        radius_m: f64,
        role: Role,
    ) {
        if sweep_deg <= 0.0 {
            return;
        }
        if sweep_deg == 360.0 {
            self.arc_block(direction, self.last_mm, role);
            return;
        }
        let pieces = (sweep_deg / 180.0).ceil().max(1.0) as usize;
        let step = sign(direction) * sweep_deg / pieces as f64;
        for k in 1..=pieces {
            let end = self.test.point(from_deg + step * k as f64, radius_m);
            self.arc_block(direction, Self::to_mm(end), role);
        }
    }

    fn program(&mut self) {
        let t = self.test;
        self.describe();
        let (_, g_plane, _) = plane_label(t.plane);
        self.line(&format!("G21 G90 G94 {g_plane}"));
        self.line(&format!("F{}", fmt_short(t.feed_m_s * 6e4)));
        let start = t.start_point();
        if t.approach_from_above_m > 0.0 {
            self.comment("up, over the start and down onto it");
            let above = start + Vector3::z() * t.approach_from_above_m;
            self.line(&format!("G0 Z{}", fmt4(above.z * 1e3)));
            self.roles.push(Role::Approach);
            self.straight("G0", above, Role::Approach);
        }
        self.comment("to the feed-in start point: fit the ball bar here");
        self.straight("G0", start, Role::Approach);
        let mut previous: Option<RunAngles> = None;
        for (run, &direction) in t.directions.iter().enumerate() {
            let angles = t.run_angles(direction);
            if let Some(prev) = previous {
                self.transit(prev, angles);
            }
            self.run(run, angles);
            previous = Some(angles);
        }
        self.line("M30");
    }

    fn describe(&mut self) {
        let t = self.test;
        let (name, g_plane, [first, second]) = plane_label(t.plane);
        let c = Self::to_mm(t.center);
        let dirs: Vec<&str> = t.directions.iter().map(|&d| direction_name(d)).collect();
        self.comment(&format!(
            "plane {name} {g_plane}; angles from {first} towards {second}; G3 = CCW increases them"
        ));
        self.comment(&format!(
            "centre {} mm; radius {} mm",
            Self::xyz(c),
            fmt4(t.radius_m * 1e3)
        ));
        self.comment(&format!(
            "feed {} mm/min; data arc {} deg from {} deg; overshoot {} deg; feed-in {} mm",
            fmt_short(t.feed_m_s * 6e4),
            fmt_short(t.arc_deg),
            fmt_short(t.start_deg),
            fmt_short(t.overshoot_deg),
            fmt_short(t.feed_in_m * 1e3)
        ));
        self.comment(&format!(
            "runs: {}; each data arc lies between DATA <dir> START and DATA <dir> END",
            dirs.join(", ")
        ));
    }

    fn run(&mut self, run: usize, a: RunAngles) {
        let t = self.test;
        let d = a.direction;
        let name = direction_name(d);
        let (r, out) = (t.radius_m, t.radius_m + t.feed_in_m);
        self.comment(&format!("run {}: {name}", run + 1));
        if t.feed_in_m > 0.0 {
            self.comment(&format!("feed in {} mm", fmt_short(t.feed_in_m * 1e3)));
            self.straight("G1", t.point(a.feed_in_deg, r), Role::FeedIn);
        }
        if t.overshoot_deg > 0.0 {
            self.comment(&format!(
                "run-in overshoot {} deg",
                fmt_short(t.overshoot_deg)
            ));
            self.arc(d, a.feed_in_deg, t.overshoot_deg, r, Role::RunIn);
        }
        self.comment(&format!("DATA {name} START"));
        let data = Role::Data { run, direction: d };
        self.arc(d, a.data_start_deg, t.arc_deg, r, data);
        self.comment(&format!("DATA {name} END"));
        if t.overshoot_deg > 0.0 {
            self.comment(&format!(
                "run-out overshoot {} deg",
                fmt_short(t.overshoot_deg)
            ));
            self.arc(d, a.data_end_deg, t.overshoot_deg, r, Role::RunOut);
        }
        if t.feed_in_m > 0.0 {
            self.comment(&format!("feed out {} mm", fmt_short(t.feed_in_m * 1e3)));
            self.straight("G1", t.point(a.feed_out_deg, out), Role::FeedOut);
        }
    }

    /// From the end of run `prev` back over its arc to the start of run `next`, at the
    /// feed-in radius (nothing when they meet).
    fn transit(&mut self, prev: RunAngles, next: RunAngles) {
        let back = sign(prev.direction) * (prev.feed_out_deg - next.feed_in_deg);
        let sweep = back.rem_euclid(360.0);
        if sweep < 1e-9 || 360.0 - sweep < 1e-9 {
            return;
        }
        let reverse = match prev.direction {
            ArcDirection::Cw => ArcDirection::Ccw,
            ArcDirection::Ccw => ArcDirection::Cw,
        };
        self.comment(&format!(
            "back over the last run to the next feed-in, {} deg",
            fmt_short(sweep)
        ));
        let radius = self.test.radius_m + self.test.feed_in_m;
        self.arc(reverse, prev.feed_out_deg, sweep, radius, Role::Transit);
    }
}

// ---------------------------------------------------------------------------------------------
// Kwon's seven-step procedure

/// Height by which step 2 raises the circle (and its centre ball) above step 1, m.
///
/// Kwon (Section VI, step 2; Section IV.2) compares a circle at a second height with step 1 to
/// see the pitch motion errors, but gives no height; 100 mm is this choice.
pub const KWON_STEP2_RAISE_M: f64 = 0.1;

/// Height above each horizontal step's start from which its program comes down onto it, m
/// ([`CircularTest::approach_from_above_m`]): every XY step then runs with Z last moved down,
/// so that Kwon's step-to-step differences (pitch from steps 1–2, XZ/YZ squareness from 3–4)
/// compare one Z direction state (a Z axis' squareness can differ by direction).
pub const KWON_APPROACH_FROM_ABOVE_M: f64 = 0.005;

/// One step of Kwon's procedure: its circular test and the ball bar that measures it.
#[derive(Clone, Debug, PartialEq)]
pub struct KwonStep {
    /// 1 to 7.
    pub number: u8,
    /// File-name-like name, e.g. `step1_xy_150mm_f500`.
    pub name: String,
    /// Length of the ball link bar, m.
    pub link_length_m: f64,
    /// Position of the centre ball (the bar's fixed end), m.
    pub pivot: Vector3<f64>,
    /// What the step measures, after the paper.
    pub purpose: &'static str,
    /// The tool path.
    pub test: CircularTest,
}

fn kwon_test(
    plane: Plane,
    center: Vector3<f64>,
    radius_m: f64,
    feed_mm_min: f64,
    arc_deg: f64,
    start_deg: f64,
) -> CircularTest {
    CircularTest {
        plane,
        center,
        radius_m,
        feed_m_s: feed_mm_min / 6e4,
        arc_deg,
        start_deg,
        directions: vec![ArcDirection::Cw, ArcDirection::Ccw],
        feed_in_m: DEFAULT_FEED_IN_M,
        overshoot_deg: 0.0,
        approach_from_above_m: if plane == Plane::Xy {
            KWON_APPROACH_FROM_ABOVE_M
        } else {
            0.0
        },
    }
}

/// Kwon's seven-step ball-link-bar procedure (Kwon, *Measurement and Analysis of CNC Machine
/// Tool Errors Using Ball Link Bar System*, Section VI and Fig. 23), with `pivot` the position of
/// the centre ball in steps 1 and 3–7, m.
///
/// | step | plane | link | circle radius | feed | arc | measures |
/// |---|---|---|---|---|---|---|
/// | 1 | XY | 150 mm | 150 mm | 500 mm/min | 360° | closing, backlash, positional, XY squareness, stick-slip |
/// | 2 | XY, 100 mm higher | 150 mm | 150 mm | 500 mm/min | 360° | pitch, compared with step 1 |
/// | 3 | XY | 100 mm | 100 mm | 500 mm/min | 360° | XZ/YZ squareness, with step 4 |
/// | 4 | XY, inclined link | 250 mm | 100 mm | 500 mm/min | 360° | XZ/YZ squareness, with step 3 |
/// | 5 | XY | 100 mm | 100 mm | 4000 mm/min | 360° | servo mismatch, start transient |
/// | 6 | ZX | 150 mm | 150 mm | 500 mm/min | 180°, upper half | Z backlash |
/// | 7 | YZ | 150 mm | 150 mm | 500 mm/min | 180°, upper half | Z backlash |
///
/// Every step runs CW then CCW ("시계 및 반시계 방향", in that order). The paper leaves open,
/// and this function chooses:
///
/// - **Planes.** The step list names no plane. Steps 1–5 are horizontal (XY): step 1 reports XY
///   squareness (least-squares ellipse, Section IV.1), and the paper's result for step 5 is
///   given "in the XY plane". Steps 6 and 7 are the vertical planes, since they give the Z
///   backlash: step 6 ZX (G18), step 7 YZ (G19).
/// - **Step 2** is step 1 at another height (Section IV.2: pitch distorts the circle at height
///   h); the height is not given, and both balls are raised by [`KWON_STEP2_RAISE_M`].
/// - **Steps 3 and 4** follow Fig. 15 and eq. (4.12): circles of the same diameter at a
///   height difference h, the short link flat and the long link inclined. With a 100 mm and a
///   250 mm link the circle radius is 100 mm and h = √(250² − 100²) = 229.13 mm, so
///   tan θ = 100 / 229.13 and 1 µm of eccentricity difference is 1 µm / (250 mm · tan θ) =
///   1.9″ — the paper's own example. The step-4 circle lies h above the centre ball.
/// - **Steps 6 and 7** run the upper half circle (the table is below the centre ball), through
///   the top, where Z reverses: ZX from −X (−90°) to +X (+90°), YZ from +Y (0°) to −Y (180°).
/// - **Approach.** Each XY step comes down onto its start from [`KWON_APPROACH_FROM_ABOVE_M`]
///   above, so that steps reached from a lower and from a higher step (3 after 2, 4 after 3)
///   share one Z direction state; the paper does not say how the heights are reached.
/// - **No overshoot.** The paper sees the closing error and the transient start peak at the
///   start of the circle (Sections III.2 and III.6), so the data arc begins where the motion
///   does, right after the radial feed-in; the 1.5 mm feed-in itself is commercial practice,
///   not the paper's.
pub fn kwon_steps(pivot: Vector3<f64>) -> Vec<KwonStep> {
    let up = Vector3::z();
    let h4 = (0.25_f64.powi(2) - 0.1_f64.powi(2)).sqrt();
    let raised = pivot + KWON_STEP2_RAISE_M * up;
    let step = |number, name: &str, link_length_m, pivot, purpose, test| KwonStep {
        number,
        name: name.to_string(),
        link_length_m,
        pivot,
        purpose,
        test,
    };
    vec![
        step(
            1,
            "step1_xy_150mm_f500",
            0.15,
            pivot,
            "closing, backlash, positional, XY squareness and stick-slip errors",
            kwon_test(Plane::Xy, pivot, 0.15, 500.0, 360.0, 0.0),
        ),
        step(
            2,
            "step2_xy_150mm_f500_raised_100mm",
            0.15,
            raised,
            "pitch motion errors, compared with step 1",
            kwon_test(Plane::Xy, raised, 0.15, 500.0, 360.0, 0.0),
        ),
        step(
            3,
            "step3_xy_100mm_f500",
            0.1,
            pivot,
            "XZ and YZ squareness, with step 4 (short link)",
            kwon_test(Plane::Xy, pivot, 0.1, 500.0, 360.0, 0.0),
        ),
        step(
            4,
            "step4_xy_250mm_inclined_f500",
            0.25,
            pivot,
            "XZ and YZ squareness, with step 3 (long link, inclined)",
            kwon_test(Plane::Xy, pivot + h4 * up, 0.1, 500.0, 360.0, 0.0),
        ),
        step(
            5,
            "step5_xy_100mm_f4000",
            0.1,
            pivot,
            "servo mismatch and the transient start peak at high feed",
            kwon_test(Plane::Xy, pivot, 0.1, 4000.0, 360.0, 0.0),
        ),
        step(
            6,
            "step6_zx_150mm_180deg_f500",
            0.15,
            pivot,
            "Z backlash (ZX plane)",
            kwon_test(Plane::Zx, pivot, 0.15, 500.0, 180.0, -90.0),
        ),
        step(
            7,
            "step7_yz_150mm_180deg_f500",
            0.15,
            pivot,
            "Z backlash (YZ plane)",
            kwon_test(Plane::Yz, pivot, 0.15, 500.0, 180.0, 0.0),
        ),
    ]
}

/// Kwon's seven steps as (name, test) pairs; see [`kwon_steps`] for the steps, the choices made
/// where the paper is silent, and the centre-ball positions. `center` is the centre ball of
/// steps 1 and 3–7, m.
pub fn kwon_seven_step(center: Vector3<f64>) -> Vec<(String, CircularTest)> {
    kwon_steps(center)
        .into_iter()
        .map(|s| (s.name, s.test))
        .collect()
}

/// The seven programs as files: (file name, G-code), each headed by the step, its link and
/// centre ball, and its purpose. `pivot` in m; `scenarios/kwon_seven_step/` holds them for
/// [`KWON_SCENARIO_PIVOT_MM`].
pub fn kwon_program_files(pivot: Vector3<f64>) -> Vec<(String, String)> {
    kwon_steps(pivot)
        .iter()
        .map(|s| {
            let p = s.pivot * 1e3;
            let lines = [
                format!(
                    "Kwon's seven-step ball-link-bar procedure, step {} of 7",
                    s.number
                ),
                format!(
                    "link {} mm; centre ball at X{} Y{} Z{} mm",
                    fmt_short(s.link_length_m * 1e3),
                    fmt4(p.x),
                    fmt4(p.y),
                    fmt4(p.z)
                ),
                format!("measures: {}", s.purpose),
                "generated by vmt-sim nc::ballbar::kwon_program_files; do not edit".to_string(),
            ];
            let header: Vec<&str> = lines.iter().map(String::as_str).collect();
            (format!("{}.nc", s.name), s.test.gcode_with_header(&header))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nc::parse::parse;

    const MM: f64 = 1e-3;

    fn centre() -> Vector3<f64> {
        Vector3::new(250.0, 200.0, 150.0) * MM
    }

    fn parsed(t: &CircularTest) -> Program {
        t.validate().unwrap();
        let text = t.gcode();
        parse(&text, t.start_point()).unwrap_or_else(|e| panic!("{e}\n{text}"))
    }

    /// Start point of every block.
    fn starts(p: &Program) -> Vec<Vector3<f64>> {
        let mut at = p.start;
        p.blocks
            .iter()
            .map(|b| {
                let s = at;
                if let Motion::Rapid { to } | Motion::Linear { to, .. } | Motion::Arc { to, .. } =
                    b.motion
                {
                    at = to;
                }
                s
            })
            .collect()
    }

    fn end_of(p: &Program) -> Vector3<f64> {
        match p.blocks.last().map(|b| &b.motion) {
            Some(Motion::Rapid { to } | Motion::Linear { to, .. } | Motion::Arc { to, .. }) => *to,
            _ => p.start,
        }
    }

    fn angle_deg(plane: Plane, c: Vector3<f64>, p: Vector3<f64>) -> f64 {
        let (u, v) = plane_axes(plane);
        let d = p - c;
        d.dot(&v).atan2(d.dot(&u)).to_degrees()
    }

    /// Sweep of an arc block, degrees, positive in its direction (360 for a full circle).
    fn sweep_deg(start: Vector3<f64>, m: &Motion) -> f64 {
        let Motion::Arc {
            to,
            center,
            plane,
            direction,
            ..
        } = *m
        else {
            panic!("{m:?}")
        };
        let d = angle_deg(plane, center, to) - angle_deg(plane, center, start);
        let s = (sign(direction) * d).rem_euclid(360.0);
        if s < 1e-9 { 360.0 } else { s }
    }

    fn radius(plane: Plane, c: Vector3<f64>, p: Vector3<f64>) -> f64 {
        let (u, v) = plane_axes(plane);
        let d = p - c;
        d.dot(&u).hypot(d.dot(&v))
    }

    /// Checks every data arc: direction, radius, total sweep, first and last angle.
    fn check_data_arcs(t: &CircularTest) {
        let p = parsed(t);
        let s = starts(&p);
        let arcs = t.data_blocks(&p).expect("layout");
        assert_eq!(arcs.len(), t.directions.len());
        let text = t.gcode();
        assert_eq!(marked_data_blocks(&text, &p).unwrap(), arcs);
        for ((direction, range), &want) in arcs.iter().zip(&t.directions) {
            assert_eq!(*direction, want);
            let mut total = 0.0;
            for k in range.clone() {
                let Motion::Arc {
                    center,
                    direction: d,
                    feed,
                    ..
                } = p.blocks[k].motion
                else {
                    panic!()
                };
                assert_eq!(d, want);
                assert!((feed - t.feed_m_s).abs() < 1e-12);
                assert!((center - t.center).norm() < 1e-7, "{center:?}");
                assert!((radius(t.plane, center, s[k]) - t.radius_m).abs() < 1e-7);
                total += sweep_deg(s[k], &p.blocks[k].motion);
            }
            assert!(
                (total - t.arc_deg).abs() < 5e-4,
                "sweep {total} vs {}",
                t.arc_deg
            );
            let a = t.run_angles(want);
            let first = angle_deg(t.plane, t.center, s[range.start]);
            let wrap = |x: f64| (x + 180.0).rem_euclid(360.0) - 180.0;
            assert!(
                wrap(first - a.data_start_deg).abs() < 5e-4,
                "{first} vs {a:?}"
            );
        }
    }

    #[test]
    fn iso_program_parses_with_the_documented_layout() {
        let t = CircularTest::iso230_4(Plane::Xy, centre(), 150.0 * MM, 1000.0 / 6e4);
        let p = parsed(&t);
        // G0, then per run: feed-in, overshoot, full circle, overshoot, feed-out.
        assert_eq!(p.blocks.len(), 1 + 2 * 5);
        assert_eq!(
            t.data_blocks(&p).unwrap(),
            vec![(ArcDirection::Cw, 3..4), (ArcDirection::Ccw, 8..9)]
        );
        // Starts at 45° (the CW run-in begins 45° above 0°), 151.5 mm out, and ends there too.
        let r = 151.5 * (45f64).to_radians().cos();
        let expected = Vector3::new(250.0 + r, 200.0 + r, 150.0) * MM;
        let Motion::Rapid { to } = p.blocks[0].motion else {
            panic!()
        };
        assert!((to - expected).norm() < 1e-7, "{to:?}");
        assert!((end_of(&p) - expected).norm() < 1e-7);
        assert!((t.start_point() - expected).norm() < 1e-12);
        // Feed-in ends on the circle, radially inwards.
        let Motion::Linear { to, feed } = p.blocks[1].motion else {
            panic!()
        };
        assert!(
            (to - Vector3::new(
                250.0 + 150.0 * 0.5f64.sqrt(),
                200.0 + 150.0 * 0.5f64.sqrt(),
                150.0
            ) * MM)
                .norm()
                < 1e-7
        );
        assert!((feed - 1000.0 / 6e4).abs() < 1e-12);
        check_data_arcs(&t);
    }

    #[test]
    fn program_text_is_readable() {
        let t = CircularTest::iso230_4(Plane::Xy, centre(), 150.0 * MM, 1000.0 / 6e4);
        let text = t.gcode();
        assert!(text.starts_with("(vmt circular test: ISO 230-4 ball bar)\n"));
        assert!(text.contains("G21 G90 G94 G17\nF1000\n"));
        assert!(text.contains(
            "(DATA CW START)\nG2 X400.0000 Y200.0000 Z150.0000 I-150.0000 J0.0000\n(DATA CW END)"
        ));
        assert!(text.contains(
            "(DATA CCW START)\nG3 X400.0000 Y200.0000 Z150.0000 I-150.0000 J0.0000\n(DATA CCW END)"
        ));
        assert!(text.ends_with("M30\n"));
    }

    #[test]
    fn all_planes_and_directions() {
        for plane in [Plane::Xy, Plane::Zx, Plane::Yz] {
            for dirs in [
                vec![ArcDirection::Cw, ArcDirection::Ccw],
                vec![ArcDirection::Ccw, ArcDirection::Cw],
                vec![ArcDirection::Ccw, ArcDirection::Ccw],
                vec![ArcDirection::Cw, ArcDirection::Cw, ArcDirection::Ccw],
            ] {
                let mut t = CircularTest::iso230_4(plane, centre(), 100.0 * MM, 2000.0 / 6e4);
                t.directions = dirs;
                t.start_deg = 30.0;
                check_data_arcs(&t);
            }
        }
    }

    #[test]
    fn partial_arcs_cover_the_requested_angles() {
        // 220° in ZX from -110° (20° below horizontal on -X) to +110°, through +Z.
        let mut t = CircularTest::iso230_4(Plane::Zx, centre(), 150.0 * MM, 500.0 / 6e4);
        t.arc_deg = 220.0;
        t.start_deg = -110.0;
        t.overshoot_deg = 2.0;
        check_data_arcs(&t);
        let p = parsed(&t);
        let arcs = t.data_blocks(&p).unwrap();
        // 220° is written as two 110° blocks per run.
        assert_eq!(
            arcs.iter().map(|(_, r)| r.len()).collect::<Vec<_>>(),
            vec![2, 2]
        );
        // The CW run starts its data at +110°: X = cx + r sin 110°, Z = cz + r cos 110°.
        let s = starts(&p);
        let first = s[arcs[0].1.start];
        let a = 110f64.to_radians();
        let want = centre() + 150.0 * MM * Vector3::new(a.sin(), 0.0, a.cos());
        assert!((first - want).norm() < 1e-7, "{first:?} vs {want:?}");
        // The lowest point of the whole program is 22° below the centre (110° + 2° overshoot).
        let lowest = s.iter().map(|q| q.z).fold(f64::INFINITY, f64::min);
        let want_low = centre().z + 151.5 * MM * (112f64).to_radians().cos();
        assert!((lowest - want_low).abs() < 1e-7, "{lowest} vs {want_low}");
    }

    #[test]
    fn half_circle_in_yz() {
        let mut t = CircularTest::iso230_4(Plane::Yz, centre(), 150.0 * MM, 500.0 / 6e4);
        t.arc_deg = 180.0;
        t.overshoot_deg = 0.0;
        check_data_arcs(&t);
        let p = parsed(&t);
        // Never below the centre: the upper half from +Y over +Z to -Y.
        for q in starts(&p) {
            assert!(q.z >= centre().z - 1e-9, "{q:?}");
        }
        // CW first: its data starts at 180° (-Y) and the program starts 1.5 mm outside it.
        let start = t.start_point();
        assert!((start - (centre() + Vector3::new(0.0, -151.5, 0.0) * MM)).norm() < 1e-12);
    }

    #[test]
    fn partial_vertical_arcs_lie_over_the_top_by_default() {
        for (plane, arc, want) in [
            (Plane::Zx, 180.0, -90.0),
            (Plane::Zx, 220.0, -110.0),
            (Plane::Yz, 180.0, 0.0),
            (Plane::Yz, 220.0, -20.0),
            (Plane::Xy, 180.0, 0.0),
            (Plane::Zx, 360.0, 0.0),
            (Plane::Yz, 360.0, 0.0),
        ] {
            let start = default_start_deg(plane, arc);
            assert_eq!(start, want, "{plane:?} {arc}");
            if plane == Plane::Xy || arc == 360.0 {
                continue;
            }
            // Both ends at one height, 20° below the centre for 220° (level for 180°), and
            // the middle at the top, +Z.
            let mut t = CircularTest::iso230_4(plane, centre(), 150.0 * MM, 500.0 / 6e4);
            (t.arc_deg, t.start_deg) = (arc, start);
            let (a, b) = (t.point(start, t.radius_m), t.point(start + arc, t.radius_m));
            let below = -150.0 * MM * ((arc - 180.0) / 2.0).to_radians().sin();
            for end in [a, b] {
                assert!(
                    (end.z - centre().z - below).abs() < 1e-12,
                    "{plane:?} {arc}"
                );
            }
            let top = t.point(start + arc / 2.0, t.radius_m) - centre();
            assert!((top - Vector3::z() * 150.0 * MM).norm() < 1e-12, "{top:?}");
        }
        // Kwon's half circles are those.
        for s in &kwon_steps(centre())[5..] {
            assert_eq!(s.test.start_deg, default_start_deg(s.test.plane, 180.0));
        }
    }

    #[test]
    fn marked_circles_are_the_tests_circles() {
        let mut t = CircularTest::iso230_4(Plane::Zx, centre(), 150.0 * MM, 1000.0 / 6e4);
        t.arc_deg = 220.0;
        t.start_deg = default_start_deg(Plane::Zx, 220.0);
        let mut other = CircularTest::iso230_4(Plane::Xy, centre(), 100.0 * MM, 500.0 / 6e4);
        other.directions = vec![ArcDirection::Ccw];
        // Two tests in a row, the second with its own start: two circles.
        let end = t.gcode().replace("M30\n", "");
        let text = format!("{end}{}", other.gcode());
        let p = parse(&text, t.start_point()).unwrap();
        let circles = marked_circles(&text, &p).unwrap();
        assert_eq!(circles.len(), 2, "{circles:?}");
        let (a, b) = (&circles[0], &circles[1]);
        assert_eq!((a.plane, b.plane), (Plane::Zx, Plane::Xy));
        assert_eq!((a.radius_m, b.radius_m), (0.15, 0.1));
        assert_eq!((a.feed_m_s, b.feed_m_s), (1000.0 / 6e4, 500.0 / 6e4));
        assert!((a.center - centre()).norm() < 1e-12);
        let own = parse(&t.gcode(), t.start_point()).unwrap();
        assert_eq!(Some(a.runs.clone()), t.data_blocks(&own));
        assert_eq!(b.runs.len(), 1);
        assert_eq!(b.runs[0].0, ArcDirection::Ccw);
    }

    #[test]
    fn marked_data_that_is_not_one_arc_is_refused_at_its_line() {
        let start = Vector3::new(0.1, 0.0, 0.0);
        for (body, line, says) in [
            ("G1 X0.2\n", 3, "not a G2/G3 move"),
            ("G3 X-100 Y0 I-100 J0\n", 3, "the other way"),
            ("G2 X-100 Y0 Z5 I-100 J0\n", 3, "helix"),
            (
                "G2 X0 Y-100 I-100 J0\nG2 X-50 Y-50 I0 J50\n",
                4,
                "another plane, centre, radius or feed",
            ),
        ] {
            let text = format!("G17 G21 F1000\n(DATA CW START)\n{body}(DATA CW END)\n");
            let p = parse(&text, start * 1e3 * MM).unwrap();
            let e = marked_circles(&text, &p).unwrap_err();
            assert_eq!(e.line, line, "{body}: {e}");
            assert!(e.message.contains(says), "{body}: {e}");
        }
    }

    #[test]
    fn feed_in_and_overshoot_can_be_zero() {
        let mut t = CircularTest::iso230_4(Plane::Xy, centre(), 50.0 * MM, 100.0 / 6e4);
        t.feed_in_m = 0.0;
        t.overshoot_deg = 0.0;
        let p = parsed(&t);
        assert_eq!(p.blocks.len(), 3);
        check_data_arcs(&t);
    }

    #[test]
    fn long_overshoots_are_split() {
        let mut t = CircularTest::iso230_4(Plane::Xy, centre(), 600.0 * MM, 100.0 / 6e4);
        t.overshoot_deg = 180.0;
        let p = parsed(&t);
        for (k, (b, s)) in p.blocks.iter().zip(starts(&p)).enumerate() {
            if matches!(b.motion, Motion::Arc { .. }) {
                let sw = sweep_deg(s, &b.motion);
                assert!(sw <= 180.0 + 1e-6 || sw == 360.0, "block {k}: {sw}");
            }
        }
        check_data_arcs(&t);
    }

    #[test]
    fn invalid_tests_are_refused() {
        let ok = CircularTest::iso230_4(Plane::Xy, centre(), 150.0 * MM, 1000.0 / 6e4);
        assert_eq!(ok.validate(), Ok(()));
        let cases: Vec<(CircularTest, TestParameter, &str)> = vec![
            (
                CircularTest {
                    radius_m: 20.0 * MM,
                    ..ok.clone()
                },
                TestParameter::Radius,
                "radius 20 mm: a ball bar measures circles of 50 to 600 mm radius",
            ),
            (
                CircularTest {
                    radius_m: 601.0 * MM,
                    ..ok.clone()
                },
                TestParameter::Radius,
                "radius 601 mm",
            ),
            (
                CircularTest {
                    feed_m_s: 0.0,
                    ..ok.clone()
                },
                TestParameter::Feed,
                "feed 0 mm/min",
            ),
            (
                CircularTest {
                    feed_m_s: f64::NAN,
                    ..ok.clone()
                },
                TestParameter::Feed,
                "feed NaN mm/min",
            ),
            (
                CircularTest {
                    arc_deg: 400.0,
                    ..ok.clone()
                },
                TestParameter::Arc,
                "data arc 400 deg",
            ),
            (
                CircularTest {
                    arc_deg: 0.0,
                    ..ok.clone()
                },
                TestParameter::Arc,
                "data arc 0 deg",
            ),
            (
                CircularTest {
                    start_deg: f64::INFINITY,
                    ..ok.clone()
                },
                TestParameter::Start,
                "start angle inf deg",
            ),
            (
                CircularTest {
                    overshoot_deg: -1.0,
                    ..ok.clone()
                },
                TestParameter::Overshoot,
                "overshoot -1 deg",
            ),
            (
                CircularTest {
                    overshoot_deg: 181.0,
                    ..ok.clone()
                },
                TestParameter::Overshoot,
                "plus both overshoots at most 720 deg",
            ),
            (
                CircularTest {
                    directions: vec![],
                    ..ok.clone()
                },
                TestParameter::Directions,
                "at least one direction",
            ),
            (
                CircularTest {
                    feed_in_m: -MM,
                    ..ok.clone()
                },
                TestParameter::FeedIn,
                "feed-in -1 mm",
            ),
            (
                CircularTest {
                    feed_in_m: 11.0 * MM,
                    ..ok.clone()
                },
                TestParameter::FeedIn,
                "feed-in 11 mm",
            ),
            (
                CircularTest {
                    approach_from_above_m: 11.0 * MM,
                    ..ok.clone()
                },
                TestParameter::Approach,
                "approach from above 11 mm: the approach must start 0 to 10 mm above the start point",
            ),
            (
                CircularTest {
                    approach_from_above_m: f64::NAN,
                    ..ok.clone()
                },
                TestParameter::Approach,
                "approach from above NaN mm",
            ),
            (
                CircularTest {
                    center: Vector3::new(f64::NAN, 0.0, 0.0),
                    ..ok.clone()
                },
                TestParameter::Center,
                "from -10000 to 10000 mm",
            ),
            (
                CircularTest {
                    center: Vector3::new(1e305, 0.0, 0.0),
                    ..ok.clone()
                },
                TestParameter::Center,
                "centre (1e308, 0, 0) mm",
            ),
            (
                CircularTest {
                    feed_m_s: 1e-300,
                    ..ok.clone()
                },
                TestParameter::Feed,
                "mm/min: the feed must be from 0.1 to 100000 mm/min",
            ),
            (
                CircularTest {
                    feed_m_s: 1e300,
                    ..ok.clone()
                },
                TestParameter::Feed,
                "e304 mm/min: the feed must be from",
            ),
            (
                CircularTest {
                    start_deg: 361.0,
                    ..ok.clone()
                },
                TestParameter::Start,
                "from -360 to 360 deg",
            ),
        ];
        for (t, parameter, text) in cases {
            let e = t.validate().unwrap_err();
            assert_eq!(e.parameter, parameter, "{e}");
            assert!(e.to_string().contains(text), "{e}");
        }
        // The bounds themselves are accepted.
        for (r, arc, ov) in [(50.0, 360.0, 180.0), (600.0, MIN_ARC_DEG, 315.0)] {
            let t = CircularTest {
                radius_m: r * MM,
                arc_deg: arc,
                overshoot_deg: ov,
                ..ok.clone()
            };
            assert_eq!(t.validate(), Ok(()), "{t:?}");
        }
    }

    #[test]
    fn data_blocks_refuses_another_program() {
        let t = CircularTest::iso230_4(Plane::Xy, centre(), 150.0 * MM, 1000.0 / 6e4);
        let other = CircularTest {
            overshoot_deg: 0.0,
            ..t.clone()
        };
        assert_eq!(t.data_blocks(&parsed(&other)), None);
    }

    #[test]
    fn markers_out_of_order_are_errors() {
        let p = parse("G0 X1", Vector3::zeros()).unwrap();
        let e = marked_data_blocks("(DATA CW END)\nG0 X1", &p).unwrap_err();
        assert_eq!(e.line, 1);
        let e = marked_data_blocks("G0 X1\n(DATA CW START)\n", &p).unwrap_err();
        assert_eq!(e.line, 2);
        let e = marked_data_blocks("(DATA CW START)\n(DATA CCW END)\n", &p).unwrap_err();
        assert_eq!(e.line, 2);
    }

    #[test]
    fn kwon_steps_follow_the_paper() {
        let pivot = Vector3::from(KWON_SCENARIO_PIVOT_MM) * MM;
        let steps = kwon_steps(pivot);
        assert_eq!(steps.len(), 7);
        let table: Vec<(Plane, f64, f64, f64, f64)> = steps
            .iter()
            .map(|s| {
                let t = &s.test;
                (
                    t.plane,
                    s.link_length_m / MM,
                    t.radius_m / MM,
                    t.feed_m_s * 6e4,
                    t.arc_deg,
                )
            })
            .collect();
        let want = [
            (Plane::Xy, 150.0, 150.0, 500.0, 360.0),
            (Plane::Xy, 150.0, 150.0, 500.0, 360.0),
            (Plane::Xy, 100.0, 100.0, 500.0, 360.0),
            (Plane::Xy, 250.0, 100.0, 500.0, 360.0),
            (Plane::Xy, 100.0, 100.0, 4000.0, 360.0),
            (Plane::Zx, 150.0, 150.0, 500.0, 180.0),
            (Plane::Yz, 150.0, 150.0, 500.0, 180.0),
        ];
        for (got, want) in table.iter().zip(want) {
            assert_eq!(got.0, want.0);
            for (a, b) in [
                (got.1, want.1),
                (got.2, want.2),
                (got.3, want.3),
                (got.4, want.4),
            ] {
                assert!((a - b).abs() < 1e-9, "{got:?} vs {want:?}");
            }
        }
        for s in &steps {
            assert_eq!(s.test.directions, vec![ArcDirection::Cw, ArcDirection::Ccw]);
            assert_eq!(s.test.overshoot_deg, 0.0);
            // The link reaches from the centre ball to every point of the circle.
            let p = s.test.point(s.test.start_deg, s.test.radius_m);
            assert!(
                ((p - s.pivot).norm() - s.link_length_m).abs() < 1e-12,
                "step {}",
                s.number
            );
            check_data_arcs(&s.test);
        }
        // Step 2 is 100 mm above step 1; step 4's circle 229.1288 mm above its centre ball.
        assert!(((steps[1].test.center - steps[0].test.center).z - 0.1).abs() < 1e-15);
        assert!(((steps[3].test.center - pivot).z - 229.128784747792 * MM).abs() < 1e-12);
        // The paper's example: 1 µm of eccentricity difference with the 100/250 mm links is
        // about 1.9 arc seconds of squareness (Section IV.1).
        let tan_theta = 0.1 / (steps[3].test.center - pivot).z;
        let arcsec = (1e-6 / (0.25 * tan_theta)).to_degrees() * 3600.0;
        assert!((arcsec - 1.89).abs() < 0.01, "{arcsec}");
        let names: Vec<String> = kwon_seven_step(pivot).into_iter().map(|(n, _)| n).collect();
        assert_eq!(names[0], "step1_xy_150mm_f500");
        assert_eq!(names[6], "step7_yz_150mm_180deg_f500");
    }

    #[test]
    fn kwon_vertical_steps_stay_above_the_centre_ball_and_reverse_z_at_the_top() {
        let pivot = Vector3::from(KWON_SCENARIO_PIVOT_MM) * MM;
        for s in &kwon_steps(pivot)[5..] {
            let p = parsed(&s.test);
            let pts = starts(&p);
            assert!(
                pts.iter().all(|q| q.z >= pivot.z - 1e-9),
                "step {}",
                s.number
            );
            // The data arcs pass through the top of the circle, 150 mm above the ball.
            let top = pivot.z + 0.15;
            let t = &s.test;
            let through_top = (0..=180).any(|k| {
                let a = t.start_deg + k as f64;
                (t.point(a, t.radius_m).z - top).abs() < 1e-12
            });
            assert!(through_top, "step {}", s.number);
        }
    }

    #[test]
    fn kwon_programs_fit_the_built_in_machine() {
        // vmc500: carriages X 0..500, Y 0..400, Z 0..400 mm; the programmed tool point is the
        // carriage position minus the 100 mm tool length, so its Z range is -100..300 mm.
        let pivot = Vector3::from(KWON_SCENARIO_PIVOT_MM) * MM;
        for s in kwon_steps(pivot) {
            let p = parsed(&s.test);
            for q in starts(&p).into_iter().chain([end_of(&p)]) {
                let q = q / MM;
                assert!(
                    (0.0..=500.0).contains(&q.x)
                        && (0.0..=400.0).contains(&q.y)
                        && (-100.0..=300.0).contains(&q.z),
                    "step {}: {q:?}",
                    s.number
                );
            }
        }
    }

    #[test]
    fn kwon_scenario_files_are_up_to_date() {
        // Set VMT_WRITE_KWON=1 to rewrite them after changing the generator.
        let dir =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/kwon_seven_step");
        let files = kwon_program_files(Vector3::from(KWON_SCENARIO_PIVOT_MM) * MM);
        if std::env::var_os("VMT_WRITE_KWON").is_some() {
            std::fs::create_dir_all(&dir).unwrap();
            for (name, text) in &files {
                std::fs::write(dir.join(name), text).unwrap();
            }
        }
        for (name, text) in &files {
            let on_disk = std::fs::read_to_string(dir.join(name))
                .unwrap_or_else(|e| panic!("{name}: {e} (VMT_WRITE_KWON=1 writes it)"));
            assert_eq!(
                &on_disk, text,
                "{name} differs from the generator (VMT_WRITE_KWON=1 rewrites it)"
            );
            // The header does not move the data arcs: the markers agree with the layout.
            let steps = kwon_steps(Vector3::from(KWON_SCENARIO_PIVOT_MM) * MM);
            let step = steps
                .iter()
                .find(|s| format!("{}.nc", s.name) == *name)
                .unwrap();
            let p = parse(&on_disk, step.test.start_point()).unwrap();
            assert_eq!(
                marked_data_blocks(&on_disk, &p).unwrap(),
                step.test.data_blocks(&p).unwrap()
            );
        }
    }
}
