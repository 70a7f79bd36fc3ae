//! From the parsed TOML to the model's types, checking every value.
//!
//! Checks return [`Invalid`] with the key path; the caller turns the path into file, line and
//! column. Accepted ranges are physical (masses and capacities positive, tables increasing) or
//! the validity range of the small-error model (translations up to 1 mm, angles up to 10 mrad).

use crate::error::{Invalid, KeyPath, ScenarioError};
use crate::schema::*;
use crate::table;
use nalgebra::Vector3;
use std::collections::BTreeMap;
use std::path::Path;
use vmt_model::Axis;
use vmt_model::geometric::{
    AxisErrors, Component, Directional, ErrorFunction, GeometricErrors, Interpolation,
    LegendreSeries, SquarenessError, SquarenessValue,
};
use vmt_model::kinematics::{Kinematics, Topology, VolumetricModel};
use vmt_model::machine::{AxisSpec, Machine, ThermalMachine};
use vmt_model::thermal::{
    Ambient, Conductance, HeatSource, NODE_TEMPERATURE_RANGE_C, Operating, Segment, ThermalNetwork,
    ThermalNode, ThermalSchedule,
};
use vmt_model::thermal_deformation::{
    AxisExpansion, JointThermalModel, LinkThermalModel, NodeSensitivity, ThermalDeformationModel,
};

/// Largest geometric translation error accepted, µm (the small-error model's range).
pub const MAX_TRANSLATION_UM: f64 = 1000.0;
/// Largest geometric angular error accepted, µrad.
pub const MAX_ANGLE_URAD: f64 = 10_000.0;

/// A thermal run: the operating schedule and the integration step.
#[derive(Clone, Debug)]
pub struct ThermalRunSpec {
    /// What the machine does over time.
    pub schedule: ThermalSchedule,
    /// Fixed step of the exact-discretisation integrator, s.
    pub step_s: f64,
}

/// What is needed to execute the scenario's job in time.
#[derive(Clone, Debug)]
pub struct Execution {
    /// Drive and servo of X, Y, Z.
    pub axes: [vmt_sim::simulate::AxisDynamics; 3],
    /// Interpolator and servo timing.
    pub controller: vmt_sim::interpolator::InterpolatorConfig,
    /// Fidelity, substeps, log rate, seed.
    pub settings: vmt_sim::simulate::SimSettings,
    /// The job.
    pub job: vmt_sim::simulate::Job,
    /// The NC program's file of a `kind = "program"` or `"milling"` job, so that errors about
    /// a block can name the file as well as the line.
    pub program_file: Option<String>,
    /// The cut of a `kind = "milling"` job.
    pub milling: Option<vmt_sim::machining::MillingJob>,
    /// What is to be said when the job runs: a servo loop that is unstable or lightly damped
    /// (run, not refused), what the job accepts but will not do (an instrument with nothing to
    /// record).
    pub notes: Vec<String>,
}

impl Execution {
    /// Runs the job on `machine` with these drives, controller and settings
    /// ([`vmt_sim::simulate::simulate`]); `text` is the scenario document, kept in the run.
    pub fn simulate(
        &self,
        machine: &Machine,
        text: &str,
        progress: &mut dyn FnMut(f64),
    ) -> std::result::Result<vmt_sim::run::Run, vmt_sim::simulate::SimError> {
        vmt_sim::simulate::simulate(
            machine,
            &self.axes,
            &self.controller,
            &self.job,
            &self.settings,
            text,
            progress,
        )
    }
}

/// A loaded scenario.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// The machine.
    pub machine: Machine,
    /// The thermal run, if the scenario has one.
    pub thermal_run: Option<ThermalRunSpec>,
    /// Drives, controller and job, if the scenario has them all.
    pub execution: Option<Execution>,
}

/// A failure while building: in this document (located by key) or in another file.
pub enum BuildError {
    /// A value of the scenario document.
    Invalid(Invalid),
    /// A referenced file (already located).
    External(ScenarioError),
}

impl From<Invalid> for BuildError {
    fn from(e: Invalid) -> Self {
        BuildError::Invalid(e)
    }
}

type Result<T> = std::result::Result<T, BuildError>;

/// Builds the scenario; `base_dir` resolves table files (`None`: files are not allowed).
pub fn scenario(raw: ScenarioFile, base_dir: Option<&Path>) -> Result<Scenario> {
    let machine = machine(&raw.machine, base_dir)?;
    let thermal_run = match &raw.thermal_run {
        None => None,
        Some(run) => {
            if machine.thermal.is_none() {
                let msg = "a thermal run needs a thermal model: add [machine.thermal]";
                return Err(Invalid::new(KeyPath::of(&["thermal_run"]), msg).into());
            }
            Some(thermal_run(run)?)
        }
    };
    let execution = execution(&raw, &machine, base_dir)?;
    Ok(Scenario {
        machine,
        thermal_run,
        execution,
    })
}

/// A located error in a file other than the scenario.
pub fn external(file: &str, position: Option<(usize, usize)>, message: String) -> BuildError {
    BuildError::External(ScenarioError {
        file: file.to_string(),
        position,
        key: None,
        message,
    })
}

