//! Kwon's seven-step procedure analysed into one machine report (Kwon 1998, Section VI).
//!
//! The steps, as `vmt` generates them (`vmt_sim::nc::ballbar::kwon_steps`; traces labelled
//! `step N: ...`): 1 XY 150 mm at 500 mm/min; 2 the same with both balls [`RAISE_MM`] higher;
//! 3 XY 100 mm; 4 the 250 mm link inclined over the same 100 mm circle, the tool ball
//! [`INCLINED_HEIGHT_MM`] above the centre ball; 5 XY 100 mm at 4000 mm/min; 6 ZX and 7 YZ half
//! circles of 150 mm over the top. Each step is diagnosed on its own; the report takes:
//!
//! - step 1: closing error, backlash X and Y, scale mismatch, XY squareness, stick-slip;
//! - steps 1 and 2 (pitch, Kwon's Fig. 17): the set-up eccentricity found at two heights differs
//!   by the tool-to-table shift the angular errors make over the height Δh. With `E` the
//!   pivot-equivalent offset of a fit (`E = e_pivot − δ_tool`), the tilt of the tool relative to
//!   the table per height is `t_x = −(E₂ₓ − E₁ₓ)/Δh` in X and likewise in Y, µm/m;
//! - steps 3 and 4 (XZ and YZ squareness, Kwon's Figs. 15–16): the same centre ball, a flat
//!   bar and a bar inclined by θ from the vertical (sin θ = 100/250). An inclined bar reads the
//!   in-plane displacement times sin θ, so `E₃ = e − δ₃`, `E₄ = (e − δ₄) sin θ`, and the shift of
//!   the tool over the height h is `δ₄ − δ₃ = E₃ − E₄ / sin θ`. A Z axis leaning by the ISO
//!   squareness EB0Z = β moves the tool by `+β h` in X, EA0Z = α by `−α h` in Y (ISO 230-1), so
//!   `β = (δ₄ − δ₃)ₓ / h`, `α = −(δ₄ − δ₃)_y / h`. Kwon's (4.12) divides the eccentricity
//!   difference by `l tan θ` instead, which treats the path as rotated about the centre ball;
//!   for a lean of the Z axis (a translation of the raised circle) the first-order result is
//!   the one used here, larger than Kwon's by 1/cos²θ (19 % for this geometry);
//! - step 5: servo mismatch (at 4000 mm/min it dominates the ellipse) and the transient peak
//!   at the start of each run (Section III.6);
//! - steps 6 and 7: Z backlash, from the reversal of Z at the top of the half circles.

use crate::diagnosis::{Diagnosis, Finding};
use serde::Serialize;

/// Height by which step 2 raises both balls over step 1, mm.
pub const RAISE_MM: f64 = 100.0;
/// Length of the inclined link of step 4, mm.
pub const INCLINED_LINK_MM: f64 = 250.0;
/// Radius of the circle of steps 3 and 4, mm.
pub const SMALL_CIRCLE_MM: f64 = 100.0;
/// Height of step 4's tool ball over the centre ball, mm: √(250² − 100²).
pub const INCLINED_HEIGHT_MM: f64 = 229.128_784_747_792;

/// One figure of the machine report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Figure {
    /// Key, e.g. `squareness_zx_kwon` or `step1.backlash_x`.
    pub key: String,
    /// Name for people.
    pub name: String,
    /// Value.
    pub value: f64,
    /// Unit.
    pub unit: &'static str,
    /// The steps it comes from.
    pub steps: String,
}

/// The machine report of a seven-step run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MachineReport {
    /// Figures, in the order of the procedure.
    pub figures: Vec<Figure>,
    /// What could not be derived, and why.
    pub missing: Vec<String>,
}

/// The step number of a diagnosis from its trace labels (`step N: ...`).
pub fn step_of(d: &Diagnosis) -> Option<u32> {
    let label = d.traces.first()?;
    label
        .strip_prefix("step ")?
        .split(':')
        .next()?
        .trim()
        .parse()
        .ok()
}

fn value(d: &Diagnosis, key: &str) -> Option<f64> {
    d.finding(key).map(|f: &Finding| f.value)
}

/// The machine report of the diagnosed steps (any subset; what needs a missing step is listed
/// in `missing`).
pub fn machine_report(tests: &[Diagnosis]) -> MachineReport {
    let step = |n: u32| tests.iter().find(|d| step_of(d) == Some(n));
    report_from(
        |n, key| step(n).and_then(|d| value(d, key)),
        |n| {
            step(n)
                .map(|d| {
                    d.findings
                        .iter()
                        .map(|f| (f.key.clone(), f.name.clone(), f.unit))
                        .collect()
                })
                .unwrap_or_default()
        },
    )
}

