//! Time-domain milling with regenerative chatter: mechanistic forces on a helical end mill, the
//! chip thickness from a memory of the machined surface, the tool point's modes integrated
//! exactly, accelerometers on the spindle housing, the machined wall, and the ground truth.
//!
//! Frames and units (SI throughout): the workpiece frame has X along the feed and Y normal to
//! it; the spindle axis is at c (m) in that frame, the tool point vibrates by u (m) relative to
//! the spindle axis, so the tool's axis is at p = c + u. Immersion angles φ are measured
//! clockwise from +Y as in vmt-model's [`vmt_model::cutting`] (Altintas, "Manufacturing
//! Automation", 2nd ed., ch. 2–3).
//!
//! One cut step h (s), at instant t_n = n·h:
//! 1. Every tooth j of every axial disk k is at φ_jk = θ + j·2π/N - (k+½)·dz·tan β/R, θ the
//!    spindle angle integrated from the spindle speed ([`process`]).
//! 2. Its tip's radial coordinate r = p·(sin φ, cos φ) + R_j (R_j with run-out,
//!    [`vmt_model::cutting::EndMill::tooth_radius`]) is compared with the surface memory of that
//!    disk, r_s(φ), the radial coordinate of the surface the teeth left at that angle
//!    ([`engagement`]): h = r - r_s(φ). If h > 0 and φ_st ≤ φ ≤ φ_ex the tooth cuts with the
//!    mechanistic force of [`vmt_model::cutting::forces::element_force`]; the memory becomes r
//!    where the tooth cut and stays where it did not (the tool left the cut). Run-out, multiple
//!    regeneration, the tool jumping out of the cut and a changing spindle speed follow.
//! 3. The force, evaluated at mid-step and held over the step, drives every mode exactly
//!    ([`vmt_model::cutting::integrator`]); the accelerometers, the wall and the once-per-tooth
//!    samples of the ground truth are updated ([`process`] on the timing and its accuracy).
//!
//! Axial disks: as many as make the helix lag per disk at most 2° (K = ⌈a_p·tan β/(R·2°)⌉,
//! at least one; a cut needing more than [`MAX_DISKS`] is refused), each of height
//! dz = a_p/K. The step must give at least 20 steps per period of the highest mode and be an
//! integer fraction of the output period.

pub mod accelerometer;
pub mod drive;
pub mod engagement;
pub mod process;
pub mod surface;
pub mod truth;

pub use accelerometer::{ANTI_ALIAS_FRACTION, AccelerometerParams, DEFAULT_PARTICIPATION};
pub use drive::{
    AccelWindow, Feed, MillingDrive, MillingRun, Supervisor, SupervisorCommand, simulate_milling,
    simulate_milling_with,
};
pub use process::{CutSample, CuttingProcess, MillingOutput};
pub use surface::SurfaceReport;

use thiserror::Error;
use vmt_model::cutting::{
    CutGeometry, CuttingCoefficients, CuttingError, EndMill, Mode, ToolDynamics,
};

/// Steps per period of the highest mode, at least.
pub const MIN_STEPS_PER_PERIOD: f64 = 20.0;

/// Everything that defines a cut apart from how the axes move.
#[derive(Clone, Debug, PartialEq)]
pub struct MillingSetup {
    /// The end mill.
    pub tool: EndMill,
    /// Mechanistic force coefficients of the tool–material pair.
    pub coefficients: CuttingCoefficients,
    /// The tool point's modes in X and Y.
    pub dynamics: ToolDynamics,
    /// Optional axial (Z) mode of the tool point, driven by the axial force; without it the
    /// Z accelerometer reads noise only.
    pub axial_mode: Option<Mode>,
    /// Axial and radial depth, up or down milling.
    pub cut: CutGeometry,
    /// Nominal feed per tooth f_t, m: the steady cut the surface memory starts from (and the
    /// scale of the wall's sampling and of the chatter threshold).
    pub feed_per_tooth: f64,
    /// Sensors on the spindle housing and the output rate of all streams.
    pub accelerometer: AccelerometerParams,
    /// Cut step h, s.
    pub step_s: f64,
    /// Seed of the sensor noise.
    pub seed: u64,
}

