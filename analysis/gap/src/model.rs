//! The model side of the gap: a scenario whose parameters can be offset by key and whose job is
//! re-simulated (vmt-sim, the scenario's own fidelity and controller) to give the traces the
//! model predicts. The ball bar is simulated without noise and without resolution rounding, so
//! that the model's traces and their sensitivities are smooth; the measured traces keep theirs.
//!
//! Offsets of geometric errors (`machine.errors.…`) and of the bar's set-up
//! (`instruments.ballbar.setup_…`, `instruments.ballbar.bar_…`) do not change the motion, only
//! what the bar reads: they are read again from the recorded motion of the model as given
//! (`vmt_sim::replay`, the same traces as a new simulation to rounding) instead of simulated;
//! so are offsets of the lumped thermal network (`machine.thermal.…`) where it alone sets the
//! thermal state, its steps taken again with the run's heat. For the finite-difference
//! sensitivities only, a change of a screw's periodic lead error under a motor encoder is
//! replayed too, the carriages moved by it quasi-statically (within about 1e-3 of the change;
//! a test checks 2 %); what the selection reports is simulated.

use crate::align::GapError;
use crate::effects::{
    Effect, PIVOT_OFFSET_KEY, library_for, per_centre, screw_heating, thermal_drift,
};
use crate::peaks::Circle;
use std::path::PathBuf;
use std::sync::OnceLock;
use std::sync::atomic::{AtomicUsize, Ordering};
use vmt_ballbar::{Trace, TraceError};
use vmt_model::drive::Feedback;
use vmt_model::thermal::HeatSource;
use vmt_scenario::edit::Template;
use vmt_sim::replay::{LeadErrorChange, Replay};
use vmt_sim::run::BallbarTrace;
use vmt_sim::simulate::PlannedPath;

/// Simulates a model's job with parameter offsets.
pub trait Forward: Sync {
    /// The model's value at `key`, if the model sets a number there.
    fn value(&self, key: &str) -> Option<f64>;
    /// The traces of the job with `(key, value)` written into the model.
    fn traces(&self, values: &[(String, f64)]) -> Result<Vec<Trace>, GapError>;
    /// Whether a sensitivity to `key` is answered without a new simulation once the model as
    /// given has run ([`Forward::sensitivity_traces`]).
    fn replayable(&self, _key: &str) -> bool {
        false
    }
    /// [`Forward::traces`] for a finite-difference sensitivity: a model may answer it from the
    /// recorded motion where that is accurate to a small fraction of the step, where `traces`
    /// answers only what a simulation would give to rounding.
    fn sensitivity_traces(&self, values: &[(String, f64)]) -> Result<Vec<Trace>, GapError> {
        self.traces(values)
    }
    /// The tool's circle of each trace of the job, in the order of the traces, where known
    /// (none: no place along an axis can be found).
    fn circles(&self) -> &[Circle] {
        &[]
    }
}

/// A scenario file as a forward model.
pub struct ScenarioModel {
    template: Template,
    file: String,
    base_dir: Option<PathBuf>,
    /// The recorded motion of the model as given, once simulated.
    base: OnceLock<Replay>,
    /// The job's program planned once for all its simulations (none if it cannot be planned:
    /// the simulation then says why).
    path: OnceLock<Option<PlannedPath>>,
    /// Evaluations answered by a replay instead of a simulation.
    replays: AtomicUsize,
    /// The thermal node the spindle's losses heat, if the model has one.
    spindle_node: Option<usize>,
    /// Per axis X, Y, Z: the lumped node its motion heats and whose temperature its scale
    /// grows with, if the model has one (and no distributed screw in its place).
    screw_nodes: [Option<usize>; 3],
    /// Whether the lumped thermal network alone sets the thermal state (no screw simulated
    /// along its length): then a change of its keys replays exactly ([`vmt_sim::replay`]).
    network_thermal: bool,
    /// Per axis X, Y, Z under a motor encoder: the screw's lead and periodic lead error
    /// `[e_c, e_s]` as given, m (for [`vmt_sim::replay::replay_lead_error`]).
    leads: [Option<(f64, [f64; 2])>; 3],
    /// The tool's circle of each trace of the job, in axis coordinates.
    circles: Vec<Circle>,
}

