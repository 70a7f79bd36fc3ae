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
use vmt_logs::ballbar::largest_deviations;
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
/// division chosen from the traces without their end transients (samples beyond the outer ring
/// are drawn on it and marked ▲), the division rings, the plane's axes and angles, the traces
/// overlaid in colours (CCW blue, CW red when there is one of each) with a legend, a title with
/// the radius and feed, and `iso_figures` (e.g. the ISO 230-4 circular deviation G and
/// hysteresis H, as ready text, one figure a line) beside the plot, in a smaller font or
/// wrapped where it would not fit.
///
/// Meant for one test (its CW and CCW runs). The axis names come from the traces' plane (`XY`:
/// +X to the right, +Y up; `ZX`: +Z right, +X up; `YZ`: +Y right, +Z up), as in ISO 230-4;
/// traces of several planes get angles only. The image is [`POLAR_SIZE`] pixels. Fails when
/// there is no trace with a finite sample or the file cannot be written.
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
    /// largest deviation within three divisions either side of the nominal circle, leaving out
    /// the [`transient_deg`](vmt_ballbar::samples::transient_deg) at each end of a trace (all
    /// of a trace that short). A run without overshoot starts with the carriages' lag at its
    /// feed-in corner (150 µm in Kwon's programs), which would otherwise set a scale that
    /// hides errors of a few µm.
    fn new(traces: &[BallbarTrace]) -> Option<Self> {
        let (all, inner) = largest_deviations(traces)?;
        let max_dev = inner.unwrap_or(all);
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

    /// The largest deviation drawn where it is, µm: the outer ring.
    fn limit_um(&self) -> f64 {
        f64::from(self.divisions) * self.div_um
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
        let planes = distinct(traces.iter().map(|t| t.plane.to_uppercase()));
        self.draw_axes(root, &planes)?;
        for (i, t) in traces.iter().enumerate() {
            self.draw_trace(root, t, trace_colour(traces, i))?;
        }
        self.draw_ring_labels(root)?;
        let y = self.draw_legend(root, traces)?;
        let y = self.draw_clipped_note(root, traces, y)?;
        if let Some(text) = iso_figures {
            draw_text_block(root, text, (1000, y + 30))?;
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
        // Labels of a multi-test job start with the test's name: `step 4: XY 250 mm ...`.
        let name = distinct(traces.iter().map(|t| match t.label.split_once(": ") {
            Some((name, _)) => format!(" ({name})"),
            None => String::new(),
        }));
        let name = if name.contains(" / ") { "" } else { &name };
        let title = format!(
            "Ball-bar circular test{name}, {plane} plane: R = {radius} mm, F = {feed} mm/min"
        );
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
        // Traces of several planes (`XY / ZX`) have no common axes: angles only.
        let letters: Vec<char> = plane.to_uppercase().chars().collect();
        let axes = match letters.as_slice() {
            [u, v] => Some((*u, *v)),
            _ => None,
        };
        let centred = Pos::new(HPos::Center, VPos::Center);
        for k in 0..12 {
            let deg = k * 30;
            let label = match (deg, axes) {
                (0, Some((u, _))) => format!("+{u}"),
                (90, Some((_, v))) => format!("+{v}"),
                (180, Some((u, _))) => format!("−{u}"),
                (270, Some((_, v))) => format!("−{v}"),
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
        let limit = self.limit_um();
        let at = |a: f64, d: f64| self.pixel(self.nominal_px + d * self.px_per_um, a);
        let finite = t
            .angle_deg
            .iter()
            .zip(&t.deviation_um)
            .filter(|(a, d)| a.is_finite() && d.is_finite());
        let mut points: Vec<(i32, i32)> = finite
            .clone()
            .map(|(a, d)| at(*a, d.clamp(-limit, limit)))
            .collect();
        let mut clipped: Vec<(i32, i32)> = finite
            .filter(|(_, d)| d.abs() > limit)
            .map(|(a, d)| at(*a, d.clamp(-limit, limit)))
            .collect();
        // A wide polyline turning back on itself (noise within a pixel or two) gets mitre joins
        // that plotters draws as long spikes; zero-length segments have no direction at all.
        // So: one point per pixel, and each segment drawn on its own, without joins.
        points.dedup();
        clipped.dedup();
        if let Some(&start) = points.first() {
            root.draw(&Circle::new(start, 5, colour.filled()))?;
        }
        for w in points.windows(2) {
            root.draw(&PathElement::new(w.to_vec(), colour.stroke_width(2)))?;
        }
        for p in clipped {
            root.draw(&TriangleMarker::new(p, 7, colour.filled()))?;
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

impl Polar {
    /// Under the legend, one line per trace with samples beyond the outer ring: how many and
    /// the farthest. Returns the y pixel below the lines.
    fn draw_clipped_note<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
        traces: &[BallbarTrace],
        mut y: i32,
    ) -> Result<i32, DrawingAreaErrorKind<DB::ErrorType>> {
        let limit = self.limit_um();
        for (i, t) in traces.iter().enumerate() {
            let beyond: Vec<f64> = t
                .deviation_um
                .iter()
                .copied()
                .filter(|d| d.is_finite() && d.abs() > limit)
                .collect();
            let Some(far) = beyond
                .iter()
                .copied()
                .reduce(|a, b| if b.abs() > a.abs() { b } else { a })
            else {
                continue;
            };
            let text = format!(
                "▲ {}: {} samples beyond ±{} µm (to {far:+.1} µm)",
                t.direction.to_uppercase(),
                beyond.len(),
                fmt_um(limit)
            );
            let font = (FONT, 14).into_font().color(&trace_colour(traces, i));
            root.draw(&Text::new(text, (1000, y), font))?;
            y += 22;
        }
        Ok(y)
    }
}

/// Margin kept free at the right and bottom of an image, pixels.
const TEXT_MARGIN: i32 = 20;
/// The font sizes a text block may take, largest first, pixels.
const TEXT_SIZES: [u32; 4] = [16, 14, 12, 10];

/// Lines of text in the monospaced font, from `top_left` down, in the largest of
/// [`TEXT_SIZES`] at which they fit between `top_left` and the image's right and bottom edges:
/// lines too long for the width are wrapped at spaces (an indented continuation), and at the
/// smallest size the lines that would pass the bottom are left out, the last line saying how
/// many.
fn draw_text_block<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    text: &str,
    top_left: (i32, i32),
) -> DrawResult<DB> {
    let (w, h) = root.dim_in_pixel();
    let (width, height) = (
        w as i32 - TEXT_MARGIN - top_left.0,
        h as i32 - TEXT_MARGIN - top_left.1,
    );
    for (k, &size) in TEXT_SIZES.iter().enumerate() {
        // Ten characters measured: one alone is rounded to a whole pixel.
        let font = (MONO, size).into_font();
        let (ten, _) = root.estimate_text_size("MMMMMMMMMM", &font.clone().into())?;
        let columns = (width * 10 / (ten as i32).max(1)).max(1) as usize;
        let mut lines = wrap(text, columns);
        let step = line_step(size);
        let rows = (height / step).max(1) as usize;
        if lines.len() > rows && k + 1 < TEXT_SIZES.len() {
            continue;
        }
        if lines.len() > rows {
            let left_out = lines.len() - (rows - 1);
            lines.truncate(rows - 1);
            lines.push(format!("… {left_out} more lines"));
        }
        let (x, mut y) = top_left;
        for line in lines {
            root.draw(&Text::new(line, (x, y), (MONO, size).into_font()))?;
            y += step;
        }
        break;
    }
    Ok(())
}

/// The distance between two lines of text of `size` pixels.
fn line_step(size: u32) -> i32 {
    (size as i32 * 3 + 1) / 2
}

/// The lines of `text` wrapped at spaces to at most `columns` characters, continuations
/// indented by two spaces more than their line (a word longer than a line stays whole).
fn wrap(text: &str, columns: usize) -> Vec<String> {
    text.lines().flat_map(|l| wrap_line(l, columns)).collect()
}

fn wrap_line(line: &str, columns: usize) -> Vec<String> {
    let indent = line.len() - line.trim_start().len();
    let pad = " ".repeat((indent + 2).min(columns / 2));
    let mut out = Vec::new();
    let mut current = line[..indent].to_string();
    let mut fresh = true;
    for word in line.split_whitespace() {
        if !fresh && current.chars().count() + 1 + word.chars().count() > columns {
            out.push(std::mem::replace(&mut current, pad.clone()));
            fresh = true;
        }
        if !fresh {
            current.push(' ');
        }
        current.push_str(word);
        fresh = false;
    }
    out.push(current);
    out
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A full circle at 500 mm/min on a 150 mm bar, one sample every 0.01°: `shape` at each
    /// angle, plus a feed-in lag of 150 µm decaying over the first 0.1° (as Kwon's runs start).
    fn trace(direction: &str, shape: impl Fn(f64) -> f64) -> BallbarTrace {
        let angle_deg: Vec<f64> = (0..36_000).map(|k| f64::from(k) * 0.01).collect();
        let deviation_um = angle_deg
            .iter()
            .map(|a| shape(*a) + 150.0 * (1.0 - a / 0.1).max(0.0))
            .collect();
        BallbarTrace {
            label: format!("step 1: XY 150 mm 500 mm/min {}", direction.to_uppercase()),
            plane: "XY".into(),
            direction: direction.into(),
            radius_mm: 150.0,
            feed_mm_min: 500.0,
            times_s: Vec::new(),
            angle_deg,
            deviation_um,
        }
    }

    fn test_pair() -> Vec<BallbarTrace> {
        let ellipse = |a: f64| 8.0 * (2.0 * a.to_radians()).cos();
        vec![trace("cw", ellipse), trace("ccw", |a| -ellipse(a))]
    }

    /// The feed-in lag at a trace's start does not set the scale: the ±8 µm ellipse is shown
    /// at 5 µm/div (the lag alone would take 50 µm/div) and the lag is drawn on the ring.
    #[test]
    fn the_scale_is_set_by_the_arc_without_its_start_transient() {
        let polar = Polar::new(&test_pair()).unwrap();
        assert_eq!((polar.div_um, polar.divisions), (5.0, 2));
        assert_eq!(polar.limit_um(), 10.0);
        // Without the lag the same scale.
        let ellipse = |a: f64| 8.0 * (2.0 * a.to_radians()).cos();
        let plain = trace("cw", ellipse);
        let mut plain = plain.clone();
        plain.deviation_um = plain.angle_deg.iter().map(|a| ellipse(*a)).collect();
        assert_eq!(Polar::new(&[plain]).unwrap().div_um, 5.0);
    }

    /// A trace no longer than its two transients is scaled by all of it.
    #[test]
    fn a_trace_within_its_transients_is_scaled_by_all_its_samples() {
        let mut short = trace("cw", |_| 0.0);
        short.angle_deg.truncate(300);
        short.deviation_um.truncate(300);
        let polar = Polar::new(&[short]).unwrap();
        assert_eq!(polar.div_um, 50.0);
    }

    #[test]
    fn cw_is_red_and_ccw_blue() {
        let pair = test_pair();
        assert_eq!(trace_colour(&pair, 0), RGBColor(200, 30, 30));
        assert_eq!(trace_colour(&pair, 1), RGBColor(30, 80, 200));
    }

    #[test]
    fn long_lines_wrap_at_spaces_with_an_indented_continuation() {
        let lines = wrap("step 1: XY 150 mm:\n  span 159.80 um, mean +0.29 um", 20);
        assert_eq!(
            lines,
            [
                "step 1: XY 150 mm:",
                "  span 159.80 um,",
                "    mean +0.29 um"
            ]
        );
    }

    /// The pixels of an image of POLAR_SIZE drawn by `draw`, RGB.
    fn pixels(draw: impl Fn(&DrawingArea<BitMapBackend, Shift>)) -> Vec<u8> {
        register_font();
        register_mono_font();
        let (w, h) = POLAR_SIZE;
        let mut buffer = vec![0u8; (w * h * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut buffer, POLAR_SIZE).into_drawing_area();
            draw(&root);
            root.present().unwrap();
        }
        buffer
    }

    /// Whether any pixel in rows `rows` and columns `columns` is not white.
    fn inked(buffer: &[u8], rows: std::ops::Range<u32>, columns: std::ops::Range<u32>) -> bool {
        let w = POLAR_SIZE.0;
        rows.flat_map(|y| columns.clone().map(move |x| ((y * w + x) * 3) as usize))
            .any(|i| buffer[i..i + 3] != [255, 255, 255])
    }

    /// A text block too long for the image (Kwon's 14 traces' figures gave 28 lines) is
    /// shrunk, cut with a note, and kept off the image's right and bottom margins.
    #[test]
    fn a_long_text_block_stays_within_the_image() {
        let line = "step 1: XY 150 mm 500 mm/min CW: span 159.80 um, mean +0.29 um, 113178 samples";
        let text = vec![line; 60].join("\n");
        let (w, h) = POLAR_SIZE;
        let buffer = pixels(|root| {
            root.fill(&WHITE).unwrap();
            draw_text_block(root, &text, (1000, 300)).unwrap();
        });
        let margin = TEXT_MARGIN as u32;
        assert!(inked(&buffer, 300..h - margin, 1000..w - margin), "drawn");
        assert!(!inked(&buffer, h - margin..h, 0..w), "bottom margin");
        assert!(!inked(&buffer, 0..h, w - margin..w), "right margin");
        // A short block keeps the full size: its first line is as tall as before.
        let short = pixels(|root| {
            root.fill(&WHITE).unwrap();
            draw_text_block(root, "G CW 11.04 µm", (1000, 300)).unwrap();
        });
        let rows = (300..330)
            .filter(|y| inked(&short, *y..y + 1, 1000..w))
            .count();
        assert!(rows >= 11, "{rows} rows of a 16 px line");
    }
}
