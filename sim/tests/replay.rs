//! Reading a run's ball bar again (`vmt_sim::replay`): with the machine unchanged it gives the
//! run's traces exactly, and with other geometric errors and another bar set-up it gives what a
//! whole new simulation gives, since neither enters the motion.

use vmt_scenario::edit::Template;
use vmt_sim::replay::{Replay, replay};
use vmt_sim::run::{BallbarTrace, Run};
use vmt_sim::simulate::{PlannedPath, simulate_with_replay};

/// The built-in machine on a short XY test (100 mm, 2000 mm/min, CW and CCW), with noise.
fn scenario_text() -> String {
    let text = vmt_scenario::BUILTIN_DEFAULT;
    let cut = text.find("[job]").expect("a job");
    let rest = &text[cut..];
    let next = rest[1..].find("\n[").map_or(rest.len(), |i| i + 1);
    format!(
        "{}[job]\nkind = \"ballbar\"\nplane = \"XY\"\ncenter_mm = [250.0, 200.0, 200.0]\nradius_mm = 100.0\nfeed_mm_min = 2000.0\narc_deg = 360.0\ndirections = [\"cw\", \"ccw\"]\n{}",
        &text[..cut],
        &rest[next..]
    )
}

/// Scenario `text` with the keys of `pairs` set to their values.
fn edited(text: &str, pairs: &[(&str, f64)]) -> String {
    Template::parse(text, "replay.toml")
        .unwrap()
        .with(pairs)
        .unwrap()
}

fn run(text: &str) -> Vec<BallbarTrace> {
    let s = vmt_scenario::parse(text, "replay.toml", None).expect("loads");
    let e = s.execution.expect("a job");
    e.simulate(&s.machine, text, &mut |_| {})
        .expect("runs")
        .ballbar
}

/// The run of scenario `text`, recorded for replays.
fn recorded(text: &str) -> (Run, Replay) {
    let (run, rec) = run_on(text, None);
    (run, rec.expect("recorded when asked"))
}

/// The run of scenario `text`, recorded, on `path` if given.
fn run_on(text: &str, path: Option<&PlannedPath>) -> (Run, Option<Replay>) {
    let s = vmt_scenario::parse(text, "replay.toml", None).expect("loads");
    let e = s.execution.as_ref().expect("a job");
    simulate_with_replay(
        &s.machine,
        &e.axes,
        &e.controller,
        &e.job,
        &e.settings,
        text,
        path,
        true,
    )
    .expect("runs")
}

/// Scenario `text`'s program planned under its controller.
fn planned(text: &str) -> PlannedPath {
    let s = vmt_scenario::parse(text, "replay.toml", None).expect("loads");
    let e = s.execution.as_ref().expect("a job");
    PlannedPath::new(&e.job.program, &e.controller).expect("plans")
}

/// The traces `rec` gives when read again on scenario `text`'s machine.
fn replayed_on(text: &str, rec: &Replay) -> Vec<BallbarTrace> {
    let s = vmt_scenario::parse(text, "replay.toml", None).expect("loads");
    let e = s.execution.as_ref().expect("a job");
    replay(&s.machine, &e.job, &e.settings, rec).expect("replays")
}

/// Asserts that `rec` read again on scenario `changed` gives what a new simulation of it gives,
/// to 1e-9 µm at the same times; returns the largest change from the recorded run's `base`
/// traces, µm.
fn replays_as_simulated(changed: &str, rec: &Replay, base: &[BallbarTrace]) -> f64 {
    let replayed = replayed_on(changed, rec);
    let simulated = run(changed);
    assert_eq!(replayed.len(), simulated.len());
    let mut largest_change = 0.0f64;
    for ((r, n), b) in replayed.iter().zip(&simulated).zip(base) {
        assert_eq!(r.times_s, n.times_s);
        for ((x, y), z) in r
            .deviation_um
            .iter()
            .zip(&n.deviation_um)
            .zip(&b.deviation_um)
        {
            assert!((x - y).abs() < 1e-9, "{x} vs {y} µm");
            largest_change = largest_change.max((x - z).abs());
        }
    }
    largest_change
}

#[test]
fn a_replay_reads_what_a_new_simulation_reads() {
    let text = scenario_text();
    let (base, rec) = recorded(&text);
    // The machine as it ran: the same traces, noise draws included, to the bit.
    assert_eq!(replayed_on(&text, &rec), base.ballbar);
    // Squareness, an X scale error and another pivot offset and bar temperature.
    let changed = edited(
        &text,
        &[
            ("machine.errors.squareness.EC0Y_urad", 40.0),
            ("machine.errors.x.forward.EXX_um[1]", 9.0),
            ("instruments.ballbar.setup_eccentricity_um[0]", -6.0),
            ("instruments.ballbar.bar_temperature_c", 21.5),
        ],
    );
    let largest_change = replays_as_simulated(&changed, &rec, &base.ballbar);
    // The changes are seen: several µm on a 100 mm circle.
    assert!(largest_change > 3.0, "{largest_change}");
}

/// The lumped thermal network does not enter the motion: with another screw capacity, screw
/// heat and a spindle head that starts warm, a replay steps the network again with the run's
/// heat and reads what a new simulation reads, to rounding; and the change is there to see.
#[test]
fn a_replay_with_another_thermal_network_reads_what_a_new_simulation_reads() {
    let text = scenario_text();
    let (base, rec) = recorded(&text);
    let changed = edited(
        &text,
        &[
            ("machine.thermal.nodes[3].capacity_j_per_k", 1200.0),
            ("machine.thermal.sources[1].w_per_mm_s", 0.8),
            ("machine.thermal.nodes[0].initial_c", 35.0),
        ],
    );
    let largest_change = replays_as_simulated(&changed, &rec, &base.ballbar);
    assert!(largest_change > 0.3, "{largest_change}");
}

/// A program planned once and run on a machine with other drives gives that machine's run bit
/// for bit, as does a path planned for another program (a smaller circle), which is not used.
#[test]
fn a_planned_path_runs_as_the_program_interpolated_anew() {
    let text = scenario_text();
    let machine = edited(&text, &[("machine.axes.x.drive.backlash_um", 6.0)]);
    let (fresh, _) = run_on(&machine, None);
    let (on_path, _) = run_on(&machine, Some(&planned(&text)));
    assert_eq!(on_path.ballbar, fresh.ballbar);
    let smaller = edited(&text, &[("job.radius_mm", 80.0)]);
    let (elsewhere, _) = run_on(&machine, Some(&planned(&smaller)));
    assert_eq!(elsewhere.ballbar, fresh.ballbar);
    assert_ne!(run_on(&smaller, None).0.ballbar, fresh.ballbar);
}
