//! `vmt gap` and `vmt gap-bench`: the sim-to-real gap of a model against measured ball-bar runs
//! (where the residual sits, which unmodelled effects explain it, how much each buys on
//! held-out runs), and the withheld-effect check of that analysis.
//!
//! Files written by `vmt gap --out DIR`: `gap.txt`, `gap.json`, `residual_before.png` and
//! `residual_after.png` (polar plots of measured − model, magnified about the nominal circle),
//! and `gap.rrd` (Rerun 0.36: the residual traces before and after as polar plots and series).

use crate::error::CliError;
use crate::plot::{self, Format};
use crate::traces::{self, CsvSetup};
use serde_json::{Value, json};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use vmt_ballbar::Trace;
use vmt_gap::discriminate::{Discrimination, Explanation, discriminate, noise_of};
use vmt_gap::localise::{self, Localisation, Place};
use vmt_gap::model::ScenarioModel;
use vmt_gap::peaks::{Circle, centre_text, distinct_centres};
use vmt_gap::select::{self, Linearisation, Selection};
use vmt_gap::split::Split;
use vmt_gap::{GapError, TracePair};
use vmt_logs::rerun::write_rrd;
use vmt_sim::run::{BallbarTrace, Run};

/// A gap analysis and what it was made from.
pub struct GapReport {
    /// The model's scenario file.
    pub model_file: String,
    /// The measured files.
    pub files: Vec<String>,
    /// The residual of the model as given, localised.
    pub before: Localisation,
    /// The residual after the selected effects, localised.
    pub after: Localisation,
    /// The selection.
    pub selection: Selection,
    /// Whether the chosen effects explain the gap (select bins, confirmed on the judge bins).
    pub explained: bool,
    /// For each plausible alternative, the test that would tell it from the chosen effect.
    pub discriminating: Vec<Discrimination>,
    /// Simulations run in all.
    pub simulations: usize,
}

fn model_error(file: &str, e: GapError) -> CliError {
    CliError::input(file, None, e.to_string())
}

/// Reads the measured traces of every file (MCAP runs or CSV traces with `csv`'s set-up).
pub fn measured(files: &[PathBuf], csv: Option<CsvSetup>) -> Result<Vec<Trace>, CliError> {
    let mut all = Vec::new();
    for f in files {
        all.extend(
            traces::read(f, csv, &crate::import::Import::default())?
                .0
                .tests
                .into_iter()
                .flatten(),
        );
    }
    if all.is_empty() {
        return Err(CliError::Argument(
            "no ball-bar trace in the measured files".into(),
        ));
    }
    Ok(all)
}

/// The gap of the scenario at `model` against `measured`.
pub fn analyse(model: &Path, files: &[PathBuf], measured: &[Trace]) -> Result<GapReport, CliError> {
    let model_file = model.display().to_string();
    let text = std::fs::read_to_string(model)
        .map_err(|e| CliError::input(&model_file, None, e.to_string()))?;
    let dir = model.parent().map(Path::to_path_buf);
    let forward =
        ScenarioModel::new(&text, &model_file, dir).map_err(|e| model_error(&model_file, e))?;
    let mut planes: Vec<(char, char)> = Vec::new();
    for t in measured {
        let (p, q) = t.plane.axes();
        let plane = (p.to_ascii_lowercase(), q.to_ascii_lowercase());
        if !planes.contains(&plane) {
            planes.push(plane);
        }
    }
    let lib = forward.library(&planes);
    let err = |e: GapError| match e {
        GapError::Model(_) => model_error(&model_file, e),
        other => CliError::Argument(other.to_string()),
    };
    let split = Split::automatic(measured).map_err(err)?;
    let lin = Linearisation::new(&forward, &lib).map_err(err)?;
    let so = select::Options::default();
    let selection = select::select(&forward, &lin, measured, &lib, split, &so).map_err(err)?;
    let o = localise::Options::default();
    let circles: Vec<Option<Circle>> = select::partners(measured, lin.base())
        .map_err(err)?
        .into_iter()
        .map(|i| forward.circles().get(i).copied())
        .collect();
    let before = Localisation::on_circles(&selection.initial_pairs, &circles, &o).map_err(err)?;
    let after = Localisation::on_circles(&selection.final_pairs, &circles, &o).map_err(err)?;
    let discriminating = discriminating_tests(&forward, &selection, measured).map_err(err)?;
    Ok(GapReport {
        model_file,
        files: files.iter().map(|f| f.display().to_string()).collect(),
        before,
        after,
        explained: selection.explained(&so),
        simulations: lin.simulations() + selection.simulations,
        selection,
        discriminating,
    })
}

