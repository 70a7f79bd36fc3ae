//! Executing a job: NC program -> interpolator -> controller -> plant -> error chain ->
//! instruments -> [`Run`].
//!
//! Programmed coordinates are the tool centre point relative to the workpiece; the controller
//! applies the tool length and TCP offset (tool length compensation, as G43 does), so the axes
//! are commanded to `q = p - ˢP_T` and the nominal tool point is the programmed one.
//!
//! Time advances in servo periods `T_s` (125 µs by default): at each tick the interpolator gives
//! the setpoint, the three axis controllers compute their force references from the quantised
//! feedback, and the plant is advanced by `n` substeps of `h = T_s / n` (semi-implicit Euler for
//! the drives and the carriages; the multibody plant has rapier advance its links every macro
//! step of about 1 ms, see `plant::multibody`). The step is checked against the stiffest
//! drive mode before the run ([`SimError::StepTooCoarse`]); the sampled position and velocity
//! loops are not refused when unstable ([`servo_warnings`] says so): an unstable loop rings,
//! bounded by the force limit and friction, as a machine tuned so would, unless the excess-error
//! alarm stops it. The actual carriage positions and
//! their direction states go through the geometric and thermal error chain of the model crate to
//! give the tool point relative to the workpiece; the thermal network is advanced every second
//! with the heat of the spindle and of the axes' motion. Instruments sample the tool point on the
//! run's clock.
//!
//! At the program's end the controller holds the last setpoint until every axis is in position
//! (|following error| ≤ [`IN_POSITION_M`]), as a CNC completes M30 after its in-position check,
//! for at most [`SETTLE_LIMIT_S`]; the log runs on until then, so that it ends with the machine
//! at rest rather than in the middle of its last approach (a laser test's carriage had still
//! been 254 µm short of the end point).

use crate::ballbar::{Ballbar, BallbarSpec};
use crate::interpolator::{Cursor, Interpolator, InterpolatorConfig, InterpolatorError, Setpoint};
use crate::laser::{DriveSample, Laser, LaserSetup, LaserSpec};
use crate::nc::program::{ArcDirection, Plane, Program, Spindle};
use crate::plant::{
    CompliantPlant, Fidelity, MultibodyPlant, Plant, PlantError, ReducedPlant, layout,
};
use crate::replay::Replay;
use crate::run::{BallbarTrace, Channel, LogBlock, LogSink, MachineSummary, Run, Stream};
use crate::truth::{TestDrift, TruthInputs};
use nalgebra::Vector3;
use std::ops::Range;
use thiserror::Error;
use vmt_model::drive::servo::{least_damped_pole, loops_are_stable, sampled_loop_radius};
use vmt_model::drive::{
    AxisCommand, CarriageState, Drive, DriveEffects, DriveParams, Feedback, ServoParams,
};
use vmt_model::kinematics::{AxisState, VolumetricEvaluator};
use vmt_model::machine::Machine;
use vmt_model::structure::Structure;
use vmt_model::thermal::screw::ScrewThermal;
use vmt_model::thermal::{Operating, ThermalStepper};
use vmt_model::{Axis, Direction, DirectionTracker};

/// Drive and controller of one axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisDynamics {
    /// Physical drive parameters (the carriage mass is the axis' moving mass).
    pub drive: DriveParams,
    /// Controller settings.
    pub servo: ServoParams,
    /// The drive's optional physics (cogging, encoder signals, preloaded nut, GMS friction);
    /// `DriveEffects::default()` for none.
    pub effects: DriveEffects,
}

/// How to simulate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimSettings {
    /// Plant fidelity.
    pub fidelity: Fidelity,
    /// Plant steps per servo period.
    pub plant_substeps: usize,
    /// Rate of the `servo` log stream, Hz.
    pub log_rate_hz: f64,
    /// Seed of every random draw (instrument noise).
    pub seed: u64,
}

/// A ball bar mounted for a circular test, and which blocks are its data arcs.
#[derive(Clone, Debug)]
pub struct BallbarSetup {
    /// Name of the test, prefixed to its trace labels (e.g. `step 1`), if any.
    pub name: Option<String>,
    /// The instrument.
    pub spec: BallbarSpec,
    /// Nominal position of the centre ball (the pivot), m.
    pub center: Vector3<f64>,
    /// Nominal bar length, m.
    pub radius_m: f64,
    /// Test plane.
    pub plane: Plane,
    /// Feed of the test, m/s.
    pub feed_m_s: f64,
    /// Data arcs: direction and the program blocks they span.
    pub data: Vec<(ArcDirection, Range<usize>)>,
    /// The tool's circle (centre, m, and radius, m) when the bar does not lie in its plane
    /// (an inclined link, Kwon's step 4); `None`: the circle about the pivot of the bar's
    /// length.
    pub circle: Option<(Vector3<f64>, f64)>,
}

impl BallbarSetup {
    /// Centre (m) and radius (m) of the tool's circle.
    pub fn tool_circle(&self) -> (Vector3<f64>, f64) {
        self.circle.unwrap_or((self.center, self.radius_m))
    }
}

/// A job: a program and the instruments watching it.
#[derive(Clone, Debug)]
pub struct Job {
    /// The NC program.
    pub program: Program,
    /// The ball bar, one set-up per circular test (the bar is remounted between tests).
    pub ballbar: Vec<BallbarSetup>,
    /// The laser interferometer, for a positioning test.
    pub laser: Option<LaserSetup>,
}

impl Job {
    /// Feed of the job's test, m/s: the first circular test's, else the positioning test's, else 0.
    pub fn test_feed_m_s(&self) -> f64 {
        match (self.ballbar.first(), &self.laser) {
            (Some(b), _) => b.feed_m_s,
            (None, Some(l)) => l.test.feed_m_s,
            (None, None) => 0.0,
        }
    }
}

/// Why a job cannot run.
#[derive(Debug, Error)]
pub enum SimError {
    /// The interpolator refused the program or its settings.
    #[error(transparent)]
    Interpolator(#[from] InterpolatorError),
    /// The machine cannot be built as a plant.
    #[error(transparent)]
    Plant(#[from] PlantError),
    /// A block takes an axis beyond its stroke.
    #[error(
        "block at line {line}: the {axis} axis would reach {position_mm:.3} mm, beyond its stroke {} to {} mm",
        crate::short(*.min_mm),
        crate::short(*.max_mm)
    )]
    Stroke {
        /// Source line of the block.
        line: usize,
        /// The axis.
        axis: Axis,
        /// Where it would go, mm.
        position_mm: f64,
        /// Stroke, mm.
        min_mm: f64,
        /// Stroke, mm.
        max_mm: f64,
    },
    /// An axis' following error passed its excess-error limit: the drive is not following.
    #[error(
        "block at line {line}: the {axis} axis' following error reached {error_mm:.3} mm at {time_s:.3} s, beyond its excess-error limit of {limit_mm:.3} mm (scenario key machine.axes.{key}.servo.following_error_limit_mm; by default twice the lag at the axis' velocity limit): the drive cannot follow its command, as when its peak torque does not overcome friction and load, and the control stops the job",
        key = axis.to_string().to_lowercase()
    )]
    ExcessError {
        /// Source line of the block being executed.
        line: usize,
        /// The axis.
        axis: Axis,
        /// Time, s.
        time_s: f64,
        /// The following error, mm.
        error_mm: f64,
        /// Its limit, mm.
        limit_mm: f64,
    },
    /// A ball-bar reading beyond the transducer's measuring range.
    #[error(
        "{trace}: the ball bar read {reading_um:+.1} µm at {angle_deg:.1}° ({time_s:.3} s), beyond its measuring range of ±{range_um} µm (instruments.ballbar.range_um): a ball-bar system stops the capture there; the machine or the set-up (the centre, the pivot's eccentricity) is off by more than the bar can read"
    )]
    BallbarOutOfRange {
        /// The trace's label.
        trace: String,
        /// Time, s.
        time_s: f64,
        /// The bar's angle, deg.
        angle_deg: f64,
        /// The reading, µm.
        reading_um: f64,
        /// The range, ± µm.
        range_um: f64,
    },
    /// The sampled servo loops of an axis are unstable.
    #[error(
        "the {axis} axis' velocity loop of {bandwidth_hz:.1} Hz is unstable at the servo period of {period_us:.1} µs (a disturbance grows {radius:.3}-fold per period, with its Kv, integral time, current loop and screw, linearised without friction or backlash): {stable}"
    )]
    ServoUnstable {
        /// The axis.
        axis: Axis,
        /// Its velocity loop bandwidth, Hz.
        bandwidth_hz: f64,
        /// The servo period, µs.
        period_us: f64,
        /// Spectral radius of the loops over one period.
        radius: f64,
        /// Which bandwidths are stable.
        stable: String,
    },
    /// The plant step is beyond the stability limit of a drive mode.
    #[error(
        "a plant step of {step_us:.2} µs is too coarse for the {mode} of the {axis} drive: the largest stable step is {limit_us:.2} µs, and up to half of it ({accepted_us:.2} µs) is accepted, where the step keeps that mode's frequency within 5 %; raise plant_substeps (scenario key controller.plant_substeps) to {substeps_needed} or more",
        accepted_us = limit_us * STABLE_STEP_FRACTION
    )]
    StepTooCoarse {
        /// The axis.
        axis: Axis,
        /// The mode.
        mode: &'static str,
        /// Step, µs.
        step_us: f64,
        /// Largest stable step, µs.
        limit_us: f64,
        /// The fewest plant steps per servo period that are stable.
        substeps_needed: usize,
    },
    /// Settings out of range.
    #[error("{0}")]
    Settings(String),
    /// The thermal model refused a step.
    #[error("thermal model: {0}")]
    Thermal(String),
    /// The [`LogSink`] of the run failed.
    #[error("{0}")]
    Log(String),
}

