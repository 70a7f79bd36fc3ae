//! `vmt gap` on accelerometer logs: a milling model against measured vibration, by
//! third-octave band (`vmt_gap::vibration`). Logs are read as `vmt chatter detect` reads them
//! (a milling run.mcap, or a CSV `time_s,ax,ay,az` in s and m/s²).

use crate::chatter;
use crate::error::CliError;
use crate::plot::{DrawResult, FONT, Figure, Format, register_font, render};
use plotters::coord::Shift;
use plotters::prelude::*;
use serde_json::{Value, json};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use vmt_gap::GapError;
use vmt_gap::vibration::{self, Log, MillingModel, Options, Share, VibrationGap};
use vmt_logs::rerun::{AxisBands, write_band_rrd};

/// Whether `path` holds accelerometer data: an MCAP with an `/accelerometer` topic, or a CSV
/// whose header names `ax`, `ay` or `az`.
pub fn is_accelerometer(path: &Path) -> Result<bool, CliError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| CliError::input(&file, None, e.to_string()))?;
    if bytes.starts_with(mcap::MAGIC) {
        return Ok(bytes.windows(14).any(|w| w == b"/accelerometer"));
    }
    let header = bytes.split(|b| *b == b'\n').next().unwrap_or_default();
    Ok(String::from_utf8_lossy(header)
        .split(',')
        .any(|c| ["ax", "ay", "az"].contains(&c.trim())))
}

fn logs(files: &[PathBuf]) -> Result<Vec<Log>, CliError> {
    files
        .iter()
        .map(|f| {
            let l = chatter::read(f, &crate::import::Import::default())?;
            Ok(Log {
                name: f.display().to_string(),
                sample_rate_hz: l.sample_rate_hz,
                channels: l.channels,
                axial_depth_mm: l.axial_depth_mm,
                spindle_rpm: l.spindle_rpm,
                teeth: l.teeth,
            })
        })
        .collect()
}

/// The vibration gap of the milling scenario at `model` against the logs in `files`.
pub fn analyse(model: &Path, files: &[PathBuf]) -> Result<VibrationGap, CliError> {
    let model_file = model.display().to_string();
    let text = std::fs::read_to_string(model)
        .map_err(|e| CliError::input(&model_file, None, e.to_string()))?;
    let err = |e: GapError| match e {
        GapError::Model(_) => CliError::input(&model_file, None, e.to_string()),
        other => CliError::Argument(other.to_string()),
    };
    let forward = MillingModel::new(&text, &model_file, model.parent().map(Path::to_path_buf))
        .map_err(err)?;
    vibration::analyse(&forward, &logs(files)?, &Options::default()).map_err(err)
}

fn shares_text(out: &mut String, title: &str, shares: &[Share], least: f64) {
    let _ = writeln!(out, "  {title}:");
    for s in shares.iter().filter(|s| s.share >= least) {
        let _ = writeln!(
            out,
            "    {:<40} {:>5.1} %  (even spread {:>5.1} %)",
            s.place,
            100.0 * s.share,
            100.0 * s.even
        );
    }
}

/// The strongest places: shares at least twice an even spread and 10 % or more.
fn concentrations(g: &VibrationGap) -> Vec<String> {
    let mut c: Vec<&Share> = g
        .before_by_band
        .iter()
        .chain(&g.before_by_axis)
        .chain(&g.before_by_kind)
        .filter(|s| s.share >= 0.1 && s.share >= 2.0 * s.even)
        .collect();
    c.sort_by(|a, b| b.share.total_cmp(&a.share));
    c.iter()
        .map(|s| format!("{} ({:.0} %)", s.place, 100.0 * s.share))
        .collect()
}