fn execution(
    raw: &ScenarioFile,
    machine: &Machine,
    base_dir: Option<&Path>,
) -> Result<Option<Execution>> {
    use crate::dynamics;
    let a = &raw.machine.axes;
    let moving = machine.axes.map(|s| s.moving_mass_kg);
    let axes = dynamics::axes(
        [
            (&a.x.drive, &a.x.servo),
            (&a.y.drive, &a.y.servo),
            (&a.z.drive, &a.z.servo),
        ],
        moving,
    )?;
    let (Some(axes), Some(c), Some(job)) = (axes, &raw.controller, &raw.job) else {
        return Ok(None);
    };
    let (controller, substeps) = dynamics::controller(c)?;
    // A step beyond a drive's stability limit is refused here, where the error can name the
    // file and line of the key as well as the largest stable step.
    vmt_sim::simulate::check_step(&axes, controller.servo_period_s, substeps).map_err(|e| {
        Invalid::new(
            KeyPath::of(&["controller", "plant_substeps"]),
            e.to_string(),
        )
    })?;
    // After the step and the loops, in the order the run checks them.
    let default = dynamics::SimulationToml {
        fidelity: "reduced".into(),
        seed: 0,
        log_rate_hz: None,
    };
    let settings = dynamics::simulation(
        raw.simulation.as_ref().unwrap_or(&default),
        substeps,
        controller.servo_period_s,
    )?;
    let program_file = match (job, base_dir) {
        (dynamics::JobToml::Program { program }, Some(dir)) => {
            Some(dir.join(program).display().to_string())
        }
        (dynamics::JobToml::Milling(m), Some(dir)) => {
            Some(dir.join(&m.program).display().to_string())
        }
        _ => None,
    };
    let milling = match job {
        dynamics::JobToml::Milling(m) => Some(crate::milling::milling_job(
            m,
            &raw.tools,
            raw.instruments.accelerometer.as_ref(),
            settings.seed,
        )?),
        _ => None,
    };
    let job_kind = job;
    let job = dynamics::job(job, &raw.instruments, machine, base_dir)?;
    if let (Some(m), Some(file)) = (&milling, &program_file) {
        check_program_cut(m, &job.program, file)?;
    }
    check_test_rates(&job, job_kind, &controller, program_file.as_deref())?;
    check_generated_travel(machine, &controller, &job, job_kind)?;
    // An unstable or lightly damped servo loop is run, not refused (a machine tuned so rings):
    // said before the run.
    let mut notes: Vec<String> =
        vmt_sim::simulate::servo_warnings(&axes, controller.servo_period_s)
            .into_iter()
            .map(|(axis, w)| {
                let key = format!(
                    "machine.axes.{}.servo.velocity_bandwidth_hz",
                    axis.to_string().to_lowercase()
                );
                format!("key `{key}`: {w}")
            })
            .collect();
    notes.extend(dynamics::instrument_notes(job_kind, &raw.instruments, &job));
    Ok(Some(Execution {
        axes,
        controller,
        settings,
        job,
        program_file,
        milling,
        notes,
    }))
}

/// A test's feed and its instruments' sample rates within what the controller can give:
/// a controller clamps a programmed feed to its maximum, so a ball-bar or positioning test
/// above it would run slower than the feed it is labelled (and diagnosed) with; a ball bar and
/// a laser are sampled at servo ticks, so they cannot be sampled faster than the servo rate,
/// and a laser's averaging window must hold at least one of its samples.
fn check_test_rates(
    job: &vmt_sim::simulate::Job,
    kind: &crate::dynamics::JobToml,
    controller: &vmt_sim::interpolator::InterpolatorConfig,
    program_file: Option<&str>,
) -> Result<()> {
    // Back in the units of the keys, rounded off the m/s conversion.
    let max_mm_min = user(controller.limits.max_feed_m_s * 60_000.0);
    let feed_key = match kind {
        crate::dynamics::JobToml::KwonSevenStep { .. } => KeyPath::of(&["job", "steps"]),
        _ => KeyPath::of(&["job", "feed_mm_min"]),
    };
    // A program's circle has its feed on the line of its first data arc.
    let refuse = |b: Option<&vmt_sim::simulate::BallbarSetup>, msg: String| -> BuildError {
        let block = b.and_then(|b| b.data.first()).map(|(_, r)| r.start);
        match (program_file, block) {
            (Some(file), Some(k)) => {
                let span = job.program.blocks[k].span;
                external(file, Some((span.line, span.column)), msg)
            }
            _ => Invalid::new(feed_key.clone(), msg).into(),
        }
    };
    let feeds = job.ballbar.iter().map(|b| (Some(b), b.feed_m_s));
    for (b, feed) in feeds.chain(job.laser.iter().map(|l| (None, l.test.feed_m_s))) {
        let mm_min = user(feed * 60_000.0);
        if mm_min > max_mm_min {
            let msg = format!(
                "a test feed of {mm_min} mm/min is not accepted: the controller's largest feed is {max_mm_min} mm/min (controller.max_feed_mm_min), to which it would clamp the test"
            );
            return Err(refuse(b, msg));
        }
    }
    // On its circle the interpolator also slows a test down to what the plane's axes allow
    // (velocity, and the centripetal acceleration v²/r).
    for b in &job.ballbar {
        let (p, q) = b.plane.axes();
        let radius = b.tool_circle().1;
        let limit = vmt_sim::interpolator::feed_limits::circle_speed_limit(
            &controller.limits,
            [p.index(), q.index()],
            radius,
        );
        let (mm_min, limit_mm_min) = (user(b.feed_m_s * 60_000.0), user(limit * 60_000.0));
        if mm_min > limit_mm_min {
            let msg = format!(
                "a test feed of {mm_min} mm/min is not accepted on a circle of {} mm: the controller runs it at most at {limit_mm_min:.1} mm/min (the plane axes' velocity, controller.rapid_mm_min, and acceleration, controller.axis_accel_m_s2, with v²/r at 90 % of it)",
                user(radius * 1e3)
            );
            return Err(refuse(Some(b), msg));
        }
    }
    // Compared exactly, as the run compares them (with its 1e-9 tolerance); rounded only in
    // the message.
    let exact_servo_hz = 1.0 / controller.servo_period_s;
    let above_servo = |rate: f64| rate > exact_servo_hz * (1.0 + 1e-9);
    let servo_hz = user(exact_servo_hz);
    for b in &job.ballbar {
        let rate = b.spec.sample_rate_hz;
        let msg = if above_servo(rate) {
            Some(format!(
                "{rate} Hz is not accepted: the ball bar is sampled at servo ticks, at most {servo_hz} Hz (1 / controller.servo_period_us)",
            ))
        } else {
            crate::dynamics::off_the_ticks(rate, controller.servo_period_s, "the ball bar")
        };
        if let Some(msg) = msg {
            let key = KeyPath::of(&["instruments", "ballbar", "sample_rate_hz"]);
            return Err(Invalid::new(key, msg).into());
        }
    }
    if let Some(l) = &job.laser {
        let laser = KeyPath::of(&["instruments", "laser"]);
        let rate = l.spec.sample_rate_hz;
        if above_servo(rate) {
            let msg = format!(
                "{} Hz is not accepted: the laser is sampled at servo ticks, at most {servo_hz} Hz (1 / controller.servo_period_us)",
                typed(rate)
            );
            return Err(Invalid::new(laser.key("sample_rate_hz"), msg).into());
        }
        if let Some(msg) =
            crate::dynamics::off_the_ticks(rate, controller.servo_period_s, "the laser")
        {
            return Err(Invalid::new(laser.key("sample_rate_hz"), msg).into());
        }
        let every = l.spec.sample_every(controller.servo_period_s);
        let exact_interval_s = every as f64 * controller.servo_period_s;
        let interval_s = user(exact_interval_s);
        if l.spec.averaging_s < exact_interval_s * (1.0 - 1e-9) {
            let msg = format!(
                "{} s is not accepted: the averaging window holds no sample; the laser samples every {interval_s} s (every {every} servo ticks at instruments.laser.sample_rate_hz = {} Hz), so at least {interval_s} s is accepted",
                typed(l.spec.averaging_s),
                typed(rate)
            );
            return Err(Invalid::new(laser.key("averaging_s"), msg).into());
        }
    }
    Ok(())
}