impl SimError {
    /// The source line of the program block the error is about, if it is about one.
    pub fn line(&self) -> Option<usize> {
        match self {
            Self::Interpolator(e) => e.line(),
            Self::Stroke { line, .. } | Self::ExcessError { line, .. } => Some(*line),
            Self::Plant(_)
            | Self::BallbarOutOfRange { .. }
            | Self::ServoUnstable { .. }
            | Self::StepTooCoarse { .. }
            | Self::Settings(_)
            | Self::Thermal(_)
            | Self::Log(_) => None,
        }
    }
}

/// Thermal update interval during a job, s.
const THERMAL_PERIOD_S: f64 = 1.0;

/// Runs `job` on `machine` and returns what was recorded. `progress` is called with the fraction
/// done (0 to 1) about a hundred times.
pub fn simulate(
    machine: &Machine,
    axes: &[AxisDynamics; 3],
    ipo: &InterpolatorConfig,
    job: &Job,
    settings: &SimSettings,
    scenario_toml: &str,
    progress: &mut dyn FnMut(f64),
) -> Result<Run, SimError> {
    simulate_logged(
        machine,
        axes,
        ipo,
        job,
        settings,
        scenario_toml,
        progress,
        None,
    )
}

/// [`simulate`], and with `replayable` also what the ball bar read at every sample (axis
/// states, thermal state, time), so that the traces can be read again on a machine with other
/// geometric errors or another bar set-up without simulating the motion again (see
/// [`crate::replay`]). With `path` (the job's program planned before, under `ipo`) its plan
/// is used instead of planning the program again; a path of another program or controller is
/// not used.
#[allow(clippy::too_many_arguments)]
pub fn simulate_with_replay(
    machine: &Machine,
    axes: &[AxisDynamics; 3],
    ipo: &InterpolatorConfig,
    job: &Job,
    settings: &SimSettings,
    scenario_toml: &str,
    path: Option<&PlannedPath>,
    replayable: bool,
) -> Result<(Run, Option<Replay>), SimError> {
    let job_run = JobRun {
        machine,
        axes,
        ipo,
        job,
        settings,
        scenario_toml,
    };
    let path = path.and_then(|p| p.of(&job.program, ipo));
    job_run.execute(&mut |_| {}, replayable, None, path)
}

/// A job's program planned once (path, feed profiles and IPO samples), for many runs of the
/// same program and controller on machines that differ elsewhere (the model evaluations of a
/// fit): each run then computes only its servo setpoints. Memory: the IPO samples, 16 bytes per
/// IPO period.
#[derive(Clone, Debug)]
pub struct PlannedPath {
    program: Program,
    config: InterpolatorConfig,
    interpolator: Interpolator,
}

impl PlannedPath {
    /// Plans `program` under `config`.
    pub fn new(program: &Program, config: &InterpolatorConfig) -> Result<Self, SimError> {
        let interpolator = Interpolator::new(program, config)?;
        Ok(Self {
            program: program.clone(),
            config: *config,
            interpolator,
        })
    }

    /// The planned interpolator, if it is of `program` under `config`.
    fn of(&self, program: &Program, config: &InterpolatorConfig) -> Option<&Interpolator> {
        (self.program == *program && self.config == *config).then_some(&self.interpolator)
    }
}

/// [`simulate`] handing the run's records to `sink`, if there is one, while the job runs (see
/// [`LogSink`]): the returned run then has everything but the `servo` stream's rows, which
/// went to the sink.
#[allow(clippy::too_many_arguments)]
pub fn simulate_logged(
    machine: &Machine,
    axes: &[AxisDynamics; 3],
    ipo: &InterpolatorConfig,
    job: &Job,
    settings: &SimSettings,
    scenario_toml: &str,
    progress: &mut dyn FnMut(f64),
    sink: Option<&mut dyn LogSink>,
) -> Result<Run, SimError> {
    let job_run = JobRun {
        machine,
        axes,
        ipo,
        job,
        settings,
        scenario_toml,
    };
    Ok(job_run.execute(progress, false, sink, None)?.0)
}

/// What a job runs on.
struct JobRun<'a> {
    machine: &'a Machine,
    axes: &'a [AxisDynamics; 3],
    ipo: &'a InterpolatorConfig,
    job: &'a Job,
    settings: &'a SimSettings,
    scenario_toml: &'a str,
}