/// The discriminating test of each plausible alternative to a chosen effect
/// ([`vmt_gap::discriminate`]), with a progress bar over the tests simulated.
fn discriminating_tests(
    model: &ScenarioModel,
    s: &Selection,
    measured: &[Trace],
) -> Result<Vec<Discrimination>, GapError> {
    // The implausible fits too: a range is a judgement, and the test tells them apart.
    let rivals: Vec<Explanation> = s
        .alternatives
        .iter()
        .map(|a| Explanation {
            label: a.effects.join(" + "),
            instead_of: a.instead_of.clone(),
            values: a.edits.clone(),
        })
        .collect();
    if rivals.is_empty() {
        return Ok(Vec::new());
    }
    let chosen = Explanation {
        label: s
            .steps
            .iter()
            .map(|x| x.effect.clone())
            .collect::<Vec<_>>()
            .join(" + "),
        instead_of: String::new(),
        values: s.final_values.clone(),
    };
    let bar = indicatif::ProgressBar::new(vmt_gap::discriminate::setups().len() as u64);
    bar.set_message("tests that tell the explanations apart");
    let found = discriminate(model, &chosen, &rivals, noise_of(measured), &|| bar.inc(1));
    bar.finish_and_clear();
    found
}

fn places_text(out: &mut String, title: &str, places: &[Place]) {
    if places.is_empty() {
        return;
    }
    let _ = writeln!(out, "  {title}:");
    for p in places {
        let _ = writeln!(
            out,
            "    {:<40} {:>5.1} %  (even spread {:>5.1} %)",
            p.name,
            100.0 * p.share,
            100.0 * p.expected
        );
    }
}

fn localisation_text(out: &mut String, l: &Localisation) {
    let _ = writeln!(out, "  RMS {:.3} um", l.rms_um);
    places_text(out, "by run", &l.by_run);
    places_text(out, "by quadrant", &l.by_quadrant);
    places_text(out, "around axis reversals", &l.by_reversal);
    places_text(out, "by direction", &l.by_direction);
    places_text(out, "by harmonic order of the angle", &l.by_harmonic);
    places_text(out, "in time", &l.by_time);
    match &l.concentrations[..] {
        [] => {
            let _ = writeln!(out, "  concentrates: nowhere in particular");
        }
        c => {
            let names: Vec<String> = c
                .iter()
                .map(|p| format!("{} ({:.0} %)", p.name, 100.0 * p.share))
                .collect();
            let _ = writeln!(out, "  concentrates in: {}", names.join(", "));
        }
    }
    if !l.peaks.is_empty() {
        let _ = writeln!(
            out,
            "  peaks on the circle (where the residual concentrates within a few degrees):"
        );
        for p in &l.peaks {
            let _ = writeln!(out, "    {}: {p}", p.test);
        }
    }
    for a in &l.axis_places {
        let _ = writeln!(out, "  a place on {}: {a} ({})", a.axis, a.test);
    }
    if let Some(c) = &l.axis_change {
        let _ = writeln!(out, "  along an axis: {c}");
    }
    if let Some(w) = l.whiteness {
        let _ = writeln!(out, "{}", whiteness_line(&w, ""));
    }
}

/// The significance level of the whiteness verdict: a residual is called white unless
/// Ljung–Box rejects it at 1 % (a report reads many series; 5 % would flag one in twenty
/// white ones).
const WHITENESS_LEVEL: f64 = 0.01;

/// The report's line on a whiteness test; `over` says what the series run over.
pub(crate) fn whiteness_line(w: &vmt_gap::whiteness::Whiteness, over: &str) -> String {
    let verdict = if w.is_white(WHITENESS_LEVEL) {
        format!("white at the {} % level", WHITENESS_LEVEL * 100.0)
    } else {
        format!(
            "not white at the {} % level: structure is left{over}",
            WHITENESS_LEVEL * 100.0
        )
    };
    format!(
        "  whiteness (Ljung-Box, {} dof): Q = {:.1}, p = {:.3} -> {verdict}",
        w.dof, w.q, w.p_value
    )
}

