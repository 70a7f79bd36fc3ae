//! The withheld-effect check behind `vmt gap-bench`: "measured" runs from the model with
//! effects switched on, the model without them, and the gap analysis asked to find them.
//!
//! Cases (all on the model's own job):
//! - every available library effect withheld alone at 1, 2 and 3 times its typical size
//!   (alternating sign);
//! - a few pairs withheld together;
//! - null cases: nothing withheld;
//! - out-of-library cases: a library effect withheld and also taken out of the candidates
//!   ([`HIDDEN`]), at three sizes: what no candidate can express must stay unexplained;
//! - withheld-physics cases ([`Physics`]): physics the simulator has and the candidate library
//!   does not, switched on in the measured machine by scenario tables no candidate edits
//!   (motor cogging, encoder interpolation error, a local guideway defect, the screw warming
//!   during the test, a nut that lost its preload, another friction law). Each states its
//!   right answer ([`Answer`]): the library effect that is physically the same thing (by
//!   another mechanism), or unexplained with the residual at the right place.
//!
//! Every case is scored on what the analysis reports: the effects found (explained on the
//! select bins and confirmed on the untouched judge bins), the equally good alternatives to
//! the first one (its ambiguity set), the sizes accepted against their plausible ranges, and
//! the peaks of the residual for "where".
//!
//! Every case adds nuisance: each available parameter is offset by N(0, (ν·typical)²) (ν =
//! [`Settings::nuisance`]), the instrument keeps its noise and resolution, and the simulation
//! seed differs. Random draws come from a generator seeded per case.

use crate::align::GapError;
use crate::axis_change::{AxisChange, angles_at};
use crate::effects::Effect;
use crate::localise::{self, Localisation};
use crate::model::{Forward, ScenarioModel};
use crate::peaks::{Circle, distinct, wrapped_deg};
use crate::select::{self, Linearisation, Options, Selection, select_without};
use crate::split::Split;
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use std::collections::BTreeMap;
use vmt_scenario::edit::Template;

/// What a case withheld.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
#[serde(tag = "kind", content = "effects", rename_all = "snake_case")]
pub enum Withheld {
    /// One library effect.
    One(String),
    /// Two library effects.
    Pair(String, String),
    /// Nothing.
    Null,
    /// An effect outside the library.
    Outside(String),
    /// Physics the library lacks, with its right answer.
    Physics(String, Answer),
}

/// The right answer to a withheld-physics case.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
#[serde(tag = "answer", rename_all = "snake_case")]
pub enum Answer {
    /// A library effect that is physically the same thing, by another mechanism: one of
    /// them found first, or in the ambiguity set of the effect found first.
    Library {
        /// Their keys (a screw's warming is a scale mismatch, and a scale that grows during
        /// the test).
        effects: Vec<String>,
    },
    /// Outside the library: left unexplained, with a peak of the residual of a test whose span
    /// (its angle ± half its width) comes within [`WHERE_TOLERANCE_DEG`] of one of the angles
    /// where that test's circle passes the physics' place: a defect under a carriage's block is
    /// felt over the block's length and more, tens of degrees of a 100 mm circle, and the peak
    /// of what the bar reads within that stretch leans to where the bar lies along the axis.
    Unexplained {
        /// Where the circles pass the physics' place; empty for physics spread over the travel
        /// (then unexplained is the whole answer).
        places: Vec<Where>,
    },
}

/// Where a test's circle passes a place on an axis.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Where {
    /// The test's radius, mm.
    pub radius_mm: f64,
    /// The test's centre, axis coordinates X, Y, Z, mm.
    pub centre_mm: [f64; 3],
    /// The circle's angle there, deg.
    pub angle_deg: f64,
}

impl Where {
    /// Where `circle` is at `angle_deg`.
    pub fn on(circle: &Circle, angle_deg: f64) -> Self {
        Self {
            radius_mm: circle.radius_mm,
            centre_mm: circle.centre_mm,
            angle_deg,
        }
    }
}

