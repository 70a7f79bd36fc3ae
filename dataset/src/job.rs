//! A scenario's job executed into a [`Run`], with no files: what each run of a dataset is, and
//! what `vmt run` shows with a progress bar and writes as it goes.

use crate::Error;
use vmt_scenario::{Execution, Scenario};
use vmt_sim::machining::simulate_machining;
use vmt_sim::plant::Fidelity;
use vmt_sim::run::{LogSink, Run};
use vmt_sim::simulate::{SimError, simulate_logged};

/// The job of `scenario`, or an error saying what a scenario with a job has.
pub fn execution(scenario: &Scenario) -> Result<&Execution, Error> {
    scenario.execution.as_ref().ok_or_else(|| {
        Error::Request(
            "the scenario has no job to run: it needs [machine.axes.<axis>.drive] and .servo for X, Y and Z, [controller] and [job]".into(),
        )
    })
}

/// What the job accepts but will not do as asked, to be said when it runs: feeds of its
/// program file above the controller's largest, and instruments with nothing to record.
pub fn notes(exec: &Execution) -> Vec<String> {
    let mut notes = match &exec.program_file {
        Some(file) => clamped_feeds(&exec.job.program, exec.controller.limits.max_feed_m_s, file),
        None => Vec::new(),
    };
    notes.extend(exec.notes.iter().cloned());
    notes
}

/// Simulates the scenario's job (at `fidelity`, or the scenario's own), reporting the share
/// done to `progress` and, for a job through the feed drives, its records to `sink` as it
/// runs (a milling job has none).
pub fn simulate(
    scenario: &Scenario,
    text: &str,
    fidelity: Option<Fidelity>,
    progress: &mut dyn FnMut(f64),
    sink: Option<&mut dyn LogSink>,
) -> Result<Run, Error> {
    let exec = execution(scenario)?;
    let mut settings = exec.settings;
    if let Some(f) = fidelity {
        settings.fidelity = f;
    }
    match &exec.milling {
        Some(m) => simulate_machining(
            &scenario.machine,
            &exec.axes,
            &exec.controller,
            &exec.job,
            m,
            &settings,
            text,
            None,
            progress,
        ),
        None => simulate_logged(
            &scenario.machine,
            &exec.axes,
            &exec.controller,
            &exec.job,
            &settings,
            text,
            progress,
            sink,
        ),
    }
    .map_err(|e| sim_error(&e, exec.program_file.as_deref()))
}

/// A simulation error as `vmt` prints it: one about a block of the program file `file` starts
/// with `file:line:`, as the program's parse errors do.
fn sim_error(e: &SimError, file: Option<&str>) -> Error {
    match (e.line(), file) {
        (Some(line), Some(file)) => Error::Model(format!("{file}:{line}: {e}")),
        _ => Error::Model(e.to_string()),
    }
}

/// The feeds of a program file above the controller's largest, which it clamps to it as a
/// controller does (a ball-bar or positioning test is refused instead, at load): one note per
/// line, naming the file and line.
pub fn clamped_feeds(program: &vmt_sim::nc::Program, max_feed_m_s: f64, file: &str) -> Vec<String> {
    use vmt_sim::nc::Motion;
    let max = (max_feed_m_s * 60_000.0 * 1e6).round() / 1e6;
    let mut notes: Vec<String> = program
        .blocks
        .iter()
        .filter_map(|b| match b.motion {
            Motion::Linear { feed, .. } | Motion::Arc { feed, .. } if feed * 60_000.0 > max * (1.0 + 1e-9) => {
                Some(format!(
                    "{file}:{}: F{} mm/min is above controller.max_feed_mm_min = {max} mm/min; the controller runs it at {max}",
                    b.span.line,
                    (feed * 60_000.0 * 1e6).round() / 1e6
                ))
            }
            _ => None,
        })
        .collect();
    notes.dedup();
    notes
}
