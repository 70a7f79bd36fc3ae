//! Ball-bar traces in: from a run of ours (the MCAP file `vmt run` writes) or from an
//! instrument's CSV export, into the diagnosis' [`Trace`]s, one code path for both.
//!
//! # CSV format
//!
//! One row per sample, a header naming the columns (any order, extra columns ignored):
//!
//! | column | unit | meaning |
//! |---|---|---|
//! | `angle_deg` | deg | angle of the bar in the test plane from the plane's first axis (X for XY, Z for ZX, Y for YZ), unwrapped or in [0, 360) — it is unwrapped on reading |
//! | `deviation_um` | µm | measured minus nominal bar length, positive outward |
//! | `direction` | — | `cw` or `ccw`: which run of the test the row belongs to |
//! | `time_s` | s | optional: sample time on one clock for the whole file |
//!
//! The radius, feed and plane come from the command line (`--radius-mm`, `--feed-mm-min`,
//! `--plane`). Rows of one direction must be consecutive and in the order measured. An
//! instrument's export is read as exported: `--columns` maps our names onto its headers,
//! `--units` (or a unit written in a header) gives its units: the deviation in µm or mm, the
//! angle in deg or rad, the time in s or ms ([`crate::import`]).

use crate::error::CliError;
use crate::import::Import;
use std::path::Path;
use vmt_ballbar::{Trace, TraceError};
use vmt_logs::csv_import::{Column, Quantity, Resolved};
use vmt_logs::input::{self, Input};
use vmt_sim::run::BallbarTrace;

pub use vmt_logs::ballbar::{Recorded, group_tests, run_tests};

/// The set-up of a CSV trace, from the command line.
#[derive(Clone, Copy, Debug)]
pub struct CsvSetup<'a> {
    /// Test plane name (`XY`, `ZX`, `YZ`).
    pub plane: &'a str,
    /// Nominal radius, mm.
    pub radius_mm: f64,
    /// Feed, mm/min.
    pub feed_mm_min: f64,
}

/// A simulated trace as a diagnosis trace.
pub fn from_run(t: &BallbarTrace, file: &str) -> Result<Trace, CliError> {
    vmt_gap::model::trace_of(t).map_err(|e| CliError::input(file, None, e.to_string()))
}

/// Reads `path`: an MCAP run (by its magic bytes) or a CSV trace file (`import`: its columns
/// and units). For a CSV, also the line that says which columns were read in which units.
pub fn read(
    path: &Path,
    csv: Option<CsvSetup>,
    import: &Import,
) -> Result<(Recorded, Option<String>), CliError> {
    let file = path.display().to_string();
    let bytes = match input::open(path, &file)? {
        Input::Mcap => {
            if import.given() {
                return Err(CliError::Argument(format!(
                    "{file} is a run of ours (MCAP), whose columns and units are its own: \
                     --columns and --units apply to CSV exports"
                )));
            }
            return Ok((vmt_logs::ballbar::read(path, &file)?, None));
        }
        Input::Other(bytes) => bytes,
    };
    let setup = csv.ok_or_else(|| {
        CliError::Argument(format!(
            "{file} is a CSV trace: give its set-up with --radius-mm, --feed-mm-min and --plane"
        ))
    })?;
    let (traces, cols) = read_csv(&bytes, &file, setup, import)?;
    let recorded = Recorded {
        tests: group_tests(traces),
        ground_truth: None,
    };
    Ok((recorded, Some(crate::import::echo(&cols))))
}

/// The columns of a ball-bar CSV.
const COLUMNS: [Column; 4] = [
    Column {
        name: "angle_deg",
        quantity: Quantity::Angle,
        required: true,
    },
    Column {
        name: "deviation_um",
        quantity: Quantity::Micrometres,
        required: true,
    },
    Column {
        name: "direction",
        quantity: Quantity::Label,
        required: true,
    },
    Column {
        name: "time_s",
        quantity: Quantity::Time,
        required: false,
    },
];

