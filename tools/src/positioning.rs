//! `vmt diagnose` of a linear positioning test (laser interferometer, ISO 230-2): readings in
//! from a run of ours or an instrument's CSV export, the evaluation of `vmt-positioning` out as
//! text, Markdown, JSON and a plot of the deviations.
//!
//! # CSV format
//!
//! One row per reading, a header naming the columns (any order, extra columns ignored):
//!
//! | column | unit | meaning |
//! |---|---|---|
//! | `target_mm` | mm | target position P_i |
//! | `direction` | — | `forward` (approached from below, ISO ↑) or `backward` (↓) |
//! | `run` | — | run number j (a positive integer) |
//! | `deviation_um` | µm | x_ij = P_ij − P_i, the reading minus the target |
//! | `reading_mm` | mm | or, instead of `deviation_um`, the reading P_ij itself |
//!
//! A file is a positioning test when its header has `target_mm` (and an MCAP run when it has a
//! `/laser` topic); the axis name comes from `--axis` (CSV) or the run.

use crate::error::CliError;
use crate::import::Import;
use crate::plot::{DrawResult, FONT, Figure, Format, register_font, render};
use crate::traces::{csv_with_header, finite_cell};
use plotters::coord::Shift;
use plotters::prelude::*;
use serde_json::{Value, json};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use vmt_logs::csv_import::{Column, Quantity, Resolved};
use vmt_logs::input::{self, Input};
use vmt_positioning::{Approach, Evaluation, PositioningRun, Reading, evaluate, report};

/// An evaluated positioning test.
pub struct Positioning {
    /// The file read.
    pub file: String,
    /// The checked readings.
    pub run: PositioningRun,
    /// Their evaluation.
    pub evaluation: Evaluation,
    /// The `laser` section of a simulated run's ground truth.
    pub truth: Option<Value>,
    /// For a CSV: which of its columns were read, in which units.
    pub columns: Option<String>,
}

/// Reads and evaluates `path` if it is a positioning test (an MCAP run with a `/laser` topic or
/// a CSV with a `target_mm` column, or one `--columns` maps it onto: `import`); `None` for any
/// other file.
pub fn read(
    path: &Path,
    axis: Option<&str>,
    import: &Import,
) -> Result<Option<Positioning>, CliError> {
    let file = path.display().to_string();
    let found = match input::open(path, &file)? {
        Input::Mcap => read_mcap(path, &file)?.map(|(r, t)| (r, t, None)),
        Input::Other(bytes) => read_csv(&bytes, &file, axis.unwrap_or("?"), import)?
            .map(|(r, cols)| (r, None, Some(crate::import::echo(&cols)))),
    };
    let Some((run, truth, columns)) = found else {
        return Ok(None);
    };
    let evaluation = evaluate(&run);
    Ok(Some(Positioning {
        file,
        run,
        evaluation,
        truth,
        columns,
    }))
}

fn direction(s: &str) -> Option<Approach> {
    match s.to_ascii_lowercase().as_str() {
        "forward" => Some(Approach::Forward),
        "backward" => Some(Approach::Backward),
        _ => None,
    }
}

fn read_mcap(path: &Path, file: &str) -> Result<Option<(PositioningRun, Option<Value>)>, CliError> {
    let bad = |m: String| CliError::input(file, None, m);
    // A run with a summary names its topics there: a ball-bar run is not read twice.
    if let Some(summary) = input::summary(path)
        && !summary.channels.values().any(|c| c.topic == "/laser")
    {
        return Ok(None);
    }
    let mut readings = Vec::new();
    let mut axis = None;
    let mut truth = None;
    for message in input::messages(path, file)? {
        let m = message?;
        match m.channel.topic.as_str() {
            "/ground_truth" => {
                truth = serde_json::from_slice::<Value>(&m.data)
                    .ok()
                    .map(|t| t["laser"].clone());
            }
            "/laser" => {
                axis = m.channel.metadata.get("axis").cloned();
                let v: Value = serde_json::from_slice(&m.data)
                    .map_err(|e| bad(format!("/laser: a message that is not JSON: {e}")))?;
                let n = readings.len() + 1;
                readings
                    .push(laser_reading(&v).map_err(|e| bad(format!("/laser message {n}: {e}")))?);
            }
            _ => {}
        }
    }
    if readings.is_empty() {
        return Ok(None);
    }
    let run = PositioningRun::new(axis.as_deref().unwrap_or("?"), readings)
        .map_err(|e| bad(e.to_string()))?;
    Ok(Some((run, truth.filter(|t| !t.is_null()))))
}

