//! Images a person can read: volumetric error maps as heat maps with colour bars.

use crate::error::CliError;
use crate::map::{APPROACHES, VolumetricMap};
use nalgebra::Vector3;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::path::Path;
use std::sync::Once;

/// Image formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// Portable Network Graphics.
    Png,
    /// Scalable Vector Graphics.
    Svg,
}

impl Format {
    /// File extension.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Png => "png",
            Format::Svg => "svg",
        }
    }
}

const FONT: &str = "sans-serif";

/// Registers the embedded DejaVu Sans font once (plotters draws text with ab_glyph).
fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The font is compiled in; registration fails only for a corrupt font file.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular());
    });
}

/// A diverging blue-white-red colour for `t` in [-1, 1].
fn diverging(t: f64) -> RGBColor {
    let t = t.clamp(-1.0, 1.0);
    let lerp = |a: f64, b: f64, s: f64| (a + (b - a) * s).round() as u8;
    let (white, blue, red) = (
        (247.0, 247.0, 247.0),
        (33.0, 102.0, 172.0),
        (178.0, 24.0, 43.0),
    );
    let (end, s) = if t < 0.0 { (blue, -t) } else { (red, t) };
    RGBColor(
        lerp(white.0, end.0, s),
        lerp(white.1, end.1, s),
        lerp(white.2, end.2, s),
    )
}

/// Draws the map: rows forward and backward approach, columns the X, Y and Z error components,
/// each column on one symmetric colour scale (µm).
pub fn draw_map(map: &VolumetricMap, path: &Path, format: Format) -> Result<(), CliError> {
    register_font();
    let size = (1500, 960);
    let err = |e: &dyn std::fmt::Display| CliError::output(path, e);
    match format {
        Format::Png => {
            let root = BitMapBackend::new(path, size).into_drawing_area();
            draw_on(&root, map).map_err(|e| err(&e))?;
            root.present().map_err(|e| err(&e))
        }
        Format::Svg => {
            let root = SVGBackend::new(path, size).into_drawing_area();
            draw_on(&root, map).map_err(|e| err(&e))?;
            root.present().map_err(|e| err(&e))
        }
    }
}

type DrawResult<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

fn draw_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    map: &VolumetricMap,
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let title = format!(
        "Volumetric error on the {} plane at {} = {:.1} mm (µm; tool relative to workpiece)",
        map.plane.to_string().to_uppercase(),
        map.plane.normal,
        map.at_m * 1e3
    );
    let (top, body) = root.split_vertically(50);
    top.draw_text(&title, &(FONT, 24).into_text_style(&top), (20, 14))?;
    let panels = body.split_evenly((2, 3));
    for (row, (_, approach)) in APPROACHES.iter().enumerate() {
        for k in 0..3 {
            let scale = (map.max_abs(k) * 1e6).max(1e-3);
            draw_panel(&panels[row * 3 + k], map, row, k, scale, approach)?;
        }
    }
    Ok(())
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    map: &VolumetricMap,
    row: usize,
    k: usize,
    scale_um: f64,
    approach: &str,
) -> DrawResult<DB> {
    let (w, _) = area.dim_in_pixel();
    let (plot_area, bar_area) = area.split_horizontally(w.saturating_sub(90));
    let (u0, u1) = (map.u_m[0] * 1e3, map.u_m[map.u_m.len() - 1] * 1e3);
    let (v0, v1) = (map.v_m[0] * 1e3, map.v_m[map.v_m.len() - 1] * 1e3);
    let component = ["ΔX", "ΔY", "ΔZ"][k];
    let mut chart = ChartBuilder::on(&plot_area)
        .caption(format!("{component}, {approach} approach"), (FONT, 18))
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(52)
        .build_cartesian_2d(u0..u1, v0..v1)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_labels(6)
        .y_labels(6)
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_label_formatter(&|v| format!("{v:.0}"))
        .x_desc(format!("{} (mm)", map.plane.u))
        .y_desc(format!("{} (mm)", map.plane.v))
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .draw()?;
    let (nu, nv) = (map.u_m.len(), map.v_m.len());
    let du = (u1 - u0) / (nu - 1) as f64;
    let dv = (v1 - v0) / (nv - 1) as f64;
    chart.draw_series(
        (0..nv)
            .flat_map(|iv| (0..nu).map(move |iu| (iu, iv)))
            .map(|(iu, iv)| {
                let e = map.errors[row][iv * nu + iu][k] * 1e6;
                let (u, v) = (u0 + du * iu as f64, v0 + dv * iv as f64);
                let corners = [
                    ((u - du / 2.0).max(u0), (v - dv / 2.0).max(v0)),
                    ((u + du / 2.0).min(u1), (v + dv / 2.0).min(v1)),
                ];
                Rectangle::new(corners, diverging(e / scale_um).filled())
            }),
    )?;
    draw_colour_bar(&bar_area, scale_um)
}