/// How close a reported peak must lie to the truth's angle, deg.
pub const WHERE_TOLERANCE_DEG: f64 = 10.0;

/// One withheld-physics case: the scenario text the measured machine gets on top of the
/// model, and the right answer.
#[derive(Clone, Debug, PartialEq)]
pub struct Physics {
    /// Case name, e.g. `rail bump X x1`.
    pub name: String,
    /// The physics, e.g. `rail_bump_x`.
    pub effect: String,
    /// TOML fragments merged into the measured machine's scenario, as `(table key, fragment)`
    /// for [`Template::with_fragment`] (tables no candidate edits).
    pub fragments: Vec<(String, String)>,
    /// The right answer.
    pub answer: Answer,
}

/// The library effects the out-of-library cases withhold and hide from the candidates: a
/// library that lacks the effect must leave it unexplained rather than force it onto another.
pub const HIDDEN: [&str; 4] = [
    "squareness",
    "straightness_x",
    "straightness_y",
    "servo_mismatch",
];

/// One case: the edits that make the measured machine from the model.
#[derive(Clone, Debug, PartialEq)]
pub struct Case {
    /// Name.
    pub name: String,
    /// What was withheld.
    pub withheld: Withheld,
    /// Absolute values written into the model to make the measured machine.
    pub edits: Vec<(String, f64)>,
    /// The withheld offsets alone (without the nuisance), from the model's values.
    pub withheld_offsets: Vec<(String, f64)>,
    /// Seed of the nuisance draws and of the simulation.
    pub seed: u64,
    /// The effect left out of the candidates (out-of-library cases).
    pub hidden: Option<String>,
    /// TOML fragments merged into the measured machine (withheld-physics cases), as
    /// [`Physics::fragments`].
    pub physics: Option<Vec<(String, String)>>,
}

/// Settings of the bench.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Nuisance size as a fraction of each parameter's typical size.
    pub nuisance: f64,
    /// Null cases.
    pub nulls: usize,
    /// Seed of the first case (the others count up).
    pub seed: u64,
    /// How many times the whole list of cases is drawn (each with its own seeds).
    pub repeats: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            nuisance: 0.05,
            nulls: 12,
            seed: 1,
            repeats: 1,
        }
    }
}

/// The offsets of every key of effect `e` at `m` times its typical size (growing parameters
/// only grow).
fn offsets_of(e: &Effect, m: f64) -> Vec<(String, f64)> {
    e.params
        .iter()
        .flat_map(|p| {
            let size = if p.increase_only { m.abs() } else { m } * p.typical;
            p.keys.iter().map(move |key| (key.clone(), size))
        })
        .collect()
}

/// The cases of the bench for `library` on `model`, with the withheld-physics cases
/// `physics`: [`Settings::repeats`] draws of the list, each with its own seeds.
pub fn cases(
    model: &dyn Forward,
    library: &[Effect],
    physics: &[Physics],
    s: &Settings,
) -> Vec<Case> {
    let mut out: Vec<Case> = Vec::new();
    for r in 0..s.repeats.max(1) {
        let seed = out.last().map_or(s.seed, |c| c.seed + 1);
        let mut draw = cases_once(model, library, physics, &Settings { seed, ..*s });
        if s.repeats > 1 {
            draw.iter_mut()
                .for_each(|c| c.name = format!("{} (draw {})", c.name, r + 1));
        }
        out.extend(draw);
    }
    out
}

