//! `vmt diagnose`: ball-bar traces in, a diagnosis report out (text, Markdown, JSON, polar
//! plots), the same for a run of ours and for an instrument's CSV.

use crate::error::CliError;
use crate::import::Import;
use crate::plot::{self, Format};
use crate::traces::{self, CsvSetup};
use serde_json::{Value, json};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use vmt_ballbar::{Diagnosis, Options, Trace, diagnose, kwon, report};
use vmt_logs::truth::{left_out_bias, truth_drift, truth_effects, truth_figures};
use vmt_sim::run::BallbarTrace;

/// Diagnoses of every test in a file, with the run's ground truth when it has one.
pub struct Diagnosed {
    /// The file read.
    pub file: String,
    /// One diagnosis per circular test, in the order of the file.
    pub tests: Vec<(Vec<Trace>, Diagnosis)>,
    /// Ground truth of a simulated run.
    pub ground_truth: Option<Value>,
    /// For a CSV: which of its columns were read, in which units.
    pub columns: Option<String>,
}

/// Ball-bar lengths accepted for a CSV trace, mm, and why (the diagnosis' cyclic-error search
/// grows with the radius: 1e7 mm exhausts memory).
pub const RADIUS_MM: (f64, f64) = (1.0, 1500.0);
const RADIUS_WHY: &str = "ball bars are 50-600 mm long, with extensions to about 1500 mm";
/// Feeds accepted for a CSV trace, mm/min, and why.
pub const FEED_MM_MIN: (f64, f64) = (1.0, 120_000.0);
const FEED_WHY: &str = "the feeds of machine tools, up to 120 m/min";

/// The set-up of a CSV ball-bar trace from the command line: all of --radius-mm, --feed-mm-min
/// and --plane or none of them, each within its range.
pub fn csv_setup(
    radius_mm: Option<f64>,
    feed_mm_min: Option<f64>,
    plane: Option<&str>,
) -> Result<Option<CsvSetup<'_>>, CliError> {
    match (radius_mm, feed_mm_min, plane) {
        (Some(radius_mm), Some(feed_mm_min), Some(plane)) => Ok(Some(CsvSetup {
            plane: crate::plane::parse(plane)
                .map_err(|e| CliError::Argument(format!("--plane {e}")))?
                .name(),
            radius_mm: crate::error::check_range(
                "--radius-mm",
                radius_mm,
                RADIUS_MM,
                "mm",
                RADIUS_WHY,
            )?,
            feed_mm_min: crate::error::check_range(
                "--feed-mm-min",
                feed_mm_min,
                FEED_MM_MIN,
                "mm/min",
                FEED_WHY,
            )?,
        })),
        (None, None, None) => Ok(None),
        _ => {
            let missing: Vec<&str> = [
                ("--radius-mm", radius_mm.is_none()),
                ("--feed-mm-min", feed_mm_min.is_none()),
                ("--plane", plane.is_none()),
            ]
            .into_iter()
            .filter_map(|(n, m)| m.then_some(n))
            .collect();
            Err(CliError::Argument(format!(
                "a CSV trace needs all of --radius-mm, --feed-mm-min and --plane; missing: {}",
                missing.join(", ")
            )))
        }
    }
}

/// What `vmt diagnose` was given, told from the file's first bytes or its CSV header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileKind {
    /// An MCAP run of ours (ball-bar traces or laser readings, with its set-up).
    Mcap,
    /// A ball-bar CSV (`angle_deg` column).
    BallbarCsv,
    /// A laser positioning CSV (`target_mm` column).
    LaserCsv,
}

/// How much of a file [`file_kind`] reads: the MCAP magic, or a CSV header line.
const HEAD_BYTES: u64 = 1 << 16;

/// Columns of a ball-bar CSV, for messages.
const BALLBAR_COLUMNS: &str = "angle_deg, deviation_um, direction (cw/ccw) and optionally time_s";
/// Columns of a laser CSV, for messages.
const LASER_COLUMNS: &str =
    "target_mm, direction (forward/backward), run, and deviation_um or reading_mm";

