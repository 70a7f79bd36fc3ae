//! A milling job driven by its NC program through the same interpolator, controller and feed
//! drives as every other job, with the cut of [`crate::milling`] integrated between servo ticks
//! and a process supervisor (a chatter detector and its compensation) able to override the
//! feed and the spindle speed while the machine runs.
//!
//! - **The cut.** It is active from the start of the first feed block (G1) run with the spindle
//!   on to the end of the last such block that follows it: the workpiece's wall is met where
//!   the first cutting block starts, and the surface memory starts as a steady cut there. The
//!   spindle axis position c (m) in the cut's frame is the tool position (carriages plus the
//!   tool offset by the nominal chain, with the carriages' deflections where the plant has them:
//!   the micrometre geometric errors of the axes
//!   are far below the cut's vibration) relative to where the cut started, with the feed along
//!   +X as the milling model assumes. Cut steps run on their own clock (h of the
//!   [`MillingSetup`]); c is linearly interpolated between servo ticks. The cutting force is
//!   fed back (two-way): each servo tick's mean cutting force acts on the tool and, as its
//!   reaction, on the workpiece over the next tick (`Plant::set_tool_force`): on the drives
//!   along their axes, and with the compliant plant on the carriages' blocks, whose deflection
//!   moves the tool point the cut sees (the servo's dynamic stiffness: following error and
//!   surface location error at cut entry).
//! - **Feed override.** A planned trajectory p(τ) is followed in path time τ, advanced by
//!   dτ = o·dt per servo period with o the override (0…1), so the setpoint is p(τ), its velocity
//!   o·p′(τ) and its acceleration o²·p″(τ) (setpoints interpolated linearly between the
//!   planned servo ticks), as a CNC's feed override scales the path speed.
//! - **Spindle speed.** The S word of the block being executed, or the supervisor's speed once
//!   it has set one.
//! - **Streams.** `servo` at the log rate (the other jobs' channels but the tool point:
//!   command_a, position_a, encoder_a, following_error_a, motor_force_a, motor_current_a,
//!   guide_friction_a, screw_friction_a for a = x, y, z; feed_override; spindle_rpm), and the cut's `accelerometer` and `cutting` streams with
//!   their times on the job's clock; the ground truth's `milling` holds the cut's truth (its
//!   times from the start of the cut) and `cut_start_s`.

use crate::interpolator::{Cursor, Interpolator, InterpolatorConfig, Setpoint};
use crate::milling::{
    AccelWindow, CuttingProcess, MillingError, MillingSetup, Supervisor, SupervisorCommand,
};
use crate::nc::{Motion, Spindle};
use crate::plant::Plant;
use crate::run::{Channel, Run, Stream};
use crate::simulate::{
    AxisDynamics, Job, SERVO_CHANNELS, SimError, SimSettings, build_plant, check_following_error,
    check_step, check_strokes, following_error_limits, push_servo_row, servo_channels, servo_tick,
    summary,
};
use nalgebra::Vector3;
use serde_json::json;
use vmt_model::Direction;
use vmt_model::drive::AxisCommand;
use vmt_model::geometric::GeometricErrors;
use vmt_model::kinematics::{AxisState, VolumetricModel};
use vmt_model::machine::Machine;
use vmt_model::thermal_deformation::ThermalDeformation;

/// What a milling job adds to its program.
#[derive(Clone, Debug, PartialEq)]
pub struct MillingJob {
    /// The cut (tool, coefficients, modes, engagement, sensors, step); its feed per tooth is
    /// replaced by the program's F / (N·S) of the first cutting block.
    pub setup: MillingSetup,
    /// How often the supervisor sees the accelerometers, s.
    pub supervisor_window_s: f64,
}

/// The stretch of planned time in which the tool cuts, and its programmed feed and speed.
struct CutPlan {
    start_s: f64,
    end_s: f64,
    feed_m_s: f64,
    spindle_rpm: f64,
}