/// One draw of the cases, seeds from `s.seed` up.
fn cases_once(
    model: &dyn Forward,
    library: &[Effect],
    physics: &[Physics],
    s: &Settings,
) -> Vec<Case> {
    let expressible = |e: &&Effect| {
        e.params
            .iter()
            .flat_map(|p| &p.keys)
            .all(|k| model.value(k).is_some())
    };
    let available: Vec<&Effect> = library.iter().filter(expressible).collect();
    let effects: Vec<&Effect> = available.iter().copied().filter(|e| !e.baseline).collect();
    let mut out = Vec::new();
    let mut seed = s.seed;
    type Fragments = Option<Vec<(String, String)>>;
    let mut push =
        |name: String, withheld: Withheld, offsets: Vec<(String, f64)>, physics: Fragments| {
            let hidden = match &withheld {
                Withheld::Outside(e) => Some(e.clone()),
                _ => None,
            };
            let edits = nuisance(model, &available, &offsets, s.nuisance, seed);
            out.push(Case {
                name,
                withheld,
                edits,
                withheld_offsets: offsets,
                seed,
                hidden,
                physics,
            });
            seed += 1;
        };
    let sizes = [1.0, -2.0, 3.0];
    for e in &effects {
        for (k, m) in sizes.into_iter().enumerate() {
            push(
                format!("{} x{}", e.key, k + 1),
                Withheld::One(e.key.clone()),
                offsets_of(e, m),
                None,
            );
        }
    }
    for pair in effects.chunks(2).take(4).filter(|c| c.len() == 2) {
        let offsets = pair.iter().flat_map(|e| offsets_of(e, 2.0)).collect();
        let withheld = Withheld::Pair(pair[0].key.clone(), pair[1].key.clone());
        push(
            format!("{} + {}", pair[0].key, pair[1].key),
            withheld,
            offsets,
            None,
        );
    }
    for i in 0..s.nulls {
        push(format!("null {}", i + 1), Withheld::Null, Vec::new(), None);
    }
    for e in effects.iter().filter(|e| HIDDEN.contains(&e.key.as_str())) {
        for (k, m) in sizes.into_iter().enumerate() {
            let name = format!("{} x{} (not in the library)", e.key, k + 1);
            push(
                name,
                Withheld::Outside(e.key.clone()),
                offsets_of(e, m),
                None,
            );
        }
    }
    for p in physics {
        let withheld = Withheld::Physics(p.effect.clone(), p.answer.clone());
        push(
            p.name.clone(),
            withheld,
            Vec::new(),
            Some(p.fragments.clone()),
        );
    }
    out
}

/// Absolute values: the model's value plus the withheld offsets, plus nuisance on every
/// available parameter: N(0, (ν·typical)²), and N(0, typical²) for the baseline (a bar is
/// never set up twice alike).
fn nuisance(
    model: &dyn Forward,
    available: &[&Effect],
    offsets: &[(String, f64)],
    size: f64,
    seed: u64,
) -> Vec<(String, f64)> {
    let mut rng = StdRng::seed_from_u64(seed);
    let mut values: BTreeMap<String, f64> = BTreeMap::new();
    for e in available {
        for p in &e.params {
            let sd = if e.baseline {
                p.typical
            } else {
                size * p.typical
            }
            .abs();
            let draw = Normal::new(0.0, sd).map_or(0.0, |d| d.sample(&mut rng));
            // Nuisance keeps a growing parameter physical: it only adds.
            let draw = if p.increase_only { draw.abs() } else { draw };
            for k in &p.keys {
                *values.entry(k.clone()).or_insert(0.0) += draw;
            }
        }
    }
    for (k, v) in offsets {
        *values.entry(k.clone()).or_insert(0.0) += v;
    }
    // Offsets are of the parameters; a key takes its parameter's value at the offset.
    let param_of = |k: &str| {
        available
            .iter()
            .flat_map(|e| &e.params)
            .find(|p| p.keys.iter().any(|key| key == k))
    };
    values
        .into_iter()
        .filter_map(|(k, v)| {
            let m = model.value(&k)?;
            let value = param_of(&k).map_or(m + v, |p| p.key_value(m, v));
            Some((k, value))
        })
        .collect()
}