/// A milling input outside its accepted range.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MillingError {
    #[error(transparent)]
    Cutting(#[from] CuttingError),
    #[error(
        "cut step {step_s} s is too coarse for the highest mode {highest_mode_hz} Hz \
         (at least 20 steps per period); the largest accepted step is {largest_step_s} s"
    )]
    StepTooCoarse {
        step_s: f64,
        highest_mode_hz: f64,
        largest_step_s: f64,
    },
    #[error(
        "cut step {step_s} s is not an integer fraction of the output period {output_period_s} s; \
         accepted: the output period divided by a whole number, e.g. {suggested_step_s} s"
    )]
    StepNotFraction {
        step_s: f64,
        output_period_s: f64,
        suggested_step_s: f64,
    },
    /// The cut needs more axial disks than [`MAX_DISKS`]: each holds a surface memory, and
    /// the tool's teeth are computed on every disk at every step.
    #[error(
        "the cut needs {disks} axial disks (helix lag a_p·tan β / R = {lag_deg:.0}° over the \
         depth of cut, at most 2° per disk); at most {max} disks are accepted (a helix lag of \
         {max_lag_deg}°): a shallower cut, a smaller helix angle or a larger tool"
    )]
    TooManyDisks {
        /// Disks the cut would need (as a real: it may exceed any integer).
        disks: f64,
        /// The helix lag over the depth of cut, deg.
        lag_deg: f64,
        /// [`MAX_DISKS`].
        max: usize,
        /// The lag [`MAX_DISKS`] disks cover, deg.
        max_lag_deg: f64,
    },
    #[error("{name} = {value} is out of range; accepted: {accepted}")]
    OutOfRange {
        name: &'static str,
        value: f64,
        accepted: &'static str,
    },
    /// The tool's vibration grew beyond its diameter: a cut this far past the stability limit
    /// breaks a real tool, and the linear modes no longer describe it.
    #[error(
        "at {time_s:.4} s of the cut the tool vibrates by {displacement_mm:.1} mm, more than its diameter: the cut is far beyond the stability limit (a real tool would break); take a smaller depth or another spindle speed"
    )]
    Runaway { time_s: f64, displacement_mm: f64 },
}

impl CutSample {
    /// [`MillingError::Runaway`] when the tool's displacement exceeds `diameter` (m).
    pub fn check_runaway(&self, diameter: f64) -> Result<(), MillingError> {
        let u = self.displacement[0].hypot(self.displacement[1]);
        if u.is_finite() && u <= diameter {
            Ok(())
        } else {
            Err(MillingError::Runaway {
                time_s: self.time_s,
                displacement_mm: u * 1e3,
            })
        }
    }
}

pub(crate) fn check(
    name: &'static str,
    value: f64,
    ok: bool,
    accepted: &'static str,
) -> Result<(), MillingError> {
    if ok && value.is_finite() {
        Ok(())
    } else {
        Err(MillingError::OutOfRange {
            name,
            value,
            accepted,
        })
    }
}

/// The feed per tooth f_t = F / (N·S), m, of a feed `feed_m_s` (m/s) with `teeth` teeth at
/// `spindle_rpm` rev/min.
pub fn feed_per_tooth(feed_m_s: f64, teeth: usize, spindle_rpm: f64) -> f64 {
    feed_m_s * 60.0 / (teeth as f64 * spindle_rpm)
}

impl MillingSetup {
    /// Checks every parameter; the first one out of range is named.
    pub fn validate(&self) -> Result<(), MillingError> {
        self.tool.validate()?;
        self.coefficients.validate()?;
        self.dynamics.validate()?;
        if let Some(m) = &self.axial_mode {
            check_mode(m)?;
        }
        self.cut.validate(&self.tool)?;
        self.check_disks()?;
        let ft = self.feed_per_tooth;
        check(
            "feed per tooth (m)",
            ft,
            ft > 0.0 && ft < self.tool.diameter / 2.0,
            "0 < f_t < tool radius",
        )?;
        self.accelerometer.validate(self.mode_count())?;
        self.check_step()?;
        Ok(())
    }

    /// Number of modes: X, Y and the axial one.
    pub(crate) fn mode_count(&self) -> usize {
        self.dynamics.x.len() + self.dynamics.y.len() + usize::from(self.axial_mode.is_some())
    }

