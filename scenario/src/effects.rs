//! Scenario sections of the optional physics: the motor's cogging and torque ripple, the
//! interpolation error of the encoders' signals, a preloaded double nut, the GMS friction law,
//! local defects of the rails, and the screws' temperature along their length. Each is off
//! when its table (or key) is absent, so a scenario without them builds as before.
//!
//! ```toml
//! [machine.axes.x.drive.motor]            # cogging and torque ripple (vmt_model::drive::motor)
//! slots = 36                              # stator slots
//! poles = 8                               # rotor poles (pole pairs = poles / 2)
//! cogging_n_m = 0.04                      # amplitude; LCM(slots, poles) periods per revolution
//! cogging_phase_deg = 0.0
//! ripple_percent = 1.0                    # torque ripple, % of the motor torque
//! ripple_harmonic = 6                     # of the electrical angle
//! ripple_phase_deg = 0.0
//!
//! [machine.axes.x.drive.encoder_signals]  # the motor encoder's sin/cos signals
//! periods_per_rev = 2048                  # (scale_signals: signal_period_um = 20.0)
//! offsets_percent = [1.0, -0.5]           # cosine, sine offsets, % of the amplitude
//! amplitude_ratio = 1.01                  # sine amplitude / cosine amplitude
//! phase_error_deg = 0.5                   # departure from quadrature
//!
//! [machine.axes.x.drive.nut]              # preloaded double nut (vmt_model::drive::nut)
//! preload_n = 1900.0                      # as made
//! stiffness_n_per_um = 800.0              # catalogue rigidity at that preload
//! remaining_preload_n = 0.0               # what wear left
//!
//! guide_friction = { ..., law = "gms", gms_elements = 4 }   # or screw_friction
//!
//! [machine.axes.x.guideway]               # the carriage on its rails
//! block_spacing_mm = 300.0                # front to rear blocks' centres
//! block_length_mm = 100.0                 # each block's loaded length
//! blocks_centre_mm = [250.0, 200.0, -250.0]   # machine coordinates, every axis at 0
//! [[machine.axes.x.guideway.defects]]
//! shape = "bump"                          # or "step" (a rail joint)
//! direction = "z"                         # the axis the rail lifts the blocks along
//! at_mm = 330.0                           # axis position with the blocks' centre over it
//! height_um = 2.0
//! width_mm = 30.0                         # a bump's full width
//! rail_offset_mm = 200.0                  # optional: on the one rail at this across offset
//!
//! [machine.thermal.screw.x]               # the screw along its length (thermal::screw)
//! span_mm = [-100.0, 600.0]               # axis positions of its bearing ends
//! fixed_end = "low"                       # where the thrust bearing is: "low" or "high"
//! diameter_mm = 28.0
//! convection_w_per_m2_k = 15.0
//! end_w_per_k = [2.0, 0.5]                # bearings to the structure, low and high end
//! nut_w_per_mm_s = 0.3                    # nut friction heat c|v|
//! nut_length_mm = 100.0
//! bearing_w_per_mm_s = 0.2                # fixed-end bearings' heat
//! warm_rise_k = 2.0                       # optional: warm where it ran before the job
//! warm_span_mm = [100.0, 400.0]
//! ```

use crate::build::{count_in_range, in_range, positive};
use crate::dynamics::{DriveToml, FrictionToml};
use crate::error::{Invalid, KeyPath};
use crate::schema::Numbers;
use nalgebra::Vector3;
use serde::Deserialize;
use vmt_model::Axis;
use vmt_model::drive::encoder::EncoderSignals;
use vmt_model::drive::gms::{GmsParams, MAX_GMS_ELEMENTS};
use vmt_model::drive::motor::MotorPulsation;
use vmt_model::drive::nut::PreloadedNut;
use vmt_model::drive::{DriveEffects, DriveParams, LuGreParams};
use vmt_model::geometric::{DefectShape, Guideway, RailDefect};
use vmt_model::machine::AxisSpec;
use vmt_model::thermal::screw::{MAX_SCREW_CELLS, ScrewThermalParams, WarmSection};

type R<T> = Result<T, Invalid>;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotorToml {
    slots: u32,
    poles: u32,
    #[serde(default)]
    cogging_n_m: f64,
    #[serde(default)]
    cogging_phase_deg: f64,
    #[serde(default)]
    ripple_percent: f64,
    #[serde(default = "six")]
    ripple_harmonic: u32,
    #[serde(default)]
    ripple_phase_deg: f64,
}