/// One `/laser` message of an MCAP run as a reading; the run number must be a positive
/// integer (1.5 is refused, not truncated to run 1), as in a CSV.
fn laser_reading(v: &Value) -> Result<Reading, String> {
    let num = |k: &str| {
        v[k].as_f64()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("no number `{k}`"))
    };
    let d = v["direction"].as_str().unwrap_or("");
    let run = num("run")?;
    if !(run >= 1.0 && run.fract() == 0.0 && run <= u32::MAX as f64) {
        return Err(format!(
            "run `{}` is not accepted; a positive integer",
            v["run"]
        ));
    }
    Ok(Reading {
        target_mm: num("target_mm")?,
        approach: direction(d).ok_or_else(|| format!("direction `{d}`; forward or backward"))?,
        run: run as usize,
        deviation_um: num("deviation_um")?,
    })
}

/// The columns of a laser positioning CSV.
const COLUMNS: [Column; 5] = [
    Column {
        name: "target_mm",
        quantity: Quantity::Millimetres,
        required: true,
    },
    Column {
        name: "direction",
        quantity: Quantity::Label,
        required: true,
    },
    Column {
        name: "run",
        quantity: Quantity::Label,
        required: true,
    },
    Column {
        name: "deviation_um",
        quantity: Quantity::Micrometres,
        required: false,
    },
    Column {
        name: "reading_mm",
        quantity: Quantity::Millimetres,
        required: false,
    },
];