    /// Highest natural frequency of all modes, axial included, Hz.
    pub fn highest_mode_hz(&self) -> f64 {
        let axial = self.axial_mode.map_or(0.0, |m| m.natural_frequency_hz);
        self.dynamics.highest_frequency_hz().max(axial)
    }

    /// Largest accepted step: the output period divided by the smallest whole number that gives
    /// at least 20 steps per period of the highest mode, s.
    pub fn largest_step_s(&self) -> f64 {
        let period = 1.0 / self.accelerometer.sample_rate_hz;
        let n = (period * MIN_STEPS_PER_PERIOD * self.highest_mode_hz())
            .ceil()
            .max(1.0);
        period / n
    }

    /// Cut steps per output sample.
    pub(crate) fn decimation(&self) -> usize {
        (1.0 / (self.accelerometer.sample_rate_hz * self.step_s)).round() as usize
    }

    /// Number of axial disks: helix lag per disk at most [`MAX_LAG_PER_DISK`] (at most
    /// [`MAX_DISKS`] in a validated setup).
    pub fn disks(&self) -> usize {
        (self.disks_needed() as usize).max(1)
    }

    /// The helix lag a_p·tan β / R over the depth of cut, rad.
    fn helix_lag(&self) -> f64 {
        self.cut.axial_depth * self.tool.helix.tan() / (self.tool.diameter / 2.0)
    }

    /// Disks of at most [`MAX_LAG_PER_DISK`] the helix lag needs, as a real (a lag near a
    /// 90° helix needs more than any integer holds).
    fn disks_needed(&self) -> f64 {
        (self.helix_lag() / MAX_LAG_PER_DISK).ceil()
    }

    fn check_disks(&self) -> Result<(), MillingError> {
        let disks = self.disks_needed();
        if disks <= MAX_DISKS as f64 {
            return Ok(());
        }
        Err(MillingError::TooManyDisks {
            disks,
            lag_deg: self.helix_lag().to_degrees(),
            max: MAX_DISKS,
            max_lag_deg: (MAX_DISKS as f64 * MAX_LAG_PER_DISK).to_degrees().round(),
        })
    }

    fn check_step(&self) -> Result<(), MillingError> {
        let h = self.step_s;
        check("cut step (s)", h, h > 0.0, "a step greater than 0 s")?;
        let f_max = self.highest_mode_hz();
        if h * f_max * MIN_STEPS_PER_PERIOD > 1.0 + 1e-9 {
            return Err(MillingError::StepTooCoarse {
                step_s: h,
                highest_mode_hz: f_max,
                largest_step_s: self.largest_step_s(),
            });
        }
        let period = 1.0 / self.accelerometer.sample_rate_hz;
        let ratio = period / h;
        if ratio < 1.0 - 1e-9 || (ratio - ratio.round()).abs() > 1e-6 * ratio {
            return Err(MillingError::StepNotFraction {
                step_s: h,
                output_period_s: period,
                suggested_step_s: period / ratio.ceil().max(1.0),
            });
        }
        Ok(())
    }
}

/// Largest helix lag of one axial disk, rad (2°).
pub const MAX_LAG_PER_DISK: f64 = 2.0 * std::f64::consts::PI / 180.0;

/// Most axial disks of a cut: a helix lag of 2000°, more than five turns of a flute within
/// the depth of cut, beyond any end mill (a 10 mm tool with a 45° helix reaches it at a depth
/// of 175 mm). Each disk holds a surface memory of [`engagement::BINS`] bins, and every tooth
/// is computed on every disk at every cut step.
pub const MAX_DISKS: usize = 1000;

fn check_mode(m: &Mode) -> Result<(), MillingError> {
    let f = m.natural_frequency_hz;
    check("axial mode natural frequency (Hz)", f, f > 0.0, "f_n > 0")?;
    check(
        "axial mode stiffness (N/m)",
        m.stiffness,
        m.stiffness > 0.0,
        "k > 0",
    )?;
    let z = m.damping_ratio;
    check(
        "axial mode damping ratio",
        z,
        (0.0..1.0).contains(&z),
        "0 ≤ ζ < 1",
    )
}