/// Samples of one direction while reading.
struct Run {
    direction: String,
    /// The file's line of each sample.
    lines: Vec<usize>,
    time: Vec<f64>,
    angle: Vec<f64>,
    deviation: Vec<f64>,
}

/// The 1-based line of the record the csv reader placed at `pos` in `bytes`: the reader
/// records a row's position before it skips the blank lines in front of it, so those are
/// counted here. `None` (no position) gives `fallback`.
pub(crate) fn record_line(bytes: &[u8], pos: Option<&csv::Position>, fallback: usize) -> usize {
    let Some(pos) = pos else {
        return fallback;
    };
    let (mut line, mut b) = (pos.line() as usize, pos.byte() as usize);
    loop {
        let rest = bytes.get(b..).unwrap_or_default();
        let skip = if rest.starts_with(b"\r\n") {
            2
        } else if rest.starts_with(b"\n") || rest.starts_with(b"\r") {
            1
        } else {
            return line;
        };
        b += skip;
        line += 1;
    }
}

/// A CSV reader over `bytes` (cells trimmed) and the header of `file`.
pub(crate) fn csv_with_header<'a>(
    bytes: &'a [u8],
    file: &str,
) -> Result<(csv::Reader<&'a [u8]>, csv::StringRecord), CliError> {
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(bytes);
    let header = reader
        .headers()
        .map_err(|e| CliError::input(file, Some(1), e.to_string()))?
        .clone();
    unique_columns(&header, file)?;
    Ok((reader, header))
}

/// Refuses a header that names a column twice: which of the two a reader took would be a guess.
pub(crate) fn unique_columns(header: &csv::StringRecord, file: &str) -> Result<(), CliError> {
    for (i, h) in header.iter().enumerate() {
        if let Some(first) = header.iter().take(i).position(|x| x == h) {
            let msg = format!(
                "column `{h}` is given twice (columns {} and {})",
                first + 1,
                i + 1
            );
            return Err(CliError::input(file, Some(1), msg));
        }
    }
    Ok(())
}

/// Cell `k` of `rec`, line `line` of `file`, as a finite number; `name` names its column.
pub(crate) fn finite_cell(
    rec: &csv::StringRecord,
    k: usize,
    name: &str,
    file: &str,
    line: usize,
) -> Result<f64, CliError> {
    let s = rec.get(k).unwrap_or("");
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(CliError::input(
            file,
            Some(line),
            format!("{name} `{s}` is not accepted; a finite number"),
        )),
    }
}

/// A trace's refusal as an error of the CSV file: at the line of the sample at fault (the
/// header is line 1), or at the first line of the direction's rows; the set-up values as the
/// command-line options they came from.
fn csv_trace_error(e: TraceError, file: &str, lines: &[usize], direction: &str) -> CliError {
    let first_line = lines[0];
    if let TraceError::Setup {
        what,
        value,
        accepted,
        ..
    } = &e
    {
        let option = format!("--{}", what.replace('_', "-"));
        return CliError::Argument(format!("{option} {value}: {accepted}"));
    }
    // The trace's own check allows an inclined bar's pace, which a CSV cannot state.
    if let TraceError::FeedMismatch {
        label,
        implied,
        radius_mm,
        feed,
    } = &e
    {
        return flat_feed_error(label, *implied, *radius_mm, *feed);
    }
    match e.sample() {
        Some(i) => CliError::input(file, lines.get(i).copied(), e.to_string()),
        None => CliError::input(
            file,
            Some(first_line),
            format!("{e} (the {direction} rows start here)"),
        ),
    }
}