/// The feed (m/s) and spindle speed (rpm) of a block that cuts: a G1 feed move with the
/// spindle on clockwise.
pub fn cutting_block(motion: &Motion, spindle: Spindle) -> Option<(f64, f64)> {
    match (motion, spindle) {
        (Motion::Linear { feed, .. }, Spindle::Clockwise(rpm)) if rpm > 0.0 => Some((*feed, rpm)),
        _ => None,
    }
}

fn cut_plan(job: &Job, ipo: &Interpolator) -> Result<CutPlan, SimError> {
    let times = ipo.block_times();
    let blocks = &job.program.blocks;
    let cutting = |b: usize| cutting_block(&blocks[b].motion, blocks[b].spindle);
    let first = times.iter().position(|(b, _, _)| cutting(*b).is_some()).ok_or_else(|| {
        SimError::Settings(
            "the milling program has no cutting block: a G1 feed move with the spindle on clockwise (M3 S…)".into(),
        )
    })?;
    let last = first
        + times[first..]
            .iter()
            .take_while(|(b, _, _)| cutting(*b).is_some())
            .count()
        - 1;
    let (feed_m_s, spindle_rpm) = cutting(times[first].0).unwrap_or_default();
    Ok(CutPlan {
        start_s: times[first].1,
        end_s: times[last].2,
        feed_m_s,
        spindle_rpm,
    })
}

/// The planned setpoint at path time `tau` (s), interpolated between servo ticks, its
/// velocity and acceleration scaled for the override `o`.
fn setpoint_at(ipo: &Interpolator, tau: f64, o: f64, cursor: &mut Cursor) -> Option<Setpoint> {
    let period = ipo.servo_period_s();
    let k = (tau / period).floor() as usize;
    let a = ipo.setpoint_from(k, cursor)?;
    let b = ipo.setpoint_from(k + 1, cursor).unwrap_or(a);
    let w = tau / period - k as f64;
    let lerp = |x: &Vector3<f64>, y: &Vector3<f64>| x + (y - x) * w;
    Some(Setpoint {
        time_s: tau,
        position: lerp(&a.position, &b.position),
        velocity: lerp(&a.velocity, &b.velocity) * o,
        acceleration: lerp(&a.acceleration, &b.acceleration) * (o * o),
        ..a
    })
}

/// Servo-rate log of the job: the channels of the other jobs' `servo` stream but the tool
/// point (a milling run does not evaluate the error chain; the cut's own tool motion is in its
/// `cutting` stream), then the feed override and the spindle speed.
struct ServoLog(Stream);

impl ServoLog {
    fn new() -> Self {
        let extra = [("feed_override", "1"), ("spindle_rpm", "rpm")].map(|(name, unit)| Channel {
            name: name.into(),
            unit: unit.into(),
            values: Vec::new(),
        });
        ServoLog(Stream {
            name: "servo".into(),
            description: "axis commands, carriage positions, encoders, following errors, motor forces and currents, friction forces, the feed override and the spindle speed".into(),
            times_s: Vec::new(),
            channels: servo_channels(0).into_iter().chain(extra).collect(),
        })
    }

    /// A row at `t` (s): the plant after the servo tick commanded by `command`.
    fn push(&mut self, t: f64, plant: &dyn Plant, command: &[AxisCommand; 3], o: f64, rpm: f64) {
        let s = &mut self.0;
        s.times_s.push(t);
        let carriages = plant.carriages();
        for (i, c) in command.iter().enumerate() {
            push_servo_row(&mut s.channels, plant, &carriages, i, c.position);
        }
        let n = SERVO_CHANNELS.len() * 3;
        s.channels[n].values.push(o);
        s.channels[n + 1].values.push(rpm);
    }
}

/// The cut in progress: the process, its clock and the supervisor's window.
struct Cut<'a> {
    process: CuttingProcess,
    origin: [f64; 2],
    clock_s: f64,
    start_s: f64,
    window: usize,
    last_called: usize,
    sample_rate_hz: f64,
    diameter: f64,
    supervisor: Option<&'a mut dyn Supervisor>,
}