impl JobRun<'_> {
    fn execute(
        &self,
        progress: &mut dyn FnMut(f64),
        replayable: bool,
        mut sink: Option<&mut dyn LogSink>,
        planned: Option<&Interpolator>,
    ) -> Result<(Run, Option<Replay>), SimError> {
        let JobRun {
            machine,
            axes,
            ipo,
            job,
            settings,
            scenario_toml,
        } = *self;
        let built;
        let interpolator = match planned {
            Some(p) => p,
            None => {
                built = Interpolator::new(&job.program, ipo)?;
                &built
            }
        };
        let tcp = machine.volumetric.kinematics.tool_offset;
        check_strokes(machine, interpolator, &job.program, &tcp)?;
        let period = interpolator.servo_period_s();
        let substeps = settings.plant_substeps.max(1);
        let h = period / substeps as f64;
        check_step(axes, period, substeps)?;
        if !(settings.log_rate_hz > 0.0 && settings.log_rate_hz <= 1.0 / period) {
            return Err(SimError::Settings(format!(
                "log rate {} Hz: from 0 to the servo rate {} Hz is accepted",
                crate::short(settings.log_rate_hz),
                crate::short(1.0 / period)
            )));
        }
        if let Some(l) = &job.laser {
            check_laser(&l.spec, period)?;
        }
        let start = job.program.start - tcp;
        let mut plant = build_plant(machine, axes, &start, settings.fidelity, h)?;
        let ticks = interpolator.servo_ticks();
        let structure = machine
            .structure
            .as_ref()
            .filter(|_| settings.fidelity == Fidelity::Compliant);
        let mut recorder = Recorder::new(
            job,
            structure,
            settings,
            period,
            &interpolator.block_times(),
            ticks,
            sink.is_some(),
        );
        if let Some(sink) = sink.as_deref_mut() {
            sink.start(&recorder.opening(machine, settings, scenario_toml))
                .map_err(SimError::Log)?;
        }
        let mut heat = HeatTracker::new(machine, axes)?;
        // Link and joint matrices of the current thermal state, rebuilt only when it changes.
        let mut evaluator = machine.volumetric.evaluator(&heat.deformation);
        let mut replay = replayable.then(|| {
            Replay::new(
                heat.deformation,
                recorder.traces.len(),
                heat.screws.is_empty(),
            )
        });
        // The thermal state at the start, middle and end of each circular test's data: the
        // middle for the truth's figures, the ends for the drift over the test.
        let spans = test_spans(job, &interpolator.block_times());
        let moments: Vec<f64> = spans
            .iter()
            .flat_map(|&(t0, t1)| [t0, 0.5 * (t0 + t1), t1])
            .collect();
        let mut at_moment = vec![heat.deformation; moments.len()];
        // And where the carriages stand from their commands then (an axis standing through a
        // test creeps as its friction relaxes: a drift of the tool along it).
        let mut drive_at_moment = vec![Vector3::zeros(); moments.len()];
        let mut next_moment = 0;
        let mut trackers =
            Axis::ALL.map(|a| DirectionTracker::new(start[a.index()], Direction::Forward, 0.05e-6));
        let mut cursor = Cursor::default();
        let limits = following_error_limits(axes, ipo);
        let mut last = None;
        for k in 0.. {
            let Some(sp) = setpoint_or_settle(
                interpolator,
                k,
                &mut cursor,
                &mut last,
                plant.as_ref(),
                recorder.log_every,
            ) else {
                break;
            };
            servo_tick(plant.as_mut(), &sp, &tcp, period, substeps);
            // While the axes settle, an alarm names the program's last block.
            let block = sp.block.or(last.and_then(|l| l.block));
            check_following_error(plant.as_ref(), &limits, sp.time_s, block, &job.program)?;
            let carriages = plant.carriages();
            let q = Vector3::from_fn(|i, _| carriages[i].position_m);
            let direction = directions(&mut trackers, &q);
            if heat.accumulate(&sp, &carriages, period, machine)? {
                evaluator = machine.volumetric.evaluator(&heat.deformation);
                if let Some(r) = replay.as_mut() {
                    r.thermal_state(heat.deformation, heat.last_step);
                }
            }
            while next_moment < moments.len() && sp.time_s >= moments[next_moment] {
                at_moment[next_moment] = heat.deformation;
                drive_at_moment[next_moment] = q - (sp.position - tcp);
                next_moment += 1;
            }
            let state = AxisState {
                position: q,
                direction,
            };
            if let Some(j) = recorder.record(k, &sp, plant.as_ref(), &state, machine, &evaluator)?
                && let Some(r) = replay.as_mut()
            {
                r.sample(j, sp.time_s, state);
            }
            if let Some(sink) = sink.as_deref_mut() {
                recorder.send(sink, LOG_BLOCK_ROWS)?;
            }
            if k.is_multiple_of((ticks / 100).max(1)) {
                progress((k as f64 / ticks as f64).min(1.0));
            }
        }
        progress(1.0);
        if let Some(sink) = sink {
            recorder.send(sink, 0)?;
        }
        recorder.end_closing(&evaluator);
        // A test ending on the last tick is at the state the run ends in (the settling wait
        // holds the last setpoint).
        let carriages = plant.carriages();
        let drive_error = last.map_or(Vector3::zeros(), |sp| {
            Vector3::from_fn(|i, _| carriages[i].position_m) - (sp.position - tcp)
        });
        for (d, e) in at_moment[next_moment..]
            .iter_mut()
            .zip(&mut drive_at_moment[next_moment..])
        {
            (*d, *e) = (heat.deformation, drive_error);
        }
        let chain = |d: &vmt_model::thermal_deformation::ThermalDeformation| {
            machine.volumetric.evaluator(d)
        };
        let at_tests: Vec<VolumetricEvaluator> =
            at_moment.chunks(3).map(|m| chain(&m[1])).collect();
        let drifts: Vec<TestDrift> = spans
            .iter()
            .zip(at_moment.chunks(3).zip(drive_at_moment.chunks(3)))
            .map(|(&(t0, t1), (m, e))| TestDrift {
                span_s: t1 - t0,
                start: chain(&m[0]),
                end: chain(&m[2]),
                drive_creep_m: e[2] - e[0],
            })
            .collect();
        let truth = TruthInputs {
            machine,
            axes,
            job,
            at_tests: &at_tests,
            drifts: &drifts,
        };
        Ok((recorder.finish(&truth, settings, scenario_toml)?, replay))
    }
}

/// One servo period: the controllers take the setpoint `sp` (the tool point less the TCP
/// offset `tcp`: the axes' commands, returned) and the plant advances `substeps` steps of
/// `period / substeps`.
pub(crate) fn servo_tick(
    plant: &mut dyn Plant,
    sp: &Setpoint,
    tcp: &Vector3<f64>,
    period: f64,
    substeps: usize,
) -> [AxisCommand; 3] {
    let commands: [AxisCommand; 3] = std::array::from_fn(|i| AxisCommand {
        position: sp.position[i] - tcp[i],
        velocity: sp.velocity[i],
        acceleration: sp.acceleration[i],
    });
    plant.control(&commands, period);
    let h = period / substeps as f64;
    for _ in 0..substeps {
        plant.step(h);
    }
    commands
}

/// Each axis' excess-error limit, m ([`ServoParams::following_error_limit`] at its velocity
/// limit in `ipo`).
pub(crate) fn following_error_limits(
    axes: &[AxisDynamics; 3],
    ipo: &InterpolatorConfig,
) -> [f64; 3] {
    std::array::from_fn(|i| {
        axes[i]
            .servo
            .following_error_limit(ipo.limits.axis_velocity_m_s[i])
    })
}

/// The excess-error alarm, after the controllers' period at `time_s`: a drive whose following
/// error passed its limit (`limits`, m) is not following its command (its torque saturated
/// against friction or load, a gain set wrong), and a control stops the job there, naming the
/// block of `program` it was executing (`block`).
pub(crate) fn check_following_error(
    plant: &dyn Plant,
    limits: &[f64; 3],
    time_s: f64,
    block: Option<usize>,
    program: &Program,
) -> Result<(), SimError> {
    let errors = plant.following_errors();
    for (i, axis) in Axis::ALL.into_iter().enumerate() {
        let e = errors[i];
        if e.abs() > limits[i] {
            return Err(SimError::ExcessError {
                line: block_line(program, block),
                axis,
                time_s,
                error_mm: e * 1e3,
                limit_mm: limits[i] * 1e3,
            });
        }
    }
    Ok(())
}

/// The ball bar's reading `reading` (m) at `angle` (rad) and `time_s` for `trace`, refused
/// beyond its measuring range.
pub(crate) fn check_range(
    bar: &Ballbar,
    trace: &BallbarTrace,
    time_s: f64,
    reading: f64,
    angle: f64,
) -> Result<(), SimError> {
    let range = bar.spec().range_m;
    if reading.abs() <= range {
        return Ok(());
    }
    Err(SimError::BallbarOutOfRange {
        trace: trace.label.clone(),
        time_s,
        angle_deg: angle.to_degrees(),
        reading_um: reading * 1e6,
        range_um: range * 1e6,
    })
}

/// The source line of block `block` of `program` (0 for none).
fn block_line(program: &Program, block: Option<usize>) -> usize {
    block
        .and_then(|b| program.blocks.get(b))
        .map_or(0, |b| b.span.line)
}

/// The axes' direction states after they moved to `q` (a loop: `array::from_fn` leaves its
/// closure out of line in this hot loop).
fn directions(trackers: &mut [DirectionTracker; 3], q: &Vector3<f64>) -> [Direction; 3] {
    let mut direction = [Direction::Forward; 3];
    for ((d, t), x) in direction.iter_mut().zip(trackers).zip(q.iter()) {
        *d = t.update(*x);
    }
    direction
}

/// The start and end of each circular test's data arcs, s (tests in job order, which is their
/// order in time; `(0, 0)` for a test without data).
fn test_spans(job: &Job, block_times: &[(usize, f64, f64)]) -> Vec<(f64, f64)> {
    job.ballbar
        .iter()
        .map(|b| {
            let (lo, hi) = block_times
                .iter()
                .filter(|(block, _, _)| b.data.iter().any(|(_, r)| r.contains(block)))
                .fold(
                    (f64::INFINITY, f64::NEG_INFINITY),
                    |(lo, hi), (_, t0, t1)| (lo.min(*t0), hi.max(*t1)),
                );
            if lo <= hi { (lo, hi) } else { (0.0, 0.0) }
        })
        .collect()
}

