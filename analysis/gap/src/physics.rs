//! The withheld-physics cases of the bench: physics the simulator has and the candidate
//! library lacks ([`vmt_scenario::withheld`]), each on each axis of the test's plane at three
//! sizes within what a machine of the model's class can have, with its right answer:
//!
//! - a nut that lost its preload is lost motion, backlash by another mechanism: `backlash_{a}`;
//! - the GMS friction law at the model's levels is guide friction: `friction_{a}`;
//! - the screw warming where the nut runs stretches the axis' scale: `scale_mismatch` of the
//!   plane (both axes of the plane share the one candidate), the screw's heating during the
//!   test, `screw_heating_{a}`, or, where the circles run past the warm stretch's end (about
//!   a second centre), the positioning error's change of slope there, `positioning_{a}`;
//! - a rail bump or a rail-joint step is outside the library: unexplained, with a peak of the
//!   residual where the circle takes a block over the defect (carriage position `at ± s/2`,
//!   `s` the blocks' spacing); the defect is placed so that one block passes it inside the
//!   circle, at a different angle for each size;
//! - motor cogging and feedback interpolation error are outside the library and spread over
//!   the whole travel: unexplained, with the residual's peaks free (no place to find);
//! - the compliant structure (`simulation.fidelity = "compliant"`: the carriages on their guide
//!   blocks) is, on a ball-bar test, their static deflection under the weights they carry,
//!   which changes as a carriage moves over the one below (the table's weight shifting over the
//!   saddle's blocks): a geometric error of the plane's axes by another mechanism, so one of
//!   `scale_mismatch`, `squareness`, the plane's straightnesses and its axes' non-linear
//!   positioning errors. Its dynamics do not reach
//!   the bar: the inertial forces of a 100 mm circle at 2000 mm/min, `m v²/R`, are 0.1 % of
//!   the weights `m g` (`tests/physics.rs` checks that the bar's change is the same at a quarter
//!   of the feed).

use crate::align::GapError;
use crate::axis_change::angles_at;
use crate::bench::{Answer, Physics, Where};
use crate::model::ScenarioModel;
use crate::peaks::{Circle, distinct};
use vmt_ballbar::Plane;
use vmt_model::Axis;
use vmt_scenario::withheld::{WITHHELD, WithheldEffect, fragments};

/// The sizes of each withheld effect, in its unit: from its typical size to the top of its
/// plausible range (a nut: fully lost, 10 % and 25 % left; the friction law: its elements).
fn sizes(e: &WithheldEffect) -> [f64; 3] {
    match e.key {
        "nut_preload" => [0.0, 10.0, 25.0],
        "gms_friction" => [2.0, 4.0, 8.0],
        _ => {
            let (t, hi) = (e.typical, e.plausible.1);
            [t, 0.5 * (t + hi), hi]
        }
    }
}

/// The circle's angle at which each size's defect is passed by a block, deg.
const DEFECT_ANGLES_DEG: [f64; 3] = [60.0, 125.0, 20.0];

/// Spacing of each axis' blocks along it, mm (as [`vmt_scenario::withheld`] builds them).
fn block_spacing_mm(axis: Axis) -> f64 {
    match axis {
        Axis::Y => 350.0,
        Axis::X | Axis::Z => 300.0,
    }
}

/// The withheld-physics cases for the bench's test in `plane` on `model`.
pub fn cases(model: &ScenarioModel, plane: Plane) -> Result<Vec<Physics>, GapError> {
    let circle = *model
        .circles()
        .first()
        .ok_or_else(|| GapError::Model("the model's job has no circular test".into()))?;
    let circles = distinct(model.circles());
    let (a, b) = plane.axes();
    let plane_axes = [axis_of(a)?, axis_of(b)?];
    let scenario_error = |e: vmt_scenario::ScenarioError| GapError::Model(e.to_string());
    let mut out = Vec::new();
    for e in &WITHHELD {
        for (side, &axis) in plane_axes.iter().enumerate() {
            let letter = axis.to_string().to_lowercase();
            for (k, size) in sizes(e).into_iter().enumerate() {
                let (at_mm, answer) = if e.placed {
                    let at = defect_place(&circle, side, axis, k);
                    let places = circles
                        .iter()
                        .flat_map(|c| passes(plane, c, axis, at))
                        .collect();
                    (Some(at), Answer::Unexplained { places })
                } else {
                    (None, answer_of(e, axis))
                };
                let fragments = fragments(model.template(), e.key, axis, size, at_mm)
                    .map_err(scenario_error)?;
                let place = at_mm.map_or(String::new(), |m| format!(" at {m:.0} mm"));
                out.push(Physics {
                    name: format!(
                        "{} {} {}{}{place} x{}",
                        e.key,
                        letter.to_uppercase(),
                        size,
                        e.unit,
                        k + 1
                    ),
                    effect: format!("{}_{letter}", e.key),
                    fragments,
                    answer,
                });
            }
        }
    }
    let geometric = ["scale_mismatch".to_string(), "squareness".to_string()]
        .into_iter()
        .chain(plane_axes.into_iter().flat_map(|a| {
            let a = a.to_string().to_lowercase();
            [format!("straightness_{a}"), format!("positioning_{a}")]
        }))
        .collect();
    out.push(Physics {
        name: "compliant structure".into(),
        effect: "compliant_structure".into(),
        fragments: vec![("simulation".into(), "fidelity = \"compliant\"\n".into())],
        answer: Answer::Library { effects: geometric },
    });
    Ok(out)
}

fn axis_of(c: char) -> Result<Axis, GapError> {
    match c {
        'X' => Ok(Axis::X),
        'Y' => Ok(Axis::Y),
        'Z' => Ok(Axis::Z),
        other => Err(GapError::Model(format!("no axis `{other}`"))),
    }
}

/// The right answer to an effect that is not placed on the axis.
fn answer_of(e: &WithheldEffect, axis: Axis) -> Answer {
    let effects = e.like_for(axis);
    if effects.is_empty() {
        Answer::Unexplained { places: Vec::new() }
    } else {
        Answer::Library { effects }
    }
}

/// Where a defect of size number `k` sits on `axis` (the plane's first axis for `side` 0, its
/// second for 1), mm: one block of the carriage passes it at [`DEFECT_ANGLES_DEG`]`[k]` of the
/// job's first circle, the other outside that circle.
fn defect_place(circle: &Circle, side: usize, axis: Axis, k: usize) -> f64 {
    let theta = DEFECT_ANGLES_DEG[k].to_radians();
    let c = circle.centre_mm[axis.index()];
    let along = if side == 0 { theta.cos() } else { theta.sin() };
    let passed = c + circle.radius_mm * along;
    let half = 0.5 * block_spacing_mm(axis);
    // The block centre over the defect, on the side of the passing point away from the
    // circle's centre, so that the other block's passing point lies outside the circle.
    if passed >= c {
        passed + half
    } else {
        passed - half
    }
}

/// The angles where `circle` (of a test in `plane`) takes a block of the carriage over a defect
/// at `at` mm on `axis` (the blocks' centre there, a block at `at ± s/2`).
fn passes(plane: Plane, circle: &Circle, axis: Axis, at: f64) -> Vec<Where> {
    let half = 0.5 * block_spacing_mm(axis);
    [at - half, at + half]
        .into_iter()
        .flat_map(|p| angles_at(plane, circle, axis.letter(), p))
        .map(|angle_deg| Where::on(circle, angle_deg))
        .collect()
}
