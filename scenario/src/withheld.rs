//! The physics a sim-to-real gap bench can withhold: effects the simulator implements in its
//! physics (`vmt_model::drive::{motor, encoder, nut, gms}`, `vmt_model::geometric::Guideway`,
//! `vmt_model::thermal::screw`), separately from the gap analysis' candidate library, and that
//! no candidate's scenario key expresses. Each is switched on by TOML a scenario does not have
//! by default, written with [`Template::with_fragment`]:
//!
//! | key | what | size | typical (plausible) |
//! |---|---|---|---|
//! | `cogging` | motor cogging (36 slots, 8 poles: 72 per revolution) and torque ripple at 6× the electrical frequency, 25 %/N·m of the cogging amplitude (1 % at 0.04 N·m) | cogging amplitude, N·m | 0.04 (0.02–0.12: 0.5–2 % of 4–6 N·m rated) |
//! | `interpolation` | sin/cos interpolation error of the position feedback: the motor encoder (2048 periods per revolution) or the linear scale (20 µm) | offsets of ±size %, amplitude ratio 1 + size %, phase error size × 0.573° | 1 (0.5–2) |
//! | `rail_bump` | a raised-cosine bump 30 mm wide on both rails at `at_mm` (vertical: Z for X and Y, Y for the Z head) | height, µm | 2 (1–3) |
//! | `rail_step` | a rail-joint step at `at_mm`, same direction | height, µm | 2 (1–5) |
//! | `screw_warming` | the screw along its length (nut 0.3 and fixed-end bearings 0.2 W per mm/s), warm over the middle half of the stroke at the start | start rise, K | 2 (0–5) |
//! | `nut_preload` | a double nut made with 1900 N preload (5 % of C_a ≈ 38 kN), 800 N/µm, keeping `size` % of it | preload left, % | 0 (0–50) |
//! | `gms_friction` | the Generalized Maxwell-Slip law on the guideways and the screw, at the model's levels | elements | 4 (2–8) |
//!
//! The carriages' block geometry is the built-in machine's (`scenarios/vmc500.toml`: table X on
//! saddle Y, spindle head Z on the column, the spindle axis at X = Y = 0 of the machine frame,
//! the tool 100 mm below the head's zero): X's blocks 300 mm apart with their centre at
//! (250, 200, −250) mm, Y's 350 mm apart at (0, 200, −350) mm, Z's 300 mm apart at
//! (0, 400, 200) mm, each block 100 mm long; the screws span their stroke and 100 mm beyond
//! each end, fixed where the lumped expansion is (`machine.thermal.expansion.<axis>`).
//! [`WithheldEffect::like`] names the candidates of the gap library that are physically the same
//! thing (a backlash by another mechanism, say), where one is.

use crate::edit::Template;
use crate::error::ScenarioError;
use vmt_model::Axis;

/// One withheld effect.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WithheldEffect {
    /// Short key, e.g. `nut_preload`.
    pub key: &'static str,
    /// What the physics is.
    pub description: &'static str,
    /// What the size is.
    pub size: &'static str,
    /// Its unit.
    pub unit: &'static str,
    /// A typical size on a machine of the built-in class.
    pub typical: f64,
    /// The plausible sizes on such a machine, lowest and highest.
    pub plausible: (f64, f64),
    /// Whether it sits at one place along the axis (`at_mm` of [`fragments`]).
    pub placed: bool,
    /// The gap library's effects that are physically the same thing, `{a}` for the axis
    /// letter (`backlash_{a}`); none when none is.
    pub like: &'static [&'static str],
}

