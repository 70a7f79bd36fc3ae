//! Points CSV in, volumetric errors out (`vmt volumetric SCENARIO --points CSV`).
//!
//! Input columns (header required, any order):
//! - `x_mm,y_mm,z_mm`: the commanded tool position relative to the workpiece, mm;
//! - `direction_x,direction_y,direction_z` (optional, each): +1 forward or -1 backward approach
//!   of that axis (default +1);
//! - either `time_s`: the time in the scenario's thermal run, s; or `temp_<node>_c` for every
//!   node of the thermal network, °C; without them the machine is at 20 °C (ISO 1).
//!
//! Output: one row per point, `dx_um,dy_um,dz_um` (CSV, or JSON objects with `--json`).

use crate::error::CliError;
use nalgebra::Vector3;
use std::io::Write;
use std::path::Path;
use vmt_model::Direction;
use vmt_model::kinematics::{AxisState, VolumetricEvaluator};
use vmt_model::machine::Machine;
use vmt_model::thermal::{NODE_TEMPERATURE_RANGE_C, temperatures_at};
use vmt_model::thermal_deformation::REFERENCE_TEMPERATURE_C;
use vmt_scenario::Scenario;

/// The thermal state the points are evaluated at.
#[derive(Clone, Debug, PartialEq)]
pub enum ThermalInput {
    /// Every node at 20 °C.
    Reference,
    /// A time in the thermal run, per point, s.
    Time(Vec<f64>),
    /// Node temperatures per point, °C.
    Temperatures(Vec<Vec<f64>>),
}

/// Points read from a CSV file.
#[derive(Clone, Debug)]
pub struct Points {
    /// The file they were read from.
    pub file: String,
    /// Axis states, one per row.
    pub states: Vec<AxisState>,
    /// File line of each row.
    pub lines: Vec<usize>,
    /// Thermal state of the rows.
    pub thermal: ThermalInput,
}

/// Longest time into a thermal run that is evaluated, s (116 days).
pub const MAX_TIME_S: f64 = 1e7;

const POSITION: [&str; 3] = ["x_mm", "y_mm", "z_mm"];
const DIRECTION: [&str; 3] = ["direction_x", "direction_y", "direction_z"];

/// Reads the points at `path` for `machine` (strokes and thermal node names are checked).
pub fn read(path: &Path, machine: &Machine) -> Result<Points, CliError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path)
        .map_err(|e| CliError::input(&file, None, format!("cannot read: {e}")))?;
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(bytes.as_slice());
    let header = reader
        .headers()
        .map_err(|e| CliError::input(&file, Some(1), format!("cannot read the header: {e}")))?;
    crate::traces::unique_columns(header, &file)?;
    let header: Vec<String> = header.iter().map(str::to_string).collect();
    let layout = Layout::of(&header, machine, &file)?;
    let mut states = Vec::new();
    let mut lines = Vec::new();
    let mut times = Vec::new();
    let mut temps = Vec::new();
    for record in reader.records() {
        let record =
            record.map_err(|e| CliError::input(&file, None, format!("malformed row: {e}")))?;
        let line = crate::traces::record_line(&bytes, record.position(), 0);
        let cell = |c: usize| -> Result<f64, CliError> { number(&record, c, &header, &file, line) };
        let mut position = Vector3::zeros();
        for (i, c) in layout.position.iter().enumerate() {
            position[i] = cell(*c)? * 1e-3;
        }
        if let Some(axis) = machine.outside_stroke(&position) {
            let spec = machine.axis(axis);
            let msg = format!(
                "{} = {} mm is outside the {axis} stroke {} to {} mm",
                POSITION[axis.index()],
                position[axis.index()] * 1e3,
                spec.min_m * 1e3,
                spec.max_m * 1e3
            );
            return Err(CliError::input(&file, Some(line), msg));
        }
        let mut direction = [Direction::Forward; 3];
        for (i, c) in layout.direction.iter().enumerate() {
            if let Some(c) = c {
                let v = cell(*c)?;
                direction[i] = Direction::from_sign(v as i64)
                    .filter(|_| v.fract() == 0.0)
                    .ok_or_else(|| {
                        CliError::input(
                            &file,
                            Some(line),
                            format!(
                                "{} = {v}; accepted: +1 (forward) or -1 (backward)",
                                DIRECTION[i]
                            ),
                        )
                    })?;
            }
        }
        if let Some(c) = layout.time {
            let t = cell(c)?;
            if !(0.0..=MAX_TIME_S).contains(&t) {
                return Err(CliError::input(
                    &file,
                    Some(line),
                    format!(
                        "time_s = {}; a time from 0 to {MAX_TIME_S:e} s is accepted",
                        record.get(c).unwrap_or_default()
                    ),
                ));
            }
            times.push(t);
        }
        if !layout.temps.is_empty() {
            temps.push(
                layout
                    .temps
                    .iter()
                    .map(|c| temperature(cell(*c)?, &header[*c], &file, line))
                    .collect::<Result<Vec<_>, _>>()?,
            );
        }
        states.push(AxisState {
            position,
            direction,
        });
        lines.push(line);
    }
    let thermal = if layout.time.is_some() {
        ThermalInput::Time(times)
    } else if !layout.temps.is_empty() {
        ThermalInput::Temperatures(temps)
    } else {
        ThermalInput::Reference
    };
    Ok(Points {
        file,
        states,
        lines,
        thermal,
    })
}