/// What the gap analysis made of a case.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Outcome {
    /// Case name.
    pub case: String,
    /// What was withheld.
    pub withheld: Withheld,
    /// The effects that explain the gap, in order (empty when it stays unexplained).
    pub found: Vec<String>,
    /// Effects chosen that did not explain the gap (partial candidates).
    pub partial: Vec<String>,
    /// Held-out RMS before, in [`Outcome::unit`].
    pub held_out_before: f64,
    /// Held-out RMS after.
    pub held_out_after: f64,
    /// Shrink of the held-out mean square.
    pub shrink: f64,
    /// How far the withheld offsets stand out on the job's held-out runs
    /// ([`Linearisation::visibility`] for the ball bar).
    pub visible: f64,
    /// Unit of the RMS figures: `um` for ball-bar deviations, `dB` for band levels.
    pub unit: &'static str,
    /// Whether the RMS figures are of untouched judge data (else of the select data: too few
    /// to judge).
    pub judged: bool,
    /// The plausible alternatives to the first effect found (its ambiguity set; a pair as
    /// `a + b`).
    pub ambiguous: Vec<String>,
    /// Effects accepted with a size outside their plausible range (the bench asks for none).
    pub implausible_accepted: Vec<String>,
    /// Angles of the peaks of the residual before any effect, deg.
    pub peaks_deg: Vec<f64>,
    /// Their widths (where their energy stays above half their height), deg.
    pub peak_widths_deg: Vec<f64>,
    /// The radius of each peak's test, mm.
    pub peak_radii_mm: Vec<f64>,
    /// The centre of each peak's test, mm, where known.
    pub peak_centres_mm: Vec<Option<[f64; 3]>>,
    /// Where along an axis the residual before any effect changes: the selection's local
    /// change ([`crate::select::Selection::local_changes`]) when it found one, else the
    /// report's ([`crate::axis_change`]).
    pub axis_change: Option<AxisChange>,
    /// Where the tests' circles pass the middle of that change.
    pub change_at: Vec<Where>,
}

impl Outcome {
    fn of(
        case: &Case,
        (s, circles): (&Selection, &[Option<Circle>]),
        o: &Options,
        visible_um: f64,
        library: &[Effect],
        model: &dyn Forward,
    ) -> Result<Self, GapError> {
        let chosen: Vec<String> = s.steps.iter().map(|x| x.effect.clone()).collect();
        let (held, judged) = match s.judged {
            Some(j) => ((j.before_um, j.after_um), true),
            None => ((s.select_before_um, s.select_after_um()), false),
        };
        let mut out = Self::new(
            &case.name,
            &case.withheld,
            chosen,
            s.explained(o),
            held,
            visible_um,
            "um",
        );
        out.judged = judged;
        if let Some(first) = out.found.first() {
            out.ambiguous = s
                .equally_good(first)
                .iter()
                .map(|a| a.effects.join(" + "))
                .collect();
        }
        let accepted: Vec<&str> = s.steps.iter().map(|x| x.effect.as_str()).collect();
        out.implausible_accepted = implausible_values(&s.final_values, &accepted, library, model);
        let before =
            Localisation::on_circles(&s.initial_pairs, circles, &localise::Options::default())?;
        out.peaks_deg = before.peaks.iter().map(|p| p.angle_deg).collect();
        out.peak_widths_deg = before.peaks.iter().map(|p| p.width_deg).collect();
        out.peak_radii_mm = before.peaks.iter().map(|p| p.radius_mm).collect();
        out.peak_centres_mm = before.peaks.iter().map(|p| p.centre_mm).collect();
        // The change the selection found and acted on (against the library's other effects
        // too), else the one the report's localisation finds.
        let change = s.local_changes.first().cloned().or(before.axis_change);
        if let (Some(c), Some(first)) = (&change, s.initial_pairs.first()) {
            out.change_at = passes(c, first.plane, circles);
        }
        out.axis_change = change;
        Ok(out)
    }