fn draw_colour_bar<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    scale_um: f64,
) -> DrawResult<DB> {
    let mut bar = ChartBuilder::on(area)
        .margin_top(40)
        .margin_bottom(44)
        .margin_right(8)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..1.0, -scale_um..scale_um)?;
    bar.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_labels(7)
        .y_label_formatter(&|v| format!("{v:.1}"))
        .label_style((FONT, 12))
        .draw()?;
    let steps = 100;
    bar.draw_series((0..steps).map(|i| {
        let a = -scale_um + 2.0 * scale_um * i as f64 / steps as f64;
        let b = a + 2.0 * scale_um / steps as f64;
        Rectangle::new([(0.0, a), (1.0, b)], diverging(a / scale_um).filled())
    }))?;
    Ok(())
}

/// Draws a thermal history: node temperatures (top) and tool-point drift (bottom) against time.
pub fn draw_thermal(
    h: &crate::thermal::ThermalHistory,
    path: &Path,
    format: Format,
) -> Result<(), CliError> {
    register_font();
    let size = (1200, 900);
    let err = |e: &dyn std::fmt::Display| CliError::output(path, e);
    match format {
        Format::Png => {
            let root = BitMapBackend::new(path, size).into_drawing_area();
            draw_thermal_on(&root, h).map_err(|e| err(&e))?;
            root.present().map_err(|e| err(&e))
        }
        Format::Svg => {
            let root = SVGBackend::new(path, size).into_drawing_area();
            draw_thermal_on(&root, h).map_err(|e| err(&e))?;
            root.present().map_err(|e| err(&e))
        }
    }
}

fn draw_thermal_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    h: &crate::thermal::ThermalHistory,
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let (top, bottom) = root.split_vertically(450);
    let hours: Vec<f64> = h.times_s.iter().map(|t| t / 3600.0).collect();
    let t_end = hours.last().copied().unwrap_or(1.0).max(1e-6);
    let all_temps = h.temps_c.iter().flatten().chain(&h.ambient_c);
    let (lo, hi) = all_temps.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), t| {
        (a.min(*t), b.max(*t))
    });
    let pad = ((hi - lo) * 0.05).max(0.1);
    let mut chart = ChartBuilder::on(&top)
        .caption("Thermal run: node temperatures", (FONT, 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_end, (lo - pad)..(hi + pad))?;
    chart
        .configure_mesh()
        .x_desc("time (h)")
        .y_desc("temperature (°C)")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 15))
        .draw()?;
    let series = h.nodes.iter().enumerate().map(|(k, name)| {
        let pts: Vec<(f64, f64)> = hours
            .iter()
            .zip(&h.temps_c)
            .map(|(t, temps)| (*t, temps[k]))
            .collect();
        (name.clone(), pts)
    });
    let ambient: Vec<(f64, f64)> = hours
        .iter()
        .copied()
        .zip(h.ambient_c.iter().copied())
        .collect();
    for (i, (name, pts)) in series
        .chain(std::iter::once(("ambient".to_string(), ambient)))
        .enumerate()
    {
        let colour = Palette99::pick(i).to_rgba();
        chart
            .draw_series(LineSeries::new(pts, colour.stroke_width(2)))?
            .label(name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .label_font((FONT, 14))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    let drift_um: Vec<Vector3<f64>> = h.drift.iter().map(|d| d * 1e6).collect();
    let m = drift_um.iter().map(|d| d.amax()).fold(0.1, f64::max) * 1.1;
    let mut chart = ChartBuilder::on(&bottom)
        .caption(
            "Thermal drift of the tool point relative to the workpiece",
            (FONT, 22),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_end, -m..m)?;
    chart
        .configure_mesh()
        .x_desc("time (h)")
        .y_desc("drift (µm)")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 15))
        .draw()?;
    for (k, (name, colour)) in [("ΔX", RED), ("ΔY", GREEN), ("ΔZ", BLUE)]
        .into_iter()
        .enumerate()
    {
        let pts: Vec<(f64, f64)> = hours
            .iter()
            .zip(&drift_um)
            .map(|(t, d)| (*t, d[k]))
            .collect();
        chart
            .draw_series(LineSeries::new(pts, colour.stroke_width(2)))?
            .label(name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .label_font((FONT, 14))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}