/// Key prefixes whose values change what the bar reads but not the motion.
const KINEMATIC: [&str; 3] = [
    "machine.errors.",
    "instruments.ballbar.setup_",
    "instruments.ballbar.bar_",
];

/// The lumped node that axis `i`'s motion heats and whose temperature its scale grows with,
/// where the machine has no distributed screw for the axis.
fn screw_node(t: &vmt_model::machine::ThermalMachine, i: usize) -> Option<usize> {
    let expands = t.deformation.joints[i].expansion.as_ref()?.node;
    let heated = t.network.sources().iter().any(
        |h| matches!(h, HeatSource::Axis { node, axis, .. } if *node == expands && *axis == i),
    );
    (heated && t.screws[i].is_none()).then_some(expands)
}

impl ScenarioModel {
    /// The model of scenario `text` (named `file`; table files resolved in `base_dir`), its
    /// ball bar without noise or rounding, its servo log thinned out.
    pub fn new(text: &str, file: &str, base_dir: Option<PathBuf>) -> Result<Self, GapError> {
        let quiet = Template::parse(text, file)
            .and_then(|t| {
                t.with_inserted(&[
                    ("instruments.ballbar.noise_um", 0.0),
                    ("instruments.ballbar.resolution_um", 0.0),
                    // Only the bar's traces are read: the servo log at 10 Hz instead of the
                    // scenario's rate spares its memory and time (the bar keeps its own rate).
                    ("simulation.log_rate_hz", 10.0),
                ])
            })
            .map_err(|e| GapError::Model(e.to_string()))?;
        Self::instrumented(&quiet, file, base_dir)
    }

    /// The same model with its `[job]` replaced by `job` (the table's body, TOML): another
    /// test the machine could run.
    /// A model whose bar is set up at several centres keeps the first centre's set-up.
    pub fn for_job(&self, job: &str) -> Result<Self, GapError> {
        let err = |e: vmt_scenario::ScenarioError| GapError::Model(e.to_string());
        let mut text = self.template.with_table("job", job).map_err(err)?;
        if self.pivot_offsets() > 1 {
            let first: Vec<String> = (0..3)
                .map(|i| {
                    format!(
                        "{:?}",
                        self.value(&format!("{PIVOT_OFFSET_KEY}[0][{i}]"))
                            .unwrap_or(0.0)
                    )
                })
                .collect();
            let fragment = format!("setup_eccentricity_um = [{}]\n", first.join(", "));
            text = Template::parse(&text, &self.file)
                .and_then(|t| t.with_fragment("instruments.ballbar", &fragment))
                .map_err(err)?;
        }
        Self::instrumented(&text, &self.file, self.base_dir.clone())
    }

    /// How many pivot offsets the bar's set-up lists, one per centre of the job (1 where it
    /// gives one offset for every pivot).
    fn pivot_offsets(&self) -> usize {
        (0..)
            .take_while(|c| self.value(&format!("{PIVOT_OFFSET_KEY}[{c}][0]")).is_some())
            .count()
            .max(1)
    }

    /// The model's scenario.
    pub fn template(&self) -> &Template {
        &self.template
    }

    /// How many evaluations were replays of the recorded motion rather than simulations.
    pub fn replays(&self) -> usize {
        self.replays.load(Ordering::Relaxed)
    }

