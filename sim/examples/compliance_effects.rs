//! What the compliant structure (the carriages as rigid bodies on their guide blocks) changes on
//! the built-in machine: each job run with the reduced plant and with the compliant multibody,
//! everything else equal (the ball bar without noise and quantisation, so that the difference
//! is the physics), and the difference of what the instruments read, printed as the README's
//! Markdown table.
//!
//! Run: `cargo run --release -p vmt-sim --example compliance_effects` (about a minute).

use vmt_scenario::{Scenario, parse};
use vmt_sim::plant::Fidelity;
use vmt_sim::run::Run;

const BUILTIN: &str = vmt_scenario::BUILTIN_DEFAULT;

fn exact_bar(text: &str) -> String {
    text.replace("resolution_um = 0.1", "resolution_um = 0.0")
        .replace("noise_um = 0.1", "noise_um = 0.0")
}

fn run(s: &Scenario, text: &str, fidelity: Fidelity) -> Run {
    let exec = s.execution.as_ref().expect("a job");
    let mut settings = exec.settings;
    settings.fidelity = fidelity;
    match &exec.milling {
        Some(m) => vmt_sim::machining::simulate_machining(
            &s.machine,
            &exec.axes,
            &exec.controller,
            &exec.job,
            m,
            &settings,
            text,
            None,
            &mut |_| {},
        ),
        None => vmt_sim::simulate::simulate(
            &s.machine,
            &exec.axes,
            &exec.controller,
            &exec.job,
            &settings,
            text,
            &mut |_| {},
        ),
    }
    .expect("the job runs")
}

/// The largest |difference| of a channel between two runs (same instants), in its unit.
fn largest_channel_difference(a: &Run, b: &Run, stream: &str, names: &[&str]) -> f64 {
    let (sa, sb) = (
        a.streams.iter().find(|s| s.name == stream).expect("stream"),
        b.streams.iter().find(|s| s.name == stream).expect("stream"),
    );
    let n = sa.times_s.len().min(sb.times_s.len());
    // The change less the one at the start, where both stand at rest: the part that varies
    // along the job (the static droop under gravity is a constant offset).
    let d = |c: &str, k: usize| sa.channel(c).unwrap().values[k] - sb.channel(c).unwrap().values[k];
    (0..n)
        .map(|k| {
            names
                .iter()
                .map(|c| (d(c, k) - d(c, 0)).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max)
}

/// The largest |value| of the named channels of the `structure` stream.
fn peak(run: &Run, prefix: &str) -> f64 {
    run.streams
        .iter()
        .find(|s| s.name == "structure")
        .map_or(0.0, |s| {
            s.channels
                .iter()
                .filter(|c| c.name.starts_with(prefix))
                .flat_map(|c| c.values.iter())
                .fold(0.0, |m: f64, v| m.max(v.abs()))
        })
}

/// ISO 230-4's circular deviation G of each trace (max − min of the readings), µm, and the
/// largest |difference| of the readings between two runs.
fn ballbar(a: &Run, b: &Run) -> (f64, f64, f64) {
    let g = |r: &Run| {
        r.ballbar
            .iter()
            .map(|t| {
                let (lo, hi) = t
                    .deviation_um
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
                        (l.min(v), h.max(v))
                    });
                hi - lo
            })
            .fold(0.0, f64::max)
    };
    let diff = a
        .ballbar
        .iter()
        .zip(&b.ballbar)
        .flat_map(|(x, y)| x.deviation_um.iter().zip(&y.deviation_um))
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    (g(a), g(b), diff)
}

