//! A diagnosis as users of ball-bar software read it: the ISO 230-4 figures, then the errors
//! ranked by their contribution to the circular deviation, then what could not be determined.
//! As plain text (terminal), Markdown and JSON.

use crate::diagnosis::{Diagnosis, Finding, MIN_CONTRIBUTION_UM};
use std::fmt::Write;

/// The decision rule, printed with every report.
pub const RULE: &str = "An error is reported present when its signature spans at least 0.5 µm \
peak to valley on this test and its value is at least 3 standard errors from zero (local shapes: \
at least 0.5 µm and above their noise floor). ± is the 95 % confidence interval.";

/// What a `bias_per_<unit>_of_<effect>` detail means, printed when a finding states one.
pub const BIAS_NOTE: &str = "bias_per_<unit>_of_<effect>: what one unit of an effect that \
this test cannot fit (see above; a drift of the pivot is over the whole test) adds to the \
value, as the least-squares fit reads it; not in its ± interval. Measured by a test that fits \
it (a full circle, both directions), the effect corrects the value.";

/// [`RULE`], and [`BIAS_NOTE`] when a finding of `d` states a bias.
fn rules(d: &Diagnosis) -> String {
    let biased = d
        .findings
        .iter()
        .any(|f| f.stated_biases().next().is_some());
    if biased {
        format!("{RULE} {BIAS_NOTE}")
    } else {
        RULE.to_string()
    }
}

fn figures_rows(d: &Diagnosis) -> Vec<(String, String)> {
    let mut rows = Vec::new();
    for dir in &d.iso.directions {
        let s = dir.sense.to_uppercase();
        let sweep = match dir.recorded_sweep_deg {
            Some(all) => format!("{:.0} of {all:.0} deg", dir.sweep_deg),
            None => format!("{:.0} deg", dir.sweep_deg),
        };
        rows.push((
            format!("Circular deviation G {s} ({sweep})"),
            format!("{:.2} µm", dir.circular_deviation_um),
        ));
        rows.push((
            format!("Radial deviation F {s} max / min"),
            format!(
                "{:+.2} / {:+.2} µm",
                dir.radial_deviation_max_um, dir.radial_deviation_min_um
            ),
        ));
        if let Some(z) = dir.minimum_zone_um {
            rows.push((
                format!("Minimum-zone circular deviation {s}"),
                format!("{z:.2} µm"),
            ));
        }
    }
    if let Some(g) = d.iso.bidirectional_deviation_um {
        rows.push((
            "Bidirectional circular deviation G(b)".into(),
            format!("{g:.2} µm"),
        ));
    }
    if let Some(h) = d.iso.hysteresis_um {
        rows.push(("Circular hysteresis H".into(), format!("{h:.2} µm")));
    }
    if let Some(settled) = &d.settled_iso {
        // A start transient is present: the figures as they would read after an overshoot.
        for dir in &settled.directions {
            rows.push((
                format!(
                    "G {} without the end transients ({:.0} deg)",
                    dir.sense.to_uppercase(),
                    dir.sweep_deg
                ),
                format!("{:.2} µm", dir.circular_deviation_um),
            ));
        }
        if let Some(h) = settled.hysteresis_um {
            rows.push(("H without the end transients".into(), format!("{h:.2} µm")));
        }
    }
    rows
}

fn value(f: &Finding) -> String {
    let digits = if f.unit == "ms" { 4 } else { 2 };
    let ci = if f.ci95.is_finite() {
        format!(" ± {:.*}", digits, f.ci95)
    } else {
        String::new()
    };
    format!("{:+.*}{ci} {}", digits, f.value, f.unit)
}