    /// The scenario as written, instrument noise and resolution included: a stand-in for a
    /// real machine in closed-loop studies.
    pub fn instrumented(
        text: &str,
        file: &str,
        base_dir: Option<PathBuf>,
    ) -> Result<Self, GapError> {
        let template = Template::parse(text, file).map_err(|e| GapError::Model(e.to_string()))?;
        let mut model = Self {
            template,
            file: file.to_string(),
            base_dir,
            base: OnceLock::new(),
            path: OnceLock::new(),
            replays: AtomicUsize::new(0),
            spindle_node: None,
            screw_nodes: [None; 3],
            network_thermal: false,
            leads: [None; 3],
            circles: Vec::new(),
        };
        // Parse once now, so a bad model is refused before any fitting.
        let s = model.scenario(text)?;
        if let Some(exec) = &s.execution {
            let offset = s.machine.volumetric.kinematics.tool_offset;
            model.circles = exec
                .job
                .ballbar
                .iter()
                .flat_map(|b| {
                    let (centre, radius) = b.tool_circle();
                    let c = (centre - offset) * 1e3;
                    b.data.iter().map(move |_| Circle {
                        centre_mm: [c.x, c.y, c.z],
                        radius_mm: radius * 1e3,
                    })
                })
                .collect();
            model.leads = std::array::from_fn(|i| {
                let d = &exec.axes[i].drive;
                (d.feedback == Feedback::MotorEncoder).then_some((d.screw.lead_m, d.screw.cyclic_m))
            });
        }
        if let Some(t) = &s.machine.thermal {
            model.spindle_node = t.network.sources().iter().find_map(|h| match h {
                HeatSource::Spindle { node, .. } => Some(*node),
                HeatSource::Axis { .. } => None,
            });
            model.screw_nodes = std::array::from_fn(|i| screw_node(t, i));
            model.network_thermal = t.screws.iter().all(Option::is_none);
        }
        Ok(model)
    }

    /// The tool's circle of each trace the job records, in the order of the traces, in axis
    /// coordinates (the tool point less the tool offset).
    pub fn circles(&self) -> &[Circle] {
        &self.circles
    }

    /// The candidate library for tests in `planes` ([`library_for`]), with the thermal drift
    /// of the spindle head when the model has a thermal node the spindle heats, and the
    /// heating of each tested axis' screw whose lumped node its motion heats.
    pub fn library(&self, planes: &[(char, char)]) -> Vec<Effect> {
        let mut out = per_centre(library_for(planes), self.pivot_offsets());
        out.extend(self.spindle_node.map(thermal_drift));
        let axes: Vec<char> = planes.iter().flat_map(|&(p, q)| [p, q]).collect();
        for (i, a) in ['x', 'y', 'z'].into_iter().enumerate() {
            if let (true, Some(node)) = (axes.contains(&a), self.screw_nodes[i]) {
                out.push(screw_heating(a, node));
            }
        }
        out
    }

    /// The axis (0, 1, 2) whose screw's periodic lead error `key` sets, when that axis reads a
    /// motor encoder (the change replays quasi-statically, [`vmt_sim::replay`]).
    fn lead_axis(&self, key: &str) -> Option<usize> {
        let rest = key.strip_prefix("machine.axes.")?;
        let axis = ["x", "y", "z"].iter().position(|a| {
            rest.strip_prefix(a) == Some(".drive.screw_cyclic_um[0]")
                || rest.strip_prefix(a) == Some(".drive.screw_cyclic_um[1]")
        })?;
        self.leads[axis].map(|_| axis)
    }

    /// Whether an offset at `key` changes what the bar reads but not the motion: a replay of
    /// the recorded motion gives what a simulation would, to rounding (the geometric errors,
    /// the bar's set-up, and the lumped thermal network where it alone sets the thermal state).
    fn exact_replay(&self, key: &str) -> bool {
        KINEMATIC.iter().any(|p| key.starts_with(p))
            || (self.network_thermal && key.starts_with("machine.thermal."))
    }

    /// The model with `values` written in, parsed, and its text.
    fn with_values(
        &self,
        values: &[(String, f64)],
    ) -> Result<(vmt_scenario::Scenario, String), GapError> {
        let pairs: Vec<(&str, f64)> = values.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        let text = self
            .template
            .with(&pairs)
            .map_err(|e| GapError::Model(e.to_string()))?;
        Ok((self.scenario(&text)?, text))
    }

