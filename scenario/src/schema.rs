//! The TOML schema of scenario files, as serde structures.
//!
//! Engineering units at the edge, always in the key name: `_mm`, `_um`, `_urad`, `_kg`, `_c`
//! (°C), `_k` (kelvin difference), `_h`, `_s`, `_w_per_k`, `_j_per_k`. Unknown keys are refused,
//! so a key in a wrong unit (`stroke_in`) is an error that lists the accepted keys.

use serde::{Deserialize, Deserializer, de::Error as _};
use std::collections::BTreeMap;
use std::ops::Deref;

/// Exactly `N` numbers. toml's deserializer lets a fixed-size array ignore extra elements, so
/// `stroke_mm = [0, 500, 9]` would load silently; this type refuses any other length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Numbers<const N: usize>(pub [f64; N]);

impl<'de, const N: usize> Deserialize<'de> for Numbers<N> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let v = Vec::<f64>::deserialize(d)?;
        let len = v.len();
        let expected = format!("an array of {N} numbers");
        v.try_into()
            .map(Numbers)
            .map_err(|_| D::Error::invalid_length(len, &expected.as_str()))
    }
}

impl<const N: usize> Default for Numbers<N> {
    fn default() -> Self {
        Numbers([0.0; N])
    }
}

impl<const N: usize> Deref for Numbers<N> {
    type Target = [f64; N];
    fn deref(&self) -> &[f64; N] {
        &self.0
    }
}

/// One point `[x, y, z]` or a list of them `[[x, y, z], ...]` (a ball-bar job's centres, and a
/// set-up offset for each).
#[derive(Debug, Clone, PartialEq)]
pub enum Points {
    /// One point.
    One(Numbers<3>),
    /// Several points, in order.
    Many(Vec<Numbers<3>>),
}

impl Default for Points {
    fn default() -> Self {
        Points::One(Numbers::default())
    }
}

impl<'de> Deserialize<'de> for Points {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Element {
            Number(f64),
            Point(Vec<f64>),
        }
        let accepted = "a point [x, y, z] or a list of points [[x, y, z], ...]";
        let v = Vec::<Element>::deserialize(d)?;
        let numbers: Option<Vec<f64>> = v
            .iter()
            .map(|e| match e {
                Element::Number(x) => Some(*x),
                Element::Point(_) => None,
            })
            .collect();
        if let Some(n) = numbers {
            let len = n.len();
            return n
                .try_into()
                .map(|a| Points::One(Numbers(a)))
                .map_err(|_| D::Error::invalid_length(len, &accepted));
        }
        v.into_iter()
            .map(|e| match e {
                Element::Point(p) if p.len() == 3 => Ok(Numbers([p[0], p[1], p[2]])),
                Element::Point(p) => Err(D::Error::invalid_length(p.len(), &accepted)),
                Element::Number(_) => Err(D::Error::custom(format!(
                    "numbers and points mixed; {accepted} is accepted"
                ))),
            })
            .collect::<Result<_, _>>()
            .map(Points::Many)
    }
}

