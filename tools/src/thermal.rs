//! `vmt thermal`: the scenario's thermal run (ISO 230-3 warm-up, cool-down, ambient drift):
//! node temperatures and the thermal drift of the tool point over time.

use crate::error::CliError;
use crate::plot;
use nalgebra::Vector3;
use std::io::Write;
use vmt_model::Direction;
use vmt_model::kinematics::AxisState;
use vmt_model::thermal::ThermalRun;
use vmt_model::thermal_deformation::REFERENCE_TEMPERATURE_C;
use vmt_scenario::Scenario;

/// Temperatures and tool-point drift sampled over a thermal run.
#[derive(Clone, Debug)]
pub struct ThermalHistory {
    /// Node names.
    pub nodes: Vec<String>,
    /// Sample times, s.
    pub times_s: Vec<f64>,
    /// Ambient temperature at each sample, °C.
    pub ambient_c: Vec<f64>,
    /// Node temperatures at each sample, °C.
    pub temps_c: Vec<Vec<f64>>,
    /// Thermal drift of the tool point at the probe position (error minus the error at 20 °C), m.
    pub drift: Vec<Vector3<f64>>,
    /// Time constants of the network, s.
    pub time_constants_s: Vec<f64>,
    /// The largest component of the drift over every step of the run (not only the samples),
    /// m, and when, s.
    pub largest_drift: (f64, f64),
}

/// Runs the thermal run of `scenario`, sampling every `every_s` seconds, with the drift of the
/// tool point at `probe` (m).
pub fn run(
    scenario: &Scenario,
    probe: Vector3<f64>,
    every_s: f64,
) -> Result<ThermalHistory, CliError> {
    let machine = &scenario.machine;
    let (Some(thermal), Some(spec)) = (&machine.thermal, &scenario.thermal_run) else {
        return Err(CliError::Argument(
            "the scenario has no thermal model or no [thermal_run]; add both to simulate one"
                .into(),
        ));
    };
    if !(every_s.is_finite() && every_s > 0.0) {
        return Err(CliError::Argument(format!(
            "--every-s {every_s}: a sampling interval > 0 s is accepted"
        )));
    }
    if let Some(axis) = machine.outside_stroke(&probe) {
        return Err(CliError::Argument(format!(
            "--probe-mm: the {axis} coordinate is outside the stroke"
        )));
    }
    let model = |e: vmt_model::thermal::ThermalError| CliError::Model(e.to_string());
    let mut run = ThermalRun::new(&thermal.network, &spec.schedule, spec.step_s).map_err(model)?;
    let state = AxisState::new(probe, Direction::Forward);
    let reference = machine
        .volumetric_error(
            &state,
            &vec![REFERENCE_TEMPERATURE_C; thermal.network.node_count()],
        )
        .map_err(|e| CliError::Model(e.to_string()))?;
    let duration = spec.schedule.duration_s();
    let samples = (duration / every_s).ceil() as usize;
    if samples > 1_000_000 {
        return Err(CliError::Argument(format!(
            "--every-s {every_s}: {samples} samples over the {duration} s run; up to 1 000 000 are accepted"
        )));
    }
    let mut h = ThermalHistory {
        nodes: thermal.network.node_names().map(str::to_string).collect(),
        times_s: Vec::new(),
        ambient_c: Vec::new(),
        temps_c: Vec::new(),
        drift: Vec::new(),
        time_constants_s: thermal.network.time_constants_s().map_err(model)?,
        largest_drift: (0.0, 0.0),
    };
    let drift_at = |run: &ThermalRun| {
        machine
            .volumetric_error(&state, run.temperatures_c())
            .map_err(|e| CliError::Model(e.to_string()))
    };
    let mut before = 0.0;
    for i in 0..=samples {
        let t = (i as f64 * every_s).min(duration);
        // The run's own step grid between samples, so that the largest drift does not depend
        // on how often the history is sampled.
        let mut k = (before / spec.step_s).floor() + 1.0;
        while k * spec.step_s <= t {
            let between = k * spec.step_s;
            run.advance_to(between).map_err(model)?;
            let d = (drift_at(&run)? - reference).amax();
            if d > h.largest_drift.0 {
                h.largest_drift = (d, between);
            }
            k += 1.0;
        }
        run.advance_to(t).map_err(model)?;
        before = t;
        let temps = run.temperatures_c().to_vec();
        let e = drift_at(&run)?;
        h.times_s.push(t);
        h.ambient_c.push(thermal.network.ambient().celsius_at(t));
        h.temps_c.push(temps);
        h.drift.push(e - reference);
    }
    Ok(h)
}

impl ThermalHistory {
    /// Writes `time_h,ambient_c,temp_<node>_c...,dx_um,dy_um,dz_um`.
    pub fn write_csv(&self, out: &mut dyn Write) -> std::io::Result<()> {
        let nodes: Vec<String> = self.nodes.iter().map(|n| format!("temp_{n}_c")).collect();
        writeln!(
            out,
            "time_h,ambient_c,{},dx_um,dy_um,dz_um",
            nodes.join(",")
        )?;
        for i in 0..self.times_s.len() {
            let temps: Vec<String> = self.temps_c[i].iter().map(|t| format!("{t:.4}")).collect();
            let d = self.drift[i] * 1e6;
            writeln!(
                out,
                "{:.4},{:.4},{},{:.4},{:.4},{:.4}",
                self.times_s[i] / 3600.0,
                self.ambient_c[i],
                temps.join(","),
                d.x,
                d.y,
                d.z
            )?;
        }
        Ok(())
    }

    /// Draws temperatures and drift against time.
    pub fn draw(&self, path: &std::path::Path, format: plot::Format) -> Result<(), CliError> {
        plot::draw_thermal(self, path, format)
    }
}
