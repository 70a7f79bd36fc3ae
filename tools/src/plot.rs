//! Images a person can read: volumetric error maps as heat maps with colour bars, thermal runs,
//! ball-bar polar plots, ISO 230-2 positioning curves; `render` writes any `Figure` as PNG or SVG.

use crate::error::CliError;
use crate::map::{APPROACHES, VolumetricMap};
use nalgebra::Vector3;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;
use std::sync::Once;
use vmt_sim::run::BallbarTrace;

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

pub(crate) const FONT: &str = "sans-serif";

/// Registers the embedded DejaVu Sans font once (plotters draws text with ab_glyph).
pub(crate) fn register_font() {
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
    struct Map<'a>(&'a VolumetricMap);
    impl Figure for Map<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
            draw_on(root, self.0)
        }
    }
    render(&Map(map), path, format, (1500, 960))
}

/// A picture drawn on one drawing area, whatever the backend.
pub(crate) trait Figure {
    /// Draws the picture on `root`.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB>;
}

/// Renders `figure` into `path` as `format`, `size` pixels.
pub(crate) fn render(
    figure: &impl Figure,
    path: &Path,
    format: Format,
    size: (u32, u32),
) -> Result<(), CliError> {
    let err = |e: &dyn std::error::Error| CliError::output(path, e);
    match format {
        Format::Png => {
            let root = BitMapBackend::new(path, size).into_drawing_area();
            figure.draw(&root).map_err(|e| err(&e))?;
            root.present().map_err(|e| err(&e))
        }
        Format::Svg => {
            let root = SVGBackend::new(path, size).into_drawing_area();
            figure.draw(&root).map_err(|e| err(&e))?;
            root.present().map_err(|e| err(&e))
        }
    }
}

pub(crate) type DrawResult<DB> =
    Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

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
    struct Thermal<'a>(&'a crate::thermal::ThermalHistory);
    impl Figure for Thermal<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
            draw_thermal_on(root, self.0)
        }
    }
    render(&Thermal(h), path, format, (1200, 900))
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
    let all: Vec<(String, Vec<(f64, f64)>)> = series
        .chain(std::iter::once(("ambient".to_string(), ambient)))
        .collect();
    for (i, (name, pts)) in all.iter().enumerate() {
        let colour = Palette99::pick(i).to_rgba();
        // A curve within a thousandth of the axis' span of a later one at every time is hidden
        // under it: the legend says so (a NaN is never hidden).
        let hidden = |other: &[(f64, f64)]| {
            other.len() == pts.len()
                && other
                    .iter()
                    .zip(pts)
                    .all(|(a, b)| (a.1 - b.1).abs() <= 1e-3 * (hi - lo + 2.0 * pad))
        };
        let name = match all[i + 1..].iter().find(|(_, other)| hidden(other)) {
            Some((twin, _)) => format!("{name} (under {twin})"),
            None => name.clone(),
        };
        let pts = pts.clone();
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

const MONO: &str = "monospace";

/// Registers the embedded DejaVu Sans Mono font once (for tables of figures).
fn register_mono_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The font is compiled in; registration fails only for a corrupt font file.
        let _ =
            plotters::style::register_font(MONO, FontStyle::Normal, dejavu::sans_mono::regular());
    });
}

/// Size of a polar plot image, pixels.
pub const POLAR_SIZE: (u32, u32) = (1400, 1000);