/// The report as text.
pub fn text(r: &GapReport) -> String {
    let s = &r.selection;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Sim-to-real gap: model {} against {}",
        r.model_file,
        r.files.join(", ")
    );
    let _ = writeln!(
        out,
        "Runs: {} measured; protocol: {}",
        s.initial_pairs.len(),
        s.split.rule
    );
    let _ = writeln!(
        out,
        "  bins of 1 deg: {} fit, {} select, {} judge",
        s.bins[0], s.bins[1], s.bins[2]
    );
    let _ = writeln!(out, "\n1. Where (measured - model, before):");
    localisation_text(&mut out, &r.before);
    let _ = writeln!(
        out,
        "\n2. Which effects explain it, and 3. how much (on data they were not fitted or chosen on):"
    );
    let judged = match s.judged {
        Some(j) => format!("judge RMS {:.3} um (untouched)", j.before_um),
        None => format!(
            "no untouched judgement: the judge data hold fewer than {} segments of {:.0} deg",
            vmt_gap::split::MIN_JUDGE_SEGMENTS,
            s.split.segment_deg
        ),
    };
    let _ = writeln!(
        out,
        "  model as given: fit RMS {:.3} um, select RMS {:.3} um, {judged}",
        s.fit_before_um, s.select_before_um
    );
    if !s.baseline.is_empty() {
        let values: Vec<String> = s.baseline.iter().map(|v| v.to_string()).collect();
        let _ = writeln!(
            out,
            "  baseline (the bar's set-up and length, fitted with every candidate): {}",
            values.join(", ")
        );
    }
    for (i, step) in s.steps.iter().enumerate() {
        let values: Vec<String> = step.values.iter().map(|v| v.to_string()).collect();
        let judge = step
            .judge_rms_um
            .map_or(String::new(), |j| format!(", judge RMS {j:.3} um"));
        let together = step.together_with.as_ref().map_or(String::new(), |o| {
            format!(" [one step with {o}: the gap needs the two together, neither passes alone]")
        });
        let _ = writeln!(
            out,
            "  + {}. {}{together} ({}): {}\n      select RMS {:.3} um ({:.0} % of the remaining mean square removed), fit RMS {:.3} um{judge}",
            i + 1,
            step.effect,
            step.description,
            values.join(", "),
            step.select_rms_um,
            100.0 * step.select_shrink,
            step.fit_rms_um
        );
    }
    for x in &s.rejected {
        let _ = writeln!(out, "  not an explanation: {} {}", x.effect, x.implausible);
    }
    if !s.set_aside.is_empty() {
        let changes: Vec<String> = s.local_changes.iter().map(|c| c.to_string()).collect();
        let _ = writeln!(
            out,
            "  set aside: {} (shapes over the whole travel, but {}: a change the circles see begin and end is local)",
            s.set_aside.join(", "),
            changes.join("; ")
        );
    }
    match (s.steps.is_empty(), r.explained, s.judged) {
        (true, _, _) => {
            let _ = writeln!(
                out,
                "  no plausible candidate effect explains the gap: it stays unexplained"
            );
        }
        (false, true, Some(j)) => {
            let _ = writeln!(
                out,
                "  explained: {:.0} % of the untouched judge data's mean square removed (RMS {:.3} -> {:.3} um)",
                100.0 * j.shrink(),
                j.before_um,
                j.after_um
            );
        }
        (false, true, None) => {
            let _ = writeln!(
                out,
                "  explained on the select data; no untouched figure (too few judge data)"
            );
        }
        (false, false, judged) => {
            let on = judged.map_or(String::new(), |j| {
                format!(" (judge RMS {:.3} -> {:.3} um)", j.before_um, j.after_um)
            });
            let _ = writeln!(
                out,
                "  the effects above explain part of it only{on}: the gap stays unexplained"
            );
        }
    }
    alternatives_text(&mut out, r);
    if !s.unavailable.is_empty() {
        let names: Vec<String> = s
            .unavailable
            .iter()
            .map(|(e, k)| format!("{e} (no `{k}` in the model)"))
            .collect();
        let _ = writeln!(
            out,
            "  candidates the model file cannot express: {}",
            names.join(", ")
        );
    }
    let _ = writeln!(out, "\nResidual left (after):");
    localisation_text(&mut out, &r.after);
    let _ = writeln!(out, "\n{} simulations.", r.simulations);
    out
}

/// The equally good explanations, the implausible fits beside them, and the tests that tell
/// them apart.
fn alternatives_text(out: &mut String, r: &GapReport) {
    let s = &r.selection;
    for step in &s.steps {
        let good = s.equally_good(&step.effect);
        if good.is_empty() {
            continue;
        }
        let _ = writeln!(
            out,
            "  equally good explanations of the {} data in place of {} (paired test over its segments, p > 0.05):",
            s.alternatives_judged_on, step.effect
        );
        for a in good {
            let values: Vec<String> = a.values.iter().map(|v| v.to_string()).collect();
            let _ = writeln!(
                out,
                "    {} ({}): RMS {:.3} um against {:.3} um, p = {:.2}",
                a.effects.join(" + "),
                values.join(", "),
                a.rms_um,
                a.chosen_rms_um,
                a.p_value
            );
        }
    }
    for a in s.alternatives.iter().filter(|a| a.implausible.is_some()) {
        if let Some(why) = &a.implausible {
            let _ = writeln!(
                out,
                "  fits as well in place of {}, but {} {why}",
                a.instead_of,
                a.effects.join(" + ")
            );
        }
    }
    for d in &r.discriminating {
        let _ = writeln!(out, "  to tell them apart: {d}");
    }
}

fn places_json(places: &[Place]) -> Value {
    serde_json::to_value(places).unwrap_or(Value::Null)
}

fn localisation_json(l: &Localisation) -> Value {
    json!({
        "rms_um": l.rms_um,
        "by_run": places_json(&l.by_run),
        "by_quadrant": places_json(&l.by_quadrant),
        "by_reversal": places_json(&l.by_reversal),
        "by_direction": places_json(&l.by_direction),
        "by_harmonic": places_json(&l.by_harmonic),
        "by_time": places_json(&l.by_time),
        "concentrations": places_json(&l.concentrations),
        "peaks": serde_json::to_value(&l.peaks).unwrap_or(Value::Null),
        "axis_places": serde_json::to_value(&l.axis_places).unwrap_or(Value::Null),
        "axis_change": serde_json::to_value(&l.axis_change).unwrap_or(Value::Null),
        "whiteness": l.whiteness.map(|w| json!({"q": w.q, "dof": w.dof, "p_value": w.p_value})),
    })
}