/// The report as text.
pub fn text(model: &str, files: &[PathBuf], g: &VibrationGap) -> String {
    let mut out = String::new();
    let names: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
    let _ = writeln!(
        out,
        "Sim-to-real gap (vibration): model {model} against {}",
        names.join(", ")
    );
    let _ = writeln!(
        out,
        "Axes {}; {} third-octave bands {:.0}-{:.0} Hz; tooth passing {:.1} Hz; split: {}\n",
        g.channels.join(", "),
        g.bands.len(),
        g.bands.first().map_or(0.0, |b| b.lo_hz),
        g.bands.last().map_or(0.0, |b| b.hi_hz),
        g.tooth_passing_hz,
        g.split
    );
    let _ = writeln!(
        out,
        "1. Where (band level, measured against model, dB; bands above the sensor noise):"
    );
    let _ = writeln!(
        out,
        "  RMS {:.2} dB fit, {:.2} dB select, {:.2} dB judge (untouched)",
        g.fit_before_db, g.select_before_db, g.judge_before_db
    );
    shares_text(&mut out, "by band (5 % or more)", &g.before_by_band, 0.05);
    shares_text(&mut out, "by axis", &g.before_by_axis, 0.0);
    shares_text(&mut out, "harmonic or not", &g.before_by_kind, 0.0);
    shares_text(
        &mut out,
        "by piece (a third of a log in time)",
        &g.before_by_piece,
        0.0,
    );
    if !g.before_in_time.is_empty() {
        let _ = writeln!(
            out,
            "  in time (windows of {} s, largest residuals):",
            vmt_gap::vibration::WINDOW_S
        );
        for t in &g.before_in_time {
            let _ = writeln!(
                out,
                "    {}: {:.2}-{:.2} s, {} {}: {:+.1} dB",
                t.log, t.from_s, t.to_s, t.axis, t.band, t.residual_db
            );
        }
    }
    let c = concentrations(g);
    let _ = writeln!(
        out,
        "  concentrates in: {}\n",
        if c.is_empty() {
            "nowhere in particular".to_string()
        } else {
            c.join(", ")
        }
    );
    let _ = writeln!(
        out,
        "2. Which effects explain it, and 3. how much (judge pieces, used neither to fit nor to choose):"
    );
    for (k, s) in g.steps.iter().enumerate() {
        let _ = writeln!(out, "  + {}. {} ({})", k + 1, s.effect, s.description);
        for v in &s.values {
            let _ = writeln!(
                out,
                "      {}: {:.4} -> {:.4} {}",
                v.name, v.model, v.value, v.unit
            );
        }
        let _ = writeln!(
            out,
            "      select RMS {:.2} dB ({:.0} % of the remaining mean square removed), fit RMS {:.2} dB, judge RMS {:.2} dB",
            s.select_rms_db,
            100.0 * s.select_shrink,
            s.fit_rms_db,
            s.judge_rms_db
        );
    }
    for r in &g.rejected {
        let _ = writeln!(out, "  not an explanation: {} {}", r.effect, r.implausible);
    }
    for a in &g.alternatives {
        let values: Vec<String> = a
            .values
            .iter()
            .map(|v| format!("{} {:.4} {}", v.name, v.value, v.unit))
            .collect();
        let verdict = match &a.implausible {
            None => "explains the judge pieces as well".to_string(),
            Some(why) => format!("fits as well, but {why}"),
        };
        let _ = writeln!(
            out,
            "  in place of {}: {} ({}) {verdict}: {:.2} dB against {:.2} dB, p = {:.2}",
            a.instead_of,
            a.effect,
            values.join(", "),
            a.judge_rms_db,
            a.chosen_judge_rms_db,
            a.p_value
        );
    }
    let o = Options::default();
    let (before, after) = (g.judge_before_db, g.judge_after_db);
    let verdict = if g.steps.is_empty() && g.select_before_db <= o.explained_floor_db {
        "the model matches the measurement to the level of band-level scatter".to_string()
    } else if g.explained(&o) {
        format!("explained: judge pieces {before:.2} -> {after:.2} dB")
    } else {
        format!(
            "unexplained residual: judge pieces {before:.2} -> {after:.2} dB; no plausible candidate accounts for the rest"
        )
    };
    let _ = writeln!(out, "  {verdict}");
    if !g.last_round.is_empty() {
        let _ = writeln!(
            out,
            "  last round (select RMS with each candidate, BIC change):"
        );
        for s in &g.last_round {
            let _ = writeln!(
                out,
                "    {:<24} {:>7.2} dB  {:>+9.1}",
                s.effect, s.select_rms_db, s.bic_change
            );
        }
    }
    let _ = writeln!(out, "\nUnexplained residual by band (after):");
    shares_text(&mut out, "by band (5 % or more)", &g.after_by_band, 0.05);
    if let Some(w) = &g.whiteness_after {
        let _ = writeln!(
            out,
            "{}",
            crate::gap::whiteness_line(w, " across the bands")
        );
    }
    let _ = writeln!(out, "\n{} simulations", g.simulations);
    out
}

/// The report as JSON.
pub fn json(model: &str, files: &[PathBuf], g: &VibrationGap) -> Value {
    json!({
        "model": model,
        "files": files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>(),
        "kind": "vibration",
        "gap": g,
        "judge_shrink": g.judge_shrink(),
        "explained": g.explained(&Options::default()),
    })
}