/// Draws ball-bar traces as the polar plot of ball-bar software: the nominal circle, the
/// deviations (measured minus nominal length) magnified about it on a scale of round µm per
/// division chosen so that the largest deviation fits the radial band, the division rings, the
/// plane's axes and angles, the traces overlaid in colours (CCW blue, CW red when there is one of
/// each) with a legend, a title with the radius and feed, and `iso_figures` (e.g. the ISO 230-4
/// circular deviation G and hysteresis H, as ready text, one figure a line) beside the plot.
///
/// The plane and its axis names come from the first trace (`XY`: +X to the right, +Y up; `ZX`:
/// +Z right, +X up; `YZ`: +Y right, +Z up), as in ISO 230-4. The image is
/// [`POLAR_SIZE`] pixels. Fails when there is no trace with a finite sample or the file cannot be
/// written.
pub fn draw_polar(
    traces: &[BallbarTrace],
    path: &Path,
    format: Format,
    iso_figures: Option<&str>,
) -> Result<(), CliError> {
    register_font();
    register_mono_font();
    let polar = Polar::new(traces).ok_or_else(|| {
        CliError::Argument(format!(
            "{}: no ball-bar trace with a finite sample to draw",
            path.display()
        ))
    })?;
    struct Plot<'a> {
        polar: Polar,
        traces: &'a [BallbarTrace],
        iso_figures: Option<&'a str>,
    }
    impl Figure for Plot<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
            self.polar.draw_on(root, self.traces, self.iso_figures)
        }
    }
    let plot = Plot {
        polar,
        traces,
        iso_figures,
    };
    render(&plot, path, format, POLAR_SIZE)
}

/// The geometry of a polar plot: where the nominal circle is and how deviations are magnified.
struct Polar {
    /// Centre of the plot, pixels.
    centre: (i32, i32),
    /// Radius of the plot area (angle labels outside it), pixels.
    half: f64,
    /// Radius of the nominal circle, pixels.
    nominal_px: f64,
    /// One division, µm.
    div_um: f64,
    /// Divisions on each side of the nominal circle.
    divisions: u32,
    /// Pixels per µm of deviation.
    px_per_um: f64,
}

impl Polar {
    /// The scale for `traces`: the smallest round division (1, 2, 5 × 10ⁿ µm) that shows the
    /// largest deviation within three divisions either side of the nominal circle.
    fn new(traces: &[BallbarTrace]) -> Option<Self> {
        let finite = traces
            .iter()
            .flat_map(|t| t.angle_deg.iter().zip(&t.deviation_um))
            .filter(|(a, d)| a.is_finite() && d.is_finite());
        let mut any = false;
        let mut max_dev = 0.0_f64;
        for (_, d) in finite {
            any = true;
            max_dev = max_dev.max(d.abs());
        }
        if !any {
            return None;
        }
        let div_um = nice_ceil_125((max_dev / 3.0).max(0.01));
        let divisions = ((max_dev / div_um).ceil() as u32).clamp(1, 3);
        let half = 420.0;
        let band = 0.32 * half;
        Some(Polar {
            centre: (60 + half as i32 + 10, 90 + half as i32),
            half,
            nominal_px: 0.6 * half,
            div_um,
            divisions,
            px_per_um: band / (f64::from(divisions) * div_um),
        })
    }

    /// The pixel of a point at radius `r_px` and `angle_deg` (counter-clockwise, y up).
    fn pixel(&self, r_px: f64, angle_deg: f64) -> (i32, i32) {
        let a = angle_deg.to_radians();
        (
            self.centre.0 + (r_px * a.cos()).round() as i32,
            self.centre.1 - (r_px * a.sin()).round() as i32,
        )
    }

