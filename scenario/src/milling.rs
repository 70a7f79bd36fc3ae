//! Scenario sections for milling: the tool table (`[tools.T1]`: geometry and the tool point's
//! modes), the cut of a `kind = "milling"` job (material coefficients, depths, up or down
//! milling, cut step) and `[instruments.accelerometer]`. Engineering units in the keys are
//! converted to SI here. See `scenarios/milling_slot.toml`.

use crate::build::{count_in_range, in_open_range, in_range, positive};
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
    // Generous bounds around milling tools (micro end mills of a tenth of a millimetre to face
    // mills of a few hundred, run-outs of a few µm): every tooth is computed at every cut step.
    let mm = |v: f64, k: &str, what: &str| positive(v, 1000.0, &p.key(k), what);
    let mill = EndMill {
        diameter: mm(t.diameter_mm, "diameter_mm", "a diameter in mm")? * 1e-3,
        // Up to slitting saws (a few hundred teeth).
        teeth: count_in_range(t.teeth, 1, 500, &p.key("teeth"), "a number of teeth")?,
        helix: t.helix_deg.to_radians(),
        flute_length: mm(t.flute_length_mm, "flute_length_mm", "a flute length in mm")? * 1e-3,
        runout: in_range(
            t.runout_um,
            0.0,
            1000.0,
            &p.key("runout_um"),
            "a run-out in µm",
        )? * 1e-6,
        runout_angle: in_range(
            t.runout_angle_deg,
            -360.0,
            360.0,
            &p.key("runout_angle_deg"),
            "an angle of the run-out in deg",
        )?
        .to_radians(),
    };
    // The rest is checked above at its key; the model checks the helix.
    mill.validate()
        .map_err(|e| Invalid::new(p.key("helix_deg"), e.to_string()))?;
    let dynamics = ToolDynamics {
        x: modes(&t.modes_x, &p.key("modes_x"))?,
        y: modes(&t.modes_y, &p.key("modes_y"))?,
    };
    dynamics
        .validate()
        .map_err(|e| mode_error(&p, &e, t.modes_x.len()))?;
    Ok(Tool { mill, dynamics })
}

/// Highest natural frequency of a tool-point mode, Hz: tool points ring at hundreds of Hz to
/// tens of kHz, and the default cut step (20 per period of the highest mode) shrinks with it.
const MAX_MODE_HZ: f64 = 1e5;

/// The tool point's modes along one direction at `path` (`modes_x` or `modes_y`).
fn modes(list: &[ModeToml], path: &KeyPath) -> Result<Vec<Mode>, Invalid> {
    list.iter()
        .enumerate()
        .map(|(i, m)| {
            let p = path.index(i);
            Ok(Mode {
                natural_frequency_hz: positive(
                    m.frequency_hz,
                    MAX_MODE_HZ,
                    &p.key("frequency_hz"),
                    "a natural frequency in Hz",
                )?,
                damping_ratio: m.damping_ratio,
                // Up to 10^6 N/µm: the shipped "rigid" direction is 10^4 N/µm.
                stiffness: positive(
                    m.stiffness_n_per_um,
                    1e6,
                    &p.key("stiffness_n_per_um"),
                    "a stiffness in N/µm",
                )? * 1e6,
            })
        })
        .collect()
}

/// Largest specific cutting force accepted (Kt, Kr, Ka), N/mm²: metals take a few hundred
/// (aluminium) to a few thousand (hardened steel, nickel alloys), and up to about 10^4 where a
/// mechanistic fit is made at chips of a few µm; 10^5 is beyond any material.
const MAX_CUTTING_N_PER_MM2: f64 = 1e5;

/// Largest edge (ploughing) force per unit of cut length accepted (Kte, Kre, Kae), N/mm:
/// measured edge coefficients are tens of N/mm (aluminium, steel, titanium), up to a few
/// hundred for worn or honed edges; 10^4 is beyond any edge.
const MAX_EDGE_N_PER_MM: f64 = 1e4;