/// Tells the kind of `path` from its first bytes (MCAP) or its CSV header (or what `--columns`
/// maps onto it: `import`), reading only its first `HEAD_BYTES` (a run's MCAP may hold a
/// gigabyte); an empty file, or a header of neither kind, is refused naming what is missing.
pub fn file_kind(path: &Path, import: &Import) -> Result<FileKind, CliError> {
    use std::io::Read;
    let file = path.display().to_string();
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(HEAD_BYTES).read_to_end(&mut bytes))
        .map_err(|e| CliError::input(&file, None, e.to_string()))?;
    // The header alone: a partial last row must not be parsed as one.
    if !bytes.starts_with(mcap::MAGIC)
        && let Some(end) = bytes.iter().position(|&b| b == b'\n')
    {
        bytes.truncate(end + 1);
    }
    if bytes.starts_with(mcap::MAGIC) {
        return Ok(FileKind::Mcap);
    }
    let mut r = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(bytes.as_slice());
    let header: Vec<String> = r
        .headers()
        .map(|h| h.iter().map(str::to_string).collect())
        .unwrap_or_default();
    let has = |c: &str| import.maps(c) || header.iter().any(|h| h == c);
    if header.iter().all(|h| h.is_empty()) {
        return Err(CliError::input(
            &file,
            Some(1),
            format!(
                "empty: no header; a ball-bar CSV has the columns {BALLBAR_COLUMNS}, a laser \
                 positioning CSV {LASER_COLUMNS}"
            ),
        ));
    }
    if has("angle_deg") {
        return Ok(FileKind::BallbarCsv);
    }
    if has("target_mm") {
        return Ok(FileKind::LaserCsv);
    }
    let found = format!(
        "{}; map the export's own headers with --columns",
        header.join(", ")
    );
    // Columns only a laser CSV has: one missing its target column.
    let message = if has("run") || has("reading_mm") {
        format!(
            "no `target_mm` column: a laser positioning CSV has {LASER_COLUMNS} (found: {found})"
        )
    } else if has("deviation_um") && has("direction") {
        format!(
            "no `angle_deg` column (a ball-bar CSV: {BALLBAR_COLUMNS}) nor `target_mm` column (a \
             laser positioning CSV: {LASER_COLUMNS}); found: {found}"
        )
    } else {
        format!(
            "neither a ball-bar CSV ({BALLBAR_COLUMNS}) nor a laser positioning CSV \
             ({LASER_COLUMNS}); found: {found}"
        )
    };
    Err(CliError::input(&file, Some(1), message))
}

/// Reads and diagnoses `path` (`import`: a CSV's columns and units).
pub fn diagnose_file(
    path: &Path,
    csv: Option<CsvSetup>,
    import: &Import,
    options: &Options,
) -> Result<Diagnosed, CliError> {
    let file = path.display().to_string();
    let (recorded, columns) = traces::read(path, csv, import)?;
    let tests = recorded
        .tests
        .into_iter()
        .map(|t| {
            let d =
                diagnose(&t, options).map_err(|e| CliError::input(&file, None, e.to_string()))?;
            Ok((t, d))
        })
        .collect::<Result<Vec<_>, CliError>>()?;
    Ok(Diagnosed {
        file,
        tests,
        ground_truth: recorded.ground_truth,
        columns,
    })
}

/// The report as text: each test's diagnosis and, for a simulated run, the truth beside it.
pub fn text(d: &Diagnosed) -> String {
    let mut s = d
        .columns
        .as_ref()
        .map_or_else(String::new, |c| format!("{c}\n\n"));
    for (i, (_, diag)) in d.tests.iter().enumerate() {
        s.push_str(&report::text(diag));
        if let Some(truth) = &d.ground_truth
            && let (Some(fig), Some(effects)) = (truth_figures(truth, i), truth_effects(truth, i))
        {
            let _ = writeln!(s, "\nAgainst the run's ground truth");
            let _ = write!(
                s,
                "  {:<26} {:>12} {:>12} {:>10}",
                "figure", "truth", "diagnosed", "error"
            );
            let biased = diag
                .findings
                .iter()
                .any(|f| f.stated_biases().next().is_some());
            let _ = writeln!(s, "{}", if biased { "    left-out bias" } else { "" });
            for (key, v) in fig {
                let (Some(t), Some(f)) = (v.as_f64(), diag.finding(key)) else {
                    continue;
                };
                let _ = write!(
                    s,
                    "  {key:<26} {t:>+12.4} {:>+12.4} {:>+10.4}",
                    f.value,
                    f.value - t
                );
                let _ = match left_out_bias(f, &effects) {
                    Some(b) => writeln!(s, " {b:>+16.4}"),
                    None => writeln!(s),
                };
            }
        }
        s.push('\n');
    }
    if let Some(k) = kwon(d) {
        s.push_str(&kwon::text(&k, kwon_truth(d).as_ref()));
    }
    s
}

/// Kwon's machine report computed from the run's truth figures, by the same formulas.
pub fn kwon_truth(d: &Diagnosed) -> Option<kwon::MachineReport> {
    let truth = d.ground_truth.as_ref()?;
    let index = |n: u32| {
        d.tests
            .iter()
            .position(|(_, x)| kwon::step_of(x) == Some(n))
    };
    let figures = |n: u32| index(n).and_then(|i| truth_figures(truth, i));
    Some(kwon::report_from(
        |n, key| figures(n)?.get(key)?.as_f64(),
        |n| {
            figures(n)
                .map(|f| f.keys().map(|k| (k.clone(), k.clone(), "")).collect())
                .unwrap_or_default()
        },
    ))
}

/// Kwon's machine report, when the file holds steps of the seven-step procedure.
pub fn kwon(d: &Diagnosed) -> Option<kwon::MachineReport> {
    let diags: Vec<Diagnosis> = d.tests.iter().map(|(_, x)| x.clone()).collect();
    diags
        .iter()
        .any(|x| kwon::step_of(x).is_some())
        .then(|| kwon::machine_report(&diags))
}