    fn draw_on<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        traces: &[BallbarTrace],
        iso_figures: Option<&str>,
    ) -> DrawResult<DB> {
        root.fill(&WHITE)?;
        self.draw_title(root, traces)?;
        self.draw_grid(root)?;
        self.draw_axes(root, traces.first().map_or("XY", |t| t.plane.as_str()))?;
        for (i, t) in traces.iter().enumerate() {
            self.draw_trace(root, t, trace_colour(traces, i))?;
        }
        self.draw_ring_labels(root)?;
        let y = self.draw_legend(root, traces)?;
        if let Some(text) = iso_figures {
            draw_text_block(root, text, (1000, y + 40))?;
        }
        Ok(())
    }

    fn draw_title<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        traces: &[BallbarTrace],
    ) -> DrawResult<DB> {
        let plane = distinct(traces.iter().map(|t| t.plane.to_uppercase()));
        let radius = distinct(traces.iter().map(|t| format!("{}", t.radius_mm)));
        let feed = distinct(traces.iter().map(|t| format!("{}", t.feed_mm_min)));
        let title =
            format!("Ball-bar circular test, {plane} plane: R = {radius} mm, F = {feed} mm/min");
        root.draw(&Text::new(title, (30, 18), (FONT, 28).into_font()))?;
        // Short enough to end left of the +Y axis label.
        let sub = "Measured − nominal bar length, magnified";
        root.draw(&Text::new(
            sub,
            (30, 54),
            (FONT, 17).into_font().color(&RGBColor(80, 80, 80)),
        ))?;
        Ok(())
    }

    fn draw_grid<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        let light = RGBColor(200, 200, 200);
        for k in (0..12).map(|k| f64::from(k) * 30.0) {
            let inner = self.pixel(0.12 * self.half, k);
            let outer = self.pixel(self.half, k);
            root.draw(&PathElement::new(vec![inner, outer], light.stroke_width(1)))?;
        }
        let n = self.divisions as i32;
        for j in -n..=n {
            let r = self.nominal_px + f64::from(j) * self.div_um * self.px_per_um;
            let style = if j == 0 {
                RGBColor(60, 60, 60).stroke_width(2)
            } else {
                light.stroke_width(1)
            };
            root.draw(&Circle::new(self.centre, r.round() as u32, style))?;
        }
        let scale = format!("Scale: {} µm/div", fmt_um(self.div_um));
        let at = (self.centre.0 - 60, self.centre.1 + 16);
        root.draw(&Text::new(scale, at, (FONT, 18).into_font()))?;
        let nominal = "nominal circle = 0".to_string();
        root.draw(&Text::new(
            nominal,
            (self.centre.0 - 60, self.centre.1 + 40),
            (FONT, 14).into_font().color(&RGBColor(90, 90, 90)),
        ))?;
        Ok(())
    }

    /// The rings' values along the 45° ray, each on a white patch so that the traces drawn
    /// before them do not hide them.
    fn draw_ring_labels<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> DrawResult<DB> {
        let n = self.divisions as i32;
        for j in -n..=n {
            let r = self.nominal_px + f64::from(j) * self.div_um * self.px_per_um;
            let step = fmt_um(f64::from(j.abs()) * self.div_um);
            let label = match j.signum() {
                0 => "0 µm".to_string(),
                1 => format!("+{step}"),
                _ => format!("−{step}"),
            };
            let font = (FONT, 13).into_font().color(&RGBColor(110, 110, 110));
            let at = self.pixel(r + 3.0, 45.0);
            let (w, h) = root.estimate_text_size(&label, &font)?;
            let patch = [
                (at.0 - 1, at.1 - 1),
                (at.0 + w as i32 + 1, at.1 + h as i32 + 1),
            ];
            root.draw(&Rectangle::new(patch, WHITE.filled()))?;
            root.draw(&Text::new(label, at, font))?;
        }
        Ok(())
    }

    fn draw_axes<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        plane: &str,
    ) -> DrawResult<DB> {
        let letters: Vec<char> = plane.to_uppercase().chars().collect();
        let (u, v) = match letters.as_slice() {
            [u, v] => (*u, *v),
            _ => ('X', 'Y'),
        };
        let centred = Pos::new(HPos::Center, VPos::Center);
        for k in 0..12 {
            let deg = k * 30;
            let label = match deg {
                0 => format!("+{u}"),
                90 => format!("+{v}"),
                180 => format!("−{u}"),
                270 => format!("−{v}"),
                _ => format!("{deg}°"),
            };
            let (size, colour) = if deg % 90 == 0 {
                (22, BLACK)
            } else {
                (14, RGBColor(110, 110, 110))
            };
            let at = self.pixel(self.half + 26.0, f64::from(deg));
            let font = (FONT, size).into_font().color(&colour).pos(centred);
            root.draw(&Text::new(label, at, font))?;
        }
        Ok(())
    }

    fn draw_trace<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        t: &BallbarTrace,
        colour: RGBColor,
    ) -> DrawResult<DB> {
        let mut points: Vec<(i32, i32)> = t
            .angle_deg
            .iter()
            .zip(&t.deviation_um)
            .filter(|(a, d)| a.is_finite() && d.is_finite())
            .map(|(a, d)| self.pixel(self.nominal_px + d * self.px_per_um, *a))
            .collect();
        // A wide polyline turning back on itself (noise within a pixel or two) gets mitre joins
        // that plotters draws as long spikes; zero-length segments have no direction at all.
        // So: one point per pixel, and each segment drawn on its own, without joins.
        points.dedup();
        if let Some(&start) = points.first() {
            root.draw(&Circle::new(start, 5, colour.filled()))?;
        }
        for w in points.windows(2) {
            root.draw(&PathElement::new(w.to_vec(), colour.stroke_width(2)))?;
        }
        Ok(())
    }

    /// The legend beside the plot; returns the y pixel below it.
    fn draw_legend<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        traces: &[BallbarTrace],
    ) -> Result<i32, DrawingAreaErrorKind<DB::ErrorType>> {
        let x = 1000;
        let mut y = 120;
        root.draw(&Text::new("Traces", (x, y), (FONT, 20).into_font()))?;
        y += 36;
        for (i, t) in traces.iter().enumerate() {
            let colour = trace_colour(traces, i);
            let line = vec![(x, y + 9), (x + 34, y + 9)];
            root.draw(&PathElement::new(line, colour.stroke_width(3)))?;
            // Labels of our runs name the direction already; a CSV's may not.
            let sense = t.direction.to_uppercase();
            let text = if t.label.split_whitespace().any(|w| w == sense) {
                t.label.clone()
            } else {
                format!("{} ({sense})", t.label)
            };
            root.draw(&Text::new(text, (x + 44, y), (FONT, 16).into_font()))?;
            y += 28;
        }
        let note = "● start of a trace";
        root.draw(&Text::new(
            note,
            (x, y + 6),
            (FONT, 14).into_font().color(&RGBColor(90, 90, 90)),
        ))?;
        Ok(y + 30)
    }
}