    /// The outcome of case `name`: the `chosen` effects are found when they `explained` the
    /// gap and partial otherwise; `held` the held-out RMS before and after, in `unit`.
    pub(crate) fn new(
        name: &str,
        withheld: &Withheld,
        chosen: Vec<String>,
        explained: bool,
        (before, after): (f64, f64),
        visible: f64,
        unit: &'static str,
    ) -> Self {
        let (found, partial) = if explained {
            (chosen, Vec::new())
        } else {
            (Vec::new(), chosen)
        };
        Self {
            case: name.to_string(),
            withheld: withheld.clone(),
            found,
            partial,
            held_out_before: before,
            held_out_after: after,
            shrink: 1.0 - (after / before).powi(2),
            visible,
            unit,
            judged: true,
            ambiguous: Vec::new(),
            implausible_accepted: Vec::new(),
            peaks_deg: Vec::new(),
            peak_widths_deg: Vec::new(),
            peak_radii_mm: Vec::new(),
            peak_centres_mm: Vec::new(),
            axis_change: None,
            change_at: Vec::new(),
        }
    }

    /// Whether the analysis gave the right answer to a withheld-physics case (`None` for the
    /// other kinds).
    pub fn physics_right(&self) -> Option<bool> {
        let Withheld::Physics(_, answer) = &self.withheld else {
            return None;
        };
        Some(match answer {
            Answer::Library { effects } => effects
                .iter()
                .any(|e| self.found.first() == Some(e) || self.ambiguous.contains(e)),
            Answer::Unexplained { places } => {
                self.found.is_empty()
                    && (places.is_empty() || self.a_peak_at(places) || self.a_change_at(places))
            }
        })
    }

    /// Whether the axis change's middle passes within [`WHERE_TOLERANCE_DEG`] of one of
    /// `places` on the same test's circle.
    fn a_change_at(&self, places: &[Where]) -> bool {
        self.change_at.iter().any(|c| {
            places.iter().any(|t| {
                t.radius_mm == c.radius_mm
                    && t.centre_mm == c.centre_mm
                    && wrapped_deg(c.angle_deg - t.angle_deg).abs() <= WHERE_TOLERANCE_DEG
            })
        })
    }

    /// Whether a peak's span, widened by [`WHERE_TOLERANCE_DEG`], holds one of `places` of
    /// its own test.
    fn a_peak_at(&self, places: &[Where]) -> bool {
        let peaks = self
            .peaks_deg
            .iter()
            .zip(&self.peak_widths_deg)
            .zip(self.peak_radii_mm.iter().zip(&self.peak_centres_mm));
        peaks.into_iter().any(|((p, w), (r, c))| {
            places.iter().any(|t| {
                t.radius_mm == *r
                    && c.is_none_or(|c| c == t.centre_mm)
                    && wrapped_deg(p - t.angle_deg).abs() <= 0.5 * w + WHERE_TOLERANCE_DEG
            })
        })
    }
}

/// Where each of `circles` (each test's once) passes the middle of the change `c`, in a test
/// of `plane`.
fn passes(c: &AxisChange, plane: vmt_ballbar::Plane, circles: &[Option<Circle>]) -> Vec<Where> {
    distinct(circles.iter().flatten())
        .iter()
        .flat_map(|circle| {
            angles_at(plane, circle, c.axis, c.at_mm)
                .into_iter()
                .map(|angle_deg| Where::on(circle, angle_deg))
        })
        .collect()
}

/// The `accepted` effects whose final values (absolute, by key) a machine of the model's class
/// cannot have, checked against the library's ranges afresh.
fn implausible_values(
    values: &[(String, f64)],
    accepted: &[&str],
    library: &[Effect],
    model: &dyn Forward,
) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for (key, value) in values {
        for e in library
            .iter()
            .filter(|e| accepted.contains(&e.key.as_str()))
        {
            for p in e.params.iter().filter(|p| p.keys.contains(key)) {
                let Some(m) = model.value(key) else { continue };
                let (m, value) = (p.scale.of_key(m), p.scale.of_key(*value));
                let (lo, hi) = p.plausible.range(m);
                if !(lo..=hi).contains(&value) && !out.contains(&e.key) {
                    out.push(e.key.clone());
                }
            }
        }
    }
    out
}

/// How far the bench's second centre lies from the first along the plane's first and second
/// axes, mm, by default: within the built-in machine's strokes for circles of 100 mm, and far
/// enough that a change at one place along an axis falls elsewhere on the second circles.
pub const CENTRE_SHIFT_MM: [f64; 2] = [80.0, 40.0];