/// Whether `job`'s program, interpolated with `ipo`, stays within `machine`'s strokes (the check
/// [`simulate`] makes before it runs, for callers that want it earlier).
pub fn check_travel(
    machine: &Machine,
    ipo: &InterpolatorConfig,
    job: &Job,
) -> Result<(), SimError> {
    let interpolator = Interpolator::new(&job.program, ipo)?;
    let tcp = machine.volumetric.kinematics.tool_offset;
    check_strokes(machine, &interpolator, &job.program, &tcp)
}

/// The extent of `job`'s path in machine coordinates (the tool point less the tool offset),
/// lowest and highest per axis, m.
pub fn travel_extent(
    machine: &Machine,
    ipo: &InterpolatorConfig,
    job: &Job,
) -> Result<(Vector3<f64>, Vector3<f64>), SimError> {
    // From the setpoints, not the segments' bounding boxes (a half circle's is the circle's).
    let interpolator = Interpolator::new(&job.program, ipo)?;
    let tcp = machine.volumetric.kinematics.tool_offset;
    let none = (
        Vector3::repeat(f64::INFINITY),
        Vector3::repeat(f64::NEG_INFINITY),
    );
    let (lo, hi) = interpolator
        .iter()
        .map(|sp| sp.position)
        .fold(none, |(lo, hi), p| (lo.inf(&p), hi.sup(&p)));
    Ok((lo - tcp, hi - tcp))
}

pub(crate) fn check_strokes(
    machine: &Machine,
    ipo: &Interpolator,
    program: &Program,
    tcp: &Vector3<f64>,
) -> Result<(), SimError> {
    // Most programs stay well inside the strokes: then the bounds of the path decide, without
    // interpolating every setpoint (a margin of 1 nm covers the rounding of a setpoint).
    let (lo, hi) = ipo.bounds();
    let margin = 1e-9;
    let inside = Axis::ALL.into_iter().all(|a| {
        let (spec, i) = (machine.axis(a), a.index());
        lo[i] - tcp[i] - margin >= spec.min_m && hi[i] - tcp[i] + margin <= spec.max_m
    });
    if inside {
        return Ok(());
    }
    // Else the first setpoint past a stroke names the block, and the block's farthest
    // setpoint along that axis (its target, for a straight move) the position it would reach.
    let mut setpoints = ipo.iter();
    while let Some(sp) = setpoints.next() {
        let q = sp.position - tcp;
        if let Some(axis) = machine.outside_stroke(&q) {
            let spec = machine.axis(axis);
            let i = axis.index();
            let above = q[i] > spec.max_m;
            let farthest = setpoints
                .by_ref()
                .take_while(|s| s.block == sp.block)
                .map(|s| s.position[i] - tcp[i])
                .fold(q[i], |m, x| if above { m.max(x) } else { m.min(x) });
            let line = block_line(program, sp.block);
            return Err(SimError::Stroke {
                line,
                axis,
                position_mm: farthest * 1e3,
                min_mm: spec.min_m * 1e3,
                max_mm: spec.max_m * 1e3,
            });
        }
    }
    Ok(())
}

/// Checks that the laser can be sampled at servo ticks of `period_s` (its rate at most the servo
/// rate) and that its averaging window holds at least one sample.
fn check_laser(spec: &LaserSpec, period_s: f64) -> Result<(), SimError> {
    let rate = spec.sample_rate_hz;
    if !(rate > 0.0 && rate <= 1.0 / period_s) {
        return Err(SimError::Settings(format!(
            "laser sample rate {} Hz: from 0 to the servo rate {} Hz is accepted",
            crate::short(rate),
            crate::short(1.0 / period_s)
        )));
    }
    let interval_s = spec.sample_every(period_s) as f64 * period_s;
    if spec.averaging_s < interval_s * (1.0 - 1e-9) {
        return Err(SimError::Settings(format!(
            "laser averaging time {} s: it holds no sample at one sample every {every} s; at least {every} s is accepted",
            crate::short(spec.averaging_s),
            every = crate::short(interval_s)
        )));
    }
    Ok(())
}

/// The share of a drive mode's largest stable step that [`check_step`] accepts. At the limit
/// `h = 2/ω` (undamped) semi-implicit Euler's discrete mode has `cos ω_d h = 1 − (ωh)²/2`, so
/// ω_d = π/h, 57 % above ω, and the mode rings at the Nyquist rate; at half of it `ω_d h =
/// π/3`, 4.7 % above.
pub const STABLE_STEP_FRACTION: f64 = 0.5;

/// Checks the plant step `period_s / substeps` against the largest stable step of every
/// drive ([`DriveParams::largest_stable_step_s`]), of which [`STABLE_STEP_FRACTION`] is
/// accepted.
pub fn check_step(
    axes: &[AxisDynamics; 3],
    period_s: f64,
    substeps: usize,
) -> Result<(), SimError> {
    let h = period_s / substeps.max(1) as f64;
    for (a, d) in Axis::ALL.into_iter().zip(axes) {
        let (limit, mode) = d.effects.largest_stable_step_s(&d.drive);
        let accepted = limit * STABLE_STEP_FRACTION;
        // A limit that is not a number (parameters beyond any drive's) refuses too.
        if h > accepted || limit.is_nan() {
            // Saturating: a limit many orders below the period (absurd stiffness) must still
            // give an error, not an overflow.
            let mut needed = (period_s / accepted).ceil() as usize;
            if period_s / needed as f64 > accepted {
                needed = needed.saturating_add(1);
            }
            return Err(SimError::StepTooCoarse {
                axis: a,
                mode,
                step_us: h * 1e6,
                limit_us: limit * 1e6,
                substeps_needed: needed,
            });
        }
    }
    Ok(())
}

/// The damping ratio below which a loop is called lightly damped: its ringing after a
/// disturbance decays by less than 1/e in 1/(2π·0.05) ≈ 3 periods of the ring.
pub const LIGHTLY_DAMPED: f64 = 0.05;

/// What the sampled loops of each axis at `period_s` give to be said before a run: an unstable
/// loop ([`check_servo`]'s message; the run goes on, the loop ringing until the force limit and
/// friction bound it, unless the excess-error alarm stops the job) or a lightly damped one
/// (its least damped pole below [`LIGHTLY_DAMPED`]).
pub fn servo_warnings(axes: &[AxisDynamics; 3], period_s: f64) -> Vec<(Axis, String)> {
    let mut out = Vec::new();
    for (a, d) in Axis::ALL.into_iter().zip(axes) {
        let pole = least_damped_pole(&d.servo, &d.drive, period_s);
        let one = [*d; 3];
        if let Err(e) = check_servo(&one, period_s) {
            let ring = pole.map_or(String::new(), |(hz, _)| format!(" at {hz:.0} Hz"));
            let e = e
                .to_string()
                .replacen("the X axis'", &format!("the {a} axis'"), 1);
            out.push((
                a,
                format!(
                    "{e}. The run goes on: the loop rings{ring}, bounded by the motor's force limit and friction, unless the excess-error alarm stops the job"
                ),
            ));
        } else if let Some((hz, zeta)) = pole.filter(|p| p.1 < LIGHTLY_DAMPED) {
            out.push((
                a,
                format!(
                    "the {a} axis' servo loops are lightly damped: a pole at {hz:.0} Hz with a damping ratio of {zeta:.3} (below {LIGHTLY_DAMPED}); a disturbance rings there"
                ),
            ));
        }
    }
    out
}