/// The milling program's first cutting block gives the feed per tooth F / (N·S) of the cut,
/// checked here at its line as the run would check it (0 < f_t < tool radius).
fn check_program_cut(
    m: &vmt_sim::machining::MillingJob,
    program: &vmt_sim::nc::program::Program,
    file: &str,
) -> Result<()> {
    use vmt_sim::machining::cutting_block;
    let Some((b, (feed_m_s, rpm))) = program
        .blocks
        .iter()
        .find_map(|b| cutting_block(&b.motion, b.spindle).map(|c| (b, c)))
    else {
        let msg = "the milling program has no cutting block: a G1 feed move with the spindle \
                   on clockwise (M3 S…)";
        return Err(external(file, None, msg.to_string()));
    };
    let (teeth, radius) = (m.setup.tool.teeth, m.setup.tool.diameter / 2.0);
    let ft = vmt_sim::milling::feed_per_tooth(feed_m_s, teeth, rpm);
    if ft > 0.0 && ft < radius {
        return Ok(());
    }
    let msg = format!(
        "the first cutting block's feed per tooth F / (N·S) = {} / ({teeth} × {}) = {} mm is \
         not accepted: from 0 to the tool radius {} mm",
        user(feed_m_s * 60_000.0),
        user(rpm),
        user(ft * 1e3),
        user(radius * 1e3)
    );
    Err(external(file, Some((b.span.line, b.span.column)), msg))
}

/// The program a test job generates kept within the strokes, refused at the job's keys (the
/// generated program's line numbers mean nothing to the scenario's author); a program file's
/// own job is checked when it runs, at its file's lines.
fn check_generated_travel(
    machine: &Machine,
    controller: &vmt_sim::interpolator::InterpolatorConfig,
    job: &vmt_sim::simulate::Job,
    kind: &crate::dynamics::JobToml,
) -> Result<()> {
    use crate::dynamics::JobToml;
    use vmt_sim::simulate::{SimError, check_travel};
    if matches!(kind, JobToml::Program { .. } | JobToml::Milling(_)) {
        return Ok(());
    }
    let invalid = |key: KeyPath, msg: String| -> BuildError { Invalid::new(key, msg).into() };
    match check_travel(machine, controller, job) {
        Ok(()) => Ok(()),
        Err(SimError::Stroke { axis, .. }) => {
            let job_key = |key: &str, fix| (KeyPath::of(&["job", key]), fix);
            let (key, fix) = match kind {
                JobToml::Iso230_2(t) => t.travel_key(axis),
                JobToml::KwonSevenStep { .. } => job_key("pivot_mm", "move the pivot"),
                // The default centre is the strokes' middle: only a smaller circle fits.
                JobToml::Ballbar(b) if b.center_mm.is_none() => job_key(
                    "radius_mm",
                    "shorten job.radius_mm (the circle is centred in the strokes)",
                ),
                _ => job_key("center_mm", "move the centre or shorten job.radius_mm"),
            };
            let msg = stroke_message(machine, controller, job, axis)?;
            Err(invalid(key, format!("{msg}: {fix}")))
        }
        Err(SimError::Interpolator(vmt_sim::interpolator::InterpolatorError::ProgramTooLong {
            duration_s,
            max_duration_s,
            ..
        })) => Err(invalid(
            KeyPath::of(&["job"]),
            format!(
                "the test lasts about {duration_s:.0} s, longer than the {max_duration_s:.0} s \
                 the interpolator holds: fewer targets, runs or steps, shorter dwells or a \
                 higher feed"
            ),
        )),
        Err(e) => Err(invalid(KeyPath::of(&["job"]), e.to_string())),
    }
}

