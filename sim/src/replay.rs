//! Reading the ball bar of a finished run again, on a machine with other geometric errors,
//! another thermal network or another bar set-up, without simulating the motion again.
//!
//! The geometric errors (ISO 230-1: the axis error functions and squareness) act only through
//! the error chain `P_tool = f(q, d, thermal state)` and the bar's set-up (pivot offset and
//! drift, bar temperature) only through its reading `|P_tool − P_pivot(t)| − L(1 + αΔT)`: neither
//! enters the drives, the controller or the thermal network, so the axis positions `q`, their
//! direction states `d` and the thermal state at every bar sample are those of the run whatever
//! their values. A [`Replay`] keeps them (from [`simulate_with_replay`]); [`replay`] evaluates
//! the chain and the bar again with the new values, and gives the traces the simulation would
//! give, to rounding (a test compares both).
//!
//! The lumped thermal network does not enter the motion either: its heat comes from the
//! spindle speed and the axes' mean speeds of each thermal step, which the motion sets, and its
//! temperatures act through the error chain alone. A [`Replay`] keeps what drove each step, and
//! [`replay`] steps the given machine's network again with it (capacities, conductances,
//! sources, start temperatures, links' and joints' sensitivities of its own). A run with a screw
//! simulated along its length keeps its recorded thermal states instead, since that screw's
//! heat follows the nut cell by cell.
//!
//! A change `Δe` of a screw's periodic lead error `e(x) = e_c cos(2πx/lead) + e_s sin(2πx/lead)`
//! does change the motion, but under a motor encoder the control does not see it and the
//! carriage follows the nut: [`replay_lead_error`] moves each recorded carriage position by
//! `Δe(x)` (quasi-statically). Far below the drive's axial resonance (a 10 mm lead at
//! 2000 mm/min repeats at 3.3 Hz, the resonance is some 100 Hz) the dynamic part is of order
//! `(f/f_n)²`, and reading `e` at the carriage instead of the motor side shifts its phase by
//! `2π·stretch/lead`: together about 1e-3 of the change, not rounding, so the gap analysis uses
//! it for sensitivities only and simulates what it reports.
//!
//! [`simulate_with_replay`]: crate::simulate::simulate_with_replay

use crate::run::BallbarTrace;
use crate::simulate::{HeatStep, Job, SimError, SimSettings, job_traces, push_sample, test_bar};
use std::borrow::Cow;
use vmt_model::kinematics::AxisState;
use vmt_model::machine::Machine;
use vmt_model::thermal_deformation::ThermalDeformation;

/// One bar sample of a run: its time, the axis states and the thermal state in effect.
#[derive(Clone, Copy, Debug)]
struct Sample {
    time_s: f64,
    state: AxisState,
    thermal: u32,
}

/// What the ball bar read at every sample of a run, per trace.
#[derive(Clone, Debug)]
pub struct Replay {
    /// The thermal states of the run in order; a sample names the one in effect.
    thermal: Vec<ThermalDeformation>,
    /// What drove each step of the thermal network (`thermal[k + 1]` followed step `k`), when
    /// the network alone set the thermal states (no screw simulated along its length, whose
    /// heat follows the nut cell by cell): then a machine with another network re-derives them.
    steps: Option<Vec<HeatStep>>,
    /// Per trace, its samples in order.
    samples: Vec<Vec<Sample>>,
}

impl Replay {
    /// An empty record of `traces` traces starting in thermal state `initial`; `network_only`
    /// when the lumped network alone sets the thermal states.
    pub(crate) fn new(initial: ThermalDeformation, traces: usize, network_only: bool) -> Self {
        Self {
            thermal: vec![initial],
            steps: network_only.then(Vec::new),
            samples: vec![Vec::new(); traces],
        }
    }

    /// The thermal network took `step`, and the thermal state is now `d`.
    pub(crate) fn thermal_state(&mut self, d: ThermalDeformation, step: HeatStep) {
        self.thermal.push(d);
        if let Some(steps) = self.steps.as_mut() {
            steps.push(step);
        }
    }