/// The ball-bar job of scenario `text` (named `file`, tables in `base_dir`) run about a second
/// centre too: its centre (given, or the strokes' middle) moved by `shift_mm` along the first
/// and second axes of `plane` (by default [`CENTRE_SHIFT_MM`], each toward the middle of its
/// stroke, or up it from there), every radius about each in turn, and the bar set up anew at
/// the second with the first's pivot offset (the bench then draws each centre's offset apart).
/// Circles about two centres tell an error that depends on the axis position (a rail step, a
/// straightness's bow) from the smooth shapes and set-up that mimic it about one.
pub fn with_second_centre(
    text: &str,
    file: &str,
    base_dir: Option<&std::path::Path>,
    plane: vmt_ballbar::Plane,
    shift_mm: Option<[f64; 2]>,
) -> Result<String, GapError> {
    let err = |e: vmt_scenario::ScenarioError| GapError::Model(e.to_string());
    let template = Template::parse(text, file).map_err(err)?;
    let given = |key: &str| -> Result<Option<[f64; 3]>, GapError> {
        let v: Vec<Option<f64>> = (0..3)
            .map(|i| template.value(&format!("{key}[{i}]")))
            .collect::<Result<_, _>>()
            .map_err(err)?;
        Ok(v.into_iter()
            .collect::<Option<Vec<f64>>>()
            .map(|v| [v[0], v[1], v[2]]))
    };
    let middle: [f64; 3] = (vmt_scenario::parse(text, file, base_dir)
        .map_err(err)?
        .machine
        .mid_stroke_tool_point()
        * 1e3)
        .into();
    let first = given("job.center_mm")?.unwrap_or(middle);
    let offset = given(crate::effects::PIVOT_OFFSET_KEY)?.unwrap_or([0.0; 3]);
    let mut second = first;
    let (p, q) = plane.axes();
    for (k, axis) in [p, q].into_iter().enumerate() {
        let i = vmt_model::Axis::from_letter(axis)
            .ok_or_else(|| GapError::Model(format!("no axis `{axis}`")))?
            .index();
        second[i] += match shift_mm {
            Some(d) => d[k],
            None if middle[i] < first[i] => -CENTRE_SHIFT_MM[k],
            None => CENTRE_SHIFT_MM[k],
        };
    }
    let list = |a: [f64; 3], b: [f64; 3]| format!("[{a:?}, {b:?}]");
    let text = template
        .with_fragment("job", &format!("center_mm = {}\n", list(first, second)))
        .map_err(err)?;
    Template::parse(&text, file)
        .and_then(|t| {
            t.with_fragment(
                "instruments.ballbar",
                &format!("setup_eccentricity_um = {}\n", list(offset, offset)),
            )
        })
        .map_err(err)
}

