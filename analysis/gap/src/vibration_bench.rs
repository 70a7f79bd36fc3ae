//! The withheld-effect check of the vibration gap (`vmt gap-bench` on a milling model):
//! accelerometer logs of the model with effects switched on, the gap analysis of the model
//! without them asked to find them.
//!
//! Cases, as for the ball bar ([`crate::bench`]): every candidate of the model's library at
//! 1, −2 and 3 times its typical size (all its parameters together); null cases; and
//! out-of-library cases: the tool's run-out (`tools.<T>.runout_um` at 5, 10 and 15 µm), which
//! puts once-per-revolution lines into the spectrum that no candidate can make. Nuisance: every
//! candidate parameter offset by N(0, (ν·typical)²), the sensor's noise kept, another seed.

use crate::align::GapError;
use crate::bench::{Outcome, Settings, Withheld};
use crate::vibration::{MillingModel, Options, VibrationGap, analyse_without, visibility};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use std::path::PathBuf;
use vmt_scenario::edit::Template;

/// Run-out sizes of the out-of-library cases, µm.
pub const RUNOUT_UM: [f64; 3] = [5.0, 10.0, 15.0];

/// One case.
#[derive(Clone, Debug, PartialEq)]
pub struct Case {
    /// Name.
    pub name: String,
    /// What was withheld.
    pub withheld: Withheld,
    /// Absolute values written into the model (nuisance included).
    pub edits: Vec<(String, f64)>,
    /// Keys the model does not set, written in as well (the run-out).
    pub inserted: Vec<(String, f64)>,
    /// The withheld offsets alone, from the model's values.
    pub offsets: Vec<(String, f64)>,
    /// Seed of the nuisance and of the simulation.
    pub seed: u64,
}

/// The cases for `model`, [`Settings::repeats`] draws of the list.
pub fn cases(model: &MillingModel, s: &Settings) -> Vec<Case> {
    let library = model.library();
    let tool = model.tool();
    let mut out = Vec::new();
    let mut seed = s.seed;
    for r in 0..s.repeats.max(1) {
        let draw = |name: String| {
            if s.repeats > 1 {
                format!("{name} (draw {})", r + 1)
            } else {
                name
            }
        };
        let mut push = |name: String, withheld: Withheld, offsets: Vec<(String, f64)>, inserted| {
            let mut rng = StdRng::seed_from_u64(seed);
            let mut edits: Vec<(String, f64)> = Vec::new();
            for p in library.iter().flat_map(|e| &e.params) {
                let sd = (s.nuisance * p.typical).abs();
                let d = Normal::new(0.0, sd).map_or(0.0, |n| n.sample(&mut rng));
                let withheld: f64 = offsets
                    .iter()
                    .filter(|(k, _)| p.keys.contains(k))
                    .map(|(_, v)| v)
                    .sum();
                for k in &p.keys {
                    if let Some(v) = model.value(k) {
                        edits.push((k.clone(), v + d + withheld));
                    }
                }
            }
            out.push(Case {
                name: draw(name),
                withheld,
                edits,
                inserted,
                offsets,
                seed,
            });
            seed += 1;
        };
        for e in &library {
            for (k, m) in [1.0, -2.0, 3.0].into_iter().enumerate() {
                let offsets = e
                    .params
                    .iter()
                    .flat_map(|p| p.keys.iter().map(move |key| (key.clone(), m * p.typical)))
                    .collect();
                push(
                    format!("{} x{}", e.key, k + 1),
                    Withheld::One(e.key.clone()),
                    offsets,
                    Vec::new(),
                );
            }
        }
        for i in 0..s.nulls {
            push(
                format!("null {}", i + 1),
                Withheld::Null,
                Vec::new(),
                Vec::new(),
            );
        }
        for (k, r) in RUNOUT_UM.iter().enumerate() {
            push(
                format!("runout x{} (not in the library)", k + 1),
                Withheld::Outside("runout".into()),
                Vec::new(),
                vec![(format!("tools.{tool}.runout_um"), *r)],
            );
        }
    }
    out
}

/// Runs every case: the measured machine simulated with its sensor, the vibration gap of
/// `model` against it. `text` is the model's scenario as written (named `file`, its program
/// and tables in `dir`); `progress` is called once per finished case.
pub fn run(
    text: &str,
    file: &str,
    dir: Option<PathBuf>,
    model: &MillingModel,
    cases: &[Case],
    o: &Options,
    progress: &(dyn Fn() + Sync),
) -> Result<Vec<Outcome>, GapError> {
    let template = Template::parse(text, file).map_err(|e| GapError::Model(e.to_string()))?;
    cases
        .par_iter()
        .map(|c| {
            let model_error = |e: vmt_scenario::ScenarioError| GapError::Model(e.to_string());
            let mut edits: Vec<(&str, f64)> =
                c.edits.iter().map(|(k, v)| (k.as_str(), *v)).collect();
            edits.push(("simulation.seed", c.seed as f64));
            let measured = template.with(&edits).map_err(model_error)?;
            let inserted: Vec<(&str, f64)> =
                c.inserted.iter().map(|(k, v)| (k.as_str(), *v)).collect();
            let measured = Template::parse(&measured, file)
                .and_then(|t| t.with_inserted(&inserted))
                .map_err(model_error)?;
            let mut log = MillingModel::instrumented(&measured, &c.name, dir.clone())?.base;
            log.name = c.name.clone();
            let hidden: Vec<&str> = match &c.withheld {
                Withheld::Outside(e) => vec![e.as_str()],
                _ => Vec::new(),
            };
            let g = analyse_without(model, &[log], &hidden, o)?;
            let visible = if c.inserted.is_empty() {
                visibility(model, &c.offsets)?
            } else {
                // The run-out is no key of the model: its size is what the log shows.
                g.judge_before_db
            };
            progress();
            Ok(outcome(c, &g, o, visible))
        })
        .collect()
}

fn outcome(c: &Case, g: &VibrationGap, o: &Options, visible: f64) -> Outcome {
    let chosen = g.steps.iter().map(|s| s.effect.clone()).collect();
    let held = (g.judge_before_db, g.judge_after_db);
    let mut out = Outcome::new(
        &c.name,
        &c.withheld,
        chosen,
        g.explained(o),
        held,
        visible,
        "dB",
    );
    if let Some(first) = out.found.first() {
        out.ambiguous = g
            .alternatives
            .iter()
            .filter(|a| &a.instead_of == first && a.implausible.is_none())
            .map(|a| a.effect.clone())
            .collect();
    }
    out
}