    fn scenario(&self, text: &str) -> Result<vmt_scenario::Scenario, GapError> {
        let s = vmt_scenario::parse(text, &self.file, self.base_dir.as_deref())
            .map_err(|e| GapError::Model(e.to_string()))?;
        if s.execution.is_none() {
            return Err(GapError::Model(format!(
                "{}: the model has no job to simulate ([controller], [job] and every axis' drive and servo are needed)",
                self.file
            )));
        }
        Ok(s)
    }
}

impl Forward for ScenarioModel {
    fn value(&self, key: &str) -> Option<f64> {
        self.template.value(key).ok().flatten()
    }

    fn circles(&self) -> &[Circle] {
        &self.circles
    }

    fn replayable(&self, key: &str) -> bool {
        self.exact_replay(key) || self.lead_axis(key).is_some()
    }

    fn sensitivity_traces(&self, values: &[(String, f64)]) -> Result<Vec<Trace>, GapError> {
        let (Some(base), true) = (
            self.base.get(),
            values.iter().all(|(k, _)| self.replayable(k)) && !values.is_empty(),
        ) else {
            return self.traces(values);
        };
        let (s, _) = self.with_values(values)?;
        let Some(exec) = &s.execution else {
            return Err(GapError::Model("no job".into()));
        };
        let changes: [LeadErrorChange; 3] = std::array::from_fn(|i| {
            let new = exec.axes[i].drive.screw.cyclic_m;
            self.leads[i].map_or_else(LeadErrorChange::default, |(lead_m, given)| {
                LeadErrorChange {
                    lead_m,
                    delta_m: [new[0] - given[0], new[1] - given[1]],
                }
            })
        });
        self.replays.fetch_add(1, Ordering::Relaxed);
        let ballbar = vmt_sim::replay::replay_lead_error(
            &s.machine,
            &exec.job,
            &exec.settings,
            base,
            &changes,
        )
        .map_err(|e| GapError::Model(format!("{}: {e}", self.file)))?;
        to_traces(&ballbar)
    }

    fn traces(&self, values: &[(String, f64)]) -> Result<Vec<Trace>, GapError> {
        let (s, text) = self.with_values(values)?;
        let Some(exec) = &s.execution else {
            return Err(GapError::Model("no job".into()));
        };
        let sim_error =
            |e: vmt_sim::simulate::SimError| GapError::Model(format!("{}: {e}", self.file));
        let kinematic = values.iter().all(|(k, _)| self.exact_replay(k));
        let ballbar: Vec<BallbarTrace> = match self.base.get() {
            Some(base) if kinematic => {
                self.replays.fetch_add(1, Ordering::Relaxed);
                vmt_sim::replay::replay(&s.machine, &exec.job, &exec.settings, base)
                    .map_err(sim_error)?
            }
            _ => {
                // The model as given keeps its motion for the kinematic offsets.
                let (run, replay) = vmt_sim::simulate::simulate_with_replay(
                    &s.machine,
                    &exec.axes,
                    &exec.controller,
                    &exec.job,
                    &exec.settings,
                    &text,
                    self.path
                        .get_or_init(|| PlannedPath::new(&exec.job.program, &exec.controller).ok())
                        .as_ref(),
                    values.is_empty(),
                )
                .map_err(sim_error)?;
                if let Some(replay) = replay {
                    let _ = self.base.set(replay);
                }
                run.ballbar
            }
        };
        to_traces(&ballbar)
    }
}

fn to_traces(ballbar: &[BallbarTrace]) -> Result<Vec<Trace>, GapError> {
    ballbar
        .iter()
        .map(|t| trace_of(t).map_err(GapError::Trace))
        .collect()
}

/// A simulated ball-bar trace as the diagnosis reads it, with its sample times.
pub fn trace_of(t: &BallbarTrace) -> Result<Trace, TraceError> {
    Trace::new(
        &t.label,
        &t.plane,
        &t.direction,
        t.radius_mm,
        t.feed_mm_min,
        t.angle_deg.clone(),
        t.deviation_um.clone(),
        Some(t.times_s.clone()),
    )
}