fn read_csv(
    bytes: &[u8],
    file: &str,
    axis: &str,
    import: &Import,
) -> Result<Option<(PositioningRun, Resolved)>, CliError> {
    let (mut reader, header) = csv_with_header(bytes, file)?;
    if !import.maps("target_mm") && !header.iter().any(|h| h == "target_mm") {
        return Ok(None);
    }
    let cols = import.resolve(&header, &COLUMNS, "a laser positioning test", file)?;
    let col = |name: &str| cols.index(name).unwrap_or(0);
    let (target, dir_col, run_col) = (col("target_mm"), col("direction"), col("run"));
    let value = match (cols.index("deviation_um"), cols.index("reading_mm")) {
        (Some(k), Some(r)) => Measured::Both(k, r),
        (Some(k), None) => Measured::Deviation(k),
        (None, Some(k)) => Measured::Reading(k),
        (None, None) => {
            return Err(CliError::input(
                file,
                Some(1),
                format!(
                    "no `deviation_um` or `reading_mm` column (found: {}); a positioning test has target_mm, direction (forward or backward), run, and deviation_um or reading_mm (an export's own headers through --columns)",
                    header.iter().collect::<Vec<_>>().join(", ")
                ),
            ));
        }
    };
    let (f_target, f_dev, f_read) = (
        cols.factor("target_mm"),
        cols.factor("deviation_um"),
        cols.factor("reading_mm"),
    );
    let mut readings = Vec::new();
    let mut lines = Vec::new();
    for (i, record) in reader.records().enumerate() {
        let rec = record.map_err(|e| {
            let line = crate::traces::record_line(bytes, e.position(), i + 2);
            CliError::input(file, Some(line), e.to_string())
        })?;
        let line = crate::traces::record_line(bytes, rec.position(), i + 2);
        let at = |msg: String| CliError::input(file, Some(line), msg);
        let number = |k: usize| finite_cell(&rec, k, header[k].trim(), file, line);
        let d = rec.get(dir_col).unwrap_or("");
        let approach = direction(d).ok_or_else(|| {
            at(format!(
                "direction `{d}` is not accepted; forward (approached from below) or backward"
            ))
        })?;
        let r = rec.get(run_col).unwrap_or("");
        let run = r
            .parse::<usize>()
            .ok()
            .filter(|&j| j > 0)
            .ok_or_else(|| at(format!("run `{r}` is not accepted; a positive integer")))?;
        let target_mm = number(target)? * f_target;
        let deviation_um = match value {
            Measured::Deviation(k) => number(k)? * f_dev,
            Measured::Reading(k) => (number(k)? * f_read - target_mm) * 1e3,
            Measured::Both(k, r) => {
                let (d, from_reading) =
                    (number(k)? * f_dev, (number(r)? * f_read - target_mm) * 1e3);
                // Each cell is rounded to its last digit: they agree within the two halves.
                let cell = |k: usize| rec.get(k).unwrap_or("");
                // The target is the nominal position, exact as written.
                let tolerance = half_last_digit(cell(k)) * f_dev
                    + half_last_digit(cell(r)) * f_read * 1e3
                    + 1e-6;
                if (d - from_reading).abs() > tolerance {
                    return Err(at(format!(
                        "deviation_um = {d} but reading_mm − target_mm = {from_reading:.4} µm; the two columns must agree within {tolerance:.4} µm (the rounding of their last digits)"
                    )));
                }
                d
            }
        };
        if deviation_um.abs() > MAX_DEVIATION_UM {
            return Err(at(format!(
                "a deviation of {deviation_um} µm from target {target_mm} mm is not accepted; a positioning error within ±{MAX_DEVIATION_UM} µm (check the units: µm, mm)"
            )));
        }
        readings.push(Reading {
            target_mm,
            approach,
            run,
            deviation_um,
        });
        lines.push(line);
    }
    PositioningRun::new(axis, readings)
        .map(|r| Some((r, cols)))
        .map_err(|e| {
            // Name the line of the reading the check points at, if it points at one.
            let line = match &e {
                vmt_positioning::PositioningError::NotFinite { reading, .. }
                | vmt_positioning::PositioningError::TargetOutOfRange { reading, .. }
                | vmt_positioning::PositioningError::TargetsTooClose { reading, .. }
                | vmt_positioning::PositioningError::Duplicate { reading, .. } => {
                    lines.get(*reading).copied()
                }
                _ => None,
            };
            CliError::input(file, line, e.to_string())
        })
}

/// Which column holds the measured value.
#[derive(Clone, Copy)]
enum Measured {
    Deviation(usize),
    Reading(usize),
    /// Both columns: the deviation, checked against the reading.
    Both(usize, usize),
}

/// Half a unit of the last digit written in a number cell: `0.0005` for `1.234`, 0.5 for `12`,
/// `5e-7` for `1.5e-5` (the mantissa's decimals less the exponent).
fn half_last_digit(cell: &str) -> f64 {
    let cell = cell.trim();
    let (mantissa, exponent) = match cell.split_once(['e', 'E']) {
        Some((m, e)) => (m, e.parse::<i32>().unwrap_or(0)),
        None => (cell, 0),
    };
    let decimals = mantissa.split_once('.').map_or(0, |(_, f)| f.len()) as i32;
    0.5 * 10f64.powi(exponent - decimals)
}
/// The largest positioning deviation accepted, µm: beyond it a unit is wrong (mm as µm) or the
/// log is broken; an uncompensated machine is off by tens of µm, a large one by some hundreds.
const MAX_DEVIATION_UM: f64 = 10_000.0;

/// The figures of the noise-free truth against the measured ones.
fn truth_rows(p: &Positioning) -> Vec<(&'static str, f64, f64)> {
    let Some(t) = p.truth.as_ref().map(|t| &t["iso230_2_exact"]) else {
        return Vec::new();
    };
    let f = &p.evaluation.iso230_2;
    [
        ("A", "a_um", f.a_um),
        ("B", "b_um", f.b_um),
        ("B mean", "b_mean_um", f.b_mean_um),
        ("E", "e_um", f.e_um),
        ("M", "m_um", f.m_um),
        ("R", "r_um", f.r_um),
    ]
    .into_iter()
    .filter_map(|(name, key, measured)| Some((name, t[key].as_f64()?, measured)))
    .collect()
}

