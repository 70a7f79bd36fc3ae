//! One gap diagnosis of Kwon's seven-step procedure (scenarios/kwon_seven_step.toml, 14 traces
//! in XY, ZX and YZ): the "measured" runs come from the model with 3 µm more X backlash, the
//! library is that of the three planes. (Not Z: gravity holds the Z nut on one flank, so 3 µm
//! more Z backlash changes the held-out traces by 0.026 µm RMS, and nothing is to be found.)
//! Goal (issues 6 and 27): at most 30 s on 2 cores. Measured 29 November 2026 on the 2-core
//! machine, otherwise idle, in turn with the bench of cf37350 (the host's speed swings by a
//! quarter or more from hour to hour): 15.7–16.1 s, median 15.8 s (linearisation 11.1–11.5 s:
//! 11 simulations and 21 replays) against 21.4–23.5 s. It gained from the program planned
//! once for all evaluations (`vmt_sim::simulate::PlannedPath`), the sensitivities binned in
//! parallel, the next step's candidate verified ahead (`Options::speculate`) and the replays
//! run while the other parameters still simulate.
//! backlash_x 3.06 µm, untouched judge shrink 98.5 %. Profile of the simulations: the reduced
//! plant's step 32 %, the drives' control 12 %, the simulation loop 12 %, the interpolator's
//! setpoints 11 %. History: 71.3 s before the geometric and bar set-up parameters were
//! replayed, 49.9 s before the lead errors were, 22.0–25.6 s before the untouched-judge
//! protocol and the screws' heating.
//! Run: `cargo bench -p vmt-gap --bench seven_step` (prints the wall time of each stage).

use std::time::Instant;
use vmt_gap::model::{Forward, ScenarioModel};
use vmt_gap::select::{Linearisation, Options, select};
use vmt_gap::split::Split;

fn main() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scenarios/kwon_seven_step.toml"
    );
    let text = std::fs::read_to_string(path).expect("the seven-step scenario");
    let dir = std::path::Path::new(path).parent().map(|p| p.to_path_buf());
    let model = ScenarioModel::new(&text, path, dir.clone()).expect("model");
    let key = "machine.axes.x.drive.backlash_um";
    let x = model.value(key).expect("X backlash in the model");
    let real_text = vmt_scenario::edit::Template::parse(&text, path)
        .unwrap()
        .with(&[(key, x + 3.0)])
        .unwrap();
    let t0 = Instant::now();
    let measured = ScenarioModel::instrumented(&real_text, path, dir)
        .unwrap()
        .traces(&[])
        .unwrap();
    eprintln!(
        "measured run simulated in {:.1} s ({} traces)",
        t0.elapsed().as_secs_f64(),
        measured.len()
    );
    let lib = model.library(&[('x', 'y'), ('z', 'x'), ('y', 'z')]);
    let t = Instant::now();
    let lin = Linearisation::new(&model, &lib).unwrap();
    let t_lin = t.elapsed().as_secs_f64();
    let split = Split::automatic(&measured).unwrap();
    let s = select(&model, &lin, &measured, &lib, split, &Options::default()).unwrap();
    let total = t.elapsed().as_secs_f64();
    let found: Vec<String> = s
        .steps
        .iter()
        .map(|x| {
            format!(
                "{} {:?}",
                x.effect,
                x.values.iter().map(|v| v.value).collect::<Vec<_>>()
            )
        })
        .collect();
    println!(
        "seven-step gap diagnosis: {total:.1} s on {} threads ({} + {} model evaluations, {} of them replays of the recorded motion; linearisation {t_lin:.1} s); found {found:?}; alternatives {:?}; untouched judge RMS before {:.3} um; judge shrink {:.1} %",
        rayon::current_num_threads(),
        lin.simulations(),
        s.simulations,
        model.replays(),
        s.alternatives
            .iter()
            .map(|a| (a.effects.join(" + "), a.implausible.is_some()))
            .collect::<Vec<_>>(),
        s.judged.map_or(f64::NAN, |j| j.before_um),
        100.0 * s.judge_shrink().unwrap_or(f64::NAN)
    );
}