/// Checks the sampled position and velocity loops of every axis at the servo period `period_s`
/// ([`sampled_loop_radius`]), naming the stable velocity bandwidths when they are not.
pub fn check_servo(axes: &[AxisDynamics; 3], period_s: f64) -> Result<(), SimError> {
    for (a, d) in Axis::ALL.into_iter().zip(axes) {
        if loops_are_stable(&d.servo, &d.drive, period_s) {
            continue;
        }
        let per_hz = d.drive.total_mass_kg() * std::f64::consts::TAU;
        let stable = |hz: f64| {
            let s = ServoParams {
                velocity_kp_n_s_per_m: per_hz * hz,
                ..d.servo
            };
            loops_are_stable(&s, &d.drive, period_s)
        };
        return Err(SimError::ServoUnstable {
            axis: a,
            bandwidth_hz: d.servo.velocity_kp_n_s_per_m / per_hz,
            period_us: period_s * 1e6,
            radius: sampled_loop_radius(&d.servo, &d.drive, period_s),
            stable: stable_bandwidths(stable, 1.0 / period_s),
        });
    }
    Ok(())
}

/// The stable velocity bandwidths below `top_hz` as words: the interval found on a log grid
/// from 0.01 Hz, its ends refined by bisection (one interval: the loop is too slow for its
/// position gain below it, too fast for its sampling and current loop above it).
fn stable_bandwidths(stable: impl Fn(f64) -> bool, top_hz: f64) -> String {
    const STEPS: usize = 400;
    let grid: Vec<f64> = (0..=STEPS)
        .map(|i| 0.01 * (top_hz / 0.01).powf(i as f64 / STEPS as f64))
        .collect();
    let Some(first) = grid.iter().position(|&hz| stable(hz)) else {
        return "no velocity bandwidth is stable with this position gain, integral time and current loop at this servo period; lengthen velocity_integral_ms, shorten current_time_constant_ms or servo_period_us, or lower kv_per_s".into();
    };
    let last = grid.iter().rposition(|&hz| stable(hz)).unwrap_or(first);
    let edge = |(mut inside, mut outside): (f64, f64)| {
        for _ in 0..40 {
            let mid = (inside * outside).sqrt();
            if stable(mid) {
                inside = mid;
            } else {
                outside = mid;
            }
        }
        inside
    };
    let lo = if first == 0 {
        grid[0]
    } else {
        edge((grid[first], grid[first - 1]))
    };
    let hi = if last == STEPS {
        grid[STEPS]
    } else {
        edge((grid[last], grid[last + 1]))
    };
    format!("stable from {lo:.1} to {hi:.1} Hz (scenario key servo.velocity_bandwidth_hz)")
}

pub(crate) fn build_plant(
    machine: &Machine,
    axes: &[AxisDynamics; 3],
    start: &Vector3<f64>,
    fidelity: Fidelity,
    h: f64,
) -> Result<Box<dyn Plant>, SimError> {
    let moving = machine.axes.map(|a| a.moving_mass_kg);
    let l = layout(&machine.volumetric.kinematics.topology, moving)?;
    let mut drives = Vec::with_capacity(3);
    for (i, a) in axes.iter().enumerate() {
        let mut params = a.drive;
        params.carriage_mass_kg = moving[i];
        let drive = Drive::new(params, a.servo, start[i])
            .with_effects(&a.effects)
            .map_err(|e| SimError::Settings(format!("{} drive: {e}", Axis::ALL[i])))?;
        drives.push(drive);
    }
    let drives: [Drive; 3] = [drives[0], drives[1], drives[2]];
    Ok(match fidelity {
        Fidelity::Reduced => Box::new(ReducedPlant::new(drives, &l)),
        Fidelity::Multibody => Box::new(MultibodyPlant::new(drives, &l, h)?),
        Fidelity::Compliant => {
            let structure = machine.structure.as_ref().ok_or(PlantError::NoStructure)?;
            let tcp = machine.volumetric.kinematics.tool_offset;
            Box::new(CompliantPlant::new(drives, &l, structure, tcp, h)?)
        }
    })
}

/// The machine's temperatures during the job: spindle and axis heat, stepped every second.
struct HeatTracker {
    stepper: Option<ThermalStepper>,
    temps_c: Vec<f64>,
    elapsed_s: f64,
    time_s: f64,
    distance_m: [f64; 3],
    spindle_rpm_s: f64,
    /// The screws simulated along their length (`thermal::screw`).
    screws: Vec<ScrewTracker>,
    deformation: vmt_model::thermal_deformation::ThermalDeformation,
    /// What drove the network's last step.
    last_step: HeatStep,
}

/// One screw's temperatures along its length and the heat its nut and bearings left in each
/// cell since the last thermal step.
struct ScrewTracker {
    axis: usize,
    model: ScrewThermal,
    temps_c: Vec<f64>,
    heat_j: Vec<f64>,
}

impl HeatTracker {
    fn new(machine: &Machine, axes: &[AxisDynamics; 3]) -> Result<Self, SimError> {
        let thermal_error = |e: String| SimError::Thermal(e);
        let (stepper, temps_c) = match &machine.thermal {
            Some(t) => {
                let (stepper, temps_c) = HeatStep::start(t)?;
                (Some(stepper), temps_c)
            }
            None => (None, Vec::new()),
        };
        let mut screws = Vec::new();
        if let Some(t) = &machine.thermal {
            let ambient = t.network.ambient().celsius_at(0.0);
            for (axis, p) in t.screws.iter().enumerate() {
                // A linear scale closes the loop on the carriage: the screw's growth does not
                // reach it (the scale's own expansion is the lumped model's).
                let (Some(p), Feedback::MotorEncoder) = (p, axes[axis].drive.feedback) else {
                    continue;
                };
                let model = ScrewThermal::new(p, THERMAL_PERIOD_S).map_err(thermal_error)?;
                screws.push(ScrewTracker {
                    axis,
                    temps_c: model.initial_temperatures(ambient),
                    heat_j: vec![0.0; p.cells],
                    model,
                });
            }
        }
        let mut tracker = Self {
            stepper,
            temps_c,
            elapsed_s: 0.0,
            time_s: 0.0,
            distance_m: [0.0; 3],
            spindle_rpm_s: 0.0,
            screws,
            deformation: Default::default(),
            last_step: HeatStep::default(),
        };
        tracker.deformation = tracker.deform(machine)?;
        Ok(tracker)
    }

    /// The deformation at the present temperatures: the network's, with each distributed
    /// screw's growth in place of its axis' lumped expansion.
    fn deform(
        &self,
        machine: &Machine,
    ) -> Result<vmt_model::thermal_deformation::ThermalDeformation, SimError> {
        let mut d = machine
            .thermal_deformation(&self.temps_c)
            .map_err(|e| SimError::Thermal(e.to_string()))?;
        for s in &self.screws {
            let joint = &mut d.joints[s.axis];
            joint.strain = 0.0;
            joint.screw = Some(s.model.growth(&s.temps_c));
        }
        Ok(d)
    }

    /// Adds one servo period of motion of the carriages; every thermal period, steps the
    /// network with the mean heat of that period. Returns whether the deformation changed.
    fn accumulate(
        &mut self,
        sp: &Setpoint,
        carriages: &[CarriageState; 3],
        dt: f64,
        machine: &Machine,
    ) -> Result<bool, SimError> {
        let (Some(stepper), Some(thermal)) = (&self.stepper, &machine.thermal) else {
            return Ok(false);
        };
        self.elapsed_s += dt;
        for (d, c) in self.distance_m.iter_mut().zip(carriages) {
            *d += c.velocity_m_s.abs() * dt;
        }
        for s in &mut self.screws {
            let c = &carriages[s.axis];
            s.model
                .deposit(&mut s.heat_j, c.position_m, c.velocity_m_s, dt);
        }
        self.spindle_rpm_s += match sp.spindle {
            Spindle::Clockwise(n) | Spindle::CounterClockwise(n) => n * dt,
            Spindle::Stopped => 0.0,
        };
        if self.elapsed_s + 1e-12 < THERMAL_PERIOD_S {
            return Ok(false);
        }
        let op = Operating {
            spindle_rpm: self.spindle_rpm_s / self.elapsed_s,
            axis_speed_m_s: self.distance_m.map(|d| d / self.elapsed_s),
        };
        self.last_step = HeatStep {
            operating: op,
            mid_time_s: self.time_s + 0.5 * self.elapsed_s,
        };
        let ambient = self.last_step.step(stepper, &mut self.temps_c, thermal);
        for s in &mut self.screws {
            let watts: Vec<f64> = s.heat_j.iter().map(|j| j / self.elapsed_s).collect();
            s.model.step(&mut s.temps_c, &watts, ambient);
            s.heat_j.iter_mut().for_each(|j| *j = 0.0);
        }
        self.time_s += self.elapsed_s;
        self.elapsed_s = 0.0;
        self.distance_m = [0.0; 3];
        self.spindle_rpm_s = 0.0;
        self.deformation = self.deform(machine)?;
        Ok(true)
    }
}