/// Band levels of the first judge piece, per axis: measured, model before and after.
struct Levels<'a>(&'a VibrationGap);

impl Figure for Levels<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        let g = self.0;
        root.fill(&WHITE)?;
        let piece = g.first_judge_piece;
        let panels = root.split_evenly((g.channels.len().max(1), 1));
        let db = |l: f64| 20.0 * l.max(1e-9).log10();
        // The frequency axis is log10(f), labelled in Hz.
        let (lo, hi) = (
            g.bands[0].lo_hz.log10(),
            g.bands[g.bands.len() - 1].hi_hz.log10(),
        );
        for (c, area) in g.channels.iter().enumerate().zip(&panels) {
            let (c, name) = c;
            let series = [
                ("measured", &g.measured[piece][c], BLACK, 3),
                ("model as given", &g.model_before[piece][c], RED, 2),
                ("model with the effects", &g.model_after[piece][c], BLUE, 1),
            ];
            let values = series.iter().flat_map(|s| s.1.iter().map(|l| db(*l)));
            let (ymin, ymax) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
            let mut chart = ChartBuilder::on(area)
                .caption(
                    format!("{name}: third-octave band levels, first judge piece"),
                    (FONT, 18),
                )
                .margin(10)
                .x_label_area_size(36)
                .y_label_area_size(60)
                .build_cartesian_2d(lo..hi, (ymin - 3.0)..(ymax + 3.0))?;
            chart
                .configure_mesh()
                .x_desc("frequency (Hz)")
                .x_labels(10)
                .x_label_formatter(&|x| format!("{:.0}", 10f64.powf(*x)))
                .y_desc("level (dB re 1 m/s²)")
                .label_style((FONT, 13))
                .axis_desc_style((FONT, 14))
                .draw()?;
            for (label, levels, colour, width) in series {
                let pts: Vec<(f64, f64)> = g
                    .bands
                    .iter()
                    .zip(levels.iter())
                    .map(|(b, l)| (b.centre_hz.log10(), db(*l)))
                    .collect();
                let style = colour.stroke_width(width);
                chart
                    .draw_series(LineSeries::new(pts, style))?
                    .label(label)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], style));
            }
            chart
                .configure_series_labels()
                .label_font((FONT, 13))
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()?;
        }
        Ok(())
    }
}

/// The band levels of the first judge piece, per axis, as a Rerun recording.
fn write_rrd(model: &str, report: &str, g: &VibrationGap, path: &Path) -> Result<(), CliError> {
    let piece = g.first_judge_piece;
    let db = |levels: &[f64]| -> Vec<f64> {
        levels.iter().map(|l| 20.0 * l.max(1e-9).log10()).collect()
    };
    let centres: Vec<f64> = g.bands.iter().map(|b| b.centre_hz).collect();
    let levels: Vec<[Vec<f64>; 3]> = (0..g.channels.len())
        .map(|c| {
            [
                db(&g.measured[piece][c]),
                db(&g.model_before[piece][c]),
                db(&g.model_after[piece][c]),
            ]
        })
        .collect();
    let axes: Vec<AxisBands> = g
        .channels
        .iter()
        .zip(&levels)
        .map(|(axis, [m, b, a])| AxisBands {
            axis,
            centres_hz: &centres,
            measured_db: m,
            before_db: b,
            after_db: a,
        })
        .collect();
    Ok(write_band_rrd(
        path,
        &format!("vmt-gap-{}", vmt_logs::slug(model)),
        report,
        &axes,
    )?)
}

/// Writes gap.txt, gap.json, gap.rrd and band_levels.png into `dir`.
pub fn write(
    model: &str,
    files: &[PathBuf],
    g: &VibrationGap,
    dir: &Path,
) -> Result<Vec<PathBuf>, CliError> {
    std::fs::create_dir_all(dir).map_err(|e| CliError::output(dir, e))?;
    let mut written = Vec::new();
    for (name, body) in [
        ("gap.txt", text(model, files, g)),
        (
            "gap.json",
            serde_json::to_string_pretty(&json(model, files, g))
                .map_err(|e| CliError::output(dir, e))?,
        ),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, body).map_err(|e| CliError::output(&path, e))?;
        written.push(path);
    }
    let rrd = dir.join("gap.rrd");
    write_rrd(model, &text(model, files, g), g, &rrd)?;
    written.push(rrd);
    register_font();
    let png = dir.join("band_levels.png");
    let height = 300 * g.channels.len().max(1) as u32;
    render(&Levels(g), &png, Format::Png, (1100, height))?;
    written.push(png);
    Ok(written)
}