/// The report as JSON: the file, each test's diagnosis, and the truth when known.
pub fn json(d: &Diagnosed) -> Value {
    let tests: Vec<Value> = d
        .tests
        .iter()
        .enumerate()
        .map(|(i, (_, diag))| {
            let mut v = report::json(diag);
            if let Some(t) = &d.ground_truth {
                if let Some(f) = truth_figures(t, i) {
                    v["ground_truth"] = Value::Object(f.clone());
                }
                if let Some(drift) = truth_drift(t, i) {
                    v["ground_truth_drift"] = Value::Object(drift.clone());
                }
            }
            v
        })
        .collect();
    json!({
        "file": d.file,
        "columns": d.columns,
        "tests": tests,
        "kwon_machine_report": kwon(d),
    })
}

/// Writes `report.txt`, `report.md`, `report.json` and one polar plot per test into `dir`.
pub fn write(d: &Diagnosed, dir: &Path) -> Result<Vec<PathBuf>, CliError> {
    std::fs::create_dir_all(dir).map_err(|e| CliError::output(dir, e))?;
    let mut files = Vec::new();
    let mut put = |name: &str, text: String| -> Result<(), CliError> {
        let p = dir.join(name);
        std::fs::write(&p, text).map_err(|e| CliError::output(&p, e))?;
        files.push(p);
        Ok(())
    };
    put("report.txt", text(d))?;
    let md: String = d
        .tests
        .iter()
        .map(|(_, diag)| report::markdown(diag))
        .collect::<Vec<_>>()
        .join("\n");
    put(
        "report.md",
        format!("# Ball-bar diagnosis of {}\n\n{md}", d.file),
    )?;
    let js = serde_json::to_string_pretty(&json(d)).map_err(|e| CliError::output(dir, e))?;
    put("report.json", js)?;
    for (i, (traces, diag)) in d.tests.iter().enumerate() {
        let p = dir.join(format!("diagnosis_{}.png", i + 1));
        plot::draw_polar(
            &centred(traces, diag),
            &p,
            Format::Png,
            Some(&figures_text(diag)),
        )?;
        files.push(p);
    }
    Ok(files)
}

/// The traces with the test's least-squares centre taken out (as ball-bar software plots
/// them), in the plot's trace type.
fn centred(traces: &[Trace], d: &Diagnosis) -> Vec<BallbarTrace> {
    let c =
        d.iso
            .directions
            .first()
            .map(|dir| dir.circle)
            .unwrap_or(vmt_ballbar::iso230_4::Circle {
                centre_p_um: 0.0,
                centre_q_um: 0.0,
                radius_offset_um: 0.0,
            });
    traces
        .iter()
        .map(|t| BallbarTrace {
            label: t.label.clone(),
            plane: t.plane.name().into(),
            direction: t.sense.name().into(),
            radius_mm: t.radius_mm,
            feed_mm_min: t.feed_mm_min,
            times_s: t.time_s.clone().unwrap_or_default(),
            angle_deg: t.angle_deg.clone(),
            deviation_um: t
                .angle_deg
                .iter()
                .zip(&t.deviation_um)
                .map(|(a, v)| c.radial(a.to_radians(), *v))
                .collect(),
        })
        .collect()
}

/// The text block printed beside the polar plot: the ISO figures past the settling (the
/// headline), the raw ones beside them and what the settling left out, then the largest
/// present errors.
fn figures_text(d: &Diagnosis) -> String {
    let mut s = iso_headline(d);
    let _ = writeln!(s, "\nLargest errors");
    for f in d.findings.iter().filter(|f| f.present).take(8) {
        let digits = if f.unit == "ms" { 4 } else { 2 };
        let _ = writeln!(s, "{}: {:+.*} {}", f.key, digits, f.value, f.unit);
    }
    s
}

/// The ISO 230-4 figures of a polar plot's headline: past the settling, the raw ones beside
/// them where they differ, and what the settling left out.
pub fn iso_headline(d: &Diagnosis) -> String {
    let mut s = String::from("ISO 230-4 (least-squares centre)\n");
    let cut = d
        .settling
        .iter()
        .any(|x| x.start_excluded_deg > 0.0 || x.end_excluded_deg > 0.0);
    let raw = |v: f64, r: Option<f64>| match r {
        Some(r) if cut && (v - r).abs() >= 0.005 => format!("{v:.2} µm (raw {r:.2})"),
        _ => format!("{v:.2} µm"),
    };
    for (dir, whole) in d.iso.directions.iter().zip(&d.raw_iso.directions) {
        let _ = writeln!(
            s,
            "G {} {}",
            dir.sense.to_uppercase(),
            raw(dir.circular_deviation_um, Some(whole.circular_deviation_um))
        );
    }
    if let Some(h) = d.iso.hysteresis_um {
        let _ = writeln!(s, "H {}", raw(h, d.raw_iso.hysteresis_um));
    }
    if let Some(g) = d.iso.bidirectional_deviation_um {
        let _ = writeln!(s, "G(b) {}", raw(g, d.raw_iso.bidirectional_deviation_um));
    }
    if cut {
        let _ = writeln!(s, "settled; left out: {}", report::excluded(d));
    }
    s
}