/// Column indices of a points file.
struct Layout {
    position: [usize; 3],
    direction: [Option<usize>; 3],
    time: Option<usize>,
    temps: Vec<usize>,
}

impl Layout {
    fn of(header: &[String], machine: &Machine, file: &str) -> Result<Self, CliError> {
        let nodes: Vec<String> = machine
            .thermal
            .as_ref()
            .map(|t| {
                t.network
                    .node_names()
                    .map(|n| format!("temp_{n}_c"))
                    .collect()
            })
            .unwrap_or_default();
        let accepted = format!(
            "accepted columns: x_mm, y_mm, z_mm (required), direction_x, direction_y, direction_z (+1/-1), and either time_s or {}",
            if nodes.is_empty() {
                "no temperatures (this machine has no thermal model)".to_string()
            } else {
                nodes.join(", ")
            }
        );
        let find = |name: &str| header.iter().position(|h| h == name);
        let mut position = [0; 3];
        for (slot, name) in position.iter_mut().zip(POSITION) {
            *slot = find(name).ok_or_else(|| {
                CliError::input(file, Some(1), format!("missing column {name}; {accepted}"))
            })?;
        }
        let direction = DIRECTION.map(find);
        let time = find("time_s");
        let temps: Vec<usize> = nodes.iter().filter_map(|n| find(n)).collect();
        if let Some(unknown) = header.iter().find(|h| {
            !POSITION.contains(&h.as_str())
                && !DIRECTION.contains(&h.as_str())
                && h.as_str() != "time_s"
                && !nodes.contains(h)
        }) {
            return Err(CliError::input(
                file,
                Some(1),
                format!("unknown column `{unknown}`; {accepted}"),
            ));
        }
        if !temps.is_empty() && temps.len() != nodes.len() {
            let missing: Vec<&String> = nodes.iter().filter(|n| find(n).is_none()).collect();
            let msg = format!("temperatures must be given for every node; missing {missing:?}");
            return Err(CliError::input(file, Some(1), msg));
        }
        if time.is_some() && !temps.is_empty() {
            return Err(CliError::input(
                file,
                Some(1),
                "give either time_s or node temperatures, not both",
            ));
        }
        if time.is_some() && machine.thermal.is_none() {
            return Err(CliError::input(
                file,
                Some(1),
                "time_s needs a scenario with a thermal model and a thermal run",
            ));
        }
        Ok(Layout {
            position,
            direction,
            time,
            temps,
        })
    }
}