fn details(f: &Finding) -> String {
    f.details
        .iter()
        // Counts (the keys without a unit suffix) as whole numbers, so that they do not read as
        // measurements; measurements keep their decimals even when whole.
        .map(|(k, v)| {
            if !k.contains('_') && v.fract() == 0.0 && v.abs() < 1e15 {
                format!("{k} {v:.0}")
            } else {
                format!("{k} {v:.3}")
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

fn header(d: &Diagnosis) -> String {
    format!(
        "Circular test {} R {:.1} mm at {:.0} mm/min: {}",
        d.plane,
        d.radius_mm,
        d.feed_mm_min,
        d.traces.join(" / ")
    )
}

/// Plain text for a terminal.
pub fn text(d: &Diagnosis) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "{}", header(d));
    let _ = writeln!(s, "\nISO 230-4");
    for (k, v) in figures_rows(d) {
        let _ = writeln!(s, "  {k:<44} {v}");
    }
    let _ = writeln!(s, "\nErrors, ranked by contribution (µm peak to valley)");
    // The name and value columns are as wide as their longest entry, so that the numbers stay
    // in columns.
    let values: Vec<String> = d.findings.iter().map(value).collect();
    let widest = |v: &mut dyn Iterator<Item = &str>| v.map(|s| s.chars().count()).max();
    let width = widest(&mut d.findings.iter().map(|f| f.name.as_str())).unwrap_or(0);
    let value_width = widest(&mut values.iter().map(String::as_str)).unwrap_or(0);
    for (f, v) in d.findings.iter().zip(&values) {
        let mark = if f.present { "*" } else { " " };
        let line = format!(
            "{mark} {:<width$}  {v:>value_width$} {:>7.2}  {}",
            f.name,
            f.contribution_um,
            details(f)
        );
        let _ = writeln!(s, "{}", line.trim_end());
    }
    if !d.not_computed.is_empty() {
        let _ = writeln!(s, "\nNot determined by this test");
        for n in &d.not_computed {
            let _ = writeln!(s, "  {:<28} {}", n.key, n.reason);
        }
    }
    let _ = writeln!(
        s,
        "\nResidual {:.3} µm RMS, noise {:.3} µm. * present. {}",
        d.residual_rms_um,
        d.noise_um,
        rules(d)
    );
    s
}

/// Markdown, for reports kept with the data.
pub fn markdown(d: &Diagnosis) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "## {}\n", header(d));
    let _ = writeln!(s, "| ISO 230-4 | value |\n|---|---|");
    for (k, v) in figures_rows(d) {
        let _ = writeln!(s, "| {k} | {v} |");
    }
    let _ = writeln!(
        s,
        "\n| error | value | contribution (µm) | present | details |\n|---|---|---|---|---|"
    );
    for f in &d.findings {
        let _ = writeln!(
            s,
            "| {} | {} | {:.2} | {} | {} |",
            f.name,
            value(f),
            f.contribution_um,
            if f.present { "yes" } else { "no" },
            details(f)
        );
    }
    if !d.not_computed.is_empty() {
        let _ = writeln!(s, "\nNot determined by this test:\n");
        for n in &d.not_computed {
            let _ = writeln!(s, "- `{}`: {}", n.key, n.reason);
        }
    }
    let _ = writeln!(
        s,
        "\nResidual {:.3} µm RMS, noise {:.3} µm. Threshold {MIN_CONTRIBUTION_UM} µm. {}",
        d.residual_rms_um,
        d.noise_um,
        rules(d)
    );
    s
}

/// JSON (the [`Diagnosis`] with the decision rule, and [`BIAS_NOTE`] when it applies).
pub fn json(d: &Diagnosis) -> serde_json::Value {
    let mut v = serde_json::to_value(d).unwrap_or(serde_json::Value::Null);
    if let Some(o) = v.as_object_mut() {
        o.insert("decision_rule".into(), rules(d).into());
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The note on stated biases comes with the reports whose findings state one, only.
    #[test]
    fn the_bias_note_comes_with_a_stated_bias() {
        use crate::synthetic::{Errors, test, trace};
        use crate::{Options, Plane, Sense, diagnose};
        let e = Errors {
            noise_um: 0.3,
            ..Default::default()
        };
        let full = diagnose(&test(Plane::Xy, &e, 1), &Options::default()).expect("diagnosis");
        let ccw = trace(
            Plane::Xy,
            Sense::Ccw,
            150.0,
            1000.0,
            0.0,
            360.0,
            &e,
            (0.0, 1.0),
            2,
        );
        let one_way = diagnose(&[ccw], &Options::default()).expect("diagnosis");
        for (d, stated) in [(full, false), (one_way, true)] {
            assert_eq!(
                d.findings
                    .iter()
                    .any(|f| f.stated_biases().next().is_some()),
                stated
            );
            for report in [
                text(&d),
                markdown(&d),
                json(&d)["decision_rule"].to_string(),
            ] {
                assert_eq!(
                    report.contains("bias_per_<unit>_of_<effect>"),
                    stated,
                    "{report}"
                );
            }
        }
    }

    #[test]
    fn counts_print_as_whole_numbers_and_measurements_keep_their_decimals_even_when_whole() {
        let f = Finding {
            key: "spike_x".into(),
            name: "Reversal spike X".into(),
            value: -3.38,
            unit: "µm",
            ci95: 0.1,
            contribution_um: 3.38,
            threshold: 0.5,
            present: true,
            details: vec![
                ("width_ms".into(), 12.0),
                ("reversals".into(), 2.0),
                ("at_minus_x_end_um".into(), 3.2366),
            ],
        };
        assert_eq!(
            details(&f),
            "width_ms 12.000, reversals 2, at_minus_x_end_um 3.237"
        );
    }
}