/// A whole scenario file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioFile {
    pub machine: MachineToml,
    pub thermal_run: Option<ThermalRunToml>,
    pub controller: Option<crate::dynamics::ControllerToml>,
    pub simulation: Option<crate::dynamics::SimulationToml>,
    pub job: Option<crate::dynamics::JobToml>,
    #[serde(default)]
    pub instruments: crate::dynamics::InstrumentsToml,
    /// Distributions for `vmt dataset`; a run ignores them.
    pub dataset: Option<crate::dataset::DatasetToml>,
    /// The tool table of milling jobs, by tool name (`[tools.T1]`).
    #[serde(default)]
    pub tools: BTreeMap<String, crate::milling::ToolTableToml>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MachineToml {
    pub name: String,
    pub topology: String,
    pub tool: ToolToml,
    pub axes: AxesToml,
    #[serde(default)]
    pub errors: Option<ErrorsToml>,
    #[serde(default)]
    pub thermal: Option<ThermalToml>,
    /// Pivots of the structural links' thermal rotations, by link name (e.g. `G-Z`).
    #[serde(default)]
    pub link_pivots_mm: BTreeMap<String, Numbers<3>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ToolToml {
    pub length_mm: f64,
    #[serde(default)]
    pub tcp_offset_mm: Numbers<2>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxesToml {
    pub x: AxisToml,
    pub y: AxisToml,
    pub z: AxisToml,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisToml {
    pub stroke_mm: Numbers<2>,
    pub moving_mass_kg: f64,
    pub drive: Option<crate::dynamics::DriveToml>,
    pub servo: Option<crate::dynamics::ServoToml>,
    /// The carriage on its rails, with local defects of the rails (`effects`); absent: none.
    pub guideway: Option<crate::effects::GuidewayToml>,
    /// The carriage as a rigid body on its guide blocks (the compliant plant).
    pub carriage: Option<crate::structure::CarriageToml>,
}

#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct ErrorsToml {
    pub x: Option<AxisErrorsToml>,
    pub y: Option<AxisErrorsToml>,
    pub z: Option<AxisErrorsToml>,
    /// `EC0Y_urad`, `EB0Z_urad`, `EA0Z_urad`: a number, `{forward, backward}` or
    /// `{ff, fb, bf, bb}`; checked by hand for a precise message.
    #[serde(default)]
    pub squareness: BTreeMap<String, toml::Value>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisErrorsToml {
    pub forward: DirectionErrorsToml,
    pub backward: Option<DirectionErrorsToml>,
}

/// The error functions of one axis for one direction: Legendre coefficients per component
/// (keys `EXX_um`, `EBX_urad`, ...; checked by hand, which also catches unknown keys, as
/// serde's `deny_unknown_fields` does not work with `flatten`) or a compensation table file.
#[derive(Debug, Deserialize)]
pub struct DirectionErrorsToml {
    pub table: Option<String>,
    pub interpolation: Option<String>,
    #[serde(flatten)]
    pub legendre: BTreeMap<String, toml::Value>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThermalToml {
    pub nodes: Vec<NodeToml>,
    #[serde(default)]
    pub conductances: Vec<ConductanceToml>,
    #[serde(default)]
    pub sources: Vec<SourceToml>,
    pub ambient: AmbientToml,
    #[serde(default)]
    pub expansion: BTreeMap<String, ExpansionToml>,
    #[serde(default)]
    pub links: BTreeMap<String, SensitivityToml>,
    #[serde(default)]
    pub joints: BTreeMap<String, SensitivityToml>,
    /// Screws simulated along their length in a job, by axis (`effects`).
    #[serde(default)]
    pub screw: BTreeMap<String, crate::effects::ScrewToml>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodeToml {
    pub name: String,
    pub capacity_j_per_k: f64,
    #[serde(default)]
    pub to_ambient_w_per_k: f64,
    pub initial_c: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConductanceToml {
    pub between: [String; 2],
    pub w_per_k: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "lowercase")]
pub enum SourceToml {
    Spindle {
        node: String,
        #[serde(default)]
        w_per_rpm: f64,
        #[serde(default)]
        w_per_rpm2: f64,
    },
    Axis {
        node: String,
        axis: String,
        w_per_mm_s: f64,
    },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "lowercase")]
pub enum AmbientToml {
    Constant {
        temperature_c: f64,
    },
    Sinusoid {
        mean_c: f64,
        amplitude_k: f64,
        period_h: f64,
        #[serde(default)]
        phase_h: f64,
    },
    Table {
        /// `[[time_h, temperature_c], ...]`
        points_h_c: Vec<Numbers<2>>,
    },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExpansionToml {
    pub node: String,
    pub alpha_per_k: f64,
    #[serde(default)]
    pub reference_mm: f64,
}

/// Sensitivities by node name: `{ node = [x, y, z] }`.
#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct SensitivityToml {
    #[serde(default)]
    pub translation_um_per_k: BTreeMap<String, Numbers<3>>,
    #[serde(default)]
    pub rotation_urad_per_k: BTreeMap<String, Numbers<3>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThermalRunToml {
    pub step_s: f64,
    pub segments: Vec<SegmentToml>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SegmentToml {
    pub until_h: f64,
    #[serde(default)]
    pub spindle_rpm: f64,
    #[serde(default)]
    pub axis_speed_mm_min: Numbers<3>,
}
