//! How large each withheld effect (`vmt_scenario::withheld`) is on the built-in machine's
//! ball-bar tests: the RMS and the peak of the change of the bar's reading against the same
//! machine without the effect, over both directions, each effect at its typical size on each
//! axis of the test's plane. The bar reads without noise and rounding (both runs otherwise the
//! same, same seed), so the difference is the effect alone; the servo log is thinned to 10 Hz.
//!
//! Run: `cargo run --release -p vmt-scenario --example withheld_sizes`
//! (docs/withheld_physics.md holds its table).

use vmt_model::Axis;
use vmt_scenario::edit::Template;
use vmt_scenario::withheld::{WITHHELD, switch_on};

type Test = (&'static str, f64, f64, [(Axis, f64); 2]);

/// The bar's readings of each trace (µm) and the run's wall time (s).
type Readings = (Vec<Vec<f64>>, f64);

/// The tests: plane, radius (mm), feed (mm/min), and where a rail defect sits on each of the
/// plane's axes (mm): inside the circle's sweep of that axis, off its middle.
const TESTS: [Test; 3] = [
    ("XY", 150.0, 1000.0, [(Axis::X, 330.0), (Axis::Y, 250.0)]),
    ("XY", 100.0, 2000.0, [(Axis::X, 330.0), (Axis::Y, 250.0)]),
    ("ZX", 100.0, 2000.0, [(Axis::Z, 250.0), (Axis::X, 330.0)]),
];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    println!(
        "| test | effect | axis | size | RMS change (nm) | peak change (nm) | run time, s (base s) |"
    );
    println!("|---|---|---|---|---:|---:|---:|");
    for (plane, radius, feed, places) in TESTS {
        let base = Template::parse(vmt_scenario::BUILTIN_DEFAULT, "vmc500.toml")?
            .with(&[("job.radius_mm", radius), ("job.feed_mm_min", feed)])?;
        let base = Template::parse(&base, "vmc500.toml")?.with_text(&[("job.plane", plane)])?;
        let base = Template::parse(&base, "vmc500.toml")?.with_inserted(&[
            ("instruments.ballbar.noise_um", 0.0),
            ("instruments.ballbar.resolution_um", 0.0),
            ("simulation.log_rate_hz", 10.0),
        ])?;
        let template = Template::parse(&base, "vmc500.toml")?;
        let (reference, base_s) = readings(&base)?;
        let test = format!("{plane} R{radius} F{feed}");
        for effect in &WITHHELD {
            for (axis, at) in places {
                let text = switch_on(&template, effect.key, axis, effect.typical, Some(at))?;
                let (with, seconds) = readings(&text)?;
                let (rms, peak) = change(&reference, &with);
                let place = if effect.placed {
                    format!(" at {at} mm")
                } else {
                    String::new()
                };
                println!(
                    "| {test} | {} | {axis}{place} | {} {} | {:.1} | {:.1} | {seconds:.2} ({base_s:.2}) |",
                    effect.key,
                    effect.typical,
                    effect.unit,
                    rms * 1e3,
                    peak * 1e3
                );
            }
        }
    }
    Ok(())
}

/// The bar's readings (µm) of every trace of the scenario `text`, and the wall time, s.
fn readings(text: &str) -> Result<Readings, Box<dyn std::error::Error>> {
    let scenario = vmt_scenario::parse(text, "vmc500.toml", None)?;
    let exec = scenario
        .execution
        .as_ref()
        .ok_or("the scenario has no job")?;
    let start = std::time::Instant::now();
    let run = exec.simulate(&scenario.machine, text, &mut |_| {})?;
    let seconds = start.elapsed().as_secs_f64();
    Ok((
        run.ballbar.iter().map(|t| t.deviation_um.clone()).collect(),
        seconds,
    ))
}

/// RMS and peak of the difference between two runs' readings (µm), over all traces.
fn change(a: &[Vec<f64>], b: &[Vec<f64>]) -> (f64, f64) {
    let (mut sum, mut n, mut peak) = (0.0, 0usize, 0.0_f64);
    for (ta, tb) in a.iter().zip(b) {
        for (x, y) in ta.iter().zip(tb) {
            let d = y - x;
            sum += d * d;
            n += 1;
            peak = peak.max(d.abs());
        }
    }
    ((sum / n.max(1) as f64).sqrt(), peak)
}