/// How far a generated test takes `axis`, against its stroke.
fn stroke_message(
    machine: &Machine,
    controller: &vmt_sim::interpolator::InterpolatorConfig,
    job: &vmt_sim::simulate::Job,
    axis: vmt_model::Axis,
) -> Result<String> {
    let (lo, hi) = vmt_sim::simulate::travel_extent(machine, controller, job)
        .map_err(|e| BuildError::from(Invalid::new(KeyPath::of(&["job"]), e.to_string())))?;
    let (i, stroke) = (axis.index(), &machine.axes[axis.index()]);
    Ok(format!(
        "the test takes the {axis} axis from {:.3} to {:.3} mm, beyond its stroke {} to {} mm",
        lo[i] * 1e3,
        hi[i] * 1e3,
        typed(user(stroke.min_m * 1e3)),
        typed(user(stroke.max_m * 1e3))
    ))
}

fn machine(m: &MachineToml, base_dir: Option<&Path>) -> Result<Machine> {
    let root = KeyPath::of(&["machine"]);
    let topology: Topology =
        m.topology
            .parse()
            .map_err(|e: vmt_model::kinematics::TopologyError| {
                Invalid::new(root.key("topology"), e.to_string())
            })?;
    let axes = [
        axis_spec(&m.axes.x, &root.key("axes").key("x"))?,
        axis_spec(&m.axes.y, &root.key("axes").key("y"))?,
        axis_spec(&m.axes.z, &root.key("axes").key("z"))?,
    ];
    let mut kinematics = Kinematics::new(topology);
    kinematics.tool_offset = tool_offset(&m.tool, &root.key("tool"))?;
    let link_names = topology.link_names();
    for (name, pivot) in &m.link_pivots_mm {
        let path = root.key("link_pivots_mm").key(name);
        let k = link_index(&link_names, name, &path)?;
        kinematics.link_pivots[k] = vector_mm(pivot, &path)?;
    }
    let mut errors = match &m.errors {
        Some(e) => geometric(e, &axes, &root.key("errors"), base_dir)?,
        None => GeometricErrors::zero(),
    };
    for (axis, a) in Axis::ALL.into_iter().zip([&m.axes.x, &m.axes.y, &m.axes.z]) {
        if let Some(g) = &a.guideway {
            let p = root
                .key("axes")
                .key(&axis.to_string().to_lowercase())
                .key("guideway");
            errors.guideways[axis.index()] = Some(crate::effects::guideway(g, axis, &p)?);
        }
    }
    let thermal = match &m.thermal {
        Some(t) => Some(thermal(t, &link_names, &axes, &root.key("thermal"))?),
        None => None,
    };
    let structure = crate::structure::structure(
        [&m.axes.x, &m.axes.y, &m.axes.z].map(|a| a.carriage.as_ref()),
        &topology,
        axes.map(|a| a.moving_mass_kg),
    )?;
    Ok(Machine {
        name: m.name.clone(),
        axes,
        volumetric: VolumetricModel::new(kinematics, errors),
        thermal,
        structure,
    })
}

fn finite(v: f64, path: &KeyPath, accepted: &str) -> std::result::Result<f64, Invalid> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(Invalid::new(
            path.clone(),
            format!("{v} is not accepted; {accepted}"),
        ))
    }
}

/// A computed value rounded to six decimals for a message, as a user would write it.
fn user(x: f64) -> f64 {
    (x * 1e6).round() / 1e6
}

/// `v` as typed: 1e306, not as 307 digits.
pub(crate) fn typed(v: f64) -> String {
    if v != 0.0 && !(1e-4..1e6).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        v.to_string()
    }
}

pub(crate) fn in_range(
    v: f64,
    lo: f64,
    hi: f64,
    path: &KeyPath,
    what: &str,
) -> std::result::Result<f64, Invalid> {
    let accepted = format!("{what} from {lo} to {hi} is accepted");
    within(v, (lo..=hi).contains(&v), path, &accepted)
}

/// [`in_range`] with both ends excluded.
pub(crate) fn in_open_range(
    v: f64,
    lo: f64,
    hi: f64,
    path: &KeyPath,
    what: &str,
) -> std::result::Result<f64, Invalid> {
    let accepted = format!("{what} above {lo} and below {hi} is accepted");
    within(v, v > lo && v < hi, path, &accepted)
}

/// `v` if it is finite and `inside` its range; the errors say what is `accepted`.
fn within(
    v: f64,
    inside: bool,
    path: &KeyPath,
    accepted: &str,
) -> std::result::Result<f64, Invalid> {
    let v = finite(v, path, accepted)?;
    if inside {
        Ok(v)
    } else {
        Err(Invalid::new(
            path.clone(),
            format!("{} is out of range; {accepted}", typed(v)),
        ))
    }
}

/// A whole number (a count, a length of a list) within `lo..=hi`.
pub(crate) fn count_in_range(
    n: usize,
    lo: usize,
    hi: usize,
    path: &KeyPath,
    what: &str,
) -> std::result::Result<usize, Invalid> {
    if (lo..=hi).contains(&n) {
        Ok(n)
    } else {
        Err(Invalid::new(
            path.clone(),
            format!("{n} is out of range; {what} from {lo} to {hi} is accepted"),
        ))
    }
}