/// Lines of text in the monospaced font, from `top_left` down.
fn draw_text_block<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    text: &str,
    top_left: (i32, i32),
) -> DrawResult<DB> {
    let (x, mut y) = top_left;
    for line in text.lines() {
        root.draw(&Text::new(line.to_string(), (x, y), (MONO, 16).into_font()))?;
        y += 24;
    }
    Ok(())
}

/// The colour of trace `i`: CCW blue and CW red when each direction appears once, otherwise a
/// palette in order.
fn trace_colour(traces: &[BallbarTrace], i: usize) -> RGBColor {
    const PALETTE: [RGBColor; 6] = [
        RGBColor(30, 80, 200),
        RGBColor(200, 30, 30),
        RGBColor(30, 150, 60),
        RGBColor(230, 130, 0),
        RGBColor(130, 50, 170),
        RGBColor(0, 150, 160),
    ];
    let dir = |t: &BallbarTrace| t.direction.to_ascii_lowercase();
    let once = |d: &str| traces.iter().filter(|t| dir(t) == d).count() == 1;
    match traces.get(i).map(dir).as_deref() {
        Some("ccw") if once("ccw") && traces.len() <= 2 => PALETTE[0],
        Some("cw") if once("cw") && traces.len() <= 2 => PALETTE[1],
        _ => PALETTE[i % PALETTE.len()],
    }
}

/// The distinct values joined by `/`, in first-seen order.
fn distinct(values: impl Iterator<Item = String>) -> String {
    let mut out: Vec<String> = Vec::new();
    for v in values {
        if !out.contains(&v) {
            out.push(v);
        }
    }
    out.join(" / ")
}

/// The smallest of 1, 2, 5 × 10ⁿ not below `x` (x > 0).
fn nice_ceil_125(x: f64) -> f64 {
    let e = 10f64.powf(x.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * e)
        .find(|v| *v >= x * (1.0 - 1e-9))
        .unwrap_or(10.0 * e)
}

/// A deviation in µm without trailing zeros: 5, 0.5, 2.5.
fn fmt_um(x: f64) -> String {
    let s = format!("{x:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}