/// What drives one step of the thermal network: the period's mean operating point and the
/// middle of the period, at which the ambient is taken.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct HeatStep {
    operating: Operating,
    mid_time_s: f64,
}

impl HeatStep {
    /// The network of `thermal` discretised for the job's thermal period, and its start
    /// temperatures.
    pub(crate) fn start(
        thermal: &vmt_model::machine::ThermalMachine,
    ) -> Result<(ThermalStepper, Vec<f64>), SimError> {
        let stepper = thermal
            .network
            .discretize(THERMAL_PERIOD_S)
            .map_err(|e| SimError::Thermal(e.to_string()))?;
        Ok((stepper, thermal.network.initial_temperatures()))
    }

    /// Steps the network of `thermal` (discretised in `stepper`) from `temps_c`; returns the
    /// ambient temperature used.
    pub(crate) fn step(
        &self,
        stepper: &ThermalStepper,
        temps_c: &mut [f64],
        thermal: &vmt_model::machine::ThermalMachine,
    ) -> f64 {
        let heat = thermal.network.heat_input_w(&self.operating);
        let ambient = thermal.network.ambient().celsius_at(self.mid_time_s);
        stepper.step(temps_c, &heat, ambient);
        ambient
    }
}

/// In-position width at the end of a program, m: every axis' following error within it.
pub const IN_POSITION_M: f64 = 1e-6;

/// The longest the controller waits for the axes to be in position after the program's last
/// setpoint, s (an axis held off by friction, or hunting about its encoder count, ends there).
pub const SETTLE_LIMIT_S: f64 = 1.0;

/// The setpoint of servo tick `k`: the interpolator's, and after its end the last one held at
/// rest (no block: no instrument records) until the axes are in position after a logged tick
/// (every `log_every`-th, so that the log's last row is in position) or [`SETTLE_LIMIT_S`] has
/// passed; `None` then.
fn setpoint_or_settle(
    ipo: &Interpolator,
    k: usize,
    cursor: &mut Cursor,
    last: &mut Option<Setpoint>,
    plant: &dyn Plant,
    log_every: usize,
) -> Option<Setpoint> {
    if let Some(sp) = ipo.setpoint_from(k, cursor) {
        *last = Some(sp);
        return Some(sp);
    }
    let held = (*last)?;
    let period = ipo.servo_period_s();
    let waited = (k + 1 - ipo.servo_ticks()) as f64 * period;
    let in_position = (k - 1).is_multiple_of(log_every)
        && plant
            .following_errors()
            .iter()
            .all(|e| e.abs() <= IN_POSITION_M);
    (!in_position && waited <= SETTLE_LIMIT_S + 0.5 * period).then(|| Setpoint {
        time_s: k as f64 * period,
        velocity: Vector3::zeros(),
        acceleration: Vector3::zeros(),
        block: None,
        ..held
    })
}

pub(crate) const SERVO_CHANNELS: [(&str, &str); 8] = [
    ("command", "m"),
    ("position", "m"),
    ("encoder", "m"),
    ("following_error", "m"),
    ("motor_force", "N"),
    ("motor_current", "A"),
    ("guide_friction", "N"),
    ("screw_friction", "N"),
];

/// One empty channel per axis for each of [`SERVO_CHANNELS`] (`command_x`, `command_y`,
/// `command_z`, `position_x`, ...), room for `rows`.
pub(crate) fn servo_channels(rows: usize) -> Vec<Channel> {
    SERVO_CHANNELS
        .iter()
        .flat_map(|(name, unit)| {
            ["x", "y", "z"].map(|a| Channel {
                name: format!("{name}_{a}"),
                unit: (*unit).into(),
                values: Vec::with_capacity(rows),
            })
        })
        .collect()
}

/// Appends to `channels` (the first ones as [`servo_channels`] orders them) the values of
/// [`SERVO_CHANNELS`] of axis `i` of `plant`, whose carriages are `carriages`, commanded to
/// `command_m` (the axis coordinate, m).
pub(crate) fn push_servo_row(
    channels: &mut [Channel],
    plant: &dyn Plant,
    carriages: &[CarriageState; 3],
    i: usize,
    command_m: f64,
) {
    let d = plant.drive(i);
    let (_, encoder) = d.feedback(carriages[i].position_m);
    let values = [
        command_m,
        carriages[i].position_m,
        encoder,
        d.following_error_m(),
        d.motor_force_n,
        d.params().current_a(d.motor_force_n),
        carriages[i].friction_force_n,
        d.screw_friction_force_n,
    ];
    for (c, v) in values.into_iter().enumerate() {
        channels[c * 3 + i].values.push(v);
    }
}

/// Servo rows a run with a [`LogSink`] holds before it hands them on: small enough that a
/// long job's log is never in memory whole, large enough to cost nothing per row.
const LOG_BLOCK_ROWS: usize = 8192;

/// Collects the streams and traces of a run.
struct Recorder {
    log_every: usize,
    bar_every: usize,
    /// The `servo` stream: rows since the last block handed to a sink (all rows without one).
    servo: Stream,
    /// The `structure` stream of a compliant plant (its carriages' motions and block forces),
    /// at the servo log's instants.
    structure: Option<Stream>,
    /// Per trace, the samples handed to a sink so far.
    sent: Vec<usize>,
    /// One bar per circular test.
    ballbar: Vec<Ballbar>,
    /// Test (index in `ballbar`) and program blocks of each trace's data arc.
    data: Vec<(usize, Range<usize>)>,
    /// The normal of each test's plane.
    normals: Vec<Vector3<f64>>,
    traces: Vec<BallbarTrace>,
    /// Per trace, the drift of its start point (see [`Closing`]).
    closing: Vec<Option<Closing>>,
    /// Per trace, what the carriages' deflections on their blocks add to the bar's length.
    dynamic: Vec<Spread>,
    /// The trace being recorded.
    active: Option<usize>,
    laser: Option<Laser>,
}

/// What a trace's closing error is made of: the tool point at the commanded start of the trace
/// then and at its end (thermal drift of the machine), the creep of the axis standing along the
/// plane's normal (its carriage's position less its command, at the first and last reading),
/// the pivot's creep, along the bar.
#[derive(Clone, Copy, Debug)]
struct Closing {
    commanded: AxisState,
    tool_start: Vector3<f64>,
    tool_end: Vector3<f64>,
    drive_start: Vector3<f64>,
    drive_end: Vector3<f64>,
    normal: Vector3<f64>,
    pivot_start: Vector3<f64>,
    pivot_end: Vector3<f64>,
    unit: Vector3<f64>,
}

impl Closing {
    /// Closing error: change of the bar length at the start point over the trace, µm.
    fn error_um(&self) -> f64 {
        let standing = self.normal * self.normal.dot(&(self.drive_end - self.drive_start));
        ((self.tool_end - self.tool_start) + standing - (self.pivot_end - self.pivot_start))
            .dot(&self.unit)
            * 1e6
    }
}

