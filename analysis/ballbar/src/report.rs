//! A diagnosis as users of ball-bar software read it: the ISO 230-4 figures, then the errors
//! ranked by their contribution to the circular deviation, then what could not be determined.
//! As plain text (terminal), Markdown and JSON.

use crate::diagnosis::{Diagnosis, Finding, MIN_CONTRIBUTION_UM, SETTLING_RULE};
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

/// [`RULE`], [`SETTLING_RULE`] when it left something out, and [`BIAS_NOTE`] when a finding of
/// `d` states a bias.
fn rules(d: &Diagnosis) -> String {
    let biased = d
        .findings
        .iter()
        .any(|f| f.stated_biases().next().is_some());
    let mut s = RULE.to_string();
    if trimmed(d) {
        s = format!("{s} {SETTLING_RULE}");
    }
    if biased {
        s = format!("{s} {BIAS_NOTE}");
    }
    s
}

/// Whether the settling rule left anything out of the figures.
fn trimmed(d: &Diagnosis) -> bool {
    d.settling
        .iter()
        .any(|s| s.start_excluded_deg > 0.0 || s.end_excluded_deg > 0.0)
}

/// What the settling rule left out, per trace: `CW first 2.6 deg, CCW first 2.9 and last
/// 0.4 deg`.
pub fn excluded(d: &Diagnosis) -> String {
    d.settling
        .iter()
        .map(|s| {
            let sense = s.sense.to_uppercase();
            let mut ends = Vec::new();
            if s.start_excluded_deg > 0.0 {
                ends.push(format!("first {:.1}", s.start_excluded_deg));
            }
            if s.end_excluded_deg > 0.0 {
                ends.push(format!("last {:.1}", s.end_excluded_deg));
            }
            let what = if ends.is_empty() {
                "none".to_string()
            } else {
                format!("{} deg", ends.join(" and "))
            };
            let unsettled = if s.settled {
                ""
            } else {
                " (does not settle within half the run: that end kept)"
            };
            format!("{sense} {what}{unsettled}")
        })
        .collect::<Vec<_>>()
        .join(", ")
}

fn figures_rows(d: &Diagnosis) -> Vec<(String, String)> {
    let mut rows = Vec::new();
    let cut = trimmed(d);
    // The raw figure beside the settled one, where they differ.
    let raw = |v: f64, r: f64, signed: bool| {
        let main = if signed {
            format!("{v:+.2}")
        } else {
            format!("{v:.2}")
        };
        if cut && (v - r).abs() >= 0.005 {
            let r = if signed {
                format!("{r:+.2}")
            } else {
                format!("{r:.2}")
            };
            format!("{main} µm (raw {r} µm)")
        } else {
            format!("{main} µm")
        }
    };
    for (dir, whole) in d.iso.directions.iter().zip(&d.raw_iso.directions) {
        let s = dir.sense.to_uppercase();
        let sweep = match (dir.recorded_sweep_deg, cut) {
            (Some(all), _) => format!("{:.0} of {all:.0} deg", dir.sweep_deg),
            (None, true) => format!(
                "settled, {:.1} of {:.1} deg",
                dir.sweep_deg, whole.sweep_deg
            ),
            (None, false) => format!("{:.0} deg", dir.sweep_deg),
        };
        rows.push((
            format!("Circular deviation G {s} ({sweep})"),
            raw(
                dir.circular_deviation_um,
                whole.circular_deviation_um,
                false,
            ),
        ));
        rows.push((
            format!("Radial deviation F {s} max / min"),
            format!(
                "{} / {}",
                raw(
                    dir.radial_deviation_max_um,
                    whole.radial_deviation_max_um,
                    true
                ),
                raw(
                    dir.radial_deviation_min_um,
                    whole.radial_deviation_min_um,
                    true
                )
            ),
        ));
        if let Some(z) = dir.minimum_zone_um {
            rows.push((
                format!("Minimum-zone circular deviation {s}"),
                raw(z, whole.minimum_zone_um.unwrap_or(z), false),
            ));
        }
    }
    if let Some(g) = d.iso.bidirectional_deviation_um {
        let r = d.raw_iso.bidirectional_deviation_um.unwrap_or(g);
        rows.push((
            "Bidirectional circular deviation G(b)".into(),
            raw(g, r, false),
        ));
    }
    if let Some(h) = d.iso.hysteresis_um {
        let r = d.raw_iso.hysteresis_um.unwrap_or(h);
        rows.push(("Circular hysteresis H".into(), raw(h, r, false)));
    }
    if cut {
        rows.push((
            "Left out as unsettled (settling rule below)".into(),
            excluded(d),
        ));
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

/// JSON (the [`Diagnosis`] with the decision rule, and [`BIAS_NOTE`] when it applies; the
/// figures past the settling as `iso`, the raw ones as `raw_iso`, the settling rule as
/// `settling_rule`).
pub fn json(d: &Diagnosis) -> serde_json::Value {
    let mut v = serde_json::to_value(d).unwrap_or(serde_json::Value::Null);
    if let Some(o) = v.as_object_mut() {
        o.insert("decision_rule".into(), rules(d).into());
        o.insert("settling_rule".into(), SETTLING_RULE.into());
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