impl Cut<'_> {
    /// Advances the cut to real time `t` (s), the tool moving from `from` to `to` (m) over
    /// the servo period ending at `t`.
    fn advance(
        &mut self,
        t: f64,
        period: f64,
        from: [f64; 2],
        to: [f64; 2],
        command: &mut SupervisorCommand,
    ) -> Result<Vector3<f64>, MillingError> {
        let h = self.process.step_s();
        let (mut force, mut steps) = (Vector3::zeros(), 0.0);
        while self.clock_s + h <= t - self.start_s + 1e-12 {
            let w =
                ((self.clock_s + 0.5 * h + self.start_s - (t - period)) / period).clamp(0.0, 1.0);
            let c = [0, 1].map(|i| from[i] + (to[i] - from[i]) * w - self.origin[i]);
            let sample = self.process.step(c, command.spindle_rpm);
            sample.check_runaway(self.diameter)?;
            force += Vector3::from(sample.force);
            steps += 1.0;
            self.clock_s += h;
        }
        let n = self.process.accelerometer_samples()[0].len();
        if let Some(s) = self.supervisor.as_deref_mut()
            && n >= self.last_called + self.window
        {
            let [ax, ay, az] = self.process.accelerometer_samples();
            let from = n - self.window;
            *command = s.update(&AccelWindow {
                time_s: self.start_s + self.clock_s,
                sample_rate_hz: self.sample_rate_hz,
                ax: &ax[from..],
                ay: &ay[from..],
                az: &az[from..],
                feed_override: command.feed_override,
                spindle_rpm: command.spindle_rpm,
            });
            self.last_called = n;
        }
        Ok(if steps > 0.0 { force / steps } else { force })
    }
}