fn number(
    record: &csv::StringRecord,
    c: usize,
    header: &[String],
    file: &str,
    line: usize,
) -> Result<f64, CliError> {
    let text = record.get(c).unwrap_or("");
    text.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| {
            CliError::input(
                file,
                Some(line),
                format!("column {}: `{text}` is not a finite number", header[c]),
            )
        })
}

/// A node temperature cell, refused outside [`NODE_TEMPERATURE_RANGE_C`].
fn temperature(t: f64, column: &str, file: &str, line: usize) -> Result<f64, CliError> {
    let (lo, hi) = NODE_TEMPERATURE_RANGE_C;
    if (lo..=hi).contains(&t) {
        return Ok(t);
    }
    let msg = format!("{column} = {t} °C; a temperature from {lo} to {hi} °C is accepted");
    Err(CliError::input(file, Some(line), msg))
}

/// The volumetric error (m) of every point.
pub fn evaluate(scenario: &Scenario, points: &Points) -> Result<Vec<Vector3<f64>>, CliError> {
    let machine = &scenario.machine;
    let n_nodes = machine
        .thermal
        .as_ref()
        .map_or(0, |t| t.network.node_count());
    let temps: Vec<Vec<f64>> = match &points.thermal {
        ThermalInput::Reference => {
            vec![vec![REFERENCE_TEMPERATURE_C; n_nodes]; points.states.len()]
        }
        ThermalInput::Temperatures(t) => t.clone(),
        ThermalInput::Time(times) => {
            let (Some(thermal), Some(run)) = (&machine.thermal, &scenario.thermal_run) else {
                return Err(CliError::Model(
                    "time_s needs [thermal_run] in the scenario".into(),
                ));
            };
            let end_s = run.schedule.duration_s();
            if let Some(i) = times.iter().position(|&t| t > end_s) {
                return Err(CliError::input(
                    &points.file,
                    Some(points.lines[i]),
                    format!(
                        "time_s = {} s: the scenario's thermal run lasts {end_s} s; a time \
                         within it is accepted (extend [thermal_run] to look later)",
                        times[i]
                    ),
                ));
            }
            temperatures_at(&thermal.network, &run.schedule, run.step_s, times)
                .map_err(|e| CliError::Model(e.to_string()))?
        }
    };
    // One evaluator per thermal state: rows at the same temperatures (all of them at 20 °C)
    // share it instead of recompiling the chain per point.
    let mut errors = Vec::with_capacity(points.states.len());
    let mut cached: Option<(&[f64], VolumetricEvaluator)> = None;
    for (state, t) in points.states.iter().zip(&temps) {
        let evaluator = match cached.take() {
            Some((at, e)) if at == t.as_slice() => e,
            _ => {
                let d = machine
                    .thermal_deformation(t)
                    .map_err(|e| CliError::Model(e.to_string()))?;
                machine.volumetric.evaluator(&d)
            }
        };
        errors.push(evaluator.volumetric_error(state));
        cached = Some((t, evaluator));
    }
    Ok(errors)
}

/// Writes `dx_um,dy_um,dz_um` rows (CSV) or objects (JSON).
pub fn write(out: &mut dyn Write, errors: &[Vector3<f64>], json: bool) -> std::io::Result<()> {
    if json {
        let rows: Vec<serde_json::Value> = errors
            .iter()
            .map(
                |e| serde_json::json!({"dx_um": e.x * 1e6, "dy_um": e.y * 1e6, "dz_um": e.z * 1e6}),
            )
            .collect();
        serde_json::to_writer_pretty(&mut *out, &rows)?;
        writeln!(out)
    } else {
        writeln!(out, "dx_um,dy_um,dz_um")?;
        for e in errors {
            writeln!(out, "{:.6},{:.6},{:.6}", e.x * 1e6, e.y * 1e6, e.z * 1e6)?;
        }
        Ok(())
    }
}