/// The withheld effects.
pub const WITHHELD: [WithheldEffect; 7] = [
    WithheldEffect {
        key: "cogging",
        description: "motor cogging (72 periods per revolution) and torque ripple (6th electrical harmonic)",
        size: "cogging amplitude",
        unit: "N·m",
        typical: 0.04,
        plausible: (0.02, 0.12),
        placed: false,
        like: &[],
    },
    WithheldEffect {
        key: "interpolation",
        description: "interpolation error of the position feedback's sin/cos signals (offsets, amplitude mismatch, quadrature error)",
        size: "signal distortion",
        unit: "%",
        typical: 1.0,
        plausible: (0.5, 2.0),
        placed: false,
        like: &[],
    },
    WithheldEffect {
        key: "rail_bump",
        description: "a bump of the rails (raised cosine, 30 mm wide) that the carriage's blocks ride over",
        size: "height",
        unit: "µm",
        typical: 2.0,
        plausible: (1.0, 3.0),
        placed: true,
        like: &[],
    },
    WithheldEffect {
        key: "rail_step",
        description: "a step at a rail joint that the carriage's blocks ride over",
        size: "height",
        unit: "µm",
        typical: 2.0,
        plausible: (1.0, 5.0),
        placed: true,
        like: &[],
    },
    WithheldEffect {
        key: "screw_warming",
        description: "the screw warming along its length where the nut runs, warm at the start where it ran before",
        size: "start rise over the middle half of the stroke",
        unit: "K",
        typical: 2.0,
        plausible: (0.0, 5.0),
        placed: false,
        like: &["scale_mismatch", "screw_heating_{a}", "positioning_{a}"],
    },
    WithheldEffect {
        key: "nut_preload",
        description: "lost motion of a double nut that lost its preload (Hertzian halves soft about zero load)",
        size: "preload left",
        unit: "%",
        typical: 0.0,
        plausible: (0.0, 50.0),
        placed: false,
        like: &["backlash_{a}"],
    },
    WithheldEffect {
        key: "gms_friction",
        description: "the Generalized Maxwell-Slip friction law instead of LuGre, at the same levels",
        size: "Maxwell-slip elements",
        unit: "",
        typical: 4.0,
        plausible: (2.0, 8.0),
        placed: false,
        like: &["friction_{a}"],
    },
];

impl WithheldEffect {
    /// The withheld effect called `key`.
    pub fn named(key: &str) -> Option<&'static WithheldEffect> {
        WITHHELD.iter().find(|e| e.key == key)
    }

    /// [`WithheldEffect::like`] for `axis`.
    pub fn like_for(&self, axis: Axis) -> Vec<String> {
        let a = axis.to_string().to_lowercase();
        self.like.iter().map(|l| l.replace("{a}", &a)).collect()
    }
}

/// The blocks of an axis' carriage on the built-in machine: spacing, length (mm), centre (mm,
/// machine coordinates with every axis at 0), and the direction a rail's defect lifts them.
fn blocks(axis: Axis) -> (f64, f64, [f64; 3], char) {
    match axis {
        Axis::X => (300.0, 100.0, [250.0, 200.0, -250.0], 'z'),
        Axis::Y => (350.0, 100.0, [0.0, 200.0, -350.0], 'z'),
        Axis::Z => (300.0, 100.0, [0.0, 400.0, 200.0], 'y'),
    }
}

fn number(t: &Template, key: &str) -> Result<f64, ScenarioError> {
    t.value(key)?.ok_or_else(|| ScenarioError {
        file: "<withheld>".into(),
        position: None,
        key: Some(key.into()),
        message: "the scenario sets no number here, which the withheld effect needs".into(),
    })
}