/// The machine report from the figures of each step: `value(step, key)` and the (key, name,
/// unit) of every figure of a step (the same formulas serve a diagnosis and a ground truth).
pub fn report_from(
    value: impl Fn(u32, &str) -> Option<f64>,
    keys: impl Fn(u32) -> Vec<(String, String, &'static str)>,
) -> MachineReport {
    let mut figures = Vec::new();
    let mut missing = Vec::new();
    let mut push = |key: &str, name: &str, value: f64, unit, steps: &str| {
        figures.push(Figure {
            key: key.into(),
            name: name.into(),
            value,
            unit,
            steps: steps.into(),
        })
    };
    let step1: Vec<_> = keys(1)
        .into_iter()
        .filter(|(k, _, _)| {
            [
                "closing_error",
                "backlash_",
                "scale_mismatch",
                "squareness",
                "stick_slip",
            ]
            .iter()
            .any(|p| k.starts_with(p))
        })
        .collect();
    if step1.is_empty() {
        missing.push("step 1 (closing, backlash X/Y, scale, XY squareness)".into());
    }
    for (k, name, unit) in step1 {
        if let Some(v) = value(1, &k) {
            push(&k, &name, v, unit, "1");
        }
    }
    let eccentricity = |n: u32| Some([value(n, "eccentricity_x")?, value(n, "eccentricity_y")?]);
    match (eccentricity(1), eccentricity(2)) {
        (Some(e1), Some(e2)) => {
            let per_m = 1e3 / RAISE_MM;
            push(
                "tilt_x_per_height_kwon",
                "Tool-to-table tilt in X over the height (pitch)",
                -(e2[0] - e1[0]) * per_m,
                "µm/m",
                "1, 2",
            );
            push(
                "tilt_y_per_height_kwon",
                "Tool-to-table tilt in Y over the height (pitch)",
                -(e2[1] - e1[1]) * per_m,
                "µm/m",
                "1, 2",
            );
        }
        _ => missing.push("pitch: needs steps 1 and 2".into()),
    }
    match (eccentricity(3), eccentricity(4)) {
        (Some(e3), Some(e4)) => {
            let sin = SMALL_CIRCLE_MM / INCLINED_LINK_MM;
            let shift = [e3[0] - e4[0] / sin, e3[1] - e4[1] / sin];
            let per_m = 1e3 / INCLINED_HEIGHT_MM;
            push(
                "squareness_zx_kwon",
                "Squareness Z to X (ISO EB0Z), flat and inclined links",
                shift[0] * per_m,
                "µm/m",
                "3, 4",
            );
            push(
                "squareness_yz_kwon",
                "Squareness Z to Y (ISO EA0Z), flat and inclined links",
                -shift[1] * per_m,
                "µm/m",
                "3, 4",
            );
        }
        _ => missing.push("XZ/YZ squareness: needs steps 3 and 4".into()),
    }
    match value(5, "servo_mismatch_xy") {
        Some(v) => push(
            "servo_mismatch_xy",
            "Servo mismatch X lag - Y lag",
            v,
            "ms",
            "5",
        ),
        None => missing.push("servo mismatch: needs step 5 in both directions".into()),
    }
    // The transient peak at the start (Kwon, Section III.6), largest at step 5's feed: what the
    // run shows, not a machine parameter, so a truth has none and nothing is missing without it.
    for sense in ["cw", "ccw"] {
        let key = format!("start_transient_{sense}");
        if let Some(v) = value(5, &key) {
            let name = format!("Transient at the start, {}", sense.to_uppercase());
            push(&key, &name, v, "µm", "5");
        }
    }
    let z: Vec<f64> = [6, 7]
        .into_iter()
        .filter_map(|n| value(n, "backlash_z"))
        .collect();
    if z.is_empty() {
        missing.push("Z backlash: needs step 6 or 7".into());
    } else {
        push(
            "backlash_z",
            "Backlash Z (half circles over the top)",
            z.iter().sum::<f64>() / z.len() as f64,
            "µm",
            "6, 7",
        );
    }
    MachineReport { figures, missing }
}

/// The machine report as text, with the same figures of `truth` beside when given.
pub fn text(r: &MachineReport, truth: Option<&MachineReport>) -> String {
    let mut s = String::from("Kwon's seven-step procedure: machine report\n");
    for f in &r.figures {
        let digits = if f.unit == "ms" { 4 } else { 2 };
        let t = truth
            .and_then(|t| t.figures.iter().find(|g| g.key == f.key))
            .map_or(String::new(), |g| {
                format!("  truth {:+.*}", digits, g.value)
            });
        s += &format!(
            "  {:<58} {:>+10.*} {:<5} (step {}){t}\n",
            f.name, digits, f.value, f.unit, f.steps
        );
    }
    for m in &r.missing {
        s += &format!("  not derived: {m}\n");
    }
    s
}
