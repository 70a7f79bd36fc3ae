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
//!   by the tool-to-table shift over the height Δh. With `E` the pivot-equivalent offset of a
//!   fit (`E = e − δ_tool`, the pivot's offset less the tool's displacement, µm), the tilt of
//!   the tool relative to the table per height is `t_x = −(E₂ₓ − E₁ₓ)/Δh` in X and likewise in
//!   Y, µm/m. Both balls are raised, so the tool moves up Z and the pivot stands higher on the
//!   table: `t_x` is the whole tool-to-workpiece rotation about Y seen over the height, the
//!   apparent squareness below plus the pitch of the workpiece side (a table turned by `b`
//!   about +Y carries the raised pivot by `+b Δh`, `t_x = −b`);
//! - steps 3 and 4 (apparent XZ and YZ squareness, Kwon's Figs. 15–16): the same centre ball,
//!   a flat bar and a bar inclined by θ from the vertical (sin θ = 100/250). An inclined bar
//!   reads the in-plane displacement times sin θ, so `E₃ = e − δ₃`, `E₄ = (e − δ₄) sin θ`, and
//!   the shift of the tool over the height h is `δ₄ − δ₃ = E₃ − E₄ / sin θ`. A Z axis leaning
//!   by the ISO squareness EB0Z = β moves the tool by `+β h` in X, EA0Z = α by `−α h` in Y
//!   (ISO 230-1), so `β = (δ₄ − δ₃)ₓ / h`, `α = −(δ₄ − δ₃)_y / h`. Everything else that moves
//!   the tool over the height at this place reads the same: the figures are the apparent
//!   squareness, EB0Z plus the slope of Z's straightness `(EXZ(z₄) − EXZ(z₃))/h` plus the
//!   change of the tool side's angular errors acting on their levers (e.g. Z's pitch EBZ on the
//!   tool's offset from the Z carriage), and EA0Z minus the slope of EYZ plus those about X.
//!   The pivot does not move between the two steps, so a tilt of the table (workpiece-side
//!   pitch) does not enter. Kwon's (4.12) divides the eccentricity difference by `l tan θ`
//!   instead, which treats the path as rotated about the centre ball; for a lean of the Z axis
//!   (a translation of the raised circle) the first-order result is the one used here, larger
//!   than Kwon's by 1/cos²θ (19 % for this geometry);
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
                "Tool-to-table tilt in X over the height (pitch + apparent EB0Z)",
                -(e2[0] - e1[0]) * per_m,
                "µm/m",
                "1, 2",
            );
            push(
                "tilt_y_per_height_kwon",
                "Tool-to-table tilt in Y over the height (pitch - apparent EA0Z)",
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
                "Apparent squareness Z to X (EB0Z + EXZ slope + tool tilts)",
                shift[0] * per_m,
                "µm/m",
                "3, 4",
            );
            push(
                "squareness_yz_kwon",
                "Apparent squareness Z to Y (EA0Z - EYZ slope + tool tilts)",
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{self, Errors};
    use crate::trace::{Plane, Sense};
    use crate::{Options, diagnose};
    use std::f64::consts::TAU;

    /// Vectors in µm, machine axes.
    type V = [f64; 3];

    /// The pivot offset `E = −(A₁, B₁)` (µm) a fit finds on a full circle (the pivot-offset
    /// signature is `Δr = −(E_p cos θ + E_q sin θ)`, `crate::signatures`), with the bar's reading
    /// computed exactly: the tool's nominal circle of `radius_mm` about the nominal pivot
    /// `pivot`, `height_mm` above it, the tool put where `tool` says, the pivot at `moved_pivot`,
    /// the reading `|tool − pivot| − l` (l the link length).
    fn fitted_offset(
        pivot: V,
        moved_pivot: V,
        radius_mm: f64,
        height_mm: f64,
        tool: impl Fn(V) -> V,
    ) -> [f64; 2] {
        let (r, h) = (radius_mm * 1e3, height_mm * 1e3);
        let link = r.hypot(h);
        let n = 3600;
        let (mut a1, mut b1) = (0.0, 0.0);
        for i in 0..n {
            let (s, c) = (TAU * i as f64 / n as f64).sin_cos();
            let t = tool([pivot[0] + r * c, pivot[1] + r * s, pivot[2] + h]);
            let d = [0, 1, 2].map(|k| t[k] - moved_pivot[k]);
            let reading = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - link;
            a1 += 2.0 / n as f64 * reading * c;
            b1 += 2.0 / n as f64 * reading * s;
        }
        [-a1, -b1]
    }

    /// The machine report from the fitted offsets of some steps (nothing else known).
    fn report(offsets: &[(u32, [f64; 2])]) -> MachineReport {
        let value = |n: u32, key: &str| {
            let e = offsets.iter().find(|(m, _)| *m == n)?.1;
            match key {
                "eccentricity_x" => Some(e[0]),
                "eccentricity_y" => Some(e[1]),
                _ => None,
            }
        };
        report_from(value, |_| Vec::new())
    }

    fn figure(r: &MachineReport, key: &str) -> f64 {
        r.figures
            .iter()
            .find(|f| f.key == key)
            .unwrap_or_else(|| panic!("no {key} in {r:?}"))
            .value
    }

    /// The pivot of the shipped scenario (`KWON_SCENARIO_PIVOT_MM`), µm, and a set-up offset.
    const PIVOT: V = [250e3, 200e3, 60e3];
    const SETUP: V = [12.0, -7.0, 3.0];

    fn add(a: V, b: V) -> V {
        [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
    }

    /// Steps 3 and 4 on a machine whose tool is displaced by `tool(p) − p`: the report.
    fn steps_3_and_4(tool: impl Fn(V) -> V + Copy) -> MachineReport {
        let moved = add(PIVOT, SETUP);
        let e3 = fitted_offset(PIVOT, moved, SMALL_CIRCLE_MM, 0.0, tool);
        let e4 = fitted_offset(PIVOT, moved, SMALL_CIRCLE_MM, INCLINED_HEIGHT_MM, tool);
        report(&[(3, e3), (4, e4)])
    }

    /// A Z axis leaning by EB0Z = −8 µrad and EA0Z = +6 µrad (ISO 230-1: the tool moves by
    /// `+β z` in X and `−α z` in Y at height z) under a set-up offset of the pivot: the flat and
    /// inclined links' offsets, computed from the exact bar length, give back β and α with
    /// their signs to 2e-3 µm/m (the second-order share of the pivot's 3 µm in Z). Kwon's
    /// `l tan θ` would read cos²θ = 0.84 of them (−6.72 µm/m), a `× sin θ` for the `/ sin θ`
    /// +44 µm/m (the set-up offset no longer cancels), a flipped sign +8 µm/m.
    #[test]
    fn squareness_of_a_leaning_z_axis_is_recovered() {
        let (beta, alpha) = (-8.0, 6.0);
        let r = steps_3_and_4(|p| [p[0] + beta * 1e-6 * p[2], p[1] - alpha * 1e-6 * p[2], p[2]]);
        let (zx, yz) = (
            figure(&r, "squareness_zx_kwon"),
            figure(&r, "squareness_yz_kwon"),
        );
        assert!((zx - beta).abs() < 2e-3, "EB0Z {zx} against {beta}");
        assert!((yz - alpha).abs() < 2e-3, "EA0Z {yz} against {alpha}");
        assert!(r.missing.iter().all(|m| !m.starts_with("XZ/YZ")), "{r:?}");
    }

    /// What the figure is: the tool-to-table tilt over the height, so a bow of Z's straightness
    /// `EXZ = κ z²` adds its slope between the two heights, `κ (z₃ + z₄)` (+10.2 µm/m here on
    /// EB0Z = −8), while a tilt of the table (the pivot turned with it) adds nothing.
    #[test]
    fn apparent_squareness_takes_z_straightness_slope_not_table_tilt() {
        let (beta, kappa) = (-8.0, 30.0); // µrad; µm/m²
        let r = steps_3_and_4(|p| {
            let z_m = p[2] * 1e-6;
            [p[0] + beta * z_m + kappa * z_m * z_m, p[1], p[2]]
        });
        let (z3, z4) = (
            PIVOT[2] * 1e-6,
            (PIVOT[2] * 1e-3 + INCLINED_HEIGHT_MM) * 1e-3,
        );
        let expected = beta + kappa * (z3 + z4);
        let zx = figure(&r, "squareness_zx_kwon");
        assert!((zx - expected).abs() < 2e-3, "{zx} against {expected}");
        assert!((expected - beta).abs() > 10.0);
        // The table turned by 20 µrad about +Y and +X about the machine's origin.
        let b: f64 = 20e-6;
        let turned = |p: V| {
            let (s, c) = b.sin_cos();
            let q = [c * p[0] + s * p[2], p[1], -s * p[0] + c * p[2]];
            [q[0], c * q[1] - s * q[2], s * q[1] + c * q[2]]
        };
        let moved = add(turned(PIVOT), SETUP);
        let e3 = fitted_offset(PIVOT, moved, SMALL_CIRCLE_MM, 0.0, |p| p);
        let e4 = fitted_offset(PIVOT, moved, SMALL_CIRCLE_MM, INCLINED_HEIGHT_MM, |p| p);
        let r = report(&[(3, e3), (4, e4)]);
        for key in ["squareness_zx_kwon", "squareness_yz_kwon"] {
            assert!(figure(&r, key).abs() < 2e-3, "{key}: {r:?}");
        }
    }

    /// Pitch from two heights: a table turned by b = +5 µrad about +Y and a = −3 µrad about +X
    /// carries the pivot on its stand by `(b z, −a z)`, the tool stays: the tool-to-table tilt
    /// over the height is `t_x = −b`, `t_y = +a` (µm/m). A Z axis leaning by EB0Z = −8 µrad adds
    /// −8 to `t_x`, as both balls are raised.
    #[test]
    fn pitch_from_two_heights_is_the_tool_to_table_tilt() {
        let (b, a): (f64, f64) = (5e-6, -3e-6);
        let turned = |p: V| {
            let (sb, cb) = b.sin_cos();
            let (sa, ca) = a.sin_cos();
            let q = [cb * p[0] + sb * p[2], p[1], -sb * p[0] + cb * p[2]];
            [q[0], ca * q[1] - sa * q[2], sa * q[1] + ca * q[2]]
        };
        let raised = add(PIVOT, [0.0, 0.0, RAISE_MM * 1e3]);
        let tilts = |tool: &dyn Fn(V) -> V| {
            let e1 = fitted_offset(PIVOT, add(turned(PIVOT), SETUP), 150.0, 0.0, tool);
            let e2 = fitted_offset(raised, add(turned(raised), SETUP), 150.0, 0.0, tool);
            let r = report(&[(1, e1), (2, e2)]);
            [
                figure(&r, "tilt_x_per_height_kwon"),
                figure(&r, "tilt_y_per_height_kwon"),
            ]
        };
        let t = tilts(&|p| p);
        assert!((t[0] - -5.0).abs() < 1e-4, "t_x {}", t[0]);
        assert!((t[1] - -3.0).abs() < 1e-4, "t_y {}", t[1]);
        let t = tilts(&|p| [p[0] - 8e-6 * p[2], p[1], p[2]]);
        assert!((t[0] - (-5.0 - 8.0)).abs() < 1e-4, "t_x with EB0Z {}", t[0]);
    }

    /// Z backlash from the half circles over the top: step 6 (ZX) made with 1.5 µm of Z
    /// backlash and step 7 (YZ) with 3.5 µm, synthetic traces with 0.3 µm noise, each diagnosed
    /// on its own; the report gives their mean, 2.5 µm (either step alone is 1 µm off).
    #[test]
    fn z_backlash_is_the_mean_of_the_half_circles() {
        let half = |plane, sense, start, backlash: [f64; 2], step, seed| {
            let e = Errors {
                backlash_um: backlash,
                noise_um: 0.3,
                ..Default::default()
            };
            let mut t = synthetic::trace(
                plane,
                sense,
                150.0,
                500.0,
                start,
                180.0,
                &e,
                (0.0, 1.0),
                seed,
            );
            t.label = format!("step {step}: half circle over the top");
            t
        };
        // ZX: p = Z, from +X (90°) over +Z (0°); YZ: q = Z, from +Y (0°) over +Z (90°).
        let step6 = [
            half(Plane::Zx, Sense::Cw, 90.0, [1.5, 0.0], 6, 1),
            half(Plane::Zx, Sense::Ccw, -90.0, [1.5, 0.0], 6, 2),
        ];
        let step7 = [
            half(Plane::Yz, Sense::Ccw, 0.0, [0.0, 3.5], 7, 3),
            half(Plane::Yz, Sense::Cw, 180.0, [0.0, 3.5], 7, 4),
        ];
        let d: Vec<_> = [&step6[..], &step7[..]]
            .into_iter()
            .map(|t| diagnose(t, &Options::default()).expect("diagnosis"))
            .collect();
        let r = machine_report(&d);
        let z = figure(&r, "backlash_z");
        let each: Vec<f64> = d.iter().map(|d| value(d, "backlash_z").unwrap()).collect();
        assert!((z - 0.5 * (each[0] + each[1])).abs() < 1e-12);
        assert!(
            (z - 2.5).abs() < 0.2,
            "Z backlash {z} against 2.5 ({each:?})"
        );
        // Without steps 1 to 5 the report says what it could not derive.
        for m in ["step 1", "pitch", "XZ/YZ squareness", "servo mismatch"] {
            assert!(r.missing.iter().any(|s| s.starts_with(m)), "{m}: {r:?}");
        }
    }
}