/// The TOML that switches `key` on for `axis` at `size` (its unit; see [`WITHHELD`]) in the
/// scenario `t`, as `(table key, fragment)` pairs for [`Template::with_fragment`]; `at_mm` is
/// the axis position of a placed effect (a rail defect), ignored by the others.
pub fn fragments(
    t: &Template,
    key: &str,
    axis: Axis,
    size: f64,
    at_mm: Option<f64>,
) -> Result<Vec<(String, String)>, ScenarioError> {
    let a = axis.to_string().to_lowercase();
    let drive = format!("machine.axes.{a}.drive");
    let fail = |message: String| ScenarioError {
        file: "<withheld>".into(),
        position: None,
        key: Some(key.into()),
        message,
    };
    Ok(match key {
        "cogging" => vec![(
            format!("{drive}.motor"),
            format!(
                "slots = 36\npoles = 8\ncogging_n_m = {size}\nripple_percent = {}\nripple_harmonic = 6\n",
                25.0 * size
            ),
        )],
        "interpolation" => {
            let scale = t.text(&format!("{drive}.feedback"))?.as_deref() == Some("linear_scale");
            let distortion = format!(
                "offsets_percent = [{size}, {}]\namplitude_ratio = {}\nphase_error_deg = {}\n",
                -size,
                1.0 + size / 100.0,
                (size / 100.0).to_degrees()
            );
            if scale {
                vec![(
                    format!("{drive}.scale_signals"),
                    format!("signal_period_um = 20.0\n{distortion}"),
                )]
            } else {
                vec![(
                    format!("{drive}.encoder_signals"),
                    format!("periods_per_rev = 2048\n{distortion}"),
                )]
            }
        }
        "rail_bump" | "rail_step" => {
            let at =
                at_mm.ok_or_else(|| fail("a rail defect needs its axis position, at_mm".into()))?;
            let (spacing, length, [cx, cy, cz], direction) = blocks(axis);
            let shape = if key == "rail_bump" {
                "shape = \"bump\"\nwidth_mm = 30.0\n"
            } else {
                "shape = \"step\"\n"
            };
            vec![(
                format!("machine.axes.{a}"),
                format!(
                    "[guideway]\nblock_spacing_mm = {spacing}\nblock_length_mm = {length}\nblocks_centre_mm = [{cx}, {cy}, {cz}]\n\n[[guideway.defects]]\n{shape}direction = \"{direction}\"\nat_mm = {at}\nheight_um = {size}\n"
                ),
            )]
        }
        "screw_warming" => {
            let lo = number(t, &format!("machine.axes.{a}.stroke_mm[0]"))?;
            let hi = number(t, &format!("machine.axes.{a}.stroke_mm[1]"))?;
            let reference = t
                .value(&format!("machine.thermal.expansion.{a}.reference_mm"))?
                .unwrap_or(lo);
            let fixed = if (reference - hi).abs() < (reference - lo).abs() {
                "high"
            } else {
                "low"
            };
            let quarter = 0.25 * (hi - lo);
            vec![(
                format!("machine.thermal.screw.{a}"),
                format!(
                    "span_mm = [{}, {}]\nfixed_end = \"{fixed}\"\ndiameter_mm = 28.0\nconvection_w_per_m2_k = 15.0\nend_w_per_k = [2.0, 0.5]\nnut_w_per_mm_s = 0.3\nnut_length_mm = 100.0\nbearing_w_per_mm_s = 0.2\nwarm_rise_k = {size}\nwarm_span_mm = [{}, {}]\n",
                    lo - 100.0,
                    hi + 100.0,
                    lo + quarter,
                    hi - quarter
                ),
            )]
        }
        "nut_preload" => vec![(
            format!("{drive}.nut"),
            format!(
                "preload_n = 1900.0\nstiffness_n_per_um = 800.0\nremaining_preload_n = {}\n",
                19.0 * size
            ),
        )],
        "gms_friction" => {
            let law = format!("law = \"gms\"\ngms_elements = {}\n", size.round());
            vec![
                (format!("{drive}.guide_friction"), law.clone()),
                (format!("{drive}.screw_friction"), law),
            ]
        }
        other => {
            let known: Vec<&str> = WITHHELD.iter().map(|e| e.key).collect();
            return Err(fail(format!(
                "`{other}` is not a withheld effect; they are {}",
                known.join(", ")
            )));
        }
    })
}

/// The scenario text of `t` with `key` switched on for `axis` at `size` ([`fragments`]).
pub fn switch_on(
    t: &Template,
    key: &str,
    axis: Axis,
    size: f64,
    at_mm: Option<f64>,
) -> Result<String, ScenarioError> {
    t.with_fragments(&fragments(t, key, axis, size, at_mm)?)
}