pub(crate) fn positive(
    v: f64,
    hi: f64,
    path: &KeyPath,
    what: &str,
) -> std::result::Result<f64, Invalid> {
    let v = in_range(v, 0.0, hi, path, what)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(Invalid::new(
            path.clone(),
            format!("{v} is not accepted; {what} must be > 0"),
        ))
    }
}

fn vector_mm(v: &[f64; 3], path: &KeyPath) -> std::result::Result<Vector3<f64>, Invalid> {
    let mut out = Vector3::zeros();
    for i in 0..3 {
        out[i] = in_range(
            v[i],
            -10_000.0,
            10_000.0,
            &path.index(i),
            "a coordinate in mm",
        )? * 1e-3;
    }
    Ok(out)
}

fn axis_spec(a: &AxisToml, path: &KeyPath) -> std::result::Result<AxisSpec, Invalid> {
    let p = path.key("stroke_mm");
    let lo = in_range(
        a.stroke_mm[0],
        -10_000.0,
        10_000.0,
        &p.index(0),
        "a stroke end in mm",
    )?;
    let hi = in_range(
        a.stroke_mm[1],
        -10_000.0,
        10_000.0,
        &p.index(1),
        "a stroke end in mm",
    )?;
    if lo >= hi {
        let msg = format!("[{lo}, {hi}] is not accepted; the stroke is [min, max] with min < max");
        return Err(Invalid::new(p, msg));
    }
    let mass = positive(
        a.moving_mass_kg,
        100_000.0,
        &path.key("moving_mass_kg"),
        "a mass in kg",
    )?;
    Ok(AxisSpec {
        min_m: lo * 1e-3,
        max_m: hi * 1e-3,
        moving_mass_kg: mass,
    })
}

fn tool_offset(t: &ToolToml, path: &KeyPath) -> std::result::Result<Vector3<f64>, Invalid> {
    let length = in_range(
        t.length_mm,
        0.0,
        1000.0,
        &path.key("length_mm"),
        "a tool length in mm",
    )?;
    let p = path.key("tcp_offset_mm");
    let x = in_range(
        t.tcp_offset_mm[0],
        -1000.0,
        1000.0,
        &p.index(0),
        "an offset in mm",
    )?;
    let y = in_range(
        t.tcp_offset_mm[1],
        -1000.0,
        1000.0,
        &p.index(1),
        "an offset in mm",
    )?;
    Ok(Vector3::new(x, y, -length) * 1e-3)
}

fn link_index(
    names: &[String; 5],
    name: &str,
    path: &KeyPath,
) -> std::result::Result<usize, Invalid> {
    names.iter().position(|n| n == name).ok_or_else(|| {
        Invalid::new(
            path.clone(),
            format!(
                "no link `{name}` in this topology; its links are {}",
                names.join(", ")
            ),
        )
    })
}

fn geometric(
    e: &ErrorsToml,
    axes: &[AxisSpec; 3],
    path: &KeyPath,
    base_dir: Option<&Path>,
) -> Result<GeometricErrors> {
    let mut out = GeometricErrors::zero();
    for (axis, raw) in Axis::ALL.into_iter().zip([&e.x, &e.y, &e.z]) {
        if let Some(raw) = raw {
            let spec = &axes[axis.index()];
            let p = path.key(&axis.to_string().to_lowercase());
            out.axes[axis.index()] = axis_errors(raw, axis, spec, &p, base_dir)?;
        }
    }
    for (key, value) in &e.squareness {
        let p = path.key("squareness").key(key);
        let which = SquarenessError::ALL
            .into_iter()
            .find(|s| format!("{}_urad", s.iso_name()) == *key)
            .ok_or_else(|| {
                Invalid::new(
                    p.clone(),
                    "unknown squareness; accepted keys: EC0Y_urad, EB0Z_urad, EA0Z_urad (µrad)",
                )
            })?;
        out.set_squareness(which, squareness(value, &p)?);
    }
    Ok(out)
}

fn axis_errors(
    raw: &AxisErrorsToml,
    axis: Axis,
    spec: &AxisSpec,
    path: &KeyPath,
    base_dir: Option<&Path>,
) -> Result<AxisErrors> {
    let forward = direction_errors(
        &raw.forward,
        None,
        axis,
        spec,
        &path.key("forward"),
        base_dir,
    )?;
    let backward = match &raw.backward {
        Some(b) => direction_errors(
            b,
            Some(&forward),
            axis,
            spec,
            &path.key("backward"),
            base_dir,
        )?,
        None => forward.clone(),
    };
    let mut out = AxisErrors::zero();
    for (k, c) in Component::ALL.into_iter().enumerate() {
        let functions = Directional {
            forward: forward[k].clone(),
            backward: backward[k].clone(),
        };
        out.set(c, functions);
    }
    Ok(out)
}

/// Key of a component in a scenario: ISO name and unit, e.g. `EXX_um`, `EBX_urad`.
fn component_key(c: Component, axis: Axis) -> String {
    let unit = if c.is_angular() { "urad" } else { "um" };
    format!("{}_{unit}", c.iso_name(axis))
}