/// The material's coefficients at `p` (`job.material`) in SI; an error names the key.
pub fn coefficients(m: &MaterialToml, p: &KeyPath) -> Result<CuttingCoefficients, Invalid> {
    let cutting = |v: f64, k: &str| {
        let what = "a specific cutting force in N/mm²";
        in_range(v, 0.0, MAX_CUTTING_N_PER_MM2, &p.key(k), what)
    };
    let edge = |v: f64, k: &str| {
        let what = "an edge force in N/mm";
        in_range(v, 0.0, MAX_EDGE_N_PER_MM, &p.key(k), what)
    };
    let c = CuttingCoefficients {
        // The tangential force does the cutting: without it there is no cut.
        tangential: positive(
            m.kt_n_per_mm2,
            MAX_CUTTING_N_PER_MM2,
            &p.key("kt_n_per_mm2"),
            "a specific cutting force in N/mm²",
        )? * 1e6,
        radial: cutting(m.kr_n_per_mm2, "kr_n_per_mm2")? * 1e6,
        axial: cutting(m.ka_n_per_mm2, "ka_n_per_mm2")? * 1e6,
        tangential_edge: edge(m.kte_n_per_mm, "kte_n_per_mm")? * 1e3,
        radial_edge: edge(m.kre_n_per_mm, "kre_n_per_mm")? * 1e3,
        axial_edge: edge(m.kae_n_per_mm, "kae_n_per_mm")? * 1e3,
    };
    // Every value is checked above at its key; the model's check stays as a guard.
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
    /// Default: [`vmt_sim::milling::ANTI_ALIAS_FRACTION`] of the sample rate.
    pub anti_alias_hz: Option<f64>,
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
fn noise() -> f64 {
    0.05
}
fn bits() -> u32 {
    16
}
fn range_g() -> f64 {
    50.0
}

/// The sensors, for a tool of `modes` modes (X, then Y).
fn accelerometer(
    a: Option<&AccelerometerToml>,
    modes: usize,
) -> Result<AccelerometerParams, Invalid> {
    let Some(a) = a else {
        return Ok(AccelerometerParams::default());
    };
    let p = KeyPath::of(&["instruments", "accelerometer"]);
    // Up to 1 MHz: the cut step divides the sample period (1 µs at 1 MHz), and vibration
    // acquisition samples at tens to hundreds of kHz.
    let fs = in_range(
        a.sample_rate_hz,
        100.0,
        1e6,
        &p.key("sample_rate_hz"),
        "a sample rate in Hz",
    )?;
    let n = a.participation.len();
    if n != 0 && n != modes {
        let msg = format!(
            "{n} participation factors are not accepted; none (0.2 for every mode) or one per mode of the tool, {modes} here (the X modes, then the Y modes)"
        );
        return Err(Invalid::new(p.key("participation"), msg));
    }
    let participation = a
        .participation
        .iter()
        .enumerate()
        .map(|(i, &k)| {
            // A fraction of the tool point's motion; ten times it is no housing.
            let what = "a participation factor";
            in_range(k, -10.0, 10.0, &p.key("participation").index(i), what)
        })
        .collect::<Result<_, _>>()?;
    Ok(AccelerometerParams {
        sample_rate_hz: fs,
        participation,
        // A mounted sensor's contact resonance: about 2 kHz held by a magnet to 100 kHz on a
        // stud.
        resonance_hz: in_range(
            a.resonance_hz,
            100.0,
            1e6,
            &p.key("resonance_hz"),
            "a resonance in Hz",
        )?,
        resonance_damping: in_open_range(
            a.resonance_damping,
            0.0,
            1.0,
            &p.key("resonance_damping"),
            "a damping ratio",
        )?,
        anti_alias_hz: in_open_range(
            a.anti_alias_hz
                .unwrap_or(vmt_sim::milling::ANTI_ALIAS_FRACTION * fs),
            0.0,
            fs / 2.0,
            &p.key("anti_alias_hz"),
            "an anti-alias corner in Hz (below half of sample_rate_hz)",
        )?,
        // Up to 100 g of noise: beyond any sensor's range.
        noise_rms: in_range(
            a.noise_m_s2,
            0.0,
            1000.0,
            &p.key("noise_m_s2"),
            "a noise RMS in m/s²",
        )?,
        adc_bits: count_in_range(
            a.adc_bits as usize,
            1,
            32,
            &p.key("adc_bits"),
            "a resolution in bits",
        )? as u32,
        // Shock accelerometers reach 100 000 g.
        adc_range: positive(a.adc_range_g, 1e5, &p.key("adc_range_g"), "a range in g")? * 9.80665,
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
    let accelerometer = accelerometer(sensors, dynamics.x.len() + dynamics.y.len())?;
    let step_s = match j.step_us {
        // At least 0.1 µs: 20 steps per period of the highest mode accepted (100 kHz) are
        // 0.5 µs; finer steps resolve nothing more and only make the run last hours. At most
        // 10 ms, the period of the slowest sample rate, which the step must divide.
        Some(us) => in_range(us, 0.1, 10_000.0, &p.key("step_us"), "a cut step in µs")? * 1e-6,
        None => default_step(&dynamics, accelerometer.sample_rate_hz),
    };
    // From one sample (what a supervisor needs to see anything) to 10 s (a supervisor that
    // looks less often cannot act on a cut).
    let window_ms = in_range(
        j.supervisor_window_ms,
        1e3 / accelerometer.sample_rate_hz,
        10_000.0,
        &p.key("supervisor_window_ms"),
        "a supervisor window in ms (at least one accelerometer sample)",
    )?;
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
    // The feed per tooth comes from the program; a placeholder within the tool's radius passes
    // the other checks.
    MillingSetup {
        feed_per_tooth: 0.01 * mill.diameter,
        ..setup.clone()
    }
    .validate()
    .map_err(|e| {
        let key = match e {
            MillingError::StepTooCoarse { .. } | MillingError::StepNotFraction { .. } => {
                p.key("step_us")
            }
            MillingError::Cutting(_) => p.key("tool"),
            // The depth of cut, with the tool's helix and diameter it is taken with.
            MillingError::TooManyDisks { .. } => {
                // The tool was found in the table above.
                let msg = match tools.get(&j.tool) {
                    Some(t) => format!(
                        "{e} (job.axial_depth_mm = {}, tools.{name}.helix_deg = {}, \
                         tools.{name}.diameter_mm = {})",
                        j.axial_depth_mm,
                        t.helix_deg,
                        t.diameter_mm,
                        name = j.tool
                    ),
                    None => e.to_string(),
                };
                return Invalid::new(p.key("axial_depth_mm"), msg);
            }
            // The sensors' values are checked at their keys above.
            _ => KeyPath::of(&["instruments", "accelerometer"]),
        };
        Invalid::new(key, e.to_string())
    })?;
    Ok(MillingJob {
        setup,
        supervisor_window_s: window_ms * 1e-3,
    })
}