/// The report as JSON.
pub fn json(r: &GapReport) -> Value {
    let s = &r.selection;
    json!({
        "model": r.model_file,
        "measured": r.files,
        "protocol": {
            "rule": s.split.rule,
            "segment_deg": s.split.segment_deg,
            "bins": {"fit": s.bins[0], "select": s.bins[1], "judge": s.bins[2]},
        },
        "before": localisation_json(&r.before),
        "baseline": s.baseline,
        "effects": s.steps,
        "explained": r.explained,
        "fit_rms_before_um": s.fit_before_um,
        "select_rms_before_um": s.select_before_um,
        "judged": s.judged.map(|j| json!({
            "bins": j.bins,
            "segments": j.segments,
            "rms_before_um": j.before_um,
            "rms_after_um": j.after_um,
            "shrink": j.shrink(),
        })),
        "not_judged_because": s.judged.is_none().then(|| format!(
            "the judge data hold fewer than {} segments of {} deg",
            vmt_gap::split::MIN_JUDGE_SEGMENTS, s.split.segment_deg
        )),
        "implausible": s.rejected,
        "alternatives": s.alternatives,
        "alternatives_judged_on": s.alternatives_judged_on,
        "discriminating_tests": r.discriminating,
        "unexplained": localisation_json(&r.after),
        "last_round": s.last_round,
        "unavailable": s.unavailable,
        "local_changes": s.local_changes,
        "set_aside": s.set_aside,
        "simulations": r.simulations,
    })
}

fn residual_traces(pairs: &[TracePair], suffix: &str) -> Vec<BallbarTrace> {
    pairs
        .iter()
        .map(|p| BallbarTrace {
            label: format!("{} {suffix}", p.label),
            plane: p.plane.to_string(),
            direction: p.sense.name().into(),
            radius_mm: p.radius_mm,
            feed_mm_min: p.feed_mm_min,
            times_s: p.time_s.clone(),
            angle_deg: p.angle_deg.clone(),
            deviation_um: p.residual_um.clone(),
        })
        .collect()
}

/// Writes gap.txt, gap.json, the residual polar plots and gap.rrd into `dir`.
pub fn write(r: &GapReport, dir: &Path) -> Result<Vec<PathBuf>, CliError> {
    std::fs::create_dir_all(dir).map_err(|e| CliError::output(dir, e))?;
    let mut files = Vec::new();
    let mut put = |name: &str, body: String| -> Result<(), CliError> {
        let path = dir.join(name);
        std::fs::write(&path, body).map_err(|e| CliError::output(&path, e))?;
        files.push(path);
        Ok(())
    };
    put("gap.txt", text(r))?;
    put(
        "gap.json",
        serde_json::to_string_pretty(&json(r)).map_err(|e| CliError::output(dir, e))?,
    )?;
    let before = residual_traces(&r.selection.initial_pairs, "residual before");
    let after = residual_traces(&r.selection.final_pairs, "residual after");
    for (name, traces, rms) in [
        ("residual_before.png", &before, r.before.rms_um),
        ("residual_after.png", &after, r.after.rms_um),
    ] {
        let path = dir.join(name);
        plot::draw_polar(
            traces,
            &path,
            Format::Png,
            Some(&format!("measured - model, RMS {rms:.3} um")),
        )?;
        files.push(path);
    }
    let rrd = dir.join("gap.rrd");
    write_rrd(&residual_run(r, before, after)?, &rrd)?;
    files.push(rrd);
    Ok(files)
}

/// The residuals as a run for the Rerun writer: the traces before and after, the report as the
/// run's ground-truth document.
fn residual_run(
    r: &GapReport,
    before: Vec<BallbarTrace>,
    after: Vec<BallbarTrace>,
) -> Result<Run, CliError> {
    let text = std::fs::read_to_string(&r.model_file)
        .map_err(|e| CliError::input(&r.model_file, None, e.to_string()))?;
    let scenario = vmt_scenario::parse(&text, &r.model_file, Path::new(&r.model_file).parent())?;
    Ok(Run {
        scenario_name: format!("gap of {}", r.model_file),
        scenario_toml: text,
        seed: 0,
        fidelity: "reduced".into(),
        machine: vmt_sim::simulate::summary(&scenario.machine),
        streams: Vec::new(),
        ballbar: before.into_iter().chain(after).collect(),
        laser: None,
        ground_truth: json(r),
    })
}