fn six() -> u32 {
    6
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SignalsToml {
    /// A motor encoder's sin/cos periods per revolution.
    periods_per_rev: Option<f64>,
    /// A linear scale's signal period (grating or magnetic pitch).
    signal_period_um: Option<f64>,
    #[serde(default)]
    offsets_percent: Numbers<2>,
    #[serde(default = "unity")]
    amplitude_ratio: f64,
    #[serde(default)]
    phase_error_deg: f64,
}

fn unity() -> f64 {
    1.0
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NutToml {
    preload_n: f64,
    stiffness_n_per_um: f64,
    remaining_preload_n: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GuidewayToml {
    block_spacing_mm: f64,
    #[serde(default)]
    block_length_mm: f64,
    blocks_centre_mm: Numbers<3>,
    #[serde(default)]
    defects: Vec<DefectToml>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DefectToml {
    shape: String,
    direction: String,
    at_mm: f64,
    height_um: f64,
    width_mm: Option<f64>,
    rail_offset_mm: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScrewToml {
    span_mm: Numbers<2>,
    fixed_end: String,
    diameter_mm: f64,
    #[serde(default = "steel_conductivity")]
    conductivity_w_per_m_k: f64,
    #[serde(default = "steel_heat_capacity")]
    heat_capacity_j_per_m3_k: f64,
    convection_w_per_m2_k: f64,
    end_w_per_k: Numbers<2>,
    nut_w_per_mm_s: f64,
    nut_length_mm: f64,
    bearing_w_per_mm_s: f64,
    #[serde(default = "steel_alpha")]
    alpha_per_k: f64,
    #[serde(default = "max_cells")]
    cells: usize,
    warm_rise_k: Option<f64>,
    warm_span_mm: Option<Numbers<2>>,
}

fn steel_conductivity() -> f64 {
    46.0
}

fn steel_heat_capacity() -> f64 {
    3.6e6
}

fn steel_alpha() -> f64 {
    11.5e-6
}

fn max_cells() -> usize {
    MAX_SCREW_CELLS
}

/// The optional physics of a drive (`params` built from the same table).
pub fn drive_effects(d: &DriveToml, params: &DriveParams, p: &KeyPath) -> R<DriveEffects> {
    let effects = DriveEffects {
        motor: d
            .motor
            .as_ref()
            .map(|m| motor(m, &p.key("motor")))
            .transpose()?,
        motor_encoder_signals: d
            .encoder_signals
            .as_ref()
            .map(|s| signals(s, Some(params.screw.lead_m), &p.key("encoder_signals")))
            .transpose()?,
        scale_signals: d
            .scale_signals
            .as_ref()
            .map(|s| signals(s, None, &p.key("scale_signals")))
            .transpose()?,
        nut: d
            .nut
            .as_ref()
            .map(|n| nut(n, params, &p.key("nut")))
            .transpose()?,
        guide_gms: law(
            &d.guide_friction,
            &params.guide_friction,
            &p.key("guide_friction"),
        )?,
        screw_gms: law(
            &d.screw_friction,
            &params.screw_friction,
            &p.key("screw_friction"),
        )?,
    };
    // What is left to check is the scale signals on an axis without a scale.
    effects
        .check(params)
        .map_err(|m| Invalid::new(p.key("scale_signals"), m))?;
    Ok(effects)
}

fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 { a } else { gcd(b, a % b) }
}

fn motor(m: &MotorToml, p: &KeyPath) -> R<MotorPulsation> {
    let slots = count_in_range(
        m.slots as usize,
        3,
        1000,
        &p.key("slots"),
        "a number of slots",
    )?;
    let poles = count_in_range(
        m.poles as usize,
        2,
        1000,
        &p.key("poles"),
        "a number of poles",
    )?;
    if poles % 2 != 0 {
        return Err(Invalid::new(
            p.key("poles"),
            format!("{poles} is not accepted; a motor has an even number of poles (pole pairs)"),
        ));
    }
    let (slots, poles) = (slots as u32, poles as u32);
    Ok(MotorPulsation {
        // Up to a whole motor's peak torque: beyond, a wrong unit.
        cogging_n_m: in_range(
            m.cogging_n_m,
            0.0,
            1000.0,
            &p.key("cogging_n_m"),
            "a torque (N·m)",
        )?,
        cogging_periods_per_rev: slots / gcd(slots, poles) * poles,
        cogging_phase_rad: phase(m.cogging_phase_deg, &p.key("cogging_phase_deg"))?,
        pole_pairs: poles / 2,
        ripple_fraction: in_range(
            m.ripple_percent,
            0.0,
            50.0,
            &p.key("ripple_percent"),
            "a torque ripple (% of the torque)",
        )? / 100.0,
        ripple_harmonic: count_in_range(
            m.ripple_harmonic as usize,
            1,
            100,
            &p.key("ripple_harmonic"),
            "a harmonic of the electrical angle",
        )? as u32,
        ripple_phase_rad: phase(m.ripple_phase_deg, &p.key("ripple_phase_deg"))?,
    })
}

fn phase(deg: f64, p: &KeyPath) -> R<f64> {
    Ok(in_range(deg, -360.0, 360.0, p, "a phase (°)")?.to_radians())
}

/// The signals of the motor encoder (`lead`: its periods per revolution are travel through
/// the screw) or of a linear scale (`None`: a signal period in µm).
fn signals(s: &SignalsToml, lead: Option<f64>, p: &KeyPath) -> R<EncoderSignals> {
    let period_m = match (lead, s.periods_per_rev, s.signal_period_um) {
        (Some(lead), Some(n), None) => {
            lead / in_range(
                n,
                1.0,
                1e6,
                &p.key("periods_per_rev"),
                "sin/cos periods per revolution",
            )?
        }
        (None, None, Some(um)) => {
            in_range(
                um,
                0.1,
                10_000.0,
                &p.key("signal_period_um"),
                "a signal period (µm)",
            )? * 1e-6
        }
        (Some(_), _, _) => {
            return Err(Invalid::new(
                p.clone(),
                "a motor encoder's signals take periods_per_rev (its sin/cos periods per motor revolution), not signal_period_um",
            ));
        }
        (None, _, _) => {
            return Err(Invalid::new(
                p.clone(),
                "a linear scale's signals take signal_period_um (its grating or magnetic pitch), not periods_per_rev",
            ));
        }
    };
    let offset = |i: usize| {
        in_range(
            s.offsets_percent[i],
            -20.0,
            20.0,
            &p.key("offsets_percent").index(i),
            "an offset (% of the amplitude)",
        )
        .map(|v| v / 100.0)
    };
    let out = EncoderSignals {
        period_m,
        offset_cos: offset(0)?,
        offset_sin: offset(1)?,
        amplitude_ratio: in_range(
            s.amplitude_ratio,
            0.5,
            2.0,
            &p.key("amplitude_ratio"),
            "a ratio of the sine to the cosine amplitude",
        )?,
        phase_error_rad: phase_error_deg_to_rad(s.phase_error_deg, &p.key("phase_error_deg"))?,
    };
    out.check()
        .map_err(|m| Invalid::new(p.key("offsets_percent"), m))?;
    Ok(out)
}

fn phase_error_deg_to_rad(deg: f64, p: &KeyPath) -> R<f64> {
    Ok(in_range(deg, -30.0, 30.0, p, "a quadrature phase error (°)")?.to_radians())
}

fn nut(n: &NutToml, params: &DriveParams, p: &KeyPath) -> R<PreloadedNut> {
    let preload = positive(n.preload_n, 1e6, &p.key("preload_n"), "a preload (N)")?;
    let out = PreloadedNut {
        preload_n: preload,
        stiffness_n_per_m: positive(
            n.stiffness_n_per_um,
            1e5,
            &p.key("stiffness_n_per_um"),
            "a nut rigidity (N/µm)",
        )? * 1e6,
        remaining_preload_n: in_range(
            n.remaining_preload_n,
            0.0,
            preload,
            &p.key("remaining_preload_n"),
            "a remaining preload (N), up to preload_n,",
        )?,
    };
    out.check(params.screw.stiffness_n_per_m)
        .map_err(|m| Invalid::new(p.key("stiffness_n_per_um"), m))?;
    Ok(out)
}

/// The GMS law of a friction contact, if `law = "gms"`.
fn law(f: &FrictionToml, lugre: &LuGreParams, p: &KeyPath) -> R<Option<GmsParams>> {
    match f.law.as_deref() {
        None | Some("lugre") => {
            for (key, given) in [
                ("gms_elements", f.gms_elements.is_some()),
                ("gms_attraction_n_per_s", f.gms_attraction_n_per_s.is_some()),
            ] {
                if given {
                    return Err(Invalid::new(
                        p.key(key),
                        format!("{key} applies to law = \"gms\" only"),
                    ));
                }
            }
            Ok(None)
        }
        Some("gms") => {
            let n = count_in_range(
                f.gms_elements.unwrap_or(4),
                1,
                MAX_GMS_ELEMENTS,
                &p.key("gms_elements"),
                "a number of Maxwell-slip elements",
            )?;
            let c = f
                .gms_attraction_n_per_s
                .map(|c| {
                    positive(
                        c,
                        1e12,
                        &p.key("gms_attraction_n_per_s"),
                        "an attraction parameter (N/s)",
                    )
                })
                .transpose()?;
            GmsParams::matching(lugre, n, c)
                .map(Some)
                .map_err(|m| Invalid::new(p.clone(), m))
        }
        Some(other) => Err(Invalid::new(
            p.key("law"),
            format!(
                "`{other}` is not accepted; law is \"lugre\" (the default) or \"gms\" (Generalized Maxwell-Slip)"
            ),
        )),
    }
}

/// The guideway of `axis` with its defects.
pub fn guideway(g: &GuidewayToml, axis: Axis, p: &KeyPath) -> R<Guideway> {
    let mut centre = Vector3::zeros();
    for i in 0..3 {
        centre[i] = in_range(
            g.blocks_centre_mm[i],
            -10_000.0,
            10_000.0,
            &p.key("blocks_centre_mm").index(i),
            "a coordinate (mm)",
        )? * 1e-3;
    }
    let defects = g
        .defects
        .iter()
        .enumerate()
        .map(|(i, d)| defect(d, axis, &p.key("defects").index(i)))
        .collect::<R<Vec<_>>>()?;
    let out = Guideway {
        axis,
        block_spacing_m: positive(
            g.block_spacing_mm,
            5000.0,
            &p.key("block_spacing_mm"),
            "a block spacing (mm)",
        )? * 1e-3,
        block_length_m: in_range(
            g.block_length_mm,
            0.0,
            1000.0,
            &p.key("block_length_mm"),
            "a block length (mm)",
        )? * 1e-3,
        blocks_centre_m: centre,
        defects,
    };
    out.check().map_err(|m| Invalid::new(p.clone(), m))?;
    Ok(out)
}

fn defect(d: &DefectToml, axis: Axis, p: &KeyPath) -> R<RailDefect> {
    let across: Vec<char> = Axis::ALL
        .into_iter()
        .filter(|a| *a != axis)
        .map(|a| a.letter().to_ascii_lowercase())
        .collect();
    let mut letters = d.direction.chars();
    let direction = match (letters.next().and_then(Axis::from_letter), letters.next()) {
        (Some(a), None) if a != axis => a,
        _ => {
            return Err(Invalid::new(
                p.key("direction"),
                format!(
                    "`{}` is not accepted; the direction the rail displaces the {axis} carriage is across it: {} or {}",
                    d.direction, across[0], across[1]
                ),
            ));
        }
    };
    let shape = match (d.shape.as_str(), d.width_mm) {
        ("bump", Some(w)) => DefectShape::Bump {
            width_m: positive(w, 10_000.0, &p.key("width_mm"), "a bump's width (mm)")? * 1e-3,
        },
        ("bump", None) => {
            return Err(Invalid::new(
                p.key("width_mm"),
                "a bump needs its full width, width_mm",
            ));
        }
        ("step", None) => DefectShape::Step,
        ("step", Some(_)) => {
            return Err(Invalid::new(
                p.key("width_mm"),
                "a step (rail joint) has no width; remove width_mm",
            ));
        }
        (other, _) => {
            return Err(Invalid::new(
                p.key("shape"),
                format!(
                    "`{other}` is not accepted; shape is \"bump\" (raised cosine) or \"step\" (rail joint)"
                ),
            ));
        }
    };
    let rail_offset_m = d
        .rail_offset_mm
        .map(|a| {
            let v = in_range(a, -5000.0, 5000.0, &p.key("rail_offset_mm"), "an across offset (mm)")?;
            if v == 0.0 {
                return Err(Invalid::new(
                    p.key("rail_offset_mm"),
                    "0 is not accepted; the rail's across offset from the blocks' centre, not 0 (leave it out for every rail)",
                ));
            }
            Ok(v * 1e-3)
        })
        .transpose()?;
    Ok(RailDefect {
        shape,
        direction,
        at_m: in_range(
            d.at_mm,
            -10_000.0,
            10_000.0,
            &p.key("at_mm"),
            "an axis position (mm)",
        )? * 1e-3,
        height_m: in_range(
            d.height_um,
            -1000.0,
            1000.0,
            &p.key("height_um"),
            "a height (µm)",
        )? * 1e-6,
        rail_offset_m,
    })
}

/// The screw of `axis`, whose stroke is `spec`, along its length.
pub fn screw(s: &ScrewToml, axis: Axis, spec: &AxisSpec, p: &KeyPath) -> R<ScrewThermalParams> {
    let span = |i: usize| {
        in_range(
            s.span_mm[i],
            -10_000.0,
            10_000.0,
            &p.key("span_mm").index(i),
            "a bearing end's axis position (mm)",
        )
    };
    let (lo, hi) = (span(0)?, span(1)?);
    if lo >= hi || lo * 1e-3 > spec.min_m || hi * 1e-3 < spec.max_m {
        return Err(Invalid::new(
            p.key("span_mm"),
            format!(
                "[{lo}, {hi}] is not accepted; the screw's bearing ends [low, high] in axis positions (mm), around the {axis} stroke {} to {} mm that its nut travels",
                spec.min_m * 1e3,
                spec.max_m * 1e3
            ),
        ));
    }
    let fixed_at_high_end = match s.fixed_end.as_str() {
        "low" => false,
        "high" => true,
        other => {
            return Err(Invalid::new(
                p.key("fixed_end"),
                format!(
                    "`{other}` is not accepted; the thrust bearing's end is \"low\" or \"high\""
                ),
            ));
        }
    };
    let end = |i: usize| {
        in_range(
            s.end_w_per_k[i],
            0.0,
            1e4,
            &p.key("end_w_per_k").index(i),
            "a conductance (W/K)",
        )
    };
    let warm = match (s.warm_rise_k, &s.warm_span_mm) {
        (None, None) => None,
        (Some(rise), Some(span)) => {
            let sp = p.key("warm_span_mm");
            let (a, b) = (
                in_range(
                    span[0],
                    -10_000.0,
                    10_000.0,
                    &sp.index(0),
                    "a position (mm)",
                )?,
                in_range(
                    span[1],
                    -10_000.0,
                    10_000.0,
                    &sp.index(1),
                    "a position (mm)",
                )?,
            );
            if a >= b {
                return Err(Invalid::new(
                    sp,
                    format!("[{a}, {b}] is not accepted; [from, to] with from < to (mm)"),
                ));
            }
            Some(WarmSection {
                rise_k: in_range(rise, -50.0, 100.0, &p.key("warm_rise_k"), "a rise (K)")?,
                from_to_m: [a * 1e-3, b * 1e-3],
            })
        }
        (Some(_), None) => {
            return Err(Invalid::new(
                p.key("warm_span_mm"),
                "a warm section needs warm_span_mm = [from, to] with warm_rise_k",
            ));
        }
        (None, Some(_)) => {
            return Err(Invalid::new(
                p.key("warm_rise_k"),
                "a warm section needs warm_rise_k with warm_span_mm",
            ));
        }
    };
    let out = ScrewThermalParams {
        span_m: [lo * 1e-3, hi * 1e-3],
        fixed_at_high_end,
        diameter_m: positive(
            s.diameter_mm,
            500.0,
            &p.key("diameter_mm"),
            "a diameter (mm)",
        )? * 1e-3,
        conductivity_w_per_m_k: positive(
            s.conductivity_w_per_m_k,
            1000.0,
            &p.key("conductivity_w_per_m_k"),
            "a conductivity (W/(m·K))",
        )?,
        heat_capacity_j_per_m3_k: positive(
            s.heat_capacity_j_per_m3_k,
            1e8,
            &p.key("heat_capacity_j_per_m3_k"),
            "a volumetric heat capacity (J/(m³·K))",
        )?,
        convection_w_per_m2_k: in_range(
            s.convection_w_per_m2_k,
            0.0,
            1000.0,
            &p.key("convection_w_per_m2_k"),
            "a convection coefficient (W/(m²·K))",
        )?,
        end_conductance_w_per_k: [end(0)?, end(1)?],
        nut_w_per_m_s: in_range(
            s.nut_w_per_mm_s,
            0.0,
            1000.0,
            &p.key("nut_w_per_mm_s"),
            "W per mm/s",
        )? * 1e3,
        nut_length_m: in_range(
            s.nut_length_mm,
            0.0,
            1000.0,
            &p.key("nut_length_mm"),
            "a length (mm)",
        )? * 1e-3,
        bearing_w_per_m_s: in_range(
            s.bearing_w_per_mm_s,
            0.0,
            1000.0,
            &p.key("bearing_w_per_mm_s"),
            "W per mm/s",
        )? * 1e3,
        alpha_per_k: in_range(
            s.alpha_per_k,
            -1e-5,
            1e-4,
            &p.key("alpha_per_k"),
            "an expansion coefficient in 1/K",
        )?,
        cells: count_in_range(
            s.cells,
            2,
            MAX_SCREW_CELLS,
            &p.key("cells"),
            "a number of cells",
        )?,
        warm,
    };
    out.check().map_err(|m| Invalid::new(p.clone(), m))?;
    Ok(out)
}
