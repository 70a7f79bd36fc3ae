//! Scenario sections for milling: the tool table (`[tools.T1]`: geometry and the tool point's
//! modes), the cut of a `kind = "milling"` job (material coefficients, depths, up or down
//! milling, cut step) and `[instruments.accelerometer]`. Engineering units in the keys are
//! converted to SI here. See `scenarios/milling_slot.toml`.

use crate::error::{Invalid, KeyPath};
use serde::Deserialize;
use std::collections::BTreeMap;
use vmt_model::cutting::{
    CutGeometry, CuttingCoefficients, CuttingError, EndMill, MillingDirection, Mode, ToolDynamics,
};
use vmt_sim::machining::MillingJob;
use vmt_sim::milling::{AccelerometerParams, MIN_STEPS_PER_PERIOD, MillingError, MillingSetup};

/// One tool of the tool table.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ToolTableToml {
    pub diameter_mm: f64,
    pub teeth: usize,
    #[serde(default)]
    pub helix_deg: f64,
    pub flute_length_mm: f64,
    #[serde(default)]
    pub runout_um: f64,
    #[serde(default)]
    pub runout_angle_deg: f64,
    pub modes_x: Vec<ModeToml>,
    pub modes_y: Vec<ModeToml>,
}

/// One mode of the tool point.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModeToml {
    pub frequency_hz: f64,
    pub damping_ratio: f64,
    pub stiffness_n_per_um: f64,
}

/// Mechanistic coefficients of the tool–material pair, N/mm² and N/mm.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialToml {
    pub kt_n_per_mm2: f64,
    pub kr_n_per_mm2: f64,
    #[serde(default)]
    pub ka_n_per_mm2: f64,
    #[serde(default)]
    pub kte_n_per_mm: f64,
    #[serde(default)]
    pub kre_n_per_mm: f64,
    #[serde(default)]
    pub kae_n_per_mm: f64,
}

/// A tool of the table in the model's types.
pub struct Tool {
    pub mill: EndMill,
    pub dynamics: ToolDynamics,
}

/// Looks tool `name` up in the table and converts it; errors name the key.
pub fn tool(
    tools: &BTreeMap<String, ToolTableToml>,
    name: &str,
    at: &KeyPath,
) -> Result<Tool, Invalid> {
    let Some(t) = tools.get(name) else {
        let known: Vec<&str> = tools.keys().map(String::as_str).collect();
        return Err(Invalid::new(
            at.clone(),
            format!("tool `{name}` is not in the tool table; [tools] holds {known:?}"),
        ));
    };
    let p = KeyPath::of(&["tools", name]);
    let mill = EndMill {
        diameter: t.diameter_mm * 1e-3,
        teeth: t.teeth,
        helix: t.helix_deg.to_radians(),
        flute_length: t.flute_length_mm * 1e-3,
        runout: t.runout_um * 1e-6,
        runout_angle: t.runout_angle_deg.to_radians(),
    };
    mill.validate().map_err(|e| located(&p, &e, "teeth"))?;
    let modes = |list: &[ModeToml]| -> Vec<Mode> {
        list.iter()
            .map(|m| Mode {
                natural_frequency_hz: m.frequency_hz,
                damping_ratio: m.damping_ratio,
                stiffness: m.stiffness_n_per_um * 1e6,
            })
            .collect()
    };
    let dynamics = ToolDynamics {
        x: modes(&t.modes_x),
        y: modes(&t.modes_y),
    };
    dynamics
        .validate()
        .map_err(|e| mode_error(&p, &e, t.modes_x.len()))?;
    Ok(Tool { mill, dynamics })
}

/// The material's coefficients in SI.
pub fn coefficients(m: &MaterialToml, p: &KeyPath) -> Result<CuttingCoefficients, Invalid> {
    let c = CuttingCoefficients {
        tangential: m.kt_n_per_mm2 * 1e6,
        radial: m.kr_n_per_mm2 * 1e6,
        axial: m.ka_n_per_mm2 * 1e6,
        tangential_edge: m.kte_n_per_mm * 1e3,
        radial_edge: m.kre_n_per_mm * 1e3,
        axial_edge: m.kae_n_per_mm * 1e3,
    };
    c.validate()
        .map_err(|e| Invalid::new(p.clone(), e.to_string()))?;
    Ok(c)
}

/// The cut's engagement, checked against the tool (depth within the flutes, width within the
/// diameter).
pub fn cut(
    axial_depth_mm: f64,
    radial_depth_mm: f64,
    direction: &str,
    mill: &EndMill,
    p: &KeyPath,
) -> Result<CutGeometry, Invalid> {
    let direction = match direction.to_ascii_lowercase().as_str() {
        "down" | "climb" => MillingDirection::Down,
        "up" | "conventional" => MillingDirection::Up,
        other => {
            return Err(Invalid::new(
                p.key("direction"),
                format!("`{other}` is not accepted; up (conventional) or down (climb)"),
            ));
        }
    };
    let cut = CutGeometry {
        axial_depth: axial_depth_mm * 1e-3,
        radial_depth: radial_depth_mm * 1e-3,
        direction,
    };
    cut.validate(mill).map_err(|e| {
        let key = match e {
            CuttingError::RadialDepthOutOfRange { .. } => "radial_depth_mm",
            _ => "axial_depth_mm",
        };
        Invalid::new(p.key(key), e.to_string())
    })?;
    Ok(cut)
}