/// The report as text, with the simulated run's truth beside it.
pub fn text(p: &Positioning) -> String {
    let mut s = p
        .columns
        .as_ref()
        .map_or_else(String::new, |c| format!("{c}\n"));
    s.push_str(&report::text(&p.evaluation));
    let rows = truth_rows(p);
    if !rows.is_empty() {
        let _ = writeln!(
            s,
            "\nAgainst the run's ground truth (the tool point without instrument noise)"
        );
        let _ = writeln!(
            s,
            "  {:<8} {:>10} {:>10} {:>10}",
            "figure", "truth", "measured", "error"
        );
        for (name, t, m) in rows {
            let _ = writeln!(s, "  {name:<8} {t:>10.3} {m:>10.3} {:>+10.3}", m - t);
        }
    }
    s
}

/// The report as JSON.
pub fn json(p: &Positioning) -> Value {
    json!({
        "file": p.file,
        "columns": p.columns,
        "positioning": p.evaluation,
        "ground_truth": p.truth.as_ref().map(|t| &t["iso230_2_exact"]),
    })
}

/// Writes `report.txt`, `report.md`, `report.json` and `positioning.png` into `dir`.
pub fn write(p: &Positioning, dir: &Path) -> Result<Vec<PathBuf>, CliError> {
    std::fs::create_dir_all(dir).map_err(|e| CliError::output(dir, e))?;
    let mut files = Vec::new();
    let mut put = |name: &str, text: String| -> Result<(), CliError> {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(|e| CliError::output(&path, e))?;
        files.push(path);
        Ok(())
    };
    put("report.txt", text(p))?;
    put("report.md", report::markdown(&p.evaluation))?;
    let js = serde_json::to_string_pretty(&json(p)).map_err(|e| CliError::output(dir, e))?;
    put("report.json", js)?;
    let png = dir.join("positioning.png");
    draw(&p.evaluation, &png, Format::Png)?;
    files.push(png);
    Ok(files)
}

/// The deviation curves as ISO 230-2 draws them: the mean deviation per direction with its
/// ±2s band, the mean bidirectional deviation, and the figures.
pub fn draw(e: &Evaluation, path: &Path, format: Format) -> Result<(), CliError> {
    register_font();
    struct Curves<'a>(&'a Evaluation);
    impl Figure for Curves<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
            draw_on(root, self.0)
        }
    }
    render(&Curves(e), path, format, (1200, 800))
}