impl Recorder {
    /// `block_times` as [`Interpolator::block_times`] gives them; `ticks` servo ticks of the
    /// program to come (the log is allocated at once for them and the longest wait for the axes
    /// to settle after them, [`SETTLE_LIMIT_S`], so that it never grows by doubling at the end; or
    /// for one block when `blocks`).
    fn new(
        job: &Job,
        structure: Option<&Structure>,
        settings: &SimSettings,
        period: f64,
        block_times: &[(usize, f64, f64)],
        ticks: usize,
        blocks: bool,
    ) -> Self {
        let every = |rate_hz: f64| ((1.0 / rate_hz) / period).round().max(1.0) as usize;
        let log_every = every(settings.log_rate_hz);
        let bar_every = job
            .ballbar
            .first()
            .map_or(usize::MAX, |b| every(b.spec.sample_rate_hz));
        // Test i's bar draws from seed + i: the first (or only) test keeps the run's seed.
        let ballbar = job
            .ballbar
            .iter()
            .enumerate()
            .map(|(i, b)| test_bar(b, i, settings))
            .collect();
        let traces: Vec<BallbarTrace> = job_traces(job).into_iter().map(|(_, t)| t).collect();
        let data = job
            .ballbar
            .iter()
            .enumerate()
            .flat_map(|(i, b)| b.data.iter().map(move |(_, r)| (i, r.clone())))
            .collect();
        // The laser's noise has its own stream ("laser" in ASCII added to the seed).
        let laser = job.laser.as_ref().map(|l| {
            let seed = settings.seed.wrapping_add(0x006c_6173_6572);
            Laser::new(l, block_times, period, seed)
        });
        let settle = (SETTLE_LIMIT_S / period).ceil() as usize + 1;
        let logged = (ticks + settle).div_ceil(log_every);
        let rows = if blocks {
            logged.min(LOG_BLOCK_ROWS)
        } else {
            logged
        };
        Self {
            log_every,
            bar_every,
            servo: servo_stream(rows),
            structure: structure.map(|s| structure_stream(s, rows)),
            sent: vec![0; traces.len()],
            ballbar,
            data,
            normals: job.ballbar.iter().map(|b| b.plane.normal()).collect(),
            closing: vec![None; traces.len()],
            dynamic: vec![Spread::default(); traces.len()],
            active: None,
            traces,
            laser,
        }
    }

    /// Ends the closing record of the active trace with the machine's present thermal state.
    fn end_closing(&mut self, evaluator: &VolumetricEvaluator) {
        if let Some(c) = self.active.and_then(|j| self.closing[j].as_mut()) {
            c.tool_end = evaluator.tool_point(&c.commanded);
        }
    }

    fn record(
        &mut self,
        k: usize,
        sp: &Setpoint,
        plant: &dyn Plant,
        state: &AxisState,
        machine: &Machine,
        evaluator: &VolumetricEvaluator,
    ) -> Result<Option<usize>, SimError> {
        let log = k.is_multiple_of(self.log_every);
        let bar = !self.ballbar.is_empty() && k.is_multiple_of(self.bar_every);
        let laser = self
            .laser
            .as_ref()
            .and_then(|l| l.window_at(k, sp.time_s, sp.block));
        if !log && !bar && laser.is_none() {
            return Ok(None);
        }
        let tool = match plant.deflections() {
            Some(d) => evaluator.tool_point_deflected(state, &d),
            None => evaluator.tool_point(state),
        };
        if let (Some(l), Some(i)) = (&mut self.laser, laser) {
            // The error chain alone: the tool point at the commanded axis positions.
            let commanded = AxisState {
                position: sp.position - machine.volumetric.kinematics.tool_offset,
                direction: state.direction,
            };
            let a = l.axis().index();
            let (carriage, d) = (plant.carriages()[a], plant.drive(a));
            // What the drive positions: the nut (the motor through the screw's lead, its
            // cyclic error included) in semi-closed loop, the carriage on a linear scale.
            let driven = match d.params().feedback {
                Feedback::MotorEncoder => d.params().screw.nut(d.motor_position_m, 0.0).0,
                Feedback::LinearScale { .. } => carriage.position_m,
            };
            let drive = DriveSample {
                holding_n: carriage.friction_force_n,
                servo_residual_m: driven - commanded.position[a],
            };
            l.sample(
                i,
                sp.time_s,
                &tool,
                &evaluator.tool_point(&commanded),
                drive,
            );
        }
        if log {
            self.servo.times_s.push(sp.time_s);
            let carriages = plant.carriages();
            for i in 0..3 {
                let command = sp.position[i] - machine.volumetric.kinematics.tool_offset[i];
                push_servo_row(&mut self.servo.channels, plant, &carriages, i, command);
                self.servo.channels[SERVO_CHANNELS.len() * 3 + i]
                    .values
                    .push(tool[i]);
            }
            if let (Some(st), Some(m)) = (self.structure.as_mut(), plant.carriage_motions()) {
                st.times_s.push(sp.time_s);
                let values = m
                    .iter()
                    .flat_map(|(t, th)| th.iter().chain(t.iter()).copied().collect::<Vec<_>>())
                    .chain(plant.block_normal_forces());
                for (c, v) in st.channels.iter_mut().zip(values) {
                    c.values.push(v);
                }
            }
        }
        if bar
            && let Some(block) = sp.block
            && let Some(j) = self.data.iter().position(|(_, r)| r.contains(&block))
        {
            if self.active != Some(j) {
                self.end_closing(evaluator);
                self.active = Some(j);
            }
            let bar = &mut self.ballbar[self.data[j].0];
            let (reading, angle) = bar.read(&tool, sp.time_s);
            check_range(bar, &self.traces[j], sp.time_s, reading, angle)?;
            let pivot = bar.pivot(sp.time_s);
            if plant.deflections().is_some() {
                // What the deflections add along the bar: the tool point less the rigid one.
                let along = (tool - evaluator.tool_point(state)).dot(&(tool - pivot).normalize());
                self.dynamic[j].add(along * 1e6);
            }
            let commanded = AxisState {
                position: sp.position - machine.volumetric.kinematics.tool_offset,
                direction: state.direction,
            };
            let drive = state.position - commanded.position;
            match &mut self.closing[j] {
                Some(c) => (c.pivot_end, c.drive_end) = (pivot, drive),
                slot @ None => {
                    let start = evaluator.tool_point(&commanded);
                    *slot = Some(Closing {
                        commanded,
                        tool_start: start,
                        tool_end: start,
                        drive_start: drive,
                        drive_end: drive,
                        normal: self.normals[self.data[j].0],
                        pivot_start: pivot,
                        pivot_end: pivot,
                        unit: (tool - pivot).normalize(),
                    });
                }
            }
            push_sample(&mut self.traces[j], sp.time_s, angle, reading);
            return Ok(Some(j));
        }
        Ok(None)
    }

    /// The run as it starts: the `servo` stream's channels with no rows, the traces with no
    /// samples, the laser test with no readings, no ground truth.
    fn opening(&self, machine: &Machine, settings: &SimSettings, scenario_toml: &str) -> Run {
        Run {
            scenario_name: machine.name.clone(),
            scenario_toml: scenario_toml.to_string(),
            seed: settings.seed,
            fidelity: settings.fidelity.name().into(),
            machine: summary(machine),
            streams: std::iter::once(servo_stream(0))
                .chain(self.structure.as_ref().map(empty_like))
                .collect(),
            ballbar: self.traces.iter().map(|t| t.samples(0..0)).collect(),
            laser: self.laser.as_ref().map(Laser::header),
            ground_truth: serde_json::Value::Null,
        }
    }

    /// Hands the rows and trace samples recorded since the last block to `sink` once there
    /// are `min_rows` servo rows or more, and forgets the rows.
    fn send(&mut self, sink: &mut dyn LogSink, min_rows: usize) -> Result<(), SimError> {
        if self.servo.times_s.len() < min_rows {
            return Ok(());
        }
        let new_samples: Vec<Range<usize>> = self
            .sent
            .iter()
            .zip(&self.traces)
            .map(|(&from, t)| from..t.times_s.len())
            .collect();
        let empty = empty_like(&self.servo);
        let streams: Vec<Stream> = std::iter::once(std::mem::replace(&mut self.servo, empty))
            .chain(self.structure.as_mut().map(|s| {
                let empty = empty_like(s);
                std::mem::replace(s, empty)
            }))
            .collect();
        sink.block(&LogBlock {
            streams: &streams,
            ballbar: &self.traces,
            new_samples: &new_samples,
        })
        .map_err(SimError::Log)?;
        let mut streams = streams.into_iter();
        if let Some(s) = streams.next() {
            self.servo = cleared(s);
        }
        if let (Some(slot), Some(s)) = (self.structure.as_mut(), streams.next()) {
            *slot = cleared(s);
        }
        for (sent, r) in self.sent.iter_mut().zip(new_samples) {
            *sent = r.end;
        }
        Ok(())
    }