fn located(p: &KeyPath, e: &CuttingError, default_key: &str) -> Invalid {
    let key = match e {
        CuttingError::ZeroTeeth => "teeth",
        CuttingError::HelixOutOfRange { .. } => "helix_deg",
        CuttingError::NotPositive { name, .. } | CuttingError::Negative { name, .. } => match *name
        {
            "tool diameter" => "diameter_mm",
            "flute length" => "flute_length_mm",
            "run-out" => "runout_um",
            _ => default_key,
        },
        _ => default_key,
    };
    Invalid::new(p.key(key), e.to_string())
}

/// Points a mode error at `modes_x[i]` or `modes_y[i]` (the model numbers X modes first).
fn mode_error(p: &KeyPath, e: &CuttingError, n_x: usize) -> Invalid {
    let at = match e {
        CuttingError::DampingOutOfRange { mode, .. } if *mode < n_x => {
            p.key("modes_x").index(*mode).key("damping_ratio")
        }
        CuttingError::DampingOutOfRange { mode, .. } => {
            p.key("modes_y").index(mode - n_x).key("damping_ratio")
        }
        CuttingError::NoModes { direction: "X" } => p.key("modes_x"),
        CuttingError::NoModes { .. } => p.key("modes_y"),
        _ => p.clone(),
    };
    Invalid::new(at, e.to_string())
}

/// `[job]` of `kind = "milling"`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MillingJobToml {
    pub program: String,
    /// Name of the tool in `[tools]`.
    pub tool: String,
    pub axial_depth_mm: f64,
    pub radial_depth_mm: f64,
    #[serde(default = "down")]
    pub direction: String,
    pub material: MaterialToml,
    /// Cut step, µs (default: the largest that gives 20 steps per period of the highest mode
    /// and divides the accelerometer period).
    pub step_us: Option<f64>,
    /// How often a supervisor sees the accelerometers, ms.
    #[serde(default = "window_ms")]
    pub supervisor_window_ms: f64,
}

fn down() -> String {
    "down".into()
}

fn window_ms() -> f64 {
    25.0
}

/// `[instruments.accelerometer]`: the sensors on the spindle housing.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AccelerometerToml {
    #[serde(default = "rate")]
    pub sample_rate_hz: f64,
    #[serde(default)]
    pub participation: Vec<f64>,
    #[serde(default = "resonance")]
    pub resonance_hz: f64,
    #[serde(default = "resonance_damping")]
    pub resonance_damping: f64,
    #[serde(default = "anti_alias")]
    pub anti_alias_hz: f64,
    #[serde(default = "noise")]
    pub noise_m_s2: f64,
    #[serde(default = "bits")]
    pub adc_bits: u32,
    #[serde(default = "range_g")]
    pub adc_range_g: f64,
}

fn rate() -> f64 {
    20_000.0
}
fn resonance() -> f64 {
    30_000.0
}
fn resonance_damping() -> f64 {
    0.05
}
fn anti_alias() -> f64 {
    9_000.0
}
fn noise() -> f64 {
    0.05
}
fn bits() -> u32 {
    16
}
fn range_g() -> f64 {
    50.0
}

fn accelerometer(a: Option<&AccelerometerToml>) -> AccelerometerParams {
    a.map_or_else(AccelerometerParams::default, |a| AccelerometerParams {
        sample_rate_hz: a.sample_rate_hz,
        participation: a.participation.clone(),
        resonance_hz: a.resonance_hz,
        resonance_damping: a.resonance_damping,
        anti_alias_hz: a.anti_alias_hz,
        noise_rms: a.noise_m_s2,
        adc_bits: a.adc_bits,
        adc_range: a.adc_range_g * 9.80665,
    })
}

/// The largest cut step with at least 20 steps per period of the highest mode that divides
/// the accelerometer period, s.
fn default_step(dynamics: &ToolDynamics, rate_hz: f64) -> f64 {
    let largest = 1.0 / (MIN_STEPS_PER_PERIOD * dynamics.highest_frequency_hz());
    let period = 1.0 / rate_hz;
    period / (period / largest).ceil()
}

/// The milling job's cut, checked against the tool and the sensors.
pub fn milling_job(
    j: &MillingJobToml,
    tools: &BTreeMap<String, ToolTableToml>,
    sensors: Option<&AccelerometerToml>,
    seed: u64,
) -> Result<MillingJob, Invalid> {
    let p = KeyPath::of(&["job"]);
    let Tool { mill, dynamics } = tool(tools, &j.tool, &p.key("tool"))?;
    let coefficients = coefficients(&j.material, &p.key("material"))?;
    let cut = cut(j.axial_depth_mm, j.radial_depth_mm, &j.direction, &mill, &p)?;
    let accelerometer = accelerometer(sensors);
    let step_s = match j.step_us {
        Some(us) => us * 1e-6,
        None => default_step(&dynamics, accelerometer.sample_rate_hz),
    };
    let setup = MillingSetup {
        tool: mill,
        coefficients,
        dynamics,
        axial_mode: None,
        cut,
        feed_per_tooth: 0.0,
        accelerometer,
        step_s,
        seed,
    };
    // The feed per tooth comes from the program; a placeholder passes the other checks.
    MillingSetup {
        feed_per_tooth: 1e-4,
        ..setup.clone()
    }
    .validate()
    .map_err(|e| {
        let key = match e {
            MillingError::StepTooCoarse { .. } | MillingError::StepNotFraction { .. } => "step_us",
            _ => "tool",
        };
        Invalid::new(p.key(key), e.to_string())
    })?;
    if !(j.supervisor_window_ms.is_finite() && j.supervisor_window_ms > 0.0) {
        return Err(Invalid::new(
            p.key("supervisor_window_ms"),
            format!(
                "{} is not accepted; a positive number of ms",
                j.supervisor_window_ms
            ),
        ));
    }
    Ok(MillingJob {
        setup,
        supervisor_window_s: j.supervisor_window_ms * 1e-3,
    })
}