    /// The thermal states of the run on `machine`: its lumped network stepped again with the
    /// run's heat, where the record allows (the same arithmetic, so the run's own states to the
    /// bit on the machine that ran), else the recorded ones.
    fn thermal_on<'a>(
        &'a self,
        machine: &Machine,
    ) -> Result<Cow<'a, [ThermalDeformation]>, SimError> {
        let (Some(steps), Some(t)) = (&self.steps, &machine.thermal) else {
            return Ok(Cow::Borrowed(&self.thermal));
        };
        if t.screws.iter().any(Option::is_some) {
            return Err(SimError::Settings(
                "replay: the machine simulates a screw along its length, the recorded run did not"
                    .into(),
            ));
        }
        let (stepper, mut temps_c) = HeatStep::start(t)?;
        let deform = |temps_c: &[f64]| {
            machine
                .thermal_deformation(temps_c)
                .map_err(|e| SimError::Thermal(e.to_string()))
        };
        let mut out = Vec::with_capacity(steps.len() + 1);
        out.push(deform(&temps_c)?);
        for step in steps {
            step.step(&stepper, &mut temps_c, t);
            out.push(deform(&temps_c)?);
        }
        Ok(Cow::Owned(out))
    }

    /// The bar read trace `trace` at `time_s` with the axes in `state`.
    pub(crate) fn sample(&mut self, trace: usize, time_s: f64, state: AxisState) {
        let thermal = u32::try_from(self.thermal.len() - 1).unwrap_or(u32::MAX);
        self.samples[trace].push(Sample {
            time_s,
            state,
            thermal,
        });
    }
}

/// The ball-bar traces of `job` read on `machine` at the samples of `replay` (a run of a job
/// with the same program and tests). The bars read in the run's order, so their noise draws
/// (from `settings.seed`) are the run's too.
pub fn replay(
    machine: &Machine,
    job: &Job,
    settings: &SimSettings,
    replay: &Replay,
) -> Result<Vec<BallbarTrace>, SimError> {
    replay_moved(machine, job, settings, replay, |s| s)
}

/// A change of one screw's periodic lead error, for [`replay_lead_error`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LeadErrorChange {
    /// The screw's lead, m.
    pub lead_m: f64,
    /// Change of `[e_c, e_s]`, m.
    pub delta_m: [f64; 2],
}

impl LeadErrorChange {
    /// `Δe(x)`, m.
    fn at(&self, x: f64) -> f64 {
        if self.lead_m <= 0.0 {
            return 0.0;
        }
        let (sin, cos) = (std::f64::consts::TAU * x / self.lead_m).sin_cos();
        self.delta_m[0] * cos + self.delta_m[1] * sin
    }
}

/// [`replay`] on a machine whose screws' periodic lead errors changed by `changes` (per axis
/// X, Y, Z; motor-encoder feedback), the carriages moved quasi-statically (module docs).
pub fn replay_lead_error(
    machine: &Machine,
    job: &Job,
    settings: &SimSettings,
    replay: &Replay,
    changes: &[LeadErrorChange; 3],
) -> Result<Vec<BallbarTrace>, SimError> {
    replay_moved(machine, job, settings, replay, |mut s| {
        for (q, c) in s.position.iter_mut().zip(changes) {
            *q += c.at(*q);
        }
        s
    })
}

/// [`replay`] with every recorded axis state passed through `moved` first.
fn replay_moved(
    machine: &Machine,
    job: &Job,
    settings: &SimSettings,
    replay: &Replay,
    moved: impl Fn(AxisState) -> AxisState,
) -> Result<Vec<BallbarTrace>, SimError> {
    let traces = job_traces(job);
    if traces.len() != replay.samples.len() {
        return Err(SimError::Settings(format!(
            "replay: the job has {} ball-bar traces, the recorded run {}",
            traces.len(),
            replay.samples.len()
        )));
    }
    let mut bars: Vec<_> = job
        .ballbar
        .iter()
        .enumerate()
        .map(|(i, b)| test_bar(b, i, settings))
        .collect();
    let thermal = replay.thermal_on(machine)?;
    let mut current: Option<(u32, _)> = None;
    let mut out = Vec::with_capacity(traces.len());
    for ((test, mut trace), samples) in traces.into_iter().zip(&replay.samples) {
        for s in samples {
            if current.as_ref().is_none_or(|(k, _)| *k != s.thermal) {
                let d = &thermal[s.thermal as usize];
                current = Some((s.thermal, machine.volumetric.evaluator(d)));
            }
            let (_, evaluator) = current.as_ref().expect("set above");
            let tool = evaluator.tool_point(&moved(s.state));
            let (reading, angle) = bars[test].read(&tool, s.time_s);
            crate::simulate::check_range(&bars[test], &trace, s.time_s, reading, angle)?;
            push_sample(&mut trace, s.time_s, angle, reading);
        }
        out.push(trace);
    }
    Ok(out)
}
