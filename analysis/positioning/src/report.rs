//! The evaluation as text and Markdown, laid out as ISO 230-2 reports are: the figures with
//! the standard's symbols, then the table per target.

use crate::evaluation::Evaluation;
use std::fmt::Write as _;

/// The figures with their ISO 230-2 symbols and names, µm.
fn figures(e: &Evaluation) -> [(&'static str, &'static str, f64); 12] {
    let f = &e.iso230_2;
    [
        ("A", "accuracy, bidirectional", f.a_um),
        ("A↑", "accuracy, forward", f.a_forward_um),
        ("A↓", "accuracy, backward", f.a_backward_um),
        ("E", "systematic positioning error, bidirectional", f.e_um),
        (
            "E↑",
            "systematic positioning error, forward",
            f.e_forward_um,
        ),
        (
            "E↓",
            "systematic positioning error, backward",
            f.e_backward_um,
        ),
        ("M", "mean bidirectional positioning error", f.m_um),
        ("R", "repeatability, bidirectional", f.r_um),
        ("R↑", "repeatability, forward", f.r_forward_um),
        ("R↓", "repeatability, backward", f.r_backward_um),
        ("B", "reversal value", f.b_um),
        ("B̄", "mean reversal value", f.b_mean_um),
    ]
}

/// Per target: P_i (mm), then x̄↑, x̄↓, s↑, s↓, B_i, −x̄, −x̄↑, −x̄↓ (µm).
fn target_rows(e: &Evaluation) -> impl Iterator<Item = [f64; 9]> + '_ {
    let f = &e.iso230_2;
    e.compensation.iter().enumerate().map(move |(i, c)| {
        [
            c.target_mm,
            f.mean_forward_um[i],
            f.mean_backward_um[i],
            f.s_forward_um[i],
            f.s_backward_um[i],
            f.reversal_um[i],
            c.bidirectional_um,
            c.forward_um,
            c.backward_um,
        ]
    })
}

fn header(e: &Evaluation) -> String {
    format!(
        "ISO 230-2 linear positioning, axis {}: {} targets from {:.3} to {:.3} mm, {} runs",
        e.axis,
        e.iso230_2.targets_mm.len(),
        e.iso230_2.targets_mm.first().copied().unwrap_or(0.0),
        e.iso230_2.targets_mm.last().copied().unwrap_or(0.0),
        e.runs
    )
}

fn trend_line(e: &Evaluation) -> String {
    format!(
        "Linear trend of the mean deviations: {:+.2} um/m (scale error, ppm), {:+.2} um at the first target; {:.2} um of M is not linear",
        e.trend.slope_um_per_m, e.trend.at_first_target_um, e.trend.residual_span_um
    )
}

/// The report as plain text.
pub fn text(e: &Evaluation) -> String {
    let mut s = header(e);
    s.push_str("\n\n");
    for (sym, name, v) in figures(e) {
        let _ = writeln!(s, "  {sym:<3} {v:>9.3} um  {name}");
    }
    let _ = writeln!(s, "\n{}\n", trend_line(e));
    let _ = writeln!(
        s,
        "  {:>10} {:>9} {:>9} {:>7} {:>7} {:>8} {:>11}",
        "target mm", "mean fw", "mean bw", "s fw", "s bw", "B_i", "correction"
    );
    for row in target_rows(e) {
        let cells: Vec<String> = row
            .iter()
            .zip([10, 9, 9, 7, 7, 8, 11])
            .map(|(v, width)| format!("{v:>width$.3}"))
            .collect();
        let _ = writeln!(s, "  {}", cells.join(" "));
    }
    s.push_str(
        "  (um; correction = -mean bidirectional deviation, the pitch-error compensation)\n",
    );
    for n in &e.notes {
        let _ = writeln!(s, "Note: {n}");
    }
    s
}

/// The report as Markdown.
pub fn markdown(e: &Evaluation) -> String {
    let mut s = format!(
        "# {}\n\n| Figure | Value (µm) | Meaning |\n|---|---|---|\n",
        header(e)
    );
    for (sym, name, v) in figures(e) {
        let _ = writeln!(s, "| {sym} | {v:.3} | {name} |");
    }
    let _ = writeln!(s, "\n{}.\n", trend_line(e));
    s.push_str("| Target (mm) | x̄↑ (µm) | x̄↓ (µm) | s↑ (µm) | s↓ (µm) | B_i (µm) | Correction −x̄ (µm) | −x̄↑ (µm) | −x̄↓ (µm) |\n|---|---|---|---|---|---|---|---|---|\n");
    for row in target_rows(e) {
        let cells: Vec<String> = row.iter().map(|v| format!("{v:.3}")).collect();
        let _ = writeln!(s, "| {} |", cells.join(" | "));
    }
    if !e.notes.is_empty() {
        s.push('\n');
        for n in &e.notes {
            let _ = writeln!(s, "- {n}");
        }
    }
    s
}