/// `vmt gap` arguments.
#[derive(clap::Args, Debug)]
pub struct GapArgs {
    /// The model: a scenario whose job is the measured test(s).
    #[arg(long)]
    pub model: PathBuf,
    /// Measured runs: our run.mcap files, ball-bar CSV traces (angle_deg, deviation_um,
    /// direction [, time_s]) with --radius-mm, --feed-mm-min and --plane, or accelerometer
    /// logs of a milling job (a milling run.mcap, or CSV time_s,ax,ay,az in s and m/s²).
    #[arg(long, num_args = 1.., required = true)]
    pub real: Vec<PathBuf>,
    /// Nominal radius of CSV traces, mm.
    #[arg(long)]
    pub radius_mm: Option<f64>,
    /// Feed of CSV traces, mm/min.
    #[arg(long)]
    pub feed_mm_min: Option<f64>,
    /// Plane of CSV traces: XY, ZX or YZ.
    #[arg(long)]
    pub plane: Option<String>,
    /// Also write gap.txt, gap.json, residual plots and gap.rrd into this folder.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Runs `vmt gap`.
pub fn command(a: &GapArgs) -> Result<(), CliError> {
    let accelerometer = a
        .real
        .iter()
        .map(|f| crate::vibration_gap::is_accelerometer(f))
        .collect::<Result<Vec<bool>, CliError>>()?;
    if accelerometer.iter().any(|x| *x) {
        if let Some(i) = accelerometer.iter().position(|x| !x) {
            return Err(CliError::Argument(format!(
                "{}: not an accelerometer log, but others are; give either accelerometer logs (milling) or ball-bar runs",
                a.real[i].display()
            )));
        }
        return vibration_command(a);
    }
    for f in &a.real {
        if crate::diagnose::file_kind(f, &crate::import::Import::default())?
            == crate::diagnose::FileKind::LaserCsv
        {
            return Err(CliError::input(
                &f.display().to_string(),
                Some(1),
                "a laser positioning CSV (ISO 230-2): `vmt gap` compares ball-bar runs or \
                 accelerometer logs with their model; `vmt diagnose` evaluates a positioning test",
            ));
        }
    }
    let csv = crate::diagnose::csv_setup(a.radius_mm, a.feed_mm_min, a.plane.as_deref())?;
    let measured = measured(&a.real, csv)?;
    // After the arguments and files are read, before the model is simulated.
    if let Some(dir) = &a.out {
        crate::out::output_dir(dir)?;
    }
    let report = analyse(&a.model, &a.real, &measured)?;
    if a.json {
        crate::outln!(
            "{}",
            serde_json::to_string_pretty(&json(&report))
                .map_err(|e| CliError::Argument(e.to_string()))?
        )?;
    } else {
        crate::out!("{}", text(&report))?;
    }
    if let Some(dir) = &a.out {
        for f in write(&report, dir)? {
            crate::errln!("wrote {}", f.display());
        }
    }
    Ok(())
}

fn vibration_command(a: &GapArgs) -> Result<(), CliError> {
    use crate::vibration_gap as vg;
    if let Some(dir) = &a.out {
        crate::out::output_dir(dir)?;
    }
    let model = a.model.display().to_string();
    let g = vg::analyse(&a.model, &a.real)?;
    if a.json {
        crate::outln!(
            "{}",
            serde_json::to_string_pretty(&vg::json(&model, &a.real, &g))
                .map_err(|e| CliError::Argument(e.to_string()))?
        )?;
    } else {
        crate::out!("{}", vg::text(&model, &a.real, &g))?;
    }
    if let Some(dir) = &a.out {
        for f in vg::write(&model, &a.real, &g, dir)? {
            crate::errln!("wrote {}", f.display());
        }
    }
    Ok(())
}

/// `vmt gap-bench` arguments.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// The model (default: the built-in machine).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Radius of the circular test every case runs, mm (written into the model's job); several,
    /// comma-separated, run a test at each about the same centre: by default two, which tell
    /// an error that depends on the axis position (a rail step) or on the path's acceleration
    /// (v²/R) from the library's smooth shapes that mimic it on one.
    #[arg(long, value_delimiter = ',', default_value = "100,50")]
    pub radius_mm: Vec<f64>,
    /// Feed of that test, mm/min.
    #[arg(long, default_value_t = 2000.0)]
    pub feed_mm_min: f64,
    /// Run the circles about a second centre too: the job's centre moved by these along the
    /// plane's first and second axes, mm (the bar set up anew there); `0,0` for one centre.
    /// Default: 80 and 40 mm, each toward the middle of its stroke (or up from the middle).
    /// Two centres tell an error that depends on the axis position (a rail step, a bow) from
    /// the smooth shapes and set-up that mimic it about one.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub center_shift_mm: Option<Vec<f64>>,
    /// Plane of that test: XY, ZX or YZ.
    #[arg(long, default_value = "XY")]
    pub plane: String,
    /// Axial depth of cut written into a milling model's job, mm (default: the model's).
    #[arg(long)]
    pub axial_depth_mm: Option<f64>,
    /// Nuisance: the other parameters' mismatch, as a fraction of their typical size.
    #[arg(long, default_value_t = 0.05)]
    pub nuisance: f64,
    /// Null cases (nothing withheld).
    #[arg(long, default_value_t = 12)]
    pub nulls: usize,
    /// Seed of the first case.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Draws of the whole list of cases, each with its own seeds.
    #[arg(long, default_value_t = 3)]
    pub repeats: usize,
    /// Write gap_bench.md and gap_bench.json into this folder.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

impl BenchArgs {
    /// The bench's own settings within what they mean and what a run of it can hold (the
    /// test's radius and feed here as options; the model's scenario checks them again against
    /// its machine: strokes, largest feed).
    fn check(&self) -> Result<(), CliError> {
        use crate::error::{check_count, check_range};
        use vmt_sim::nc::ballbar::{BALLBAR_MAX_RADIUS_M, BALLBAR_MIN_RADIUS_M, FEED_RANGE_MM_MIN};
        if self.radius_mm.len() > vmt_scenario::MAX_RADII {
            return Err(CliError::Argument(format!(
                "--radius-mm: {} radii given; 1 to {} are accepted, each a test about the same centre",
                self.radius_mm.len(),
                vmt_scenario::MAX_RADII
            )));
        }
        for &r in &self.radius_mm {
            check_range(
                "--radius-mm",
                r,
                (BALLBAR_MIN_RADIUS_M * 1e3, BALLBAR_MAX_RADIUS_M * 1e3),
                "mm",
                "the circles a ball bar measures",
            )?;
        }
        check_range(
            "--feed-mm-min",
            self.feed_mm_min,
            FEED_RANGE_MM_MIN,
            "mm/min",
            "a test program's feed",
        )?;
        let shift = self.center_shift_mm.as_deref().unwrap_or(&[0.0, 0.0]);
        if shift.len() != 2 {
            return Err(CliError::Argument(format!(
                "--center-shift-mm: two numbers are accepted, the shift along the plane's first and second axes (mm); {} given",
                shift.len()
            )));
        }
        for &d in shift {
            check_range(
                "--center-shift-mm",
                d,
                (-1000.0, 1000.0),
                "mm",
                "a shift of the circles' centre within a machine's travel",
            )?;
        }
        check_range(
            "--nuisance",
            self.nuisance,
            (0.0, 1.0),
            "× typical",
            "a fraction of each other parameter's typical size",
        )?;
        check_count(
            "--nulls",
            self.nulls,
            (0, 1000),
            "each is a fit over the library",
        )?;
        check_count(
            "--repeats",
            self.repeats,
            (1, 100),
            "each draws the whole list of cases again",
        )?;
        Ok(())
    }

