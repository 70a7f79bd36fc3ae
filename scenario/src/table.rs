//! Compensation tables: CSV files in the layout of controller compensation tables.
//!
//! One row per position, columns named after the axis and its six errors, e.g. for X:
//! `X, EXX, EYX, EZX, EAX, EBX, ECX` with the position in mm, translations in µm and rotations in
//! µrad. Columns may come in any order; every one is required.

use crate::build::{MAX_ANGLE_URAD, MAX_TRANSLATION_UM};
use crate::error::ScenarioError;
use std::path::Path;
use vmt_model::Axis;
use vmt_model::geometric::{Component, ErrorFunction, ErrorTable, Interpolation};

/// The six error functions (SI units) of `axis` read from the table at `path`, which must cover
/// the stroke `[lo, hi]` (m); `key` is the scenario key that names the file, reported with every
/// error so that the user knows which reference to fix.
pub fn read(
    path: &Path,
    key: &str,
    axis: Axis,
    interpolation: Interpolation,
    stroke: (f64, f64),
) -> Result<[ErrorFunction; 6], ScenarioError> {
    let file = path.display().to_string();
    let fail = |position: Option<(usize, usize)>, message: String| ScenarioError {
        file: file.clone(),
        position,
        key: Some(key.to_string()),
        message,
    };
    let names: Vec<String> = std::iter::once(axis.letter().to_string())
        .chain(Component::ALL.iter().map(|c| c.iso_name(axis)))
        .collect();
    let layout = format!(
        "a compensation table for {axis} has the columns {} (mm, then µm for EX{axis}/EY{axis}/EZ{axis} and µrad for EA{axis}/EB{axis}/EC{axis})",
        names.join(", ")
    );
    let bytes =
        std::fs::read(path).map_err(|e| fail(None, format!("cannot read the table: {e}")))?;
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(bytes.as_slice());
    let header = reader
        .headers()
        .map_err(|e| fail(Some((1, 1)), format!("cannot read the header: {e}")))?
        .clone();
    let header_line = record_line(&bytes, header.position()).unwrap_or(1);
    let mut columns = [0usize; 7];
    for (slot, name) in columns.iter_mut().zip(&names) {
        let mut at = (0..header.len()).filter(|&i| header[i].eq_ignore_ascii_case(name));
        *slot = at.next().ok_or_else(|| {
            fail(
                Some((header_line, 1)),
                format!("missing column {name}; {layout}"),
            )
        })?;
        if let Some(again) = at.next() {
            return Err(fail(
                Some((header_line, again + 1)),
                format!(
                    "column {name} is given twice, as columns {} and {}; give each column once: {layout}",
                    *slot + 1,
                    again + 1
                ),
            ));
        }
    }
    let mut rows: Vec<[f64; 7]> = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| {
            let line = record_line(&bytes, e.position());
            // The csv crate's own message names the line before any blank or comment lines.
            let message = match e.kind() {
                csv::ErrorKind::UnequalLengths {
                    expected_len, len, ..
                } => format!("malformed row: {len} fields, the rows before have {expected_len}"),
                _ => format!("malformed row: {e}"),
            };
            fail(line.map(|l| (l, 1)), message)
        })?;
        let line = record_line(&bytes, record.position()).unwrap_or(0);
        let mut row = [0.0; 7];
        for (k, (&c, name)) in columns.iter().zip(&names).enumerate() {
            let text = record.get(c).unwrap_or("");
            row[k] = text
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    fail(
                        Some((line, c + 1)),
                        format!("column {name}: `{text}` is not a finite number"),
                    )
                })?;
            // Column 0 is the position; 1-3 translations, 4-6 rotations.
            let (limit, unit) = match k {
                0 => (f64::INFINITY, "mm"),
                1..=3 => (MAX_TRANSLATION_UM, "µm"),
                _ => (MAX_ANGLE_URAD, "µrad"),
            };
            if row[k].abs() > limit {
                return Err(fail(
                    Some((line, c + 1)),
                    format!(
                        "column {name}: {} {unit} is beyond the accepted ±{limit} {unit}",
                        row[k]
                    ),
                ));
            }
        }
        if let Some(prev) = rows.last()
            && row[0] <= prev[0]
        {
            return Err(fail(
                Some((line, columns[0] + 1)),
                format!(
                    "positions must increase strictly: {} mm after {} mm",
                    row[0], prev[0]
                ),
            ));
        }
        rows.push(row);
    }
    if rows.len() < 2 {
        return Err(fail(
            None,
            format!("a table needs at least 2 rows, found {}", rows.len()),
        ));
    }
    let (first, last) = (rows[0][0] * 1e-3, rows[rows.len() - 1][0] * 1e-3);
    if first > stroke.0 + 1e-12 || last < stroke.1 - 1e-12 {
        return Err(fail(
            None,
            format!(
                "the table covers {} to {} mm but the {axis} stroke is {} to {} mm; it must cover the stroke",
                first * 1e3,
                last * 1e3,
                stroke.0 * 1e3,
                stroke.1 * 1e3
            ),
        ));
    }
    let positions: Vec<f64> = rows.iter().map(|r| r[0] * 1e-3).collect();
    let mut out: [ErrorFunction; 6] = Default::default();
    for (k, c) in Component::ALL.iter().enumerate() {
        let values = rows.iter().map(|r| r[k + 1] * 1e-6).collect();
        let table = ErrorTable::new(positions.clone(), values, interpolation)
            .map_err(|e| fail(None, format!("{}: {e}", c.iso_name(axis))))?;
        out[k] = ErrorFunction::Table(table);
    }
    Ok(out)
}

/// The 1-based line of the record the csv reader placed at `pos` in `bytes`: the reader records
/// a row's position before it skips the blank and `#` lines in front of it, so those are counted
/// here (as vmt-tools' reader of traces does for blank lines).
fn record_line(bytes: &[u8], pos: Option<&csv::Position>) -> Option<usize> {
    let pos = pos?;
    let (mut line, mut b) = (pos.line() as usize, pos.byte() as usize);
    loop {
        let rest = bytes.get(b..).unwrap_or_default();
        // A comment runs to the end of its line.
        let text = if rest.first() == Some(&b'#') {
            rest.iter()
                .position(|&c| c == b'\n' || c == b'\r')
                .unwrap_or(rest.len())
        } else {
            0
        };
        let end = &rest[text..];
        let newline = if end.starts_with(b"\r\n") {
            2
        } else if end.starts_with(b"\n") || end.starts_with(b"\r") {
            1
        } else {
            return Some(line);
        };
        b += text + newline;
        line += 1;
    }
}