/// Runs every case: the measured machine simulated with its instrument, the gap analysis of
/// `model` against it. `progress` is called once per finished case.
pub fn run(
    text: &str,
    model: &ScenarioModel,
    library: &[Effect],
    cases: &[Case],
    o: &Options,
    progress: &(dyn Fn() + Sync),
) -> Result<Vec<Outcome>, GapError> {
    let lin = Linearisation::new(model, library)?;
    // The cases run side by side: no core is idle for a selection to verify ahead on.
    let o = &Options {
        speculate: false,
        ..*o
    };
    let template = Template::parse(text, "model").map_err(|e| GapError::Model(e.to_string()))?;
    let scenario_error = |e: vmt_scenario::ScenarioError| GapError::Model(e.to_string());
    // The physics' visibility: the model with it, noise-free, against the model as given; the
    // same for every draw of a case.
    let mut physics: Vec<&[(String, String)]> = Vec::new();
    for f in cases.iter().filter_map(|c| c.physics.as_deref()) {
        if !physics.contains(&f) {
            physics.push(f);
        }
    }
    let visible_physics: Vec<(&[(String, String)], f64)> = physics
        .par_iter()
        .map(|fragments| {
            let with = with_physics(text, fragments).map_err(scenario_error)?;
            let changed = ScenarioModel::new(&with, "physics", None)?.traces(&[])?;
            Ok((*fragments, lin.visibility_of(library, &changed, o)?))
        })
        .collect::<Result<_, GapError>>()?;
    cases
        .par_iter()
        .map(|c| {
            let mut edits: Vec<(&str, f64)> =
                c.edits.iter().map(|(k, v)| (k.as_str(), *v)).collect();
            let seed = c.seed as f64;
            edits.push(("simulation.seed", seed));
            let mut measured_text = template.with(&edits).map_err(scenario_error)?;
            if let Some(fragments) = &c.physics {
                measured_text = with_physics(&measured_text, fragments).map_err(scenario_error)?;
            }
            let measured =
                ScenarioModel::instrumented(&measured_text, &c.name, None)?.traces(&[])?;
            let split = Split::automatic(&measured)?;
            let hidden: Vec<&str> = c.hidden.iter().map(String::as_str).collect();
            let s = select_without(model, &lin, &measured, library, &hidden, split, o)?;
            let visible = match &c.physics {
                Some(f) => visible_physics
                    .iter()
                    .find(|(g, _)| *g == f.as_slice())
                    .map_or(0.0, |(_, v)| *v),
                None => lin.visibility(library, &c.withheld_offsets, o)?,
            };
            let circles: Vec<Option<Circle>> = select::partners(&measured, lin.base())?
                .into_iter()
                .map(|i| model.circles().get(i).copied())
                .collect();
            progress();
            Outcome::of(c, (&s, &circles), o, visible, library, model)
        })
        .collect()
}

/// Scenario `text` with the withheld physics' `fragments` merged in.
fn with_physics(
    text: &str,
    fragments: &[(String, String)],
) -> Result<String, vmt_scenario::ScenarioError> {
    Template::parse(text, "<withheld physics>")?.with_fragments(fragments)
}

/// The bench's figures, with cases below the visibility floor `floor` set apart.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Figures {
    /// Single-effect cases whose first effect found is the withheld one, fraction.
    pub top1: f64,
    /// Single-effect cases.
    pub single_cases: usize,
    /// Null cases with any effect found, fraction.
    pub false_attribution_null: f64,
    /// Null cases.
    pub null_cases: usize,
    /// Out-of-library cases with no effect found, fraction.
    pub unexplained_outside: f64,
    /// Out-of-library cases.
    pub outside_cases: usize,
    /// Pair cases with both effects among the first two found, fraction.
    pub pairs_both_found: f64,
    /// Pair cases.
    pub pair_cases: usize,
    /// Median held-out shrink over the in-library cases (single and pairs).
    pub median_shrink: f64,
    /// Withheld-physics cases whose right answer is a library effect, answered right
    /// (attributed to it, or to an ambiguity set holding it), fraction.
    pub physics_attributed: f64,
    /// Such cases.
    pub physics_library_cases: usize,
    /// The same cases attributed to their library effect in full or as the partial
    /// explanation of a gap left unexplained (the effect fitted first removes part of the gap
    /// and the rest stays, [`Outcome::partial`]), fraction: not the goal's figure, shown beside
    /// it so that what is missing from a full attribution is measured.
    pub physics_attributed_or_partial: f64,
    /// Withheld-physics cases outside the library left unexplained with the right "where",
    /// fraction.
    pub physics_unexplained: f64,
    /// Such cases.
    pub physics_outside_cases: usize,
    /// Cases (of any kind) in which an effect was accepted with an implausible size.
    pub implausible_accepted: usize,
    /// Cases whose held-out figures are of the select data, the judge data being too few.
    pub not_judged: usize,
    /// Confusion counts: withheld (or `null`, `outside`) → first found (or `none`).
    pub confusion: BTreeMap<String, BTreeMap<String, usize>>,
    /// The visibility floor, in the outcomes' unit (the selection's least effect).
    pub floor: f64,
    /// Single-effect, out-of-library and withheld-physics cases whose withheld effect stands
    /// out by less than the floor on the job ([`Outcome::visible`]): no analysis of these runs
    /// can see them, so they are listed here and left out of the rates, the confusion and the
    /// shrink.
    pub below_floor: Vec<String>,
}