fn draw_on<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, e: &Evaluation) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let f = &e.iso230_2;
    let t = &f.targets_mm;
    let band = |m: &[f64], s: &[f64], k: f64| -> Vec<(f64, f64)> {
        t.iter()
            .zip(m.iter().zip(s))
            .map(|(x, (m, s))| (*x, m + k * s))
            .collect()
    };
    // Per direction: the mean (solid, with its points), and its ±2s band (thin).
    let mut curves = Vec::new();
    for (dir, m, sd, colour) in [
        ("forward", &f.mean_forward_um, &f.s_forward_um, BLUE),
        ("backward", &f.mean_backward_um, &f.s_backward_um, RED),
    ] {
        curves.push((format!("{dir} mean"), band(m, sd, 0.0), colour, false));
        curves.push((format!("{dir} mean ± 2s"), band(m, sd, 2.0), colour, true));
        curves.push((String::new(), band(m, sd, -2.0), colour, true));
    }
    let (lo, hi) = curves
        .iter()
        .flat_map(|c| c.1.iter().map(|p| p.1))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    let pad = ((hi - lo) * 0.1).max(0.1);
    let (x0, x1) = (t[0], t[t.len() - 1]);
    let xpad = (x1 - x0) * 0.03;
    let (plot, side) = root.split_horizontally(880);
    let mut chart = ChartBuilder::on(&plot)
        .caption(
            format!("ISO 230-2 positioning, axis {} ({} runs)", e.axis, e.runs),
            (FONT, 22),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d((x0 - xpad)..(x1 + xpad), (lo - pad)..(hi + pad))?;
    chart
        .configure_mesh()
        .x_desc("target position (mm)")
        .y_desc("deviation (µm)")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 15))
        .draw()?;
    // The legend goes in the side panel: inside the chart it covered the curves.
    let mut legend = Vec::new();
    for (name, pts, colour, dashed) in curves {
        let style = if dashed {
            colour.mix(0.5).stroke_width(1)
        } else {
            colour.stroke_width(2)
        };
        if !dashed {
            chart.draw_series(pts.iter().map(|p| Circle::new(*p, 3, colour.filled())))?;
        }
        chart.draw_series(LineSeries::new(pts, style))?;
        if !name.is_empty() {
            legend.push((name, style));
        }
    }
    let lines = [
        format!("A {:.3} µm", f.a_um),
        format!("A↑ {:.3} µm", f.a_forward_um),
        format!("A↓ {:.3} µm", f.a_backward_um),
        format!("E {:.3} µm", f.e_um),
        format!("M {:.3} µm", f.m_um),
        format!("R {:.3} µm", f.r_um),
        format!("R↑ {:.3} µm", f.r_forward_um),
        format!("R↓ {:.3} µm", f.r_backward_um),
        format!("B {:.3} µm", f.b_um),
        format!("B mean {:+.3} µm", f.b_mean_um),
        String::new(),
        format!("trend {:+.2} µm/m", e.trend.slope_um_per_m),
    ];
    for (k, l) in lines.iter().enumerate() {
        side.draw(&Text::new(
            l.as_str(),
            (20, 80 + 26 * k as i32),
            (FONT, 17).into_font(),
        ))?;
    }
    let top = 80 + 26 * (lines.len() as i32 + 1);
    for (k, (name, style)) in legend.into_iter().enumerate() {
        let y = top + 24 * k as i32;
        side.draw(&PathElement::new(vec![(20, y + 8), (44, y + 8)], style))?;
        side.draw(&Text::new(name, (52, y), (FONT, 15).into_font()))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn half_the_last_digit_of_a_cell() {
        for (cell, half) in [
            ("1.234", 5e-4),
            ("12", 0.5),
            (" 100.003 ", 5e-4),
            ("1.5e-5", 5e-7),
            ("2E3", 500.0),
        ] {
            assert!((half_last_digit(cell) - half).abs() < 1e-15, "{cell}");
        }
    }

    /// A reading to the µm (3 decimals in mm) and a deviation to 0.1 µm may differ by up to
    /// 0.55 µm and still be the same measurement.
    #[test]
    fn both_columns_agree_within_their_rounding() {
        let csv = |dev: &str| {
            let mut s = String::from("run,direction,target_mm,reading_mm,deviation_um\n");
            for run in 1..=2 {
                for d in ["forward", "backward"] {
                    for t in [0, 100, 200, 300, 400] {
                        s += &format!("{run},{d},{t},{t}.003,{dev}\n");
                    }
                }
            }
            s
        };
        let none = Import::default();
        assert!(read_csv(csv("2.6").as_bytes(), "l.csv", "X", &none).is_ok());
        let e = read_csv(csv("2.4").as_bytes(), "l.csv", "X", &none).unwrap_err();
        assert!(e.to_string().contains("within 0.5500 µm"), "{e}");
    }

    #[test]
    fn laser_run_numbers_must_be_positive_integers() {
        let msg = |run: Value| json!({"target_mm": 10.0, "direction": "forward", "run": run, "deviation_um": 1.0});
        assert_eq!(laser_reading(&msg(json!(2))).unwrap().run, 2);
        assert_eq!(laser_reading(&msg(json!(2.0))).unwrap().run, 2);
        for bad in [json!(1.5), json!(1.7), json!(0), json!(-1), json!("1")] {
            let e = laser_reading(&msg(bad.clone())).map(|r| r.run).unwrap_err();
            assert!(
                e.contains("a positive integer") || e.contains("no number `run`"),
                "{bad}: {e}"
            );
        }
        assert!(
            laser_reading(&msg(json!(1.5)))
                .unwrap_err()
                .contains("run `1.5`")
        );
    }
}
