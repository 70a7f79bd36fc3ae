//! End-to-end tests of vmt across its crates, run on the scenarios shipped in `scenarios/`.
//! The tests are in `tests/tests/`; this library holds what several of them do alike.

use vmt_ballbar::Trace;
use vmt_sim::run::Run;

/// The job of the scenario `text` (named `name` in errors) run to its end, without progress.
pub fn simulate_text(text: &str, name: &str) -> Run {
    let s = vmt_scenario::parse(text, name, None).expect("the scenario loads");
    let e = s.execution.expect("the scenario has a job");
    e.simulate(&s.machine, text, &mut |_| {})
        .expect("the job runs")
}

/// The ball-bar traces of `run` as the diagnosis reads them, in the order run.
pub fn traces(run: &Run) -> Vec<Trace> {
    run.ballbar
        .iter()
        .map(|t| vmt_gap::model::trace_of(t).expect("a valid trace"))
        .collect()
}