/// The figures of a bench's outcomes.
pub fn figures(outcomes: &[Outcome], floor: f64) -> Figures {
    let frac = |hits: usize, n: usize| {
        if n == 0 {
            f64::NAN
        } else {
            hits as f64 / n as f64
        }
    };
    let first = |o: &Outcome| o.found.first().cloned().unwrap_or_else(|| "none".into());
    let mut confusion: BTreeMap<String, BTreeMap<String, usize>> = BTreeMap::new();
    let (
        mut single,
        mut top1,
        mut null,
        mut false_null,
        mut outside,
        mut unexplained,
        mut pairs,
        mut both,
    ) = (0, 0, 0, 0, 0, 0, 0, 0);
    let mut shrinks = Vec::new();
    let mut below_floor = Vec::new();
    let (mut lib_cases, mut lib_right, mut out_cases, mut out_right) = (0, 0, 0, 0);
    let mut lib_partial = 0;
    for o in outcomes {
        let seen = o.visible >= floor;
        if !seen
            && matches!(
                o.withheld,
                Withheld::One(_) | Withheld::Outside(_) | Withheld::Physics(..)
            )
        {
            below_floor.push(o.case.clone());
            continue;
        }
        let row = match &o.withheld {
            Withheld::One(e) => {
                single += 1;
                top1 += usize::from(o.found.first() == Some(e));
                shrinks.push(o.shrink);
                e.clone()
            }
            Withheld::Pair(a, b) => {
                pairs += 1;
                let head: Vec<&String> = o.found.iter().take(2).collect();
                both += usize::from(head.contains(&a) && head.contains(&b));
                shrinks.push(o.shrink);
                format!("{a} + {b}")
            }
            Withheld::Null => {
                null += 1;
                false_null += usize::from(!o.found.is_empty());
                "null".into()
            }
            Withheld::Outside(_) => {
                outside += 1;
                unexplained += usize::from(o.found.is_empty());
                "outside".into()
            }
            Withheld::Physics(effect, answer) => {
                let right = usize::from(o.physics_right() == Some(true));
                match answer {
                    Answer::Library { effects } => {
                        (lib_cases, lib_right) = (lib_cases + 1, lib_right + right);
                        let partly = o.found.is_empty()
                            && o.partial.first().is_some_and(|p| effects.contains(p));
                        lib_partial += right.max(usize::from(partly));
                    }
                    Answer::Unexplained { .. } => {
                        (out_cases, out_right) = (out_cases + 1, out_right + right)
                    }
                }
                format!("physics: {effect}")
            }
        };
        *confusion
            .entry(row)
            .or_default()
            .entry(first(o))
            .or_default() += 1;
    }
    shrinks.sort_by(f64::total_cmp);
    Figures {
        top1: frac(top1, single),
        single_cases: single,
        false_attribution_null: frac(false_null, null),
        null_cases: null,
        unexplained_outside: frac(unexplained, outside),
        outside_cases: outside,
        pairs_both_found: frac(both, pairs),
        pair_cases: pairs,
        median_shrink: shrinks.get(shrinks.len() / 2).copied().unwrap_or(f64::NAN),
        physics_attributed: frac(lib_right, lib_cases),
        physics_library_cases: lib_cases,
        physics_attributed_or_partial: frac(lib_partial, lib_cases),
        physics_unexplained: frac(out_right, out_cases),
        physics_outside_cases: out_cases,
        implausible_accepted: outcomes
            .iter()
            .filter(|o| !o.implausible_accepted.is_empty())
            .count(),
        not_judged: outcomes.iter().filter(|o| !o.judged).count(),
        confusion,
        floor,
        below_floor,
    }
}