fn read_csv(
    bytes: &[u8],
    file: &str,
    setup: CsvSetup,
    import: &Import,
) -> Result<(Vec<Trace>, Resolved), CliError> {
    let (mut reader, header) = csv_with_header(bytes, file)?;
    let resolved = import.resolve(&header, &COLUMNS, "a ball-bar trace", file)?;
    let col = |name: &str| resolved.index(name).unwrap_or(0);
    let (angle_col, deviation_col, direction_col) =
        (col("angle_deg"), col("deviation_um"), col("direction"));
    let time_col = resolved.index("time_s");
    let (angle_factor, deviation_factor, time_factor) = (
        resolved.factor("angle_deg"),
        resolved.factor("deviation_um"),
        resolved.factor("time_s"),
    );
    let mut runs: Vec<Run> = Vec::new();
    for (i, record) in reader.records().enumerate() {
        let rec = record.map_err(|e| {
            let line = record_line(bytes, e.position(), i + 2);
            CliError::input(file, Some(line), e.to_string())
        })?;
        // The reader's own line count: blank lines are skipped, quoted cells may span lines.
        let line = record_line(bytes, rec.position(), i + 2);
        let number = |k: usize| finite_cell(&rec, k, header[k].trim(), file, line);
        let direction = rec.get(direction_col).unwrap_or("").to_ascii_lowercase();
        if direction != "cw" && direction != "ccw" {
            return Err(CliError::input(
                file,
                Some(line),
                format!("direction `{direction}` is not accepted; cw or ccw"),
            ));
        }
        if runs.last().is_none_or(|r| r.direction != direction) {
            if runs.iter().any(|r| r.direction == direction) {
                return Err(CliError::input(
                    file,
                    Some(line),
                    format!(
                        "the {direction} rows resume after another direction; the rows of one direction must be consecutive"
                    ),
                ));
            }
            runs.push(Run {
                direction: direction.clone(),
                lines: Vec::new(),
                time: Vec::new(),
                angle: Vec::new(),
                deviation: Vec::new(),
            });
        }
        let run = runs.last_mut().expect("pushed above");
        let mut angle = number(angle_col)? * angle_factor;
        if let Some(last) = run.angle.last() {
            // Unwrap: the nearest turn to the previous sample.
            angle += 360.0 * ((last - angle) / 360.0).round();
        }
        run.angle.push(angle);
        run.lines.push(line);
        run.deviation
            .push(number(deviation_col)? * deviation_factor);
        if let Some(k) = time_col {
            run.time.push(number(k)? * time_factor);
        }
    }
    if runs.is_empty() {
        return Err(CliError::input(file, None, "no samples after the header"));
    }
    let traces = runs
        .into_iter()
        .map(|r| {
            let label = format!("{file} {}", r.direction.to_uppercase());
            Trace::new(
                &label,
                setup.plane,
                &r.direction,
                setup.radius_mm,
                setup.feed_mm_min,
                r.angle,
                r.deviation,
                time_col.map(|_| r.time),
            )
            .map_err(|e| csv_trace_error(e, file, &r.lines, &r.direction))
        })
        .collect::<Result<Vec<_>, _>>()?;
    for t in &traces {
        check_flat_feed(t, setup)?;
    }
    Ok((traces, resolved))
}

/// A CSV trace's times against `--feed-mm-min` within [`vmt_ballbar::trace::FEED_TOLERANCE`]
/// both ways: its set-up is a bar in the plane of its circle (the trace's own check allows an
/// inclined bar's faster angular pace, which a CSV cannot state), so a feed typed 2 to 10
/// times too low is refused too.
fn check_flat_feed(t: &Trace, setup: CsvSetup) -> Result<(), CliError> {
    let Some(speed) = t.timed_speed_mm_min() else {
        return Ok(());
    };
    if (speed / setup.feed_mm_min - 1.0).abs() > vmt_ballbar::trace::FEED_TOLERANCE {
        return Err(flat_feed_error(
            &t.label,
            speed,
            setup.radius_mm,
            setup.feed_mm_min,
        ));
    }
    Ok(())
}

/// The times of the trace `label` give `speed` (mm/min) on the circle of `radius_mm`, not the
/// stated `feed`.
fn flat_feed_error(label: &str, speed: f64, radius_mm: f64, feed: f64) -> CliError {
    CliError::Argument(format!(
        "--feed-mm-min {feed}: the times of {label} give {speed:.1} mm/min along the {radius_mm} mm circle (within {} % is accepted); check the feed, --radius-mm and the unit of time_s (s; --units time_s=ms for ms)",
        vmt_ballbar::trace::FEED_TOLERANCE * 100.0
    ))
}
