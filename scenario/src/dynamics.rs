//! Scenario sections for executing jobs: each axis' drive and servo, the controller, the
//! simulation settings, the job and the ball bar.

use crate::build::{BuildError, count_in_range, in_range, positive, typed};
use crate::error::{Invalid, KeyPath};
use crate::schema::{Numbers, Points};
use nalgebra::Vector3;
use serde::Deserialize;
use std::path::Path;
use vmt_model::Axis;
use vmt_model::drive::{DriveParams, Feedback, LuGreParams, ScrewParams, ServoParams};
use vmt_model::machine::Machine;
use vmt_sim::ballbar::BallbarSpec;
use vmt_sim::interpolator::{InterpolatorConfig, Limits};
use vmt_sim::laser::{LaserSetup, LaserSpec, PositioningTest};
use vmt_sim::nc::ballbar::default_start_deg;
use vmt_sim::nc::{ArcDirection, CircularTest, Plane, Program, kwon_steps, marked_circles, parse};
use vmt_sim::plant::Fidelity;
use vmt_sim::simulate::{AxisDynamics, BallbarSetup, Job, SimSettings};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveToml {
    pub motor_inertia_kg_m2: f64,
    pub screw_lead_mm: f64,
    pub screw_stiffness_n_per_um: f64,
    pub screw_damping_n_s_per_m: f64,
    pub backlash_um: f64,
    /// Periodic lead error of the screw, cosine and sine amplitudes over one revolution, µm.
    #[serde(default)]
    pub screw_cyclic_um: [f64; 2],
    pub encoder_counts_per_rev: f64,
    pub torque_constant_n_m_per_a: f64,
    #[serde(default = "motor_encoder")]
    pub feedback: String,
    pub scale_resolution_nm: Option<f64>,
    pub guide_friction: FrictionToml,
    pub screw_friction: FrictionToml,
    /// Cogging and torque ripple of the motor (`effects`); absent: none.
    pub motor: Option<crate::effects::MotorToml>,
    /// Interpolation error of the motor encoder's signals; absent: none.
    pub encoder_signals: Option<crate::effects::SignalsToml>,
    /// Interpolation error of the linear scale's signals; absent: none.
    pub scale_signals: Option<crate::effects::SignalsToml>,
    /// A preloaded double nut; absent: the linear screw spring alone.
    pub nut: Option<crate::effects::NutToml>,
}