/// The six functions of one direction. Components a backward set leaves out are the forward
/// ones (no backlash in them).
fn direction_errors(
    raw: &DirectionErrorsToml,
    defaults: Option<&[ErrorFunction; 6]>,
    axis: Axis,
    spec: &AxisSpec,
    path: &KeyPath,
    base_dir: Option<&Path>,
) -> Result<[ErrorFunction; 6]> {
    let interpolation = match raw.interpolation.as_deref() {
        None | Some("linear") => Interpolation::Linear,
        Some("pchip") => Interpolation::Pchip,
        Some(other) => {
            let msg =
                format!("`{other}` is not accepted; interpolation is \"linear\" or \"pchip\"");
            return Err(Invalid::new(path.key("interpolation"), msg).into());
        }
    };
    if let Some(file) = &raw.table {
        if let Some(key) = raw.legendre.keys().next() {
            let msg = "give either a table or Legendre coefficients for one direction, not both";
            return Err(Invalid::new(path.key(key), msg).into());
        }
        let Some(dir) = base_dir else {
            let msg = "the built-in scenario cannot refer to files; copy it to a file first";
            return Err(Invalid::new(path.key("table"), msg).into());
        };
        let stroke = (spec.min_m, spec.max_m);
        let key = path.key("table").to_string();
        return table::read(&dir.join(file), &key, axis, interpolation, stroke)
            .map_err(BuildError::External);
    }
    if raw.interpolation.is_some() {
        let msg = "interpolation applies to tables only; add `table = \"file.csv\"` or remove it";
        return Err(Invalid::new(path.key("interpolation"), msg).into());
    }
    let mut out: [ErrorFunction; 6] = defaults.cloned().unwrap_or_default();
    let accepted: Vec<String> = Component::ALL
        .iter()
        .map(|c| component_key(*c, axis))
        .collect();
    for (key, value) in &raw.legendre {
        let p = path.key(key);
        let k = accepted.iter().position(|a| a == key).ok_or_else(|| {
            let msg = format!(
                "unknown key; accepted: table, interpolation, or Legendre coefficients {} (µm, µrad)",
                accepted.join(", ")
            );
            Invalid::new(p.clone(), msg)
        })?;
        out[k] = legendre(value, Component::ALL[k], spec, &p)?;
    }
    Ok(out)
}

fn legendre(
    value: &toml::Value,
    c: Component,
    spec: &AxisSpec,
    path: &KeyPath,
) -> std::result::Result<ErrorFunction, Invalid> {
    let (limit, unit) = if c.is_angular() {
        (MAX_ANGLE_URAD, "µrad")
    } else {
        (MAX_TRANSLATION_UM, "µm")
    };
    let coeffs = numbers(
        value,
        path,
        "a list of Legendre coefficients [c0, c1, c2, ...]",
    )?;
    let total: f64 = coeffs.iter().map(|c| c.abs()).sum();
    if total > limit {
        let msg = format!(
            "the coefficients reach {total} {unit}; up to {limit} {unit} in sum of magnitudes is accepted (the small-error model's range)"
        );
        return Err(Invalid::new(path.clone(), msg));
    }
    let si = coeffs.iter().map(|c| c * 1e-6).collect();
    let series = LegendreSeries::new(si, spec.min_m, spec.max_m)
        .map_err(|e| Invalid::new(path.clone(), e.to_string()))?;
    Ok(ErrorFunction::Legendre(series))
}

fn numbers(
    value: &toml::Value,
    path: &KeyPath,
    what: &str,
) -> std::result::Result<Vec<f64>, Invalid> {
    let arr = value
        .as_array()
        .ok_or_else(|| Invalid::new(path.clone(), format!("expected {what}")))?;
    arr.iter()
        .enumerate()
        .map(|(i, v)| {
            let x = v.as_float().or_else(|| v.as_integer().map(|n| n as f64));
            x.filter(|x| x.is_finite()).ok_or_else(|| {
                Invalid::new(
                    path.index(i),
                    format!("`{v}` is not accepted; expected finite numbers: {what}"),
                )
            })
        })
        .collect()
}

/// A squareness value: a number, `{forward, backward}` (direction of the rotated axis) or
/// `{ff, fb, bf, bb}` (reference axis direction, then rotated axis direction).
fn squareness(
    value: &toml::Value,
    path: &KeyPath,
) -> std::result::Result<SquarenessValue, Invalid> {
    const FORMS: &str = "a number (µrad), { forward = .., backward = .. } by the direction of the rotated axis, or { ff = .., fb = .., bf = .., bb = .. } by the directions of the reference and rotated axes";
    let get = |v: &toml::Value, p: &KeyPath| -> std::result::Result<f64, Invalid> {
        let x = v.as_float().or_else(|| v.as_integer().map(|n| n as f64));
        let x = x.ok_or_else(|| Invalid::new(p.clone(), format!("expected {FORMS}")))?;
        Ok(in_range(
            x,
            -MAX_ANGLE_URAD,
            MAX_ANGLE_URAD,
            p,
            "a squareness in µrad",
        )? * 1e-6)
    };
    if let Some(table) = value.as_table() {
        let mut keys: Vec<&str> = table.keys().map(String::as_str).collect();
        keys.sort_unstable();
        let field = |k: &str| get(&table[k], &path.key(k));
        let values = match keys.as_slice() {
            ["backward", "forward"] => {
                let (f, b) = (field("forward")?, field("backward")?);
                [[f, b], [f, b]]
            }
            ["bb", "bf", "fb", "ff"] => {
                [[field("ff")?, field("fb")?], [field("bf")?, field("bb")?]]
            }
            _ => return Err(Invalid::new(path.clone(), format!("expected {FORMS}"))),
        };
        return Ok(SquarenessValue { values });
    }
    Ok(SquarenessValue::constant(get(value, path)?))
}

fn node_index(
    names: &BTreeMap<&str, usize>,
    name: &str,
    path: &KeyPath,
) -> std::result::Result<usize, Invalid> {
    names.get(name).copied().ok_or_else(|| {
        let known: Vec<&str> = names.keys().copied().collect();
        Invalid::new(
            path.clone(),
            format!(
                "no thermal node `{name}`; the nodes are {}",
                known.join(", ")
            ),
        )
    })
}