/// Runs a milling job: `job`'s program with the cut of `milling`, and `supervisor` (if any)
/// in the loop. `progress` is called with the fraction done about a hundred times.
#[allow(clippy::too_many_arguments)]
pub fn simulate_machining(
    machine: &Machine,
    axes: &[AxisDynamics; 3],
    ipo_config: &InterpolatorConfig,
    job: &Job,
    milling: &MillingJob,
    settings: &SimSettings,
    scenario_toml: &str,
    supervisor: Option<&mut dyn Supervisor>,
    progress: &mut dyn FnMut(f64),
) -> Result<Run, SimError> {
    let ipo = Interpolator::new(&job.program, ipo_config)?;
    let tcp = machine.volumetric.kinematics.tool_offset;
    check_strokes(machine, &ipo, &job.program, &tcp)?;
    let period = ipo.servo_period_s();
    let substeps = settings.plant_substeps.max(1);
    check_step(axes, period, substeps)?;
    let plan = cut_plan(job, &ipo)?;
    let teeth = milling.setup.tool.teeth.max(1);
    let setup = MillingSetup {
        feed_per_tooth: crate::milling::feed_per_tooth(plan.feed_m_s, teeth, plan.spindle_rpm),
        ..milling.setup.clone()
    };
    let process =
        CuttingProcess::new(&setup).map_err(|e| SimError::Settings(format!("milling: {e}")))?;
    let start = job.program.start - tcp;
    let mut plant = build_plant(
        machine,
        axes,
        &start,
        settings.fidelity,
        period / substeps as f64,
    )?;
    let window = (milling.supervisor_window_s * setup.accelerometer.sample_rate_hz)
        .round()
        .max(1.0) as usize;
    let mut cut: Option<Cut> = None;
    let mut pending = Some(Cut {
        process,
        origin: [0.0; 2],
        clock_s: 0.0,
        start_s: 0.0,
        window,
        last_called: 0,
        sample_rate_hz: setup.accelerometer.sample_rate_hz,
        diameter: setup.tool.diameter,
        supervisor,
    });
    let mut command = SupervisorCommand {
        feed_override: 1.0,
        spindle_rpm: plan.spindle_rpm,
    };
    let log_every = ((1.0 / settings.log_rate_hz) / period).round().max(1.0) as usize;
    let (mut log, mut cursor) = (ServoLog::new(), Cursor::default());
    let (mut tau, mut k) = (0.0, 0usize);
    let duration = ipo.duration_s();
    // The tool point relative to the workpiece by the nominal chain, with the carriages'
    // deflections on their guide blocks where the plant has them.
    let nominal = VolumetricModel::new(
        machine.volumetric.kinematics.clone(),
        GeometricErrors::zero(),
    );
    let chain = nominal.evaluator(&ThermalDeformation::default());
    let tool_xy = |p: &dyn crate::plant::Plant| {
        let c = p.carriages();
        match p.deflections() {
            Some(d) => {
                let q = Vector3::from_fn(|i, _| c[i].position_m);
                let t = chain.tool_point_deflected(&AxisState::new(q, Direction::Forward), &d);
                [t.x, t.y]
            }
            None => [c[0].position_m + tcp.x, c[1].position_m + tcp.y],
        }
    };
    let mut before = tool_xy(plant.as_ref());
    let mut speed_taken_over = false;
    let limits = following_error_limits(axes, ipo_config);
    while tau <= duration {
        let o = command.feed_override;
        let Some(sp) = setpoint_at(&ipo, tau, o, &mut cursor) else {
            break;
        };
        let commands = servo_tick(plant.as_mut(), &sp, &tcp, period, substeps);
        check_following_error(plant.as_ref(), &limits, sp.time_s, sp.block, &job.program)?;
        // Logged at the tick's own time, as the other jobs' servo rows (from 0), with the
        // spindle speed of this tick (set below, from its block or the supervisor).
        let logged = k.is_multiple_of(log_every).then_some(k as f64 * period);
        k += 1;
        let t = k as f64 * period;
        let now = tool_xy(plant.as_ref());
        if tau >= plan.start_s && tau <= plan.end_s {
            if let Some(mut c) = pending.take() {
                (c.origin, c.start_s) = (before, t - period);
                cut = Some(c);
            }
        } else if tau > plan.end_s {
            pending = None;
        }
        // The program's S holds until the supervisor asks for another speed.
        let programmed = match sp.spindle {
            Spindle::Clockwise(s) | Spindle::CounterClockwise(s) => s,
            Spindle::Stopped => 0.0,
        };
        if !speed_taken_over {
            command.spindle_rpm = programmed;
        }
        if let Some(c) = cut.as_mut().filter(|_| tau <= plan.end_s) {
            let force = c
                .advance(t, period, before, now, &mut command)
                .map_err(|e| SimError::Settings(format!("milling: {e}")))?;
            // Two-way: the tick's mean cutting force pushes back on the machine (the tool
            // side and, as its reaction, the workpiece side) over the next tick.
            plant.set_tool_force(force);
            speed_taken_over |= command.spindle_rpm != programmed;
        } else {
            plant.set_tool_force(Vector3::zeros());
        }
        if let Some(time) = logged {
            log.push(time, plant.as_ref(), &commands, o, command.spindle_rpm);
        }
        before = now;
        tau += o * period;
        if k.is_multiple_of(((duration / period) as usize / 100).max(1)) {
            progress((tau / duration).min(1.0));
        }
    }
    progress(1.0);
    let cut =
        cut.ok_or_else(|| SimError::Settings("the program ended before its cutting block".into()))?;
    let out = cut.process.finish();
    let mut streams = vec![log.0];
    streams.extend(out.streams.into_iter().map(|mut s| {
        s.times_s.iter_mut().for_each(|x| *x += cut.start_s);
        s
    }));
    Ok(Run {
        scenario_name: machine.name.clone(),
        scenario_toml: scenario_toml.to_string(),
        seed: settings.seed,
        fidelity: settings.fidelity.name().into(),
        machine: summary(machine),
        streams,
        ballbar: Vec::new(),
        laser: None,
        ground_truth: json!({ "milling": out.truth, "cut_start_s": cut.start_s }),
    })
}