    fn finish(
        self,
        truth: &TruthInputs,
        settings: &SimSettings,
        scenario_toml: &str,
    ) -> Result<Run, SimError> {
        let opening = self.opening(truth.machine, settings, scenario_toml);
        let laser = self
            .laser
            .map(Laser::finish)
            .transpose()
            .map_err(SimError::Settings)?;
        let closing: Vec<Option<f64>> = self
            .closing
            .iter()
            .map(|c| c.map(|c| c.error_um()))
            .collect();
        let mut ground_truth = crate::truth::ground_truth(truth, &closing, laser.as_ref());
        if self.structure.is_some()
            && let Some(o) = ground_truth.as_object_mut()
        {
            let traces: Vec<serde_json::Value> = self
                .traces
                .iter()
                .zip(&self.dynamic)
                .map(|(t, d)| d.json(&t.label))
                .collect();
            o.insert(
                "structure_dynamics".into(),
                serde_json::json!({
                    "description": "the dynamic part of the axes' errors, kept apart from the geometric ones: what the carriages' deflections on their guide blocks (tilts and offsets under gravity, inertial, drive and process forces) add to each trace's bar length, µm",
                    "traces": traces,
                }),
            );
        }
        Ok(Run {
            ground_truth,
            laser: laser.map(|(run, _)| run),
            streams: std::iter::once(self.servo).chain(self.structure).collect(),
            ballbar: self.traces,
            ..opening
        })
    }
}

/// Mean, extremes and root mean square of a series of values.
#[derive(Clone, Copy, Debug)]
struct Spread {
    n: usize,
    sum: f64,
    sum_sq: f64,
    lo: f64,
    hi: f64,
}

impl Default for Spread {
    fn default() -> Self {
        Self {
            n: 0,
            sum: 0.0,
            sum_sq: 0.0,
            lo: f64::INFINITY,
            hi: f64::NEG_INFINITY,
        }
    }
}

impl Spread {
    fn add(&mut self, x: f64) {
        self.n += 1;
        self.sum += x;
        self.sum_sq += x * x;
        self.lo = self.lo.min(x);
        self.hi = self.hi.max(x);
    }

    /// The trace `label`'s figures (its values in µm) as JSON.
    fn json(&self, label: &str) -> serde_json::Value {
        let n = self.n.max(1) as f64;
        let mean = self.sum / n;
        serde_json::json!({
            "label": label,
            "mean_um": mean,
            "peak_to_valley_um": if self.n > 0 { self.hi - self.lo } else { 0.0 },
            "rms_about_mean_um": (self.sum_sq / n - mean * mean).max(0.0).sqrt(),
        })
    }
}

/// A stream with `s`'s name, description and channels but no rows.
fn empty_like(s: &Stream) -> Stream {
    Stream {
        name: s.name.clone(),
        description: s.description.clone(),
        times_s: Vec::new(),
        channels: s
            .channels
            .iter()
            .map(|c| Channel {
                name: c.name.clone(),
                unit: c.unit.clone(),
                values: Vec::new(),
            })
            .collect(),
    }
}

/// `s` with its rows removed, its room kept.
fn cleared(mut s: Stream) -> Stream {
    s.times_s.clear();
    for c in &mut s.channels {
        c.values.clear();
    }
    s
}

/// The `structure` stream of a compliant plant with no rows, room for `rows`: for each carriage
/// `a` of X, Y, Z its rotation about its blocks' centroid `tilt_a_x`, `tilt_a_y`, `tilt_a_z`
/// (rad) and its translation across its axis `offset_a_x`, … (m), then each block's force on
/// its carriage along the block's normal, `block_a_k` (N).
fn structure_stream(structure: &Structure, rows: usize) -> Stream {
    let ch = |name: String, unit: &str| Channel {
        name,
        unit: unit.into(),
        values: Vec::with_capacity(rows),
    };
    let axes = ["x", "y", "z"];
    let motions = axes.iter().flat_map(|a| {
        let tilt = axes.map(|c| ch(format!("tilt_{a}_{c}"), "rad"));
        let offset = axes.map(|c| ch(format!("offset_{a}_{c}"), "m"));
        tilt.into_iter().chain(offset)
    });
    let blocks = structure
        .carriages
        .iter()
        .zip(axes)
        .flat_map(|(c, a)| (0..c.blocks.len()).map(move |k| ch(format!("block_{a}_{k}"), "N")));
    Stream {
        name: "structure".into(),
        description: "the carriages on their guide blocks: rotation about the blocks' centroid (rad) and translation across the axis (m) of each, and each block's normal force on its carriage (N)".into(),
        times_s: Vec::with_capacity(rows),
        channels: motions.chain(blocks).collect(),
    }
}

/// The `servo` stream with no rows, room for `rows`: for each of [`SERVO_CHANNELS`] one channel
/// per axis, then the tool point.
fn servo_stream(rows: usize) -> Stream {
    let tool = ["x", "y", "z"].map(|a| Channel {
        name: format!("tool_{a}"),
        unit: "m".into(),
        values: Vec::with_capacity(rows),
    });
    Stream {
        name: "servo".into(),
        description: "axis commands, carriage positions, encoders, following errors, motor forces and currents, friction forces, tool point".into(),
        times_s: Vec::with_capacity(rows),
        channels: servo_channels(rows).into_iter().chain(tool).collect(),
    }
}

/// Appends a bar reading (m) at `angle` (rad, wrapped) to a trace, the angle unwrapped onto the
/// trace's previous sample.
pub(crate) fn push_sample(t: &mut BallbarTrace, time_s: f64, angle: f64, reading: f64) {
    let mut deg = angle.to_degrees();
    if let Some(last) = t.angle_deg.last() {
        deg += 360.0 * ((last - deg) / 360.0).round();
    }
    t.times_s.push(time_s);
    t.angle_deg.push(deg);
    t.deviation_um.push(reading * 1e6);
}

/// The empty traces of a job's circular tests, in the order they run, and the test of each.
pub(crate) fn job_traces(job: &Job) -> Vec<(usize, BallbarTrace)> {
    job.ballbar
        .iter()
        .enumerate()
        .flat_map(|(i, b)| b.data.iter().map(move |(d, _)| (i, new_trace(b, *d))))
        .collect()
}

/// Test `i`'s bar, drawing its noise from the run's seed plus `i`.
pub(crate) fn test_bar(b: &BallbarSetup, i: usize, settings: &SimSettings) -> Ballbar {
    Ballbar::new(
        b.spec,
        b.center,
        b.radius_m,
        b.plane,
        settings.seed.wrapping_add(i as u64),
    )
}

fn new_trace(b: &BallbarSetup, d: ArcDirection) -> BallbarTrace {
    let plane = match b.plane {
        Plane::Xy => "XY",
        Plane::Zx => "ZX",
        Plane::Yz => "YZ",
    };
    let dir = match d {
        ArcDirection::Cw => "cw",
        ArcDirection::Ccw => "ccw",
    };
    let prefix = b.name.as_ref().map_or(String::new(), |n| format!("{n}: "));
    BallbarTrace {
        label: format!(
            "{prefix}{plane} {:.0} mm {:.0} mm/min {}",
            b.radius_m * 1e3,
            b.feed_m_s * 60_000.0,
            dir.to_uppercase()
        ),
        plane: plane.into(),
        direction: dir.into(),
        radius_mm: b.radius_m * 1e3,
        feed_mm_min: b.feed_m_s * 60_000.0,
        times_s: Vec::new(),
        angle_deg: Vec::new(),
        deviation_um: Vec::new(),
    }
}

/// The machine as viewers draw it.
pub fn summary(machine: &Machine) -> MachineSummary {
    MachineSummary {
        name: machine.name.clone(),
        topology: machine.volumetric.kinematics.topology.to_string(),
        strokes_m: machine.axes.map(|a| [a.min_m, a.max_m]),
        tool_length_m: -machine.volumetric.kinematics.tool_offset.z,
    }
}