fn axis_named(name: &str, path: &KeyPath) -> std::result::Result<Axis, Invalid> {
    let mut chars = name.chars();
    match (chars.next().and_then(Axis::from_letter), chars.next()) {
        (Some(a), None) => Ok(a),
        _ => Err(Invalid::new(
            path.clone(),
            format!("`{name}` is not an axis; accepted: x, y, z"),
        )),
    }
}

fn thermal(
    t: &ThermalToml,
    link_names: &[String; 5],
    axes: &[AxisSpec; 3],
    path: &KeyPath,
) -> Result<ThermalMachine> {
    let mut names = BTreeMap::new();
    let mut nodes = Vec::new();
    for (i, n) in t.nodes.iter().enumerate() {
        let p = path.key("nodes").index(i);
        if names.insert(n.name.as_str(), i).is_some() {
            return Err(Invalid::new(
                p.key("name"),
                format!("node name `{}` is used twice; names must be unique", n.name),
            )
            .into());
        }
        nodes.push(ThermalNode {
            name: n.name.clone(),
            capacity_j_per_k: positive(
                n.capacity_j_per_k,
                1e9,
                &p.key("capacity_j_per_k"),
                "a heat capacity in J/K",
            )?,
            to_ambient_w_per_k: in_range(
                n.to_ambient_w_per_k,
                0.0,
                1e6,
                &p.key("to_ambient_w_per_k"),
                "a conductance in W/K",
            )?,
            initial_c: match n.initial_c {
                Some(c) => Some(in_range(
                    c,
                    NODE_TEMPERATURE_RANGE_C.0,
                    NODE_TEMPERATURE_RANGE_C.1,
                    &p.key("initial_c"),
                    "a temperature in °C",
                )?),
                None => None,
            },
        });
    }
    if nodes.is_empty() {
        return Err(Invalid::new(path.key("nodes"), "at least one thermal node is needed").into());
    }
    let mut conductances = Vec::new();
    for (i, c) in t.conductances.iter().enumerate() {
        let p = path.key("conductances").index(i);
        let a = node_index(&names, &c.between[0], &p.key("between").index(0))?;
        let b = node_index(&names, &c.between[1], &p.key("between").index(1))?;
        if a == b {
            return Err(
                Invalid::new(p.key("between"), "a conductance joins two different nodes").into(),
            );
        }
        let w = in_range(
            c.w_per_k,
            0.0,
            1e6,
            &p.key("w_per_k"),
            "a conductance in W/K",
        )?;
        conductances.push(Conductance { a, b, w_per_k: w });
    }
    let sources = t
        .sources
        .iter()
        .enumerate()
        .map(|(i, s)| source(s, &names, &path.key("sources").index(i)))
        .collect::<std::result::Result<Vec<_>, _>>()?;
    let ambient = ambient(&t.ambient, &path.key("ambient"))?;
    let network = ThermalNetwork::new(nodes, conductances, sources, ambient)
        .map_err(|e| Invalid::new(path.clone(), e.to_string()))?;
    let deformation = deformation(t, &names, link_names, path)?;
    let mut screws = [None; 3];
    for (name, s) in &t.screw {
        let p = path.key("screw").key(name);
        let axis = axis_named(name, &p)?;
        screws[axis.index()] = Some(crate::effects::screw(s, axis, &axes[axis.index()], &p)?);
    }
    Ok(ThermalMachine {
        network,
        deformation,
        screws,
    })
}

fn source(
    s: &SourceToml,
    names: &BTreeMap<&str, usize>,
    p: &KeyPath,
) -> std::result::Result<HeatSource, Invalid> {
    Ok(match s {
        SourceToml::Spindle {
            node,
            w_per_rpm,
            w_per_rpm2,
        } => HeatSource::Spindle {
            node: node_index(names, node, &p.key("node"))?,
            w_per_rpm: in_range(*w_per_rpm, 0.0, 100.0, &p.key("w_per_rpm"), "W/rpm")?,
            w_per_rpm2: in_range(*w_per_rpm2, 0.0, 1.0, &p.key("w_per_rpm2"), "W/rpm²")?,
        },
        SourceToml::Axis {
            node,
            axis,
            w_per_mm_s,
        } => HeatSource::Axis {
            node: node_index(names, node, &p.key("node"))?,
            axis: axis_named(axis, &p.key("axis"))?.index(),
            // W per (mm/s) to W per (m/s).
            w_per_m_per_s: in_range(*w_per_mm_s, 0.0, 1000.0, &p.key("w_per_mm_s"), "W per mm/s")?
                * 1e3,
        },
    })
}

