//! A standalone straight cut: the spindle axis moves along +X at a constant feed rate (times
//! the override) while the spindle turns at its speed; an optional [`Supervisor`] sees the
//! accelerometer readings every window and may change the feed override and the spindle speed.
//!
//! The feed rate is held in mm/min as an NC program's F is: given per tooth, it is converted
//! at the initial spindle speed (v_f = f_t·N·S/60), so a later speed change alters the feed per
//! tooth as on a machine. Changes take effect at the next cut step, without ramps.

use serde_json::{Value, json};

use super::{CuttingProcess, MillingError, MillingSetup, SurfaceReport, check};
use crate::run::Stream;

/// The programmed feed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Feed {
    /// Feed per tooth, m.
    PerTooth(f64),
    /// Feed rate, mm/min.
    MmPerMin(f64),
}

/// How the straight cut is driven.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MillingDrive {
    /// Spindle speed at the start, rpm.
    pub spindle_rpm: f64,
    /// Programmed feed.
    pub feed: Feed,
    /// Length of the cut in time, s.
    pub duration_s: f64,
    /// How often the supervisor is called, s (rounded to whole output samples).
    pub supervisor_window_s: f64,
}

impl MillingDrive {
    fn validate(&self) -> Result<(), MillingError> {
        let s = self.spindle_rpm;
        check("spindle speed (rpm)", s, s > 0.0, "> 0")?;
        let (name, v) = match self.feed {
            Feed::PerTooth(v) => ("feed per tooth (m)", v),
            Feed::MmPerMin(v) => ("feed rate (mm/min)", v),
        };
        check(name, v, v > 0.0, "> 0")?;
        let d = self.duration_s;
        check("cut duration (s)", d, d > 0.0, "> 0")?;
        let w = self.supervisor_window_s;
        check("supervisor window (s)", w, w > 0.0, "> 0")
    }

    /// Feed rate, m/s, for `teeth` teeth.
    fn feed_rate(&self, teeth: usize) -> f64 {
        match self.feed {
            Feed::PerTooth(ft) => ft * teeth as f64 * self.spindle_rpm / 60.0,
            Feed::MmPerMin(f) => f / 60_000.0,
        }
    }
}

/// The latest accelerometer readings handed to a supervisor.
pub struct AccelWindow<'a> {
    /// Time of the last sample, s.
    pub time_s: f64,
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
    /// X, Y, Z readings of the window, m/s².
    pub ax: &'a [f64],
    pub ay: &'a [f64],
    pub az: &'a [f64],
    /// Feed override and spindle speed in force.
    pub feed_override: f64,
    pub spindle_rpm: f64,
}

/// What a supervisor asks of the machine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SupervisorCommand {
    /// Feed override, 1 = as programmed (≥ 0).
    pub feed_override: f64,
    /// Spindle speed, rpm (> 0).
    pub spindle_rpm: f64,
}

/// A process monitor in the loop (a chatter detector with its compensation).
pub trait Supervisor {
    /// Called every window with the latest readings.
    fn update(&mut self, window: &AccelWindow<'_>) -> SupervisorCommand;
}

impl<F: FnMut(&AccelWindow<'_>) -> SupervisorCommand> Supervisor for F {
    fn update(&mut self, window: &AccelWindow<'_>) -> SupervisorCommand {
        self(window)
    }
}

/// A finished straight cut.
#[derive(Clone, Debug, PartialEq)]
pub struct MillingRun {
    /// `accelerometer` and `cutting` streams.
    pub streams: Vec<Stream>,
    /// Surface location error, wall profile, Ra, Rz.
    pub surface: SurfaceReport,
    /// Chatter, cut and drive parameters in engineering units.
    pub ground_truth: Value,
}

/// Simulates a straight cut without supervision.
pub fn simulate_milling(
    setup: &MillingSetup,
    drive: &MillingDrive,
) -> Result<MillingRun, MillingError> {
    run(setup, drive, None)
}

/// Simulates a straight cut with `supervisor` in the loop.
pub fn simulate_milling_with(
    setup: &MillingSetup,
    drive: &MillingDrive,
    supervisor: &mut dyn Supervisor,
) -> Result<MillingRun, MillingError> {
    run(setup, drive, Some(supervisor))
}

fn run(
    setup: &MillingSetup,
    drive: &MillingDrive,
    mut supervisor: Option<&mut dyn Supervisor>,
) -> Result<MillingRun, MillingError> {
    drive.validate()?;
    let teeth = setup.tool.teeth.max(1);
    let feed_rate = drive.feed_rate(teeth);
    let setup = MillingSetup {
        feed_per_tooth: super::feed_per_tooth(feed_rate, teeth, drive.spindle_rpm),
        ..setup.clone()
    };
    let mut process = CuttingProcess::new(&setup)?;
    let h = setup.step_s;
    let fs = setup.accelerometer.sample_rate_hz;
    let window = (drive.supervisor_window_s * fs).round().max(1.0) as usize;
    let window_steps = window * setup.decimation();
    let steps = (drive.duration_s / h).round() as usize;
    let (mut rpm, mut feed_override) = (drive.spindle_rpm, 1.0);
    let (mut x, mut travel_rpm_sum) = (0.0, 0.0);
    let mut commands = Vec::new();
    for n in 0..steps {
        process
            .step([x, 0.0], rpm)
            .check_runaway(setup.tool.diameter)?;
        x += feed_rate * feed_override * h;
        travel_rpm_sum += rpm;
        let Some(sup) = supervisor.as_deref_mut() else {
            continue;
        };
        if !(n + 1).is_multiple_of(window_steps) {
            continue;
        }
        let [ax, ay, az] = process.accelerometer_samples();
        let from = ax.len().saturating_sub(window);
        let cmd = sup.update(&AccelWindow {
            time_s: (ax.len() - 1) as f64 / fs,
            sample_rate_hz: fs,
            ax: &ax[from..],
            ay: &ay[from..],
            az: &az[from..],
            feed_override,
            spindle_rpm: rpm,
        });
        // A command out of range is ignored: the machine keeps what it had.
        let ok_override = cmd.feed_override.is_finite() && cmd.feed_override >= 0.0;
        let ok_rpm = cmd.spindle_rpm.is_finite() && cmd.spindle_rpm > 0.0;
        if (ok_override && cmd.feed_override != feed_override) || (ok_rpm && cmd.spindle_rpm != rpm)
        {
            feed_override = if ok_override {
                cmd.feed_override
            } else {
                feed_override
            };
            rpm = if ok_rpm { cmd.spindle_rpm } else { rpm };
            commands.push(json!({
                "time_s": (n + 1) as f64 * h,
                "feed_override": feed_override,
                "spindle_rpm": rpm,
            }));
        }
    }
    let out = process.finish();
    let duration = steps as f64 * h;
    let mean_feed = x / duration.max(f64::MIN_POSITIVE);
    let mut truth = out.truth;
    let extra = json!({
        "duration_s": duration,
        "feed_mm_min": feed_rate * 60_000.0,
        "mean_feed_mm_min": mean_feed * 60_000.0,
        "mean_spindle_rpm": travel_rpm_sum / steps.max(1) as f64,
        "removal_rate_mm3_s": mean_feed * setup.cut.axial_depth * setup.cut.radial_depth * 1e9,
        "cut_length_mm": x * 1e3,
        "supervisor_commands": commands,
    });
    if let (Value::Object(t), Value::Object(e)) = (&mut truth, extra) {
        t.extend(e);
    }
    Ok(MillingRun {
        streams: out.streams,
        surface: out.surface,
        ground_truth: truth,
    })
}