fn row(name: &str, reduced: &Run, compliant: &Run) {
    let tool = ["tool_x", "tool_y", "tool_z"];
    let tool_um = if reduced.streams[0].channel("tool_x").is_some() {
        format!(
            "{:.3}",
            largest_channel_difference(reduced, compliant, "servo", &tool) * 1e6
        )
    } else {
        "—".into()
    };
    let bar = if reduced.ballbar.is_empty() {
        "—".into()
    } else {
        let (g0, g1, d) = ballbar(reduced, compliant);
        format!("G {g0:.3} → {g1:.3}; largest reading change {d:.3}")
    };
    let tilt = ["x", "y", "z"]
        .map(|a| format!("{:.3}", peak(compliant, &format!("tilt_{a}_")) * 1e6))
        .join(" / ");
    let block = ["x", "y", "z"]
        .map(|a| format!("{:.0}", peak(compliant, &format!("block_{a}_"))))
        .join(" / ");
    println!("| {name} | {tool_um} | {bar} | {tilt} | {block} |");
}

fn milling_row(reduced: &Run, compliant: &Run) {
    let m = |r: &Run, k: &str| r.ground_truth["milling"][k].as_f64().unwrap_or(f64::NAN);
    let fe = largest_channel_difference(
        reduced,
        compliant,
        "servo",
        &[
            "following_error_x",
            "following_error_y",
            "following_error_z",
        ],
    );
    let sle: Vec<String> = ["sle_mean_um", "sle_max_abs_um", "ra_um", "rz_um"]
        .iter()
        .map(|k| {
            format!(
                "{} {:.3} → {:.3}",
                k.trim_end_matches("_um"),
                m(reduced, k),
                m(compliant, k)
            )
        })
        .collect();
    println!(
        "| slot cut, scenarios/milling_slot.toml | largest following-error change {:.3} | {} (µm) | — | — |",
        fe * 1e6,
        sle.join("; ")
    );
}

fn case(name: &str, text: &str, base: Option<&std::path::Path>) {
    let s = parse(text, name, base).unwrap_or_else(|e| panic!("{name}: {e}"));
    let reduced = run(&s, text, Fidelity::Reduced);
    let compliant = run(&s, text, Fidelity::Compliant);
    if s.execution.as_ref().is_some_and(|e| e.milling.is_some()) {
        milling_row(&reduced, &compliant);
    } else {
        row(name, &reduced, &compliant);
    }
}

fn main() {
    println!(
        "| job (built-in machine) | largest tool-point change along the job, µm | ball bar: max − min of the readings, reduced → compliant; largest reading change, µm | peak tilt X / Y / Z carriage, µrad | peak block force X / Y / Z, N |"
    );
    println!("|---|---|---|---|---|");
    let bar = exact_bar(BUILTIN);
    case("ball bar 150 mm, 1000 mm/min", &bar, None);
    case(
        "ball bar 150 mm, 4000 mm/min",
        &bar.replace("feed_mm_min = 1000.0", "feed_mm_min = 4000.0"),
        None,
    );
    // The highest path acceleration a ball bar can give here: its shortest circle (50 mm) at
    // the highest feed (10 m/min), v²/R = 0.56 m/s² (the path limit, 2 m/s², would need a
    // 14 mm circle).
    case(
        "ISO 230-4 circle 50 mm at 10000 mm/min (0.56 m/s²)",
        &bar.replace("feed_mm_min = 1000.0", "feed_mm_min = 10000.0")
            .replace("radius_mm = 150.0", "radius_mm = 50.0"),
        None,
    );
    let dir = std::env::temp_dir().join("vmt_compliance_effects");
    std::fs::create_dir_all(&dir).expect("temp folder");
    // A 90° corner at the axis acceleration limit: X then Y at the highest feed, the corner
    // taken at the speed the axes' 5 m/s² allow within the corner tolerance.
    std::fs::write(
        dir.join("corner.nc"),
        "G90 G1 X150 Y150 Z300 F10000\nG1 X350 Y150\nG1 X350 Y350\n",
    )
    .expect("program");
    let corner = BUILTIN.split("[job]").next().expect("text").to_string()
        + "[job]\nkind = \"program\"\nprogram = \"corner.nc\"\n";
    case("corner X→Y at 10000 mm/min", &corner, Some(&dir));
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios");
    let slot = std::fs::read_to_string(root.join("milling_slot.toml")).expect("milling_slot.toml");
    case("slot", &slot, Some(&root));
}