fn motor_encoder() -> String {
    "motor_encoder".into()
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrictionToml {
    pub coulomb_n: f64,
    pub static_n: f64,
    pub stribeck_mm_s: f64,
    #[serde(default = "two")]
    pub stribeck_exponent: f64,
    pub bristle_stiffness_n_per_um: f64,
    pub bristle_damping_n_s_per_m: f64,
    pub viscous_n_s_per_m: f64,
    /// The friction law: "lugre" (absent) or "gms" (`effects`).
    pub law: Option<String>,
    /// Elements of the GMS law (4 if absent).
    pub gms_elements: Option<usize>,
    /// Attraction parameter of the GMS law, N/s (σ0·vs if absent).
    pub gms_attraction_n_per_s: Option<f64>,
}

fn two() -> f64 {
    2.0
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServoToml {
    pub kv_per_s: f64,
    pub velocity_bandwidth_hz: f64,
    pub velocity_integral_ms: f64,
    #[serde(default)]
    pub velocity_ff: f64,
    #[serde(default)]
    pub acceleration_ff: f64,
    pub current_time_constant_ms: f64,
    pub peak_torque_n_m: f64,
    /// The excess-error alarm's limit; absent: the control's default (twice the lag at the
    /// rapid rate).
    pub following_error_limit_mm: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerToml {
    pub servo_period_us: f64,
    pub ipo_period_ms: f64,
    pub plant_substeps: usize,
    pub rapid_mm_min: f64,
    pub max_feed_mm_min: f64,
    pub path_accel_m_s2: f64,
    pub path_jerk_m_s3: f64,
    pub axis_accel_m_s2: Numbers<3>,
    pub corner_tolerance_um: f64,
    #[serde(default)]
    pub exact_stop: bool,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimulationToml {
    #[serde(default = "reduced")]
    pub fidelity: String,
    #[serde(default)]
    pub seed: u64,
    /// Default: 1 kHz, or the servo rate when that is slower.
    #[serde(default)]
    pub log_rate_hz: Option<f64>,
}

fn reduced() -> String {
    "reduced".into()
}

fn khz() -> f64 {
    1000.0
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "lowercase")]
pub enum JobToml {
    Ballbar(BallbarJobToml),
    Program {
        program: String,
    },
    /// ISO 230-2 linear positioning test with a laser interferometer.
    #[serde(rename = "iso230_2")]
    Iso230_2(PositioningToml),
    /// A milling program with its cut (`scenarios/milling_slot.toml`).
    Milling(crate::milling::MillingJobToml),
    /// Kwon's seven-step ball-bar procedure, the steps in a row.
    #[serde(rename = "kwon_seven_step")]
    KwonSevenStep {
        #[serde(default = "kwon_pivot")]
        pivot_mm: Numbers<3>,
        #[serde(default = "all_steps")]
        steps: Vec<u8>,
    },
}

/// An ISO 230-4 ball-bar job; the keys of `vmt program ballbar`'s options.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BallbarJobToml {
    plane: String,
    /// Default: the tool point with every carriage at the middle of its stroke. A list of
    /// centres runs every radius about each in turn, the bar set up anew at each.
    pub center_mm: Option<Points>,
    radius_mm: Radii,
    feed_mm_min: f64,
    #[serde(default = "full")]
    arc_deg: f64,
    /// Default: `vmt_sim::nc::ballbar::default_start_deg` (over the top in ZX and YZ).
    start_deg: Option<f64>,
    #[serde(default = "overshoot")]
    overshoot_deg: f64,
    #[serde(default = "feed_in")]
    feed_in_mm: f64,
    #[serde(default = "both")]
    directions: Vec<String>,
}

/// The radius of a ball-bar job, or several: the tests then run in turn, one per radius about
/// the same centre, each in every direction (ISO 230-4 tests at two radii tell an error that
/// depends on the axis position from one that depends on the path's curvature).
#[derive(Debug)]
enum Radii {
    One(f64),
    Many(Vec<f64>),
}

impl<'de> Deserialize<'de> for Radii {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visit;
        impl<'de> serde::de::Visitor<'de> for Visit {
            type Value = Radii;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("f64, a radius in mm, or a list of radii")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<Radii, E> {
                Ok(Radii::One(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<Radii, E> {
                Ok(Radii::One(v as f64))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<Radii, E> {
                Ok(Radii::One(v as f64))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut a: A) -> Result<Radii, A::Error> {
                let mut v = Vec::new();
                while let Some(r) = a.next_element::<f64>()? {
                    v.push(r);
                }
                Ok(Radii::Many(v))
            }
        }
        d.deserialize_any(Visit)
    }
}

impl Radii {
    fn list(&self) -> &[f64] {
        match self {
            Radii::One(r) => std::slice::from_ref(r),
            Radii::Many(v) => v,
        }
    }
}

fn overshoot() -> f64 {
    vmt_sim::nc::ballbar::DEFAULT_OVERSHOOT_DEG
}

fn feed_in() -> f64 {
    vmt_sim::nc::ballbar::DEFAULT_FEED_IN_M * 1e3
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PositioningToml {
    axis: String,
    targets_mm: Option<Vec<f64>>,
    range_mm: Option<Numbers<2>>,
    count: Option<usize>,
    #[serde(default = "five")]
    runs: usize,
    #[serde(default = "two")]
    dwell_s: f64,
    feed_mm_min: f64,
    overrun_mm: f64,
    beam_line_mm: Numbers<2>,
}

impl PositioningToml {
    /// The key of `[job]` that takes `axis` beyond its stroke, and what to do about it: the
    /// targets (with the overrun) for the test's own axis, the beam line's coordinate for the
    /// others (which the test holds still on the line).
    pub(crate) fn travel_key(&self, axis: Axis) -> (KeyPath, &'static str) {
        let p = KeyPath::of(&["job"]);
        let test = self
            .axis
            .to_ascii_uppercase()
            .parse::<char>()
            .ok()
            .and_then(Axis::from_letter);
        if test == Some(axis) {
            let key = if self.targets_mm.is_some() {
                "targets_mm"
            } else {
                "range_mm"
            };
            let fix = "bring the targets and overrun (job.overrun_mm) within the stroke";
            return (p.key(key), fix);
        }
        // beam_line_mm lists the other two axes in X, Y, Z order.
        let k = Axis::ALL
            .into_iter()
            .filter(|a| Some(*a) != test)
            .position(|a| a == axis)
            .unwrap_or(0);
        let fix = "put the beam line within the strokes of the axes the test holds still";
        (p.key("beam_line_mm").index(k), fix)
    }
}

fn five() -> usize {
    5
}

fn kwon_pivot() -> Numbers<3> {
    Numbers(vmt_sim::nc::ballbar::KWON_SCENARIO_PIVOT_MM)
}

fn all_steps() -> Vec<u8> {
    (1..=7).collect()
}

fn full() -> f64 {
    360.0
}

fn both() -> Vec<String> {
    vec!["cw".into(), "ccw".into()]
}

#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct InstrumentsToml {
    pub ballbar: Option<BallbarToml>,
    pub laser: Option<LaserToml>,
    pub accelerometer: Option<crate::milling::AccelerometerToml>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LaserToml {
    #[serde(default = "one")]
    pub resolution_nm: f64,
    #[serde(default)]
    pub noise_nm: f64,
    #[serde(default = "khz")]
    pub sample_rate_hz: f64,
    #[serde(default = "one")]
    pub averaging_s: f64,
    #[serde(default)]
    pub air_temperature_error_k: f64,
    #[serde(default)]
    pub air_pressure_error_hpa: f64,
    #[serde(default)]
    pub humidity_error_percent: f64,
    #[serde(default)]
    pub material_temperature_error_k: f64,
    #[serde(default = "steel")]
    pub material_alpha_per_k: f64,
    #[serde(default)]
    pub dead_path_mm: f64,
    #[serde(default)]
    pub air_drift_k_per_h: f64,
}

fn one() -> f64 {
    1.0
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BallbarToml {
    #[serde(default = "tenth")]
    pub resolution_um: f64,
    #[serde(default)]
    pub noise_um: f64,
    #[serde(default = "khz")]
    pub sample_rate_hz: f64,
    /// One pivot offset, or one per centre of a ball-bar job with a list of centres.
    #[serde(default)]
    pub setup_eccentricity_um: Points,
    #[serde(default)]
    pub setup_drift_um_per_min: Numbers<3>,
    #[serde(default = "twenty")]
    pub bar_temperature_c: f64,
    #[serde(default = "steel")]
    pub bar_alpha_per_k: f64,
    #[serde(default = "one_mm_in_um")]
    pub range_um: f64,
}

fn one_mm_in_um() -> f64 {
    1000.0
}

fn tenth() -> f64 {
    0.1
}

fn twenty() -> f64 {
    20.0
}

fn steel() -> f64 {
    11.5e-6
}

type R<T> = Result<T, Invalid>;

fn pos(v: f64, path: &KeyPath, what: &str) -> R<f64> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(Invalid::new(
            path.clone(),
            format!("{v} is not accepted; {what} must be a finite number > 0"),
        ))
    }
}

/// `v` when each of its three components lies within ±`max`; the error names the component.
fn within3(v: &Numbers<3>, max: f64, path: &KeyPath, what: &str) -> R<Vector3<f64>> {
    for (i, &x) in v.iter().enumerate() {
        in_range(x, -max, max, &path.index(i), what)?;
    }
    Ok(Vector3::from(v.0))
}

/// Largest friction force accepted, N: ten tonnes moving at a friction coefficient of 0.1.
const MAX_FRICTION_N: f64 = 1e5;

/// Largest peak torque of a servo motor accepted, N·m.
const MAX_PEAK_TORQUE_N_M: f64 = 1e5;

fn friction(f: &FrictionToml, p: &KeyPath) -> R<LuGreParams> {
    // Generous bounds around guideways and screws (bristles of 1 to 100 N/µm, Stribeck
    // velocities of 0.1 to 10 mm/s, viscous friction of hundreds of N·s/m): beyond them the
    // traces span millimetres or overflow.
    let force = |v: f64, k: &str| in_range(v, 0.0, MAX_FRICTION_N, &p.key(k), "a force (N)");
    let out = LuGreParams {
        sigma0_n_per_m: in_range(
            f.bristle_stiffness_n_per_um,
            0.01,
            1e5,
            &p.key("bristle_stiffness_n_per_um"),
            "a bristle stiffness (N/µm)",
        )? * 1e6,
        sigma1_n_s_per_m: in_range(
            f.bristle_damping_n_s_per_m,
            0.0,
            1e8,
            &p.key("bristle_damping_n_s_per_m"),
            "a damping (N·s/m)",
        )?,
        sigma2_n_s_per_m: in_range(
            f.viscous_n_s_per_m,
            0.0,
            1e6,
            &p.key("viscous_n_s_per_m"),
            "a viscous coefficient (N·s/m)",
        )?,
        coulomb_n: force(f.coulomb_n, "coulomb_n")?,
        static_n: force(f.static_n, "static_n")?,
        stribeck_m_s: in_range(
            f.stribeck_mm_s,
            0.001,
            1000.0,
            &p.key("stribeck_mm_s"),
            "a Stribeck velocity (mm/s)",
        )? * 1e-3,
        // δ of exp(−|v/v_s|^δ): 0.5 to 2 in the literature (Armstrong-Hélouvry 1994).
        stribeck_exponent: in_range(
            f.stribeck_exponent,
            0.1,
            10.0,
            &p.key("stribeck_exponent"),
            "a Stribeck exponent",
        )?,
    };
    // All within range, what is left is the static force below the Coulomb force.
    out.check()
        .map_err(|m| Invalid::new(p.key("static_n"), m))?;
    Ok(out)
}

/// The drive of an axis.
pub fn drive(d: &DriveToml, moving_mass_kg: f64, p: &KeyPath) -> R<DriveParams> {
    let feedback = match d.feedback.as_str() {
        "motor_encoder" => Feedback::MotorEncoder,
        "linear_scale" => {
            let r = d.scale_resolution_nm.ok_or_else(|| {
                Invalid::new(
                    p.key("scale_resolution_nm"),
                    "a linear scale needs scale_resolution_nm",
                )
            })?;
            Feedback::LinearScale {
                resolution_m: in_range(
                    r,
                    0.001,
                    10_000.0,
                    &p.key("scale_resolution_nm"),
                    "a resolution (nm)",
                )? * 1e-9,
            }
        }
        other => {
            let msg = format!(
                "`{other}` is not accepted; feedback is \"motor_encoder\" (semi-closed loop) or \"linear_scale\""
            );
            return Err(Invalid::new(p.key("feedback"), msg));
        }
    };
    Ok(DriveParams {
        // Bounds around feed drives (rotors of 1e-5 to 0.1 kg·m², leads of 2 to 50 mm, screws of
        // tens to hundreds of N/µm), generous, so that the step and loop checks can evaluate them.
        motor_inertia_kg_m2: in_range(
            d.motor_inertia_kg_m2,
            1e-7,
            10.0,
            &p.key("motor_inertia_kg_m2"),
            "an inertia (kg·m²)",
        )?,
        screw: ScrewParams {
            lead_m: in_range(
                d.screw_lead_mm,
                0.1,
                1000.0,
                &p.key("screw_lead_mm"),
                "a lead (mm)",
            )? * 1e-3,
            stiffness_n_per_m: in_range(
                d.screw_stiffness_n_per_um,
                0.01,
                1e5,
                &p.key("screw_stiffness_n_per_um"),
                "a stiffness (N/µm)",
            )? * 1e6,
            damping_n_s_per_m: in_range(
                d.screw_damping_n_s_per_m,
                0.0,
                1e8,
                &p.key("screw_damping_n_s_per_m"),
                "a damping (N·s/m)",
            )?,
            // Worn screws reach tens of µm; a millimetre is beyond any drive.
            backlash_m: in_range(
                d.backlash_um,
                0.0,
                1000.0,
                &p.key("backlash_um"),
                "a backlash (µm)",
            )? * 1e-6,
            cyclic_m: cyclic(d.screw_cyclic_um, &p.key("screw_cyclic_um"))?,
        },
        carriage_mass_kg: moving_mass_kg,
        guide_friction: friction(&d.guide_friction, &p.key("guide_friction"))?,
        screw_friction: friction(&d.screw_friction, &p.key("screw_friction"))?,
        encoder_counts_per_rev: encoder_counts(
            d.encoder_counts_per_rev,
            &p.key("encoder_counts_per_rev"),
        )?,
        torque_constant_n_m_per_a: in_range(
            d.torque_constant_n_m_per_a,
            0.001,
            1000.0,
            &p.key("torque_constant_n_m_per_a"),
            "a torque constant (N·m/A)",
        )?,
        feedback,
    })
}

/// Encoder counts per motor revolution: a whole number from a single-line quadrature encoder's
/// 4 to a 32-bit absolute encoder's 2^32.
fn encoder_counts(v: f64, path: &KeyPath) -> R<f64> {
    const WHAT: &str = "a whole number of counts per revolution";
    let counts = in_range(v, 4.0, 4_294_967_296.0, path, WHAT)?;
    if counts.fract() != 0.0 {
        return Err(Invalid::new(
            path.clone(),
            format!("{counts} is not accepted; {WHAT} from 4 to 4294967296 is accepted"),
        ));
    }
    Ok(counts)
}

/// The screw's periodic lead error, µm -> m: finite, and under a tenth of a millimetre (a
/// larger one is a wrong unit, not a ball screw).
fn cyclic(v: [f64; 2], path: &KeyPath) -> R<[f64; 2]> {
    if v.iter().any(|x| !x.is_finite() || x.abs() > 100.0) {
        return Err(Invalid::new(
            path.clone(),
            format!(
                "{v:?} is not accepted; the cosine and sine amplitudes of the lead error in µm, each finite and within ±100"
            ),
        ));
    }
    Ok(v.map(|x| x * 1e-6))
}

/// The servo of an axis driving `drive`: the velocity gain from the bandwidth and total mass.
pub fn servo(s: &ServoToml, drive: &DriveParams, p: &KeyPath) -> R<ServoParams> {
    let ff = |v: f64, k: &str| -> R<f64> {
        if (0.0..=1.0).contains(&v) {
            Ok(v)
        } else {
            Err(Invalid::new(
                p.key(k),
                format!("{v} is not accepted; a feed-forward factor from 0 to 1"),
            ))
        }
    };
    // Generous bounds around servo drives (Kv 10–100 1/s, velocity loops of tens to hundreds of
    // Hz, current loops of 0.1–2 ms), so that the loop check has numbers it can evaluate.
    let bandwidth = in_range(
        s.velocity_bandwidth_hz,
        0.1,
        1e4,
        &p.key("velocity_bandwidth_hz"),
        "a bandwidth (Hz)",
    )?;
    Ok(ServoParams {
        kv_per_s: in_range(
            s.kv_per_s,
            0.1,
            1e3,
            &p.key("kv_per_s"),
            "a position loop gain (1/s)",
        )?,
        velocity_kp_n_s_per_m: drive.total_mass_kg() * std::f64::consts::TAU * bandwidth,
        velocity_ti_s: in_range(
            s.velocity_integral_ms,
            0.01,
            1e5,
            &p.key("velocity_integral_ms"),
            "an integral time (ms)",
        )? * 1e-3,
        velocity_ff: ff(s.velocity_ff, "velocity_ff")?,
        acceleration_ff: ff(s.acceleration_ff, "acceleration_ff")?,
        current_time_constant_s: in_range(
            s.current_time_constant_ms,
            0.001,
            100.0,
            &p.key("current_time_constant_ms"),
            "a time constant (ms)",
        )? * 1e-3,
        // Feed-axis servo motors peak at a few to a few hundred N·m, direct-drive torque
        // motors at thousands; 10^5 N·m is beyond any of them.
        force_limit_n: positive(
            s.peak_torque_n_m,
            MAX_PEAK_TORQUE_N_M,
            &p.key("peak_torque_n_m"),
            "a peak torque (N·m)",
        )? / drive.screw.m_per_rad(),
        following_error_limit_m: s
            .following_error_limit_mm
            .map(|mm| {
                positive(
                    mm,
                    10_000.0,
                    &p.key("following_error_limit_mm"),
                    "a following-error limit (mm)",
                )
            })
            .transpose()?
            .map(|mm| mm * 1e-3),
    })
}

/// The controller: interpolator settings and plant substeps.
pub fn controller(c: &ControllerToml) -> R<(InterpolatorConfig, usize)> {
    let p = KeyPath::of(&["controller"]);
    let mm_min = 1.0 / 60_000.0;
    // Generous bounds around machine tools (rapids up to 120 m/min, accelerations of 1 to
    // 50 m/s², jerks of 10 to 10^4 m/s³, corner tolerances of µm to tenths of a mm): a limit
    // near zero stretches a program beyond the interpolator, which would be refused at [job].
    let accel = |v: f64, key: KeyPath| in_range(v, 0.01, 1000.0, &key, "an acceleration (m/s²)");
    let mut axis_accel = [0.0; 3];
    for (i, (slot, v)) in axis_accel.iter_mut().zip(c.axis_accel_m_s2.0).enumerate() {
        *slot = accel(v, p.key("axis_accel_m_s2").index(i))?;
    }
    let speed = |v: f64, key: &str, what: &str| in_range(v, 1.0, 1e6, &p.key(key), what);
    let rapid = speed(c.rapid_mm_min, "rapid_mm_min", "a rapid rate (mm/min)")? * mm_min;
    let limits = Limits {
        rapid_m_s: rapid,
        max_feed_m_s: speed(c.max_feed_mm_min, "max_feed_mm_min", "a feed (mm/min)")? * mm_min,
        path_accel_m_s2: accel(c.path_accel_m_s2, p.key("path_accel_m_s2"))?,
        path_jerk_m_s3: in_range(
            c.path_jerk_m_s3,
            0.1,
            1e6,
            &p.key("path_jerk_m_s3"),
            "a jerk (m/s³)",
        )?,
        axis_velocity_m_s: [rapid; 3],
        axis_accel_m_s2: axis_accel,
        corner_tolerance_m: in_range(
            c.corner_tolerance_um,
            0.001,
            10_000.0,
            &p.key("corner_tolerance_um"),
            "a tolerance (µm)",
        )? * 1e-6,
    };
    let config = InterpolatorConfig {
        limits,
        ipo_period_s: in_range(
            c.ipo_period_ms,
            0.01,
            100.0,
            &p.key("ipo_period_ms"),
            "a period (ms)",
        )? * 1e-3,
        servo_period_s: in_range(
            c.servo_period_us,
            10.0,
            10_000.0,
            &p.key("servo_period_us"),
            "a period (µs)",
        )? * 1e-6,
        exact_stop: c.exact_stop,
    };
    config.validate().map_err(|e| {
        use vmt_sim::interpolator::InterpolatorError as E;
        let key = match e {
            E::JerkWindowTooShort { .. } => p.key("path_jerk_m_s3"),
            E::ServoPeriodNotDivisor { .. } => p.key("servo_period_us"),
            _ => p.clone(),
        };
        Invalid::new(key, e.to_string())
    })?;
    if !(1..=64).contains(&c.plant_substeps) {
        return Err(Invalid::new(
            p.key("plant_substeps"),
            format!(
                "{} is not accepted; 1 to 64 plant steps per servo period",
                c.plant_substeps
            ),
        ));
    }
    Ok((config, c.plant_substeps))
}

/// Simulation settings; the log is taken at servo ticks of `servo_period_s`.
pub fn simulation(s: &SimulationToml, substeps: usize, servo_period_s: f64) -> R<SimSettings> {
    let p = KeyPath::of(&["simulation"]);
    let fidelity = match s.fidelity.as_str() {
        "reduced" => Fidelity::Reduced,
        "multibody" => Fidelity::Multibody,
        "compliant" => Fidelity::Compliant,
        other => {
            return Err(Invalid::new(
                p.key("fidelity"),
                format!(
                    "`{other}` is not accepted; \"reduced\", \"multibody\" or \"compliant\" (the multibody on compliant guide blocks, which needs every axis' carriage)"
                ),
            ));
        }
    };
    Ok(SimSettings {
        fidelity,
        plant_substeps: substeps,
        log_rate_hz: match s.log_rate_hz {
            Some(rate) => log_rate(rate, servo_period_s, &p.key("log_rate_hz"))?,
            None => DEFAULT_LOG_RATE_HZ.min(1.0 / servo_period_s),
        },
        seed: s.seed,
    })
}

/// The log rate when none is given, Hz.
const DEFAULT_LOG_RATE_HZ: f64 = 1000.0;

/// A log rate above 0 and at most the servo rate (the run's own check, made here where the
/// error can name the key), and a whole number of servo ticks per sample.
fn log_rate(rate: f64, servo_period_s: f64, path: &KeyPath) -> R<f64> {
    let servo_hz = 1.0 / servo_period_s;
    if !(rate > 0.0 && rate <= servo_hz) {
        return Err(Invalid::new(
            path.clone(),
            format!(
                "{} is out of range; a log rate in Hz above 0 and up to the servo rate, {} (1 / controller.servo_period_us), is accepted",
                typed(rate),
                (servo_hz * 1e6).round() / 1e6
            ),
        ));
    }
    match off_the_ticks(rate, servo_period_s, "the log") {
        Some(msg) => Err(Invalid::new(path.clone(), msg)),
        None => Ok(rate),
    }
}

/// Why `rate` (Hz, at most the servo rate) cannot be a rate of `what`, sampled at servo ticks of
/// `servo_period_s`: it is no whole number of ticks per sample (a rate of 3 kHz at 8 kHz would
/// be taken every 3 ticks, at 2.667 kHz). The run rounds within 1e-9, as it counts ticks.
pub(crate) fn off_the_ticks(rate: f64, servo_period_s: f64, what: &str) -> Option<String> {
    let servo_hz = 1.0 / servo_period_s;
    let ticks = servo_hz / rate;
    let every = ticks.round().max(1.0);
    if (ticks / every - 1.0).abs() <= 1e-9 {
        return None;
    }
    let (fewer, more) = (ticks.floor().max(1.0), ticks.ceil());
    let hz = |n: f64| (servo_hz / n * 1e3).round() / 1e3;
    Some(format!(
        "{} Hz is not accepted: {what} is sampled at servo ticks ({} Hz, 1 / controller.servo_period_us), so its rate is the servo rate over a whole number of ticks; the nearest are {} Hz (every {fewer} ticks) and {} Hz (every {more})",
        typed(rate),
        hz(1.0),
        hz(fewer),
        hz(more),
    ))
}

/// The bar of a job with one pivot (a program's circles, Kwon's steps): one set-up offset.
fn ballbar_spec(b: Option<&BallbarToml>) -> R<BallbarSpec> {
    Ok(ballbar_specs(b, 1)?.remove(0))
}

/// The bar as set up at each of `centres` pivots: `setup_eccentricity_um` one offset for all,
/// or a list of one per centre.
fn ballbar_specs(b: Option<&BallbarToml>, centres: usize) -> R<Vec<BallbarSpec>> {
    let Some(b) = b else {
        return Ok(vec![BallbarSpec::default(); centres]);
    };
    let p = KeyPath::of(&["instruments", "ballbar"]);
    let key = p.key("setup_eccentricity_um");
    let offsets = match &b.setup_eccentricity_um {
        Points::One(e) => vec![(e, key); centres],
        Points::Many(v) if v.len() == centres => v
            .iter()
            .enumerate()
            .map(|(i, e)| (e, key.index(i)))
            .collect(),
        Points::Many(v) => {
            let msg = format!(
                "{} offsets are not accepted; one [x, y, z] for every pivot, or a list of one per centre of the job ({centres})",
                v.len()
            );
            return Err(Invalid::new(key, msg));
        }
    };
    let spec = bar_spec(b, &p)?;
    offsets
        .into_iter()
        .map(|(e, key)| {
            // Within the bar's ±1 mm range.
            let what = "an offset of the pivot within the bar's range (µm)";
            Ok(BallbarSpec {
                setup_eccentricity_m: within3(e, 1000.0, &key, what)? * 1e-6,
                ..spec
            })
        })
        .collect()
}

/// The bar's settings other than its set-up offset.
fn bar_spec(b: &BallbarToml, p: &KeyPath) -> R<BallbarSpec> {
    let within = |v: f64, key: &str, (lo, hi): (f64, f64), what: &str| -> R<f64> {
        if (lo..=hi).contains(&v) {
            Ok(v)
        } else {
            Err(Invalid::new(
                p.key(key),
                format!("{v} is not accepted; {what} from {lo} to {hi}"),
            ))
        }
    };
    Ok(BallbarSpec {
        // A ball bar's range is ±1 mm; it resolves 0.1 µm with noise well below a micrometre.
        resolution_m: in_range(
            b.resolution_um,
            0.0,
            100.0,
            &p.key("resolution_um"),
            "a resolution (µm)",
        )? * 1e-6,
        noise_m: in_range(b.noise_um, 0.0, 100.0, &p.key("noise_um"), "a noise (µm)")? * 1e-6,
        sample_rate_hz: pos(b.sample_rate_hz, &p.key("sample_rate_hz"), "a sample rate")?,
        setup_eccentricity_m: Vector3::zeros(),
        // A drift that leaves the bar's range only after ten minutes.
        setup_drift_m_per_s: within3(
            &b.setup_drift_um_per_min,
            100.0,
            &p.key("setup_drift_um_per_min"),
            "a drift of the pivot (µm/min)",
        )? * (1e-6 / 60.0),
        bar_temperature_c: within(
            b.bar_temperature_c,
            "bar_temperature_c",
            (-50.0, 150.0),
            "a workshop temperature (°C)",
        )?,
        // Invar and carbon fibre near 0, steel 11.5e-6, aluminium 23e-6.
        bar_alpha_per_k: within(
            b.bar_alpha_per_k,
            "bar_alpha_per_k",
            (-5e-6, 5e-5),
            "an expansion coefficient (1/K)",
        )?,
        range_m: within(
            b.range_um,
            "range_um",
            (1.0, 2000.0),
            "a measuring range (± µm; ball bars read ±1000)",
        )? * 1e-6,
    })
}

fn laser_spec(l: Option<&LaserToml>) -> R<LaserSpec> {
    let Some(l) = l else {
        return Ok(LaserSpec::default());
    };
    let p = KeyPath::of(&["instruments", "laser"]);
    let range =
        |v: f64, k: &str, (lo, hi): (f64, f64), what: &str| in_range(v, lo, hi, &p.key(k), what);
    // Physical ranges: interferometers resolve 0.001 to 10 nm with tens of nm of noise per
    // sample and measure up to 80 m; a weather station off by more than 30 K, 300 hPa (sea
    // level against 2000 m) or the whole humidity scale, or a material sensor off by more than
    // 30 K, or air drifting by more than 10 K/h, is a wrong unit or no sensor at all.
    Ok(LaserSpec {
        resolution_m: range(
            l.resolution_nm,
            "resolution_nm",
            (0.0, 1000.0),
            "a resolution (nm)",
        )? * 1e-9,
        noise_m: range(l.noise_nm, "noise_nm", (0.0, 1000.0), "a noise (nm)")? * 1e-9,
        sample_rate_hz: laser_rate(l.sample_rate_hz, &p.key("sample_rate_hz"))?,
        averaging_s: pos(l.averaging_s, &p.key("averaging_s"), "an averaging time")?,
        air_temperature_error_k: range(
            l.air_temperature_error_k,
            "air_temperature_error_k",
            (-30.0, 30.0),
            "a temperature error (K)",
        )?,
        air_pressure_error_hpa: range(
            l.air_pressure_error_hpa,
            "air_pressure_error_hpa",
            (-300.0, 300.0),
            "a pressure error (hPa)",
        )?,
        humidity_error_percent: range(
            l.humidity_error_percent,
            "humidity_error_percent",
            (-100.0, 100.0),
            "a humidity error (%RH)",
        )?,
        material_temperature_error_k: range(
            l.material_temperature_error_k,
            "material_temperature_error_k",
            (-30.0, 30.0),
            "a temperature error (K)",
        )?,
        // Invar and CFRP near 0 (slightly negative), steel 11.5e-6, aluminium 23e-6: the range
        // of the machine's own `expansion.alpha_per_k`.
        material_alpha_per_k: range(
            l.material_alpha_per_k,
            "material_alpha_per_k",
            (-1e-5, 1e-4),
            "an expansion coefficient (1/K)",
        )?,
        dead_path_m: range(
            l.dead_path_mm,
            "dead_path_mm",
            (0.0, 100_000.0),
            "a dead path (mm)",
        )? * 1e-3,
        air_drift_k_per_s: range(
            l.air_drift_k_per_h,
            "air_drift_k_per_h",
            (-10.0, 10.0),
            "an air temperature drift (K/h)",
        )? / 3600.0,
    })
}

/// A laser's sample rate: interferometers sample at tens of Hz to tens of kHz; the upper
/// bound, the servo rate, is checked with the controller.
fn laser_rate(rate: f64, path: &KeyPath) -> R<f64> {
    if rate.is_finite() && rate >= 1.0 {
        return Ok(rate);
    }
    Err(Invalid::new(
        path.clone(),
        format!(
            "{} is out of range; a sample rate in Hz from 1 to the servo rate (1 / controller.servo_period_us) is accepted",
            typed(rate)
        ),
    ))
}

fn plane_of(name: &str, path: KeyPath) -> R<Plane> {
    match name.to_ascii_uppercase().as_str() {
        "XY" => Ok(Plane::Xy),
        "ZX" | "XZ" => Ok(Plane::Zx),
        "YZ" => Ok(Plane::Yz),
        other => Err(Invalid::new(
            path,
            format!("`{other}` is not accepted; XY, ZX or YZ"),
        )),
    }
}

/// The job, its program and instruments, on `machine` (its strokes give a ball-bar job's
/// default centre, its tool offset a program's start); `base_dir` resolves program files.
pub fn job(
    j: &JobToml,
    instruments: &InstrumentsToml,
    machine: &Machine,
    base_dir: Option<&Path>,
) -> Result<Job, BuildError> {
    let p = KeyPath::of(&["job"]);
    let tool_offset = machine.volumetric.kinematics.tool_offset;
    match j {
        JobToml::Ballbar(b) => Ok(ballbar_job(b, instruments, machine)?),
        JobToml::Program { program } => {
            let bar = instruments.ballbar.as_ref();
            program_job(program, tool_offset, base_dir, &p, Some(bar))
        }
        JobToml::Milling(m) => program_job(&m.program, tool_offset, base_dir, &p, None),
        JobToml::Iso230_2(t) => Ok(positioning_job(t, instruments)?),
        JobToml::KwonSevenStep { pivot_mm, steps } => Ok(kwon_job(pivot_mm, steps, instruments)?),
    }
}

fn ballbar_job(b: &BallbarJobToml, instruments: &InstrumentsToml, machine: &Machine) -> R<Job> {
    let p = KeyPath::of(&["job"]);
    let radii = b.radius_mm.list();
    if radii.is_empty() || radii.len() > MAX_RADII {
        let msg = format!(
            "{} radii are not accepted; a radius (mm) or a list of 1 to {MAX_RADII} radii is accepted",
            radii.len()
        );
        return Err(Invalid::new(p.key("radius_mm"), msg));
    }
    let centres = centres(b, machine, &p)?;
    let specs = ballbar_specs(instruments.ballbar.as_ref(), centres.len())?;
    let (mut text, mut ballbar, mut blocks, mut start) = (String::new(), Vec::new(), 0, None);
    let tests = centres.iter().zip(specs).flat_map(|(centre, spec)| {
        radii
            .iter()
            .enumerate()
            .map(move |(k, &r)| (centre, spec, k, r))
    });
    for ((center, center_key), spec, k, r) in tests {
        let radius_key = match b.radius_mm {
            Radii::One(_) => p.key("radius_mm"),
            Radii::Many(_) => p.key("radius_mm").index(k),
        };
        let keys = TestKeys {
            job: &p,
            center: center_key,
            radius: &radius_key,
        };
        let test = circular_test(b, *center, r, &keys)?;
        // Each test's program without its end, the end once after the last.
        let gcode: String = test
            .gcode()
            .lines()
            .filter(|l| l.trim() != "M30")
            .map(|l| format!("{l}\n"))
            .collect();
        let own = parse(&gcode, test.start_point())
            .map_err(|e| Invalid::new(p.clone(), e.to_string()))?;
        let data = test.data_blocks(&own).unwrap_or_default();
        ballbar.push(BallbarSetup {
            name: None,
            spec,
            center: test.center,
            radius_m: test.radius_m,
            plane: test.plane,
            feed_m_s: test.feed_m_s,
            data: data
                .into_iter()
                .map(|(d, r)| (d, r.start + blocks..r.end + blocks))
                .collect(),
            circle: None,
        });
        blocks += own.blocks.len();
        start.get_or_insert(test.start_point());
        text.push_str(&gcode);
    }
    text.push_str("M30\n");
    let program = parse(&text, start.unwrap_or_default())
        .map_err(|e| Invalid::new(p.clone(), e.to_string()))?;
    if program.blocks.len() != blocks {
        return Err(Invalid::new(
            p.key("radius_mm"),
            "the joined program of the circles does not parse as its parts",
        ));
    }
    Ok(Job {
        program,
        ballbar,
        laser: None,
    })
}

/// The centres of a ball-bar job's circles, m, each with its key (`job.center_mm` or its
/// element): the one given, each of a list, or the tool point with every carriage at the
/// middle of its stroke.
fn centres(b: &BallbarJobToml, machine: &Machine, p: &KeyPath) -> R<Vec<(Vector3<f64>, KeyPath)>> {
    let key = p.key("center_mm");
    let list = match &b.center_mm {
        None => return Ok(vec![(machine.mid_stroke_tool_point(), key)]),
        Some(Points::One(c)) => vec![(c, key)],
        Some(Points::Many(v)) if (1..=MAX_CENTRES).contains(&v.len()) => v
            .iter()
            .enumerate()
            .map(|(i, c)| (c, key.index(i)))
            .collect(),
        Some(Points::Many(v)) => {
            let msg = format!(
                "{} centres are not accepted; a centre [x, y, z] (mm) or a list of 1 to {MAX_CENTRES}",
                v.len()
            );
            return Err(Invalid::new(key, msg));
        }
    };
    Ok(list
        .into_iter()
        .map(|(c, key)| (Vector3::from(c.0) * 1e-3, key))
        .collect())
}

/// The keys a circular test's refusals name.
struct TestKeys<'a> {
    job: &'a KeyPath,
    center: &'a KeyPath,
    radius: &'a KeyPath,
}

/// The ball-bar job's test about `center` (m), validated, each refusal at its key.
fn circular_test(
    b: &BallbarJobToml,
    center: Vector3<f64>,
    radius_mm: f64,
    keys: &TestKeys,
) -> R<CircularTest> {
    let p = keys.job;
    let plane = plane_of(&b.plane, p.key("plane"))?;
    let mut test =
        CircularTest::iso230_4(plane, center, radius_mm * 1e-3, b.feed_mm_min / 60_000.0);
    test.arc_deg = b.arc_deg;
    test.start_deg = b
        .start_deg
        .unwrap_or_else(|| default_start_deg(plane, b.arc_deg));
    test.overshoot_deg = b.overshoot_deg;
    test.feed_in_m = b.feed_in_mm * 1e-3;
    test.directions = directions(&b.directions, p)?;
    test.validate().map_err(|e| {
        use vmt_sim::nc::ballbar::TestParameter as T;
        let key = match e.parameter {
            T::Center => keys.center.clone(),
            T::Radius => keys.radius.clone(),
            T::Feed => p.key("feed_mm_min"),
            T::Arc => p.key("arc_deg"),
            T::Start => p.key("start_deg"),
            T::Overshoot => p.key("overshoot_deg"),
            T::FeedIn => p.key("feed_in_mm"),
            T::Directions => p.key("directions"),
            // Not a key of [job]: the generator's default.
            T::Approach => p.clone(),
        };
        Invalid::new(key, e.to_string())
    })?;
    Ok(test)
}

/// The runs of a ball-bar job, each `cw` or `ccw`.
fn directions(names: &[String], p: &KeyPath) -> R<Vec<ArcDirection>> {
    // Each direction is a whole circle in the generated program and its traces.
    if names.len() > MAX_DIRECTIONS {
        let msg = format!(
            "{} directions are not accepted; a list of up to {MAX_DIRECTIONS} directions (cw, ccw) is accepted",
            names.len()
        );
        return Err(Invalid::new(p.key("directions"), msg));
    }
    names
        .iter()
        .enumerate()
        .map(|(i, d)| match d.to_ascii_lowercase().as_str() {
            "cw" => Ok(ArcDirection::Cw),
            "ccw" => Ok(ArcDirection::Ccw),
            other => Err(Invalid::new(
                p.key("directions").index(i),
                format!("`{other}` is not accepted; cw or ccw"),
            )),
        })
        .collect()
}

/// A job of an NC program file (relative to the scenario's folder). `ballbar` is `None` for a
/// job that records no ball bar (milling), else the `[instruments.ballbar]` table if any: the
/// bar then records every circle between the program's DATA markers ([`marked_ballbar`]; a
/// program without them records none, which [`instrument_notes`] says).
fn program_job(
    program: &str,
    tool_offset: Vector3<f64>,
    base_dir: Option<&Path>,
    p: &KeyPath,
    ballbar: Option<Option<&BallbarToml>>,
) -> Result<Job, BuildError> {
    let Some(dir) = base_dir else {
        return Err(Invalid::new(
            p.key("program"),
            "the built-in scenario cannot refer to files",
        )
        .into());
    };
    let path = dir.join(program);
    let file = path.display().to_string();
    let text = std::fs::read_to_string(&path)
        .map_err(|e| crate::build::external(&file, None, format!("cannot read: {e}")))?;
    let program = parse(&text, tool_offset)
        .map_err(|e| crate::build::external(&file, Some((e.line, e.column)), e.message.clone()))?;
    if program.blocks.is_empty() {
        let msg = "the program has no blocks to run (no motion, dwell or spindle command)";
        return Err(crate::build::external(&file, None, msg.to_string()));
    }
    let ballbar = match ballbar {
        Some(bar) => marked_ballbar(&text, &program, bar, &file)?,
        None => Vec::new(),
    };
    Ok(Job {
        program,
        ballbar,
        laser: None,
    })
}

/// The ball bar of a program job: one set-up per circle its DATA markers measure
/// ([`marked_circles`]), the bar as `[instruments.ballbar]` gives it (or the default bar, as a
/// ball-bar job has).
fn marked_ballbar(
    text: &str,
    program: &Program,
    bar: Option<&BallbarToml>,
    file: &str,
) -> Result<Vec<BallbarSetup>, BuildError> {
    let circles = marked_circles(text, program)
        .map_err(|e| crate::build::external(file, Some((e.line, e.column)), e.message.clone()))?;
    let spec = ballbar_spec(bar)?;
    Ok(circles
        .into_iter()
        .map(|c| BallbarSetup {
            name: None,
            spec,
            center: c.center,
            radius_m: c.radius_m,
            plane: c.plane,
            feed_m_s: c.feed_m_s,
            data: c.runs,
            circle: None,
        })
        .collect())
}

/// What the job accepts but does not do, for the command running it to say: an instrument
/// table the kind of job does not read (a ball bar on a cut, a laser on a circular test, an
/// accelerometer off a cut), and a program job given `[instruments.ballbar]` whose program
/// marks no data arc.
pub fn instrument_notes(j: &JobToml, instruments: &InstrumentsToml, job: &Job) -> Vec<String> {
    let (kind, reads) = match j {
        JobToml::Ballbar(_) => ("ballbar", ["ballbar"].as_slice()),
        JobToml::KwonSevenStep { .. } => ("kwon_seven_step", ["ballbar"].as_slice()),
        JobToml::Program { .. } => ("program", ["ballbar"].as_slice()),
        JobToml::Iso230_2(_) => ("iso230_2", ["laser"].as_slice()),
        JobToml::Milling(_) => ("milling", ["accelerometer"].as_slice()),
    };
    let given = [
        (
            "ballbar",
            instruments.ballbar.is_some(),
            "ballbar, kwon_seven_step or program",
        ),
        ("laser", instruments.laser.is_some(), "iso230_2"),
        (
            "accelerometer",
            instruments.accelerometer.is_some(),
            "milling",
        ),
    ];
    let mut notes: Vec<String> = given
        .into_iter()
        .filter(|(name, is, _)| *is && !reads.contains(name))
        .map(|(name, _, by)| {
            format!(
                "[instruments.{name}] records nothing: a `{kind}` job does not use it (a job of kind {by} does)"
            )
        })
        .collect();
    if let JobToml::Program { program } = j
        && instruments.ballbar.is_some()
        && job.ballbar.is_empty()
    {
        notes.push(format!(
            "[instruments.ballbar] records nothing: {program} marks no data arc with \
             (DATA CW START) ... (DATA CW END) lines (or CCW), as `vmt program ballbar` \
             writes them"
        ));
    }
    notes
}

/// Most circles of one ball-bar job.
const MAX_DIRECTIONS: usize = 8;

/// Most radii of one ball-bar job.
pub const MAX_RADII: usize = 8;

/// Most centres a ball-bar job runs its circles about.
pub const MAX_CENTRES: usize = 4;

/// Most targets and runs of an ISO 230-2 job, bounded before its program (two dwells per target
/// and run) is generated. The standard asks for 5 runs over at least 5 targets per metre: a 5 m
/// axis at 1 mm steps has 5000 targets (the program's length is checked after).
const MAX_TARGETS: usize = 10_000;
/// The closest two targets may be, mm: what the evaluation accepts
/// (`vmt_positioning::run::MIN_TARGET_SPACING_MM`, 1 µm).
const MIN_TARGET_SPACING_MM: f64 = 1e-3;
const MAX_RUNS: usize = 100;
/// Longest dwell at a target of an ISO 230-2 job, s: the standard's dwells last seconds (long
/// enough for the axis to settle and the reading to be averaged); an hour at every target
/// measures the machine's thermal drift (ISO 230-3), not its positioning.
const MAX_DWELL_S: f64 = 3600.0;

/// Most steps of a Kwon job: the seven, each up to four times.
const MAX_KWON_STEPS: usize = 7 * 4;

/// The ISO 230-2 targets: `targets_mm`, or `count` evenly spaced over `range_mm`, m.
fn targets(
    list: &Option<Vec<f64>>,
    range: &Option<[f64; 2]>,
    count: &Option<usize>,
    p: &KeyPath,
) -> R<Vec<f64>> {
    let mm = match (list, range, count) {
        (Some(t), None, None) => {
            if t.len() > MAX_TARGETS {
                let msg = format!(
                    "{} targets are not accepted; a list of up to {MAX_TARGETS} targets is accepted",
                    t.len()
                );
                return Err(Invalid::new(p.key("targets_mm"), msg));
            }
            t.clone()
        }
        (None, Some([a, b]), Some(n)) => {
            if !(a.is_finite() && b.is_finite() && b > a) {
                return Err(Invalid::new(
                    p.key("range_mm"),
                    format!("[{a}, {b}] is not accepted; an increasing pair of finite numbers"),
                ));
            }
            let n = count_in_range(
                *n,
                2,
                MAX_TARGETS,
                &p.key("count"),
                "a number of targets (ISO 230-2 asks for 5 per metre, at least 5)",
            )?;
            (0..n)
                .map(|i| a + (b - a) * i as f64 / (n - 1) as f64)
                .collect()
        }
        _ => {
            return Err(Invalid::new(
                p.clone(),
                "give the targets as targets_mm = [..] or as range_mm = [first, last] with count = n",
            ));
        }
    };
    if mm.len() < 2
        || mm.iter().any(|v| !v.is_finite())
        || mm.windows(2).any(|w| w[1] - w[0] < MIN_TARGET_SPACING_MM)
    {
        let key = if list.is_some() {
            "targets_mm"
        } else {
            "count"
        };
        return Err(Invalid::new(
            p.key(key),
            format!(
                "at least two finite target positions in increasing order, at least \
                 {MIN_TARGET_SPACING_MM} mm apart (mm)"
            ),
        ));
    }
    Ok(mm.into_iter().map(|v| v * 1e-3).collect())
}

fn positioning_job(j: &PositioningToml, instruments: &InstrumentsToml) -> R<Job> {
    let PositioningToml {
        axis,
        targets_mm,
        range_mm,
        count,
        runs,
        dwell_s,
        feed_mm_min,
        overrun_mm,
        beam_line_mm,
    } = j;
    let p = KeyPath::of(&["job"]);
    let upper = axis.to_ascii_uppercase();
    let Some(axis) = upper.parse::<char>().ok().and_then(Axis::from_letter) else {
        let msg = format!("`{upper}` is not accepted; X, Y or Z");
        return Err(Invalid::new(p.key("axis"), msg));
    };
    count_in_range(
        *runs,
        2,
        MAX_RUNS,
        &p.key("runs"),
        "a number of runs (ISO 230-2 asks for 5)",
    )?;
    let mut line = Vector3::zeros();
    let others: Vec<usize> = (0..3).filter(|&i| i != axis.index()).collect();
    for (k, (&i, v)) in others.iter().zip(beam_line_mm.0).enumerate() {
        if !v.is_finite() {
            return Err(Invalid::new(
                p.key("beam_line_mm").index(k),
                format!("{v} is not accepted; a finite coordinate (mm)"),
            ));
        }
        line[i] = v * 1e-3;
    }
    let dwell = positive(*dwell_s, MAX_DWELL_S, &p.key("dwell_s"), "a dwell (s)")?;
    let spec = laser_spec(instruments.laser.as_ref())?;
    if spec.averaging_s > dwell {
        return Err(Invalid::new(
            KeyPath::of(&["instruments", "laser", "averaging_s"]),
            format!(
                "{} s is not accepted; the averaging must fit in the dwell (job.dwell_s = {dwell} s)",
                spec.averaging_s
            ),
        ));
    }
    let test = PositioningTest {
        axis,
        targets_m: targets(targets_mm, &range_mm.map(|r| r.0), count, &p)?,
        line_m: line,
        runs: *runs,
        dwell_s: dwell,
        // The feeds a test program may ask for (its F word has one decimal).
        feed_m_s: in_range(
            *feed_mm_min,
            vmt_sim::nc::ballbar::FEED_RANGE_MM_MIN.0,
            vmt_sim::nc::ballbar::FEED_RANGE_MM_MIN.1,
            &p.key("feed_mm_min"),
            "a feed in mm/min",
        )? / 60_000.0,
        overrun_m: pos(*overrun_mm, &p.key("overrun_mm"), "an overrun")? * 1e-3,
    };
    test.validate().map_err(|m| Invalid::new(p.clone(), m))?;
    let (text, datum_block, measurements) = test.gcode();
    let program =
        parse(&text, test.start_point()).map_err(|e| Invalid::new(p.clone(), e.to_string()))?;
    test.check_program(&program, datum_block, &measurements)
        .map_err(|e| Invalid::new(p.clone(), e.to_string()))?;
    Ok(Job {
        program,
        ballbar: Vec::new(),
        laser: Some(LaserSetup {
            spec,
            test,
            datum_block,
            measurements,
        }),
    })
}

/// Kwon's steps in a row as one program (each step's program without its M30, the bar
/// remounted at the next step's start point), one ball-bar set-up per step.
fn kwon_job(pivot_mm: &[f64; 3], steps: &[u8], instruments: &InstrumentsToml) -> R<Job> {
    let p = KeyPath::of(&["job"]);
    if pivot_mm.iter().any(|v| !v.is_finite()) {
        return Err(Invalid::new(
            p.key("pivot_mm"),
            "every coordinate of the centre ball must be a finite number (mm)",
        ));
    }
    let all = kwon_steps(Vector3::from(*pivot_mm) * 1e-3);
    if steps.is_empty() {
        return Err(Invalid::new(
            p.key("steps"),
            "give at least one step, 1 to 7",
        ));
    }
    if steps.len() > MAX_KWON_STEPS {
        let msg = format!(
            "{} steps are not accepted; a list of up to {MAX_KWON_STEPS} steps (each of 1 to 7) is accepted",
            steps.len()
        );
        return Err(Invalid::new(p.key("steps"), msg));
    }
    let spec = ballbar_spec(instruments.ballbar.as_ref())?;
    let mut text = String::new();
    let mut ballbar = Vec::new();
    let mut blocks = 0;
    for (k, &n) in steps.iter().enumerate() {
        let Some(step) = all.iter().find(|s| s.number == n) else {
            return Err(Invalid::new(
                p.key("steps").index(k),
                format!("{n} is not accepted; Kwon's steps are 1 to 7"),
            ));
        };
        let t = &step.test;
        let gcode: String = t
            .gcode_with_header(&[&format!("Kwon's seven-step procedure, step {n}")])
            .lines()
            .filter(|l| l.trim() != "M30")
            .map(|l| format!("{l}\n"))
            .collect();
        let own =
            parse(&gcode, t.start_point()).map_err(|e| Invalid::new(p.clone(), e.to_string()))?;
        let data = t.data_blocks(&own).ok_or_else(|| {
            Invalid::new(
                p.clone(),
                format!("step {n}: its program lost its data arcs"),
            )
        })?;
        ballbar.push(BallbarSetup {
            name: Some(format!("step {n}")),
            spec,
            center: step.pivot,
            radius_m: step.link_length_m,
            plane: t.plane,
            feed_m_s: t.feed_m_s,
            circle: Some((t.center, t.radius_m)),
            data: data
                .into_iter()
                .map(|(d, r)| (d, r.start + blocks..r.end + blocks))
                .collect(),
        });
        blocks += own.blocks.len();
        text.push_str(&gcode);
    }
    text.push_str("M30\n");
    let start = all
        .iter()
        .find(|s| s.number == steps[0])
        .map_or(Vector3::zeros(), |s| s.test.start_point());
    let program = parse(&text, start).map_err(|e| Invalid::new(p.clone(), e.to_string()))?;
    if program.blocks.len() != blocks {
        return Err(Invalid::new(
            p.clone(),
            "the joined program of the steps does not parse as its parts",
        ));
    }
    Ok(Job {
        program,
        ballbar,
        laser: None,
    })
}

/// All axes' dynamics, if every axis has both a drive and a servo section.
pub fn axes(
    raw: [(&Option<DriveToml>, &Option<ServoToml>); 3],
    moving: [f64; 3],
) -> R<Option<[AxisDynamics; 3]>> {
    let mut out = Vec::new();
    for (i, (d, s)) in raw.into_iter().enumerate() {
        let name = ["x", "y", "z"][i];
        let p = KeyPath::of(&["machine", "axes", name]);
        match (d, s) {
            (Some(d), Some(s)) => {
                let drive = drive(d, moving[i], &p.key("drive"))?;
                let servo = servo(s, &drive, &p.key("servo"))?;
                let effects = crate::effects::drive_effects(d, &drive, &p.key("drive"))?;
                out.push(AxisDynamics {
                    drive,
                    servo,
                    effects,
                });
            }
            (None, None) => return Ok(None),
            (Some(_), None) => {
                return Err(Invalid::new(
                    p.clone(),
                    "a drive needs its servo section [machine.axes.<axis>.servo]",
                ));
            }
            (None, Some(_)) => {
                return Err(Invalid::new(
                    p.clone(),
                    "a servo needs its drive section [machine.axes.<axis>.drive]",
                ));
            }
        }
    }
    Ok(out.try_into().ok())
}