    /// The radii as a TOML value: a number for one, an array for several.
    fn radii_toml(&self) -> String {
        match self.radius_mm.as_slice() {
            [r] => format!("{r:?}"),
            many => format!("{many:?}"),
        }
    }

    /// The radii as the command line gives them (`100,50`).
    fn radii_text(&self) -> String {
        let v: Vec<String> = self.radius_mm.iter().map(|r| r.to_string()).collect();
        v.join(",")
    }

    /// The folder of the model's file, where its tables and program are.
    fn model_dir(&self) -> Option<PathBuf> {
        self.model
            .as_deref()
            .and_then(Path::parent)
            .map(Path::to_path_buf)
    }

    fn settings(&self) -> vmt_gap::bench::Settings {
        vmt_gap::bench::Settings {
            nuisance: self.nuisance,
            nulls: self.nulls,
            seed: self.seed,
            repeats: self.repeats,
        }
    }

    /// A bar over `n` cases, hidden with `--quiet`.
    fn progress(&self, n: usize, message: &'static str) -> indicatif::ProgressBar {
        let bar = if self.quiet {
            indicatif::ProgressBar::hidden()
        } else {
            indicatif::ProgressBar::new(n as u64)
        };
        bar.set_message(message);
        bar
    }
}

/// Runs `vmt gap-bench`.
pub fn bench_command(a: &BenchArgs) -> Result<(), CliError> {
    use vmt_gap::bench;
    a.check()?;
    if let Some(dir) = &a.out {
        crate::out::output_dir(dir)?;
    }
    let (text, file) = match &a.model {
        Some(p) => (
            std::fs::read_to_string(p)
                .map_err(|e| CliError::input(&p.display().to_string(), None, e.to_string()))?,
            p.display().to_string(),
        ),
        None => (
            vmt_scenario::BUILTIN_DEFAULT.to_string(),
            vmt_scenario::BUILTIN_NAME.to_string(),
        ),
    };
    let plane =
        crate::plane::parse(&a.plane).map_err(|e| CliError::Argument(format!("--plane {e}")))?;
    if vmt_scenario::edit::Template::parse(&text, &file)?
        .text("job.kind")?
        .as_deref()
        == Some("milling")
    {
        let text = match a.axial_depth_mm {
            Some(d) => vmt_scenario::edit::Template::parse(&text, &file)?
                .with(&[("job.axial_depth_mm", d)])?,
            None => text,
        };
        return vibration_bench(a, &text, &file);
    }
    let text = vmt_scenario::edit::Template::parse(&text, &file)?
        .with(&[("job.feed_mm_min", a.feed_mm_min)])?;
    let text = vmt_scenario::edit::Template::parse(&text, &file)?
        .with_fragment("job", &format!("radius_mm = {}", a.radii_toml()))?;
    let text = vmt_scenario::edit::Template::parse(&text, &file)?
        .with_text(&[("job.plane", &plane.to_string())])?;
    let shift = a.center_shift_mm.as_ref().map(|d| [d[0], d[1]]);
    let text = match shift {
        Some([0.0, 0.0]) => text,
        _ => bench::with_second_centre(&text, &file, a.model_dir().as_deref(), plane, shift)
            .map_err(|e| model_error(&file, e))?,
    };
    let model =
        ScenarioModel::new(&text, &file, a.model_dir()).map_err(|e| model_error(&file, e))?;
    let (p, q) = plane.axes();
    let lib = model.library(&[(p.to_ascii_lowercase(), q.to_ascii_lowercase())]);
    let physics = vmt_gap::physics::cases(&model, plane).map_err(|e| model_error(&file, e))?;
    let cases = bench::cases(&model, &lib, &physics, &a.settings());
    let bar = a.progress(cases.len(), "gap-bench cases");
    let o = select::Options::default();
    let outcomes = bench::run(&text, &model, &lib, &cases, &o, &|| bar.inc(1))
        .map_err(|e| model_error(&file, e))?;
    bar.finish_and_clear();
    // What changes the job by less than the level at which the selection starts (the model's
    // other small mismatches), or by less than an effect must change it, nothing can attribute.
    let figures = bench::figures(&outcomes, o.min_effect_um.max(o.explained_floor_um));
    let centres = distinct_centres(model.circles());
    let about = match centres.len() {
        1 => "about one centre".to_string(),
        n => format!(
            "about {n} centres in turn ({}; axis coordinates)",
            centres
                .iter()
                .map(|c| centre_text(*c))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let job = format!(
        "{} circle {} mm at {} mm/min {about}, CW and CCW (segments of 40 deg in turn fit, select and judge); the bar's set-up drawn anew",
        a.plane,
        a.radii_text(),
        a.feed_mm_min
    );
    let command = format!(
        "vmt gap-bench --plane {} --radius-mm {} --feed-mm-min {}{} --nuisance {} --nulls {} --seed {} --repeats {}",
        a.plane,
        a.radii_text(),
        a.feed_mm_min,
        shift.map_or(String::new(), |[p, q]| format!(
            " --center-shift-mm {p},{q}"
        )),
        a.nuisance,
        a.nulls,
        a.seed,
        a.repeats
    );
    let report = bench_report(&command, &file, &job, a, &figures, &outcomes);
    finish_bench(a, &report, &figures, &outcomes)
}

/// Prints the bench's report and writes gap_bench.md and gap_bench.json into `--out`.
fn finish_bench(
    a: &BenchArgs,
    report: &str,
    figures: &vmt_gap::bench::Figures,
    outcomes: &[vmt_gap::bench::Outcome],
) -> Result<(), CliError> {
    crate::out!("{report}")?;
    let Some(dir) = &a.out else {
        return Ok(());
    };
    let md = dir.join("gap_bench.md");
    std::fs::write(&md, report).map_err(|e| CliError::output(&md, e))?;
    let js = dir.join("gap_bench.json");
    let model = a.model.as_ref().map(|p| p.display().to_string());
    let body = json!({"settings": {"model": model, "plane": a.plane, "radius_mm": a.radius_mm, "feed_mm_min": a.feed_mm_min, "center_shift_mm": a.center_shift_mm, "nuisance": a.nuisance, "nulls": a.nulls, "seed": a.seed, "repeats": a.repeats}, "figures": figures, "cases": outcomes});
    std::fs::write(
        &js,
        serde_json::to_string_pretty(&body).map_err(|e| CliError::output(&js, e))?,
    )
    .map_err(|e| CliError::output(&js, e))
}

/// `vmt gap-bench` on a milling model: the vibration gap's withheld-effect check.
fn vibration_bench(a: &BenchArgs, text: &str, file: &str) -> Result<(), CliError> {
    use vmt_gap::{vibration, vibration_bench as vb};
    let dir = a.model_dir();
    let model =
        vibration::MillingModel::new(text, file, dir.clone()).map_err(|e| model_error(file, e))?;
    let cases = vb::cases(&model, &a.settings());
    let bar = a.progress(cases.len(), "gap-bench cases (vibration)");
    let o = vibration::Options::default();
    let outcomes = vb::run(text, file, dir, &model, &cases, &o, &|| bar.inc(1))
        .map_err(|e| model_error(file, e))?;
    bar.finish_and_clear();
    let figures = vmt_gap::bench::figures(&outcomes, o.min_effect_db.max(o.explained_floor_db));
    let job = format!(
        "the milling job of the model (accelerometer logs, tooth passing {:.0} Hz; one log per case, its first half fits, its second half judges)",
        model.tooth_passing_hz()
    );
    let depth = a
        .axial_depth_mm
        .map_or(String::new(), |d| format!(" --axial-depth-mm {d}"));
    let command = format!(
        "vmt gap-bench --model {file}{depth} --nuisance {} --nulls {} --seed {} --repeats {}",
        a.nuisance, a.nulls, a.seed, a.repeats
    );
    let report = bench_report(&command, file, &job, a, &figures, &outcomes);
    finish_bench(a, &report, &figures, &outcomes)
}

/// A share as a percentage; a share of no cases (0/0) is not one.
fn pct(x: f64) -> String {
    if x.is_nan() {
        "no cases".into()
    } else {
        format!("{:.1} %", 100.0 * x)
    }
}

/// The bench's report in Markdown: `command` made it, on `job` of the model `file`.
fn bench_report(
    command: &str,
    file: &str,
    job: &str,
    a: &BenchArgs,
    f: &vmt_gap::bench::Figures,
    outcomes: &[vmt_gap::bench::Outcome],
) -> String {
    let unit = outcomes.first().map_or("um", |o| o.unit);
    let mut out = String::new();
    let _ = writeln!(out, "# Sim-to-real gap: withheld-effect check\n");
    let _ = writeln!(out, "Made by `{command}`.\n");
    let _ = writeln!(
        out,
        "Model {file}, job: {job}; nuisance {} x typical on every other parameter, instrument noise kept, a seed per case (first seed {}, {} draws of the list).\n",
        a.nuisance, a.seed, a.repeats
    );
    let _ = writeln!(
        out,
        "| Figure | Measured | Goal | Cases |\n|---|---|---|---|"
    );
    let rows = [
        ("Top-1 attribution (one effect withheld)".to_string(), pct(f.top1), ">= 95 %", f.single_cases),
        ("False attribution (nothing withheld)".into(), pct(f.false_attribution_null), "<= 5 %", f.null_cases),
        ("Median held-out shrink (in-library cases)".into(), pct(f.median_shrink), ">= 80 %", f.single_cases + f.pair_cases),
        ("Out-of-library effect left unexplained".into(), pct(f.unexplained_outside), ">= 90 %", f.outside_cases),
        ("Pairs: both effects found".into(), pct(f.pairs_both_found), "-", f.pair_cases),
        (
            "Withheld physics that is a library effect by another mechanism: attributed to it or to an ambiguity set holding it".into(),
            pct(f.physics_attributed),
            ">= 90 %",
            f.physics_library_cases,
        ),
        (
            "The same, counting an attribution of part of the gap to it (the rest left unexplained)".into(),
            pct(f.physics_attributed_or_partial),
            "-",
            f.physics_library_cases,
        ),
        (
            format!(
                "Withheld physics outside the library: unexplained, a peak (its span) or the middle of a change along an axis within {} deg of the truth",
                vmt_gap::bench::WHERE_TOLERANCE_DEG
            ),
            pct(f.physics_unexplained),
            ">= 90 %",
            f.physics_outside_cases,
        ),
        (
            "Cases with an effect accepted at an implausible size".into(),
            f.implausible_accepted.to_string(),
            "0",
            outcomes.len(),
        ),
    ];
    for (figure, measured, goal, cases) in rows {
        let _ = writeln!(out, "| {figure} | {measured} | {goal} | {cases} |");
    }
    let _ = writeln!(
        out,
        "\nHeld-out figures are of the judge data, used neither to fit nor to choose ({} of {} cases had too few and are of the select data).\n",
        f.not_judged,
        outcomes.len()
    );
    if !f.below_floor.is_empty() {
        let _ = writeln!(
            out,
            "Below the visibility floor ({} {unit} of change predicted for the withheld effect on the select and judge data: the level at which the selection starts, that of a model's other small mismatches), so invisible on this job and left out of the figures: {}.\n",
            f.floor,
            f.below_floor.join("; ")
        );
    }
    let _ = writeln!(
        out,
        "## Confusion (withheld -> first effect found)\n\n| Withheld | Found |\n|---|---|"
    );
    for (row, cols) in &f.confusion {
        let cells: Vec<String> = cols.iter().map(|(c, n)| format!("{c} x{n}")).collect();
        let _ = writeln!(out, "| {row} | {} |", cells.join(", "));
    }
    let _ = writeln!(
        out,
        "\n## Cases\n\n| Case | Visible ({unit}) | Found | Equally good | Partial | Right | Held-out RMS before ({unit}) | after ({unit}) | Shrink | Peaks (deg); where along an axis |\n|---|---|---|---|---|---|---|---|---|---|"
    );
    for o in outcomes {
        let right = match o.physics_right() {
            Some(true) => "yes",
            Some(false) => "no",
            None => "",
        };
        let tests: Vec<(&f64, &Option<[f64; 3]>)> =
            o.peak_radii_mm.iter().zip(&o.peak_centres_mm).collect();
        let several = tests.iter().any(|t| Some(t) != tests.first());
        let mut peaks: Vec<String> = o
            .peaks_deg
            .iter()
            .zip(&tests)
            .map(|(p, (r, c))| match (several, c) {
                (true, Some([x, y, z])) => format!("{p:.0} (R{r} @{x:.0},{y:.0},{z:.0})"),
                (true, None) => format!("{p:.0} (R{r})"),
                (false, _) => format!("{p:.0}"),
            })
            .collect();
        if let Some(c) = &o.axis_change {
            let back = if c.comes_back { " and back" } else { "" };
            peaks.push(format!(
                "{} changes along {} at {:.0} mm over {:.0} mm{back}",
                c.direction, c.axis, c.at_mm, c.width_mm
            ));
        }
        let _ = writeln!(
            out,
            "| {} | {:.3} | {} | {} | {} | {right} | {:.3} | {:.3} | {} | {} |",
            o.case,
            o.visible,
            o.found.join(", "),
            o.ambiguous.join(", "),
            o.partial.join(", "),
            o.held_out_before,
            o.held_out_after,
            pct(o.shrink),
            peaks.join(", ")
        );
    }
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_share_of_no_cases_says_so() {
        assert_eq!(super::pct(0.5833), "58.3 %");
        assert_eq!(super::pct(f64::NAN), "no cases");
    }
}