fn ambient(a: &AmbientToml, p: &KeyPath) -> std::result::Result<Ambient, Invalid> {
    const H: f64 = 3600.0;
    Ok(match a {
        AmbientToml::Constant { temperature_c } => Ambient::Constant {
            celsius: in_range(*temperature_c, -50.0, 80.0, &p.key("temperature_c"), "°C")?,
        },
        AmbientToml::Sinusoid {
            mean_c,
            amplitude_k,
            period_h,
            phase_h,
        } => Ambient::Sinusoid {
            mean_c: in_range(*mean_c, -50.0, 80.0, &p.key("mean_c"), "°C")?,
            amplitude_k: in_range(*amplitude_k, 0.0, 50.0, &p.key("amplitude_k"), "K")?,
            period_s: positive(*period_h, 1e4, &p.key("period_h"), "a period in h")? * H,
            // Within the longest period accepted: a phase beyond it is a wrong unit.
            phase_s: in_range(*phase_h, -1e4, 1e4, &p.key("phase_h"), "a phase in h")? * H,
        },
        AmbientToml::Table { points_h_c } => {
            let pp = p.key("points_h_c");
            if points_h_c.is_empty() {
                return Err(Invalid::new(
                    pp,
                    "at least one [time_h, temperature_c] point is needed",
                ));
            }
            let mut times_s = Vec::new();
            let mut celsius = Vec::new();
            for (i, Numbers([t, c])) in points_h_c.iter().enumerate() {
                let t = finite(*t, &pp.index(i).index(0), "a time in h")?;
                if let Some(last) = times_s.last()
                    && t * H <= *last
                {
                    return Err(Invalid::new(
                        pp.index(i).index(0),
                        format!("{t} h is not accepted; times must increase strictly"),
                    ));
                }
                times_s.push(t * H);
                celsius.push(in_range(*c, -50.0, 80.0, &pp.index(i).index(1), "°C")?);
            }
            Ambient::Table { times_s, celsius }
        }
    })
}

fn sensitivities(
    map: &BTreeMap<String, Numbers<3>>,
    names: &BTreeMap<&str, usize>,
    limit: f64,
    path: &KeyPath,
) -> std::result::Result<Vec<NodeSensitivity>, Invalid> {
    map.iter()
        .map(|(node, v)| {
            let p = path.key(node);
            let node = node_index(names, node, &p)?;
            let mut per_kelvin = Vector3::zeros();
            for i in 0..3 {
                per_kelvin[i] =
                    in_range(v[i], -limit, limit, &p.index(i), "a sensitivity per K")? * 1e-6;
            }
            Ok(NodeSensitivity { node, per_kelvin })
        })
        .collect()
}

fn deformation(
    t: &ThermalToml,
    names: &BTreeMap<&str, usize>,
    link_names: &[String; 5],
    path: &KeyPath,
) -> std::result::Result<ThermalDeformationModel, Invalid> {
    let mut model = ThermalDeformationModel::default();
    for (axis_name, e) in &t.expansion {
        let p = path.key("expansion").key(axis_name);
        let axis = axis_named(axis_name, &p)?;
        model.joints[axis.index()].expansion = Some(AxisExpansion {
            node: node_index(names, &e.node, &p.key("node"))?,
            alpha_per_k: in_range(
                e.alpha_per_k,
                -1e-5,
                1e-4,
                &p.key("alpha_per_k"),
                "an expansion coefficient in 1/K",
            )?,
            reference_m: finite(e.reference_mm, &p.key("reference_mm"), "a position in mm")? * 1e-3,
        });
    }
    for (name, s) in &t.links {
        let p = path.key("links").key(name);
        let k = link_index(link_names, name, &p)?;
        model.links[k] = LinkThermalModel {
            translation: sensitivities(
                &s.translation_um_per_k,
                names,
                1000.0,
                &p.key("translation_um_per_k"),
            )?,
            rotation: sensitivities(
                &s.rotation_urad_per_k,
                names,
                1000.0,
                &p.key("rotation_urad_per_k"),
            )?,
        };
    }
    for (axis_name, s) in &t.joints {
        let p = path.key("joints").key(axis_name);
        let axis = axis_named(axis_name, &p)?;
        if !s.translation_um_per_k.is_empty() {
            let msg = "joints take rotation_urad_per_k only; the axis' growth is [machine.thermal.expansion]";
            return Err(Invalid::new(p.key("translation_um_per_k"), msg));
        }
        let joint: &mut JointThermalModel = &mut model.joints[axis.index()];
        joint.rotation = sensitivities(
            &s.rotation_urad_per_k,
            names,
            1000.0,
            &p.key("rotation_urad_per_k"),
        )?;
    }
    Ok(model)
}

fn thermal_run(run: &ThermalRunToml) -> std::result::Result<ThermalRunSpec, Invalid> {
    let path = KeyPath::of(&["thermal_run"]);
    let step_s = in_range(run.step_s, 0.01, 3600.0, &path.key("step_s"), "a step in s")?;
    let mut segments = Vec::new();
    for (i, s) in run.segments.iter().enumerate() {
        let p = path.key("segments").index(i);
        let until_h = positive(s.until_h, 1e5, &p.key("until_h"), "an end time in h")?;
        if let Some(last) = segments.last().map(|l: &Segment| l.until_s)
            && until_h * 3600.0 <= last
        {
            let msg = format!("{until_h} h is not accepted; segment end times must increase");
            return Err(Invalid::new(p.key("until_h"), msg));
        }
        let rpm = in_range(
            s.spindle_rpm,
            0.0,
            vmt_sim::nc::parse::MAX_SPINDLE_RPM,
            &p.key("spindle_rpm"),
            "a spindle speed in rpm",
        )?;
        let mut v = [0.0; 3];
        for (k, (slot, mm_min)) in v.iter_mut().zip(s.axis_speed_mm_min.0).enumerate() {
            let pk = p.key("axis_speed_mm_min").index(k);
            *slot = in_range(mm_min, 0.0, 1e6, &pk, "a mean axis speed in mm/min")? / 60_000.0;
        }
        segments.push(Segment {
            until_s: until_h * 3600.0,
            op: Operating {
                spindle_rpm: rpm,
                axis_speed_m_s: v,
            },
        });
    }
    let schedule =
        ThermalSchedule::new(segments).map_err(|e| Invalid::new(path.clone(), e.to_string()))?;
    Ok(ThermalRunSpec { schedule, step_s })
}
