//! A run as a [Rerun](https://rerun.io) recording (`.rrd`, Rerun 0.36): the machine's moving
//! assemblies in 3D following the servo positions, the tool path, the ball-bar traces as
//! magnified polar plots, following errors and friction forces as time series, and a viewer
//! layout (blueprint).
//!
//! # Clock and determinism
//!
//! Everything temporal is on one timeline, **`sim_time`**, a duration timeline in nanoseconds
//! from the start of the job (`round(t_s · 1e9)`). The SDK's automatic `log_time` (wall clock,
//! on by default) and `log_tick` (off by default) timelines are switched off for the recording,
//! and every temporal value is sent with `send_columns`, which never adds them. The recording id
//! is derived from the run (scenario name, seed and a hash of the scenario text and fidelity),
//! and no recording start time is sent. The *contents* are therefore a pure function of the run,
//! but the file is **not byte-identical** between two writes: Rerun stamps every chunk and row
//! with a time-ordered unique id (TUID: wall-clock nanoseconds plus a random part) and the
//! blueprint store gets a random id, and the 0.36 SDK offers no way to set those. Use the MCAP
//! writer when byte-identical files matter.
//!
//! # Entity paths
//!
//! Lengths in the 3D scene are in metres (SI), in a right-handed Z-up frame (`/machine` has
//! `ViewCoordinates::RIGHT_HAND_Z_UP`). The assemblies follow the machine's topology
//! (`run.machine.topology`, e.g. `WXYGZT`): the axes between W and G carry the workpiece and
//! move it opposite to the commanded coordinate; the axes between G and T carry the tool and move
//! it with the coordinate. Each assembly is an entity with a `Transform3D` translation over
//! `sim_time` (relative to its parent) and a static `Boxes3D`; for `WXYGZT`:
//!
//! | entity | content |
//! |---|---|
//! | `/machine/base` | static box: the bed (ground) |
//! | `/machine/y_axis` | saddle Y: `Transform3D` translation (0, −position_y, 0) per servo sample |
//! | `/machine/y_axis/x_axis` | table X: translation (−position_x, 0, 0) relative to the saddle |
//! | `/machine/y_axis/x_axis/workpiece` | static box: the workpiece; origin = workpiece zero |
//! | `/machine/y_axis/x_axis/workpiece/tool_path` | static `LineStrips3D`: (`tool_x`, `tool_y`, `tool_z`), m, in workpiece coordinates |
//! | `/machine/z_axis` | spindle head Z: translation (0, 0, +position_z) |
//! | `/machine/z_axis/tool` | static box: the tool; origin = tool point |
//! | `/machine/.../<a>_axis/deflection_x10000` | a run with a `structure` stream (the compliant plant): a wireframe copy of the carriage's box, turned about its centre by 10 000 × the carriage's tilt (`tilt_a_*`, rad, as an axis and angle) and moved by 10 000 × its offset (`offset_a_*`, m) per structure sample: 1 µm shows as 10 mm, 10 µrad as 5.7° |
//!
//! In general: `/machine/<ground-side axis>_axis/.../<workpiece-side axis>_axis/workpiece` and
//! `/machine/<ground-side axis>_axis/.../tool`, e.g. `WGXYZT` (gantry) gives
//! `/machine/workpiece` and `/machine/x_axis/y_axis/z_axis/tool`. Positions come from the
//! `servo` stream's `position_a` channels (the carriages), or `command_a` when a run has no
//! `position_a`; without a `servo` stream the machine stands at zero and there is no tool path.
//!
//! | entity | content |
//! |---|---|
//! | `/ballbar/<plane>_<radius>_mm/nominal` | static `LineStrips2D`: the nominal circle, mm |
//! | `/ballbar/<plane>_<radius>_mm/grid` | static `LineStrips2D`: circles at ±1 and ±2 divisions about the nominal, label `<d> µm/div` |
//! | `/ballbar/<plane>_<radius>_mm/<trace>` | static `LineStrips2D`: radius R + k·deviation at the bar angle, mm; label with the magnification ×(1000·k) |
//! | `/series/following_error_um/{x,y,z}` | `Scalars` over `sim_time`: following error, µm |
//! | `/series/friction_n/{guide,screw}_{x,y,z}` | `Scalars` over `sim_time`: guideway and screw friction force, N |
//! | `/series/ballbar_deviation_um/<trace>` | `Scalars` over `sim_time`: measured − nominal bar length, µm |
//! | `/series/laser_deviation_um/{forward,backward}` | `Scalars` over `sim_time`: laser deviations x_ij of an ISO 230-2 test, µm, one row per reading (at the end of its averaging window) |
//! | `/series/<stream>_<unit>/<channel>` | `Scalars` over `sim_time`: every channel of a stream other than `servo`, and the servo's `feed_override` and `spindle_rpm`, as they are: a milling run's `/series/accelerometer_m_s_2/{ax,ay,az}`, `/series/cutting_N/{fx,fy,fz}`, `/series/cutting_m/{ux,uy}`, `/series/cutting_rpm/spindle_rpm`, `/series/servo_1/feed_override`, `/series/servo_rpm/spindle_rpm`; one time-series view per stream and unit |
//! | `/info/run`, `/info/ground_truth`, `/info/scenario` | static `TextDocument` (Markdown): seed, fidelity, machine; the ground truth JSON; the scenario TOML |
//!
//! `<trace>` is the trace label as a lower-case name (`XY 150 mm 1000 mm/min CCW` ->
//! `xy_150_mm_1000_mm_min_ccw`); with several circular tests each has its own view,
//! `<n>_<plane>_<radius>_mm`. The polar plots share one magnification k (mm per µm) per
//! circular test, so that CW and CCW overlay; it is a round number chosen so that the largest
//! deviation spans about a quarter of the radius, leaving out the transients at the ends of
//! each trace as the PNG plots do (a start transient still shows, beyond the rings). The plot's y is negated because Rerun's 2D
//! views draw +y downwards (image convention): on screen the plane's second axis points up, as on
//! a ball-bar report.
//!
//! # Blueprint
//!
//! The Rust SDK 0.36 sends blueprints (`rerun::blueprint`: containers, the 3D, 2D, time-series
//! and text views, the time panel). The layout: left, the 3D machine above tabs with the run
//! information, ground truth and scenario; right, the polar plots (one tab per plane and
//! radius), following errors, friction forces and ball-bar deviations over time; the time panel
//! on `sim_time`. What the Rust blueprint API of 0.36 lacks compared with Python's: view
//! properties of the spatial and time-series views (background, line grid, eye controls, visual
//! bounds, axis ranges, legend position) and visible time ranges; it has only per-view
//! `defaults` and visualizer overrides. The entity paths are laid out so that the viewer's own
//! heuristics give much the same views when the blueprint is reset.

use super::{
    Partial, RunFile, atomically, check_stream, check_trace, slug, unique_slugs, write_whole,
};
use crate::error::FileError;
use rerun::blueprint::{
    Blueprint, ContainerLike, Horizontal, Spatial2DView, Spatial3DView, Tabs, TextDocumentView,
    TimePanel, TimeSeriesView, Vertical,
};
use rerun::components::FillMode;
use rerun::{
    Boxes3D, Color, LineStrips2D, LineStrips3D, RecordingStream, Scalars, SerializationResult,
    SerializedComponentColumn, SeriesLines, TextDocument, TimeColumn, Transform3D, ViewCoordinates,
};
use std::hash::{DefaultHasher, Hash, Hasher};
use std::ops::Range;
use std::path::Path;
use vmt_model::Axis;
use vmt_model::kinematics::{Element, Topology};
use vmt_sim::run::{BallbarTrace, Channel, LaserReading, LaserRun, MachineSummary, Run, Stream};

/// Name of the timeline of simulation time.
pub const TIMELINE: &str = "sim_time";

/// The magnification of the carriages' tilts and offsets in the 3D scene (the compliant plant's
/// µrad and µm would not show at 1:1 on carriages of hundreds of mm).
pub const DEFLECTION_MAGNIFICATION: f64 = 1e4;

/// Application id of the recordings.
pub const APPLICATION_ID: &str = "vmt";

/// Rows of a time series sent to the recording at a time: small enough that a long run is
/// never converted to Arrow whole, large enough to cost nothing per row (the format tests'
/// 18 850-row streams go in three blocks).
const SERIES_BLOCK: usize = 8192;

/// Writes `run` to the Rerun recording `path` (written as `<path>.partial`
/// and renamed when complete) with the entities and the
/// blueprint listed in the [module documentation](self); the timeline is `sim_time`.
///
/// Fails when the topology is not one of the 24, when a stream or trace is inconsistent, when a
/// sample time is not finite or beyond ±292 years, or when the file cannot be written.
pub fn write_rrd(run: &Run, path: &Path) -> Result<(), FileError> {
    write_whole::<RrdFile>(run, path)
}

/// A Rerun recording of a run written while its job runs: the layout, the machine and the
/// series' styles when it is created, the motion and the series block by block, the tool path,
/// polar plots, laser series and ground truth at the end. Written as `<path>.partial` and
/// renamed when finished; removed if dropped unfinished (an error).
pub struct RrdFile {
    // Declared before `partial`: closed before the partial file is removed.
    rec: RecordingStream,
    partial: Partial,
    groups: Vec<PolarGroup>,
    slugs: Vec<String>,
    layout: Layout,
    /// The tool path so far (it is drawn whole, as one static strip, at the end).
    tool_path: Vec<[f32; 3]>,
    /// Rows of each stream (by name) and samples of each trace sent so far (errors give a
    /// row's index in the whole run).
    sent: (std::collections::BTreeMap<String, usize>, Vec<usize>),
    /// The series of the streams' other channels ([`other_series`]).
    others: Vec<OtherSeries>,
}

/// A channel plotted as it is, outside the servo series of following errors and friction (a
/// milling run's accelerometers, cutting forces, tool deflection, spindle speed and feed
/// override): its stream, channel, entity, and the view that groups it with the stream's
/// channels of the same unit.
struct OtherSeries {
    stream: String,
    channel: String,
    entity: String,
    view: (String, String),
}

/// The channels of `streams` that [`OtherSeries`] plots: every channel of a stream other than
/// `servo`, and the servo's feed override and spindle speed. Grouped by stream and unit:
/// `/series/<stream>_<unit>/<channel>`, one view each titled `<stream> (<unit>)`.
fn other_series(streams: &[Stream]) -> Vec<OtherSeries> {
    let mut out = Vec::new();
    for s in streams {
        let plotted = |c: &Channel| {
            s.name != "servo" || matches!(c.name.as_str(), "feed_override" | "spindle_rpm")
        };
        for c in s.channels.iter().filter(|c| plotted(c)) {
            // The unit as written (N and n differ), made a path part.
            let unit: String = c
                .unit
                .chars()
                .map(|ch| if ch.is_ascii_alphanumeric() { ch } else { '_' })
                .collect();
            let origin = format!("/series/{}_{unit}", slug(&s.name));
            out.push(OtherSeries {
                stream: s.name.clone(),
                channel: c.name.clone(),
                entity: format!("{origin}/{}", slug(&c.name)),
                view: (format!("{} ({})", s.name, c.unit), origin),
            });
        }
    }
    out
}

impl RunFile for RrdFile {
    /// Creates the recording with its blueprint, information, machine and series styles.
    fn create(path: &Path, opening: &Run) -> Result<Self, FileError> {
        let topology: Topology = opening
            .machine
            .topology
            .parse()
            .map_err(|e| FileError::output(path, e))?;
        let partial = Partial::new(path);
        let groups = polar_groups(&opening.ballbar);
        let others = other_series(&opening.streams);
        let mut views: Vec<(String, String)> = Vec::new();
        for o in &others {
            if !views.contains(&o.view) {
                views.push(o.view.clone());
            }
        }
        let rec = rerun::RecordingStreamBuilder::new(APPLICATION_ID)
            .recording_id(recording_id(opening))
            .enabled(true)
            .with_blueprint(blueprint(
                &groups,
                &views,
                !opening.ballbar.is_empty(),
                opening.laser.is_some(),
            ))
            .save(partial.path())
            .map_err(|e| FileError::output(path, e))?;
        rec.set_log_time_enabled(false);
        rec.set_log_tick_enabled(false);
        let file = Self {
            rec,
            partial,
            groups,
            slugs: unique_slugs(opening.ballbar.iter().map(|t| t.label.as_str())),
            layout: Layout::new(&opening.machine, topology),
            tool_path: Vec::new(),
            sent: (
                std::collections::BTreeMap::new(),
                vec![0; opening.ballbar.len()],
            ),
            others,
        };
        let log = file.logger();
        log.info(opening)?;
        log.machine(&file.layout)?;
        if structure(&opening.streams).is_some() {
            log.deflection_boxes(&file.layout)?;
        }
        if let Some(servo) = servo(&opening.streams) {
            log.servo_styles(servo)?;
        }
        for (k, o) in file.others.iter().enumerate() {
            let name = format!("{} ({})", o.channel, o.view.0);
            // An axis' channel (ax, fy, ux...) in the axis' colour, as the servo series.
            let colour = match o.channel.chars().last() {
                Some(a @ ('x' | 'y' | 'z')) if o.channel.len() == 2 => axis_colour(&a.to_string()),
                _ => palette(k),
            };
            log.style(&o.entity, &name, colour)?;
        }
        for (t, slug) in opening.ballbar.iter().zip(&file.slugs) {
            log.style(
                &deviation_entity(slug),
                &format!("{} (µm)", t.label),
                direction_colour(t),
            )?;
        }
        Ok(file)
    }

    /// Sends the block's rows and samples and waits for them to be written.
    fn block(&mut self, streams: &[Stream], traces: &[BallbarTrace]) -> Result<(), FileError> {
        if let Some(servo) = servo(streams) {
            extend_tool_path(&mut self.tool_path, servo);
        }
        let log = self.logger();
        streams.iter().try_for_each(|s| check_stream(s, log.path))?;
        traces.iter().try_for_each(|t| check_trace(t, log.path))?;
        if let Some(servo) = servo(streams) {
            let first = self.rows_sent(servo);
            for (entity, axis, sign) in &self.layout.carriages {
                log.carriage_motion(entity, servo, first, *axis, *sign)?;
            }
            log.servo_series(servo, first)?;
        }
        if let Some(st) = structure(streams) {
            let first = self.rows_sent(st);
            for (entity, axis, part) in self.layout.carriage_parts() {
                log.carriage_deflection(entity, part.centre, st, first, axis)?;
            }
        }
        for s in streams {
            let first = self.rows_sent(s);
            for o in self.others.iter().filter(|o| o.stream == s.name) {
                let Some(c) = s.channel(&o.channel) else {
                    continue;
                };
                log.send_blocks(&o.entity, (&s.times_s, first), &o.entity, |rows| {
                    Scalars::new(rows.map(|i| c.values[i])).columns_of_unit_batches()
                })?;
            }
        }
        for ((t, slug), &first) in traces.iter().zip(&self.slugs).zip(&self.sent.1) {
            let value = |i: usize| t.deviation_um[i];
            let series = (&t.times_s[..], first);
            log.send_blocks(&deviation_entity(slug), series, &t.label, |rows| {
                Scalars::new(rows.map(value)).columns_of_unit_batches()
            })?;
        }
        // Waits for the block to be on disk: the SDK would otherwise buffer up to 100 MB ahead
        // of a slow disk, and a file sink that has failed shows only here (its own error goes
        // to the log, not to us).
        flush(&self.rec).map_err(|e| log.err(e))?;
        for s in streams {
            *self.sent.0.entry(s.name.clone()).or_insert(0) += s.times_s.len();
        }
        for (sent, t) in self.sent.1.iter_mut().zip(traces) {
            *sent += t.times_s.len();
        }
        Ok(())
    }

    /// Logs what needs the finished `run` (the tool path, the polar plots of its traces, its
    /// laser readings and ground truth) and completes the file.
    fn complete(self, run: &Run) -> Result<Partial, FileError> {
        let log = self.logger();
        if !self.tool_path.is_empty() {
            let strip = LineStrips3D::new([&self.tool_path])
                .with_colors([Color::from_rgb(20, 20, 20)])
                .with_radii([rerun::Radius::new_ui_points(1.0)])
                .with_labels(["tool path (tool_x, tool_y, tool_z)"]);
            log.log_static(format!("{}/tool_path", self.layout.workpiece), &strip)?;
        }
        for g in &self.groups {
            log.polar(g, &run.ballbar, &self.slugs)?;
        }
        if let Some(l) = &run.laser {
            log.laser_series(l)?;
        }
        log.ground_truth(&run.ground_truth)?;
        flush(&self.rec).map_err(|e| log.err(e))?;
        // Completes the file (footer with the chunk manifest) before it is renamed.
        self.rec.finalize_deferred_sinks();
        let Self { rec, partial, .. } = self;
        drop(rec);
        Ok(partial)
    }
}

impl RrdFile {
    /// Rows of `stream` sent before this block.
    fn rows_sent(&self, stream: &Stream) -> usize {
        self.sent.0.get(&stream.name).copied().unwrap_or(0)
    }

    fn logger(&self) -> Logger<'_> {
        Logger {
            rec: &self.rec,
            path: self.partial.target(),
        }
    }
}

/// The `servo` stream of `streams`, if there is one.
fn servo(streams: &[Stream]) -> Option<&Stream> {
    streams.iter().find(|s| s.name == "servo")
}

/// The compliant plant's `structure` stream, if the run has one.
fn structure(streams: &[Stream]) -> Option<&Stream> {
    streams.iter().find(|s| s.name == "structure")
}

/// The entity of a carriage's magnified deflection.
fn deflection_entity(carriage: &str) -> String {
    format!("{carriage}/deflection_x{DEFLECTION_MAGNIFICATION}")
}

/// The finite points of the servo stream's `tool_x`, `tool_y`, `tool_z` appended to `path`.
fn extend_tool_path(path: &mut Vec<[f32; 3]>, servo: &Stream) {
    let (Some(x), Some(y), Some(z)) = (
        servo.channel("tool_x"),
        servo.channel("tool_y"),
        servo.channel("tool_z"),
    ) else {
        return;
    };
    let points = (x.values.iter().zip(&y.values).zip(&z.values))
        .filter(|((x, y), z)| x.is_finite() && y.is_finite() && z.is_finite())
        .map(|((x, y), z)| [*x as f32, *y as f32, *z as f32]);
    path.extend(points);
}

fn deviation_entity(slug: &str) -> String {
    format!("/series/ballbar_deviation_um/{slug}")
}

/// A recording id that depends only on the run: `vmt-<scenario>-<seed>-<hash>`.
fn recording_id(run: &Run) -> String {
    let mut h = DefaultHasher::new();
    run.scenario_toml.hash(&mut h);
    run.fidelity.hash(&mut h);
    run.machine.topology.hash(&mut h);
    format!(
        "vmt-{}-{}-{:016x}",
        slug(&run.scenario_name),
        run.seed,
        h.finish()
    )
}

/// The ball-bar traces of one circular test (its CW and CCW runs): drawn in one polar plot
/// with one magnification.
struct PolarGroup {
    /// Entity name, e.g. `xy_150_mm`, or `3_xy_100_mm` for the third of several tests.
    name: String,
    /// Title, e.g. `Ball bar XY 150 mm`, or `Ball bar 3: XY 100 mm`.
    title: String,
    /// Nominal radius, mm.
    radius_mm: f64,
    /// Indices of the traces in `run.ballbar`.
    traces: Vec<usize>,
}

/// One group per circular test, the tests numbered as `vmt diagnose` and the polar PNGs
/// number them ([`crate::ballbar::run_tests`]); a single test keeps the plain name.
fn polar_groups(traces: &[BallbarTrace]) -> Vec<PolarGroup> {
    let tests = crate::ballbar::run_tests(traces);
    let several = tests.len() > 1;
    let mut first = 0;
    let mut groups = Vec::with_capacity(tests.len());
    for (k, test) in tests.iter().enumerate() {
        let t = &test[0];
        let what = format!("{} {} mm", t.plane.to_uppercase(), t.radius_mm);
        let (name, title) = if several {
            let n = k + 1;
            (
                slug(&format!("{n} {what}")),
                format!("Ball bar {n}: {what}"),
            )
        } else {
            (slug(&what), format!("Ball bar {what}"))
        };
        groups.push(PolarGroup {
            name,
            title,
            radius_mm: t.radius_mm,
            traces: (first..first + test.len()).collect(),
        });
        first += test.len();
    }
    groups
}

fn blueprint(
    groups: &[PolarGroup],
    others: &[(String, String)],
    has_ballbar: bool,
    has_laser: bool,
) -> Blueprint {
    let info = Tabs::new([
        TextDocumentView::new("Run").with_origin("/info/run").into(),
        TextDocumentView::new("Ground truth")
            .with_origin("/info/ground_truth")
            .into(),
        TextDocumentView::new("Scenario")
            .with_origin("/info/scenario")
            .into(),
    ]);
    let left = Vertical::new([
        Spatial3DView::new("Machine").with_origin("/machine").into(),
        info.into(),
    ])
    .with_row_shares(vec![3.0_f32, 1.0]);
    let mut right: Vec<ContainerLike> = Vec::new();
    if !groups.is_empty() {
        let polar = groups.iter().map(|g| {
            Spatial2DView::new(g.title.clone())
                .with_origin(format!("/ballbar/{}", g.name))
                .into()
        });
        right.push(Tabs::new(polar).into());
    }
    right.push(
        TimeSeriesView::new("Following error (µm)")
            .with_origin("/series/following_error_um")
            .into(),
    );
    right.push(
        TimeSeriesView::new("Friction force (N)")
            .with_origin("/series/friction_n")
            .into(),
    );
    if has_ballbar {
        right.push(
            TimeSeriesView::new("Ball-bar deviation (µm)")
                .with_origin("/series/ballbar_deviation_um")
                .into(),
        );
    }
    if has_laser {
        right.push(
            TimeSeriesView::new("Laser deviation (µm)")
                .with_origin("/series/laser_deviation_um")
                .into(),
        );
    }
    for (title, origin) in others {
        right.push(
            TimeSeriesView::new(title.clone())
                .with_origin(origin.clone())
                .into(),
        );
    }
    let shares: Vec<f32> = (0..right.len())
        .map(|k| {
            if k == 0 && !groups.is_empty() {
                2.0
            } else {
                1.0
            }
        })
        .collect();
    let right = Vertical::new(right).with_row_shares(shares);
    Blueprint::new(
        Horizontal::new([left.into(), right.into()]).with_column_shares(vec![3.0_f32, 2.0]),
    )
    .with_time_panel(TimePanel::new().with_timeline(TIMELINE))
}

/// Logs the parts of a run to one recording stream.
struct Logger<'a> {
    rec: &'a RecordingStream,
    path: &'a Path,
}

/// How long a flush waits for the file writer. A block takes milliseconds on a local disk, but
/// Rerun's file writer, once a write has failed (a full disk, a file-size limit), stops with
/// its error in its own log and leaves a flush queued behind it waiting for ever.
const FLUSH_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(60);

/// Why a recording could not be flushed to its file.
#[derive(Debug, thiserror::Error)]
enum FlushError {
    #[error(
        "the Rerun file writer took nothing for {} s: it stops on a write error (a full disk, a file-size limit), which Rerun reports only to its log",
        FLUSH_TIMEOUT.as_secs()
    )]
    Stalled,
    #[error(transparent)]
    Sink(rerun::sink::SinkFlushError),
}

/// Flushes `rec` to its file within [`FLUSH_TIMEOUT`].
fn flush(rec: &rerun::RecordingStream) -> Result<(), FlushError> {
    match rec.flush_with_timeout(FLUSH_TIMEOUT) {
        Ok(()) => Ok(()),
        Err(rerun::sink::SinkFlushError::Timeout) => {
            // Dropping the stream would join its thread, which waits on the dead writer for
            // ever: the stalled stream is left to the end of the process instead.
            std::mem::forget(rec.clone());
            Err(FlushError::Stalled)
        }
        Err(e) => Err(FlushError::Sink(e)),
    }
}

impl Logger<'_> {
    fn err(&self, e: impl std::error::Error) -> FileError {
        FileError::output(self.path, e)
    }

    fn log_static(
        &self,
        entity: impl Into<rerun::EntityPath>,
        what: &dyn rerun::AsComponents,
    ) -> Result<(), FileError> {
        self.rec.log_static(entity, what).map_err(|e| self.err(e))
    }

    /// The run's and the scenario's text documents.
    fn info(&self, run: &Run) -> Result<(), FileError> {
        let m = &run.machine;
        let text = format!(
            "# {}\n\n| | |\n|---|---|\n| scenario | {} |\n| seed | {} |\n| fidelity | {} |\n\
             | machine | {} |\n| topology | {} |\n| strokes X, Y, Z (m) | {:?} |\n\
             | tool length (m) | {} |\n| timeline | `{TIMELINE}`: simulation time |\n",
            run.scenario_name,
            run.scenario_name,
            run.seed,
            run.fidelity,
            m.name,
            m.topology,
            m.strokes_m,
            m.tool_length_m
        );
        self.log_static("/info/run", &TextDocument::from_markdown(text))?;
        self.log_static(
            "/info/scenario",
            &TextDocument::from_markdown(format!(
                "# Scenario\n\n```toml\n{}\n```\n",
                run.scenario_toml
            )),
        )
    }

    fn ground_truth(&self, truth: &serde_json::Value) -> Result<(), FileError> {
        let truth = serde_json::to_string_pretty(truth).unwrap_or_default();
        self.log_static(
            "/info/ground_truth",
            &TextDocument::from_markdown(format!("# Ground truth\n\n```json\n{truth}\n```\n")),
        )
    }

    /// The machine's assemblies as static boxes.
    fn machine(&self, layout: &Layout) -> Result<(), FileError> {
        self.log_static("/machine", &ViewCoordinates::RIGHT_HAND_Z_UP())?;
        for part in &layout.parts {
            let boxes = Boxes3D::from_centers_and_sizes([part.centre], [part.size])
                .with_colors([part.colour])
                .with_fill_mode(part.fill)
                .with_labels([part.label.clone()]);
            self.log_static(part.entity.clone(), &boxes)?;
        }
        Ok(())
    }

    /// A wireframe copy of each carriage's box, centred on its entity's origin, which
    /// [`Logger::carriage_deflection`] moves.
    fn deflection_boxes(&self, layout: &Layout) -> Result<(), FileError> {
        for (entity, axis, part) in layout.carriage_parts() {
            let boxes = Boxes3D::from_centers_and_sizes([[0.0; 3]], [part.size])
                .with_colors([scale(part.colour, 0.6)])
                .with_fill_mode(FillMode::MajorWireframe)
                .with_labels([format!(
                    "{} carriage: tilt and offset x{DEFLECTION_MAGNIFICATION}",
                    axis.letter()
                )]);
            self.log_static(deflection_entity(entity), &boxes)?;
        }
        Ok(())
    }

    /// A carriage's tilt and offset over time, magnified ([`DEFLECTION_MAGNIFICATION`]): the
    /// copy of its box turned about its centre (`centre`, in the carriage entity's frame) and
    /// moved from it.
    fn carriage_deflection(
        &self,
        entity: &str,
        centre: [f32; 3],
        structure: &Stream,
        first_row: usize,
        axis: Axis,
    ) -> Result<(), FileError> {
        let a = axis.letter().to_ascii_lowercase();
        let channels = |kind: &str| -> Option<[&Channel; 3]> {
            let [x, y, z] = ["x", "y", "z"].map(|c| structure.channel(&format!("{kind}_{a}_{c}")));
            Some([x?, y?, z?])
        };
        let (Some(tilt), Some(offset)) = (channels("tilt"), channels("offset")) else {
            return Ok(());
        };
        let k = DEFLECTION_MAGNIFICATION;
        self.send_blocks(
            &deflection_entity(entity),
            (&structure.times_s, first_row),
            &structure.name,
            |rows| {
                let translations = rows.clone().map(|i| {
                    std::array::from_fn::<f32, 3, _>(|c| {
                        centre[c] + (k * offset[c].values[i]) as f32
                    })
                });
                let rotations = rows.map(|i| {
                    let t = [0, 1, 2].map(|c| k * tilt[c].values[i]);
                    let angle = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
                    let axis = if angle > 0.0 {
                        t.map(|v| (v / angle) as f32)
                    } else {
                        [0.0, 0.0, 1.0]
                    };
                    rerun::RotationAxisAngle::new(axis, rerun::Angle::from_radians(angle as f32))
                });
                Transform3D::update_fields()
                    .with_many_translation(translations)
                    .with_many_rotation_axis_angle(rotations)
                    .columns_of_unit_batches()
            },
        )
    }

    /// The translation of a carriage over time: `sign · position_a` along its axis.
    fn carriage_motion(
        &self,
        entity: &str,
        servo: &Stream,
        first_row: usize,
        axis: Axis,
        sign: f64,
    ) -> Result<(), FileError> {
        let a = axis.letter().to_ascii_lowercase();
        let Some(ch) = servo
            .channel(&format!("position_{a}"))
            .or_else(|| servo.channel(&format!("command_{a}")))
        else {
            return Ok(());
        };
        let k = axis.index();
        self.send_blocks(entity, (&servo.times_s, first_row), &servo.name, |rows| {
            let translations = ch.values[rows].iter().map(|&p| {
                let mut v = [0.0_f32; 3];
                v[k] = (sign * p) as f32;
                v
            });
            Transform3D::update_fields()
                .with_many_translation(translations)
                .columns_of_unit_batches()
        })
    }

    /// Sends the rows of `entity` at the times `times_s` ([`SERIES_BLOCK`] rows at a time, so
    /// that a long run is not converted to Arrow all at once: a 17-minute job logged at 1 kHz
    /// has a million rows per entity), with the columns `columns` makes of each block of rows;
    /// `first_row` is the index of the first of `times_s` in the whole run (for errors).
    fn send_blocks<C: IntoIterator<Item = SerializedComponentColumn>>(
        &self,
        entity: &str,
        (times_s, first_row): (&[f64], usize),
        what: &str,
        columns: impl Fn(Range<usize>) -> SerializationResult<C>,
    ) -> Result<(), FileError> {
        for first in (0..times_s.len()).step_by(SERIES_BLOCK) {
            let rows = first..(first + SERIES_BLOCK).min(times_s.len());
            let time = self.time_column(&times_s[rows.clone()], first_row + first, what)?;
            let columns = columns(rows).map_err(|e| self.err(e))?;
            self.rec
                .send_columns(entity, [time], columns)
                .map_err(|e| self.err(e))?;
        }
        Ok(())
    }

    /// `times_s` as a `sim_time` column in integer nanoseconds.
    fn time_column(
        &self,
        times_s: &[f64],
        first: usize,
        what: &str,
    ) -> Result<TimeColumn, FileError> {
        let mut nanos = Vec::with_capacity(times_s.len());
        for (i, &t) in (first..).zip(times_s) {
            let ns = (t * 1e9).round();
            // i64::MIN is reserved by Rerun; keep well inside the range.
            if !(ns.is_finite() && ns.abs() < 9.2e18) {
                return Err(FileError::output_message(
                    self.path,
                    format!("`{what}`, sample {i}: time {t} s is not a finite simulation time"),
                ));
            }
            nanos.push(ns as i64);
        }
        Ok(TimeColumn::new_duration_nanos(TIMELINE, nanos))
    }

    /// The name and colour of the series `entity`.
    fn style(&self, entity: &str, name: &str, colour: Color) -> Result<(), FileError> {
        self.log_static(
            entity,
            &SeriesLines::new().with_names([name]).with_colors([colour]),
        )
    }

    /// One scalar series over time, with its name and colour.
    fn series(
        &self,
        entity: &str,
        name: &str,
        colour: Color,
        times_s: &[f64],
        value: impl Fn(usize) -> f64,
    ) -> Result<(), FileError> {
        self.style(entity, name, colour)?;
        self.send_blocks(entity, (times_s, 0), entity, |rows| {
            Scalars::new(rows.map(&value)).columns_of_unit_batches()
        })
    }

    /// The servo series of `servo`'s channels: entity, name, colour and channel of each.
    fn servo_channels(servo: &Stream) -> Vec<(String, String, Color, &Channel)> {
        let mut out = Vec::new();
        for axis in ["x", "y", "z"] {
            let colour = axis_colour(axis);
            if let Some(c) = servo.channel(&format!("following_error_{axis}")) {
                out.push((
                    format!("/series/following_error_um/{axis}"),
                    format!("following error {axis} (µm)"),
                    colour,
                    c,
                ));
            }
            for (kind, shade) in [("guide", 1.0), ("screw", 0.6)] {
                if let Some(c) = servo.channel(&format!("{kind}_friction_{axis}")) {
                    out.push((
                        format!("/series/friction_n/{kind}_{axis}"),
                        format!("{kind} friction {axis} (N)"),
                        scale(colour, shade),
                        c,
                    ));
                }
            }
        }
        out
    }

    fn servo_styles(&self, servo: &Stream) -> Result<(), FileError> {
        for (entity, name, colour, _) in Self::servo_channels(servo) {
            self.style(&entity, &name, colour)?;
        }
        Ok(())
    }

    /// The following errors (µm) and friction forces (N) of the rows of `servo`, the first of
    /// them row `first_row` of the run.
    fn servo_series(&self, servo: &Stream, first_row: usize) -> Result<(), FileError> {
        for (entity, _, _, c) in Self::servo_channels(servo) {
            let k = if entity.starts_with("/series/following_error_um") {
                1e6
            } else {
                1.0
            };
            self.send_blocks(&entity, (&servo.times_s, first_row), &entity, |rows| {
                Scalars::new(rows.map(|i| c.values[i] * k)).columns_of_unit_batches()
            })?;
        }
        Ok(())
    }

    /// The laser deviations over time, one series per direction of approach.
    fn laser_series(&self, l: &LaserRun) -> Result<(), FileError> {
        for (dir, colour) in [
            ("forward", Color::from_rgb(30, 80, 200)),
            ("backward", Color::from_rgb(200, 30, 30)),
        ] {
            let mine: Vec<&LaserReading> =
                l.readings.iter().filter(|r| r.direction == dir).collect();
            if mine.is_empty() {
                continue;
            }
            let entity = format!("/series/laser_deviation_um/{dir}");
            let name = format!("{} {dir} deviation (µm)", l.axis);
            let times: Vec<f64> = mine.iter().map(|r| r.time_s).collect();
            let value = |i: usize| mine[i].deviation_um;
            self.series(&entity, &name, colour, &times, value)?;
        }
        Ok(())
    }

    fn polar(
        &self,
        g: &PolarGroup,
        traces: &[BallbarTrace],
        slugs: &[String],
    ) -> Result<(), FileError> {
        let scale = PolarScale::new(g.radius_mm, group_deviation_um(g, traces));
        let base = format!("/ballbar/{}", g.name);
        let nominal = circle(g.radius_mm);
        let label = format!(
            "nominal R = {} mm; deviations ×{} ({} µm/div)",
            g.radius_mm,
            fmt_num(scale.k_mm_per_um * 1e3),
            fmt_num(scale.div_um)
        );
        self.log_static(
            format!("{base}/nominal"),
            &LineStrips2D::new([nominal])
                .with_colors([Color::from_rgb(90, 90, 90)])
                .with_labels([label]),
        )?;
        let rings: Vec<Vec<[f32; 2]>> = [-2.0, -1.0, 1.0, 2.0]
            .iter()
            .map(|j| circle(g.radius_mm + j * scale.div_um * scale.k_mm_per_um))
            .collect();
        self.log_static(
            format!("{base}/grid"),
            &LineStrips2D::new(rings)
                .with_colors([Color::from_rgb(200, 200, 200)])
                .with_labels([format!("{} µm/div", fmt_num(scale.div_um))]),
        )?;
        for &i in &g.traces {
            let t = &traces[i];
            let strip = polar_strip(t, &scale);
            let label = format!("{} ×{}", t.label, fmt_num(scale.k_mm_per_um * 1e3));
            self.log_static(
                format!("{base}/{}", slugs[i]),
                &LineStrips2D::new([strip])
                    .with_colors([direction_colour(t)])
                    .with_labels([label]),
            )?;
        }
        Ok(())
    }
}

/// The deviation (µm) a test's polar view is scaled for: its traces' largest, without the
/// transients at their ends, as the PNG plots are scaled (a run without overshoot, as in
/// Kwon's steps, starts with 150 µm of lag that had set a scale hiding errors of a few µm).
fn group_deviation_um(g: &PolarGroup, traces: &[BallbarTrace]) -> f64 {
    crate::ballbar::largest_deviations(g.traces.iter().map(|&i| &traces[i]))
        .map_or(0.0, |(all, inner)| inner.unwrap_or(all))
}

/// The magnification of a polar plot.
struct PolarScale {
    /// Nominal radius, mm.
    radius_mm: f64,
    /// Plotted millimetres per micrometre of deviation.
    k_mm_per_um: f64,
    /// One division of the grid, µm.
    div_um: f64,
}

impl PolarScale {
    /// A round magnification that draws `max_dev_um` at about a quarter of the radius, and a
    /// round division of about half the largest deviation.
    fn new(radius_mm: f64, max_dev_um: f64) -> Self {
        let max_dev = if max_dev_um > 1e-6 { max_dev_um } else { 1.0 };
        let r = if radius_mm.is_finite() && radius_mm > 0.0 {
            radius_mm
        } else {
            1.0
        };
        PolarScale {
            radius_mm: r,
            k_mm_per_um: nice_floor(0.25 * r / max_dev),
            div_um: nice_ceil(max_dev / 2.0),
        }
    }

    /// The plotted point of a deviation at an angle, mm, with y negated for Rerun's 2D views.
    fn point(&self, angle_deg: f64, deviation_um: f64) -> [f32; 2] {
        let rho = self.radius_mm + self.k_mm_per_um * deviation_um;
        let a = angle_deg.to_radians();
        [(rho * a.cos()) as f32, (-rho * a.sin()) as f32]
    }
}

/// The largest of 1, 2, 5 × 10ⁿ not above `x` (x > 0).
pub(crate) fn nice_floor(x: f64) -> f64 {
    let e = 10f64.powf(x.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * e)
        .find(|v| *v <= x * (1.0 + 1e-9))
        .unwrap_or(e)
}

/// The smallest of 1, 2, 5 × 10ⁿ not below `x` (x > 0).
pub(crate) fn nice_ceil(x: f64) -> f64 {
    let e = 10f64.powf(x.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * e)
        .find(|v| *v >= x * (1.0 - 1e-9))
        .unwrap_or(10.0 * e)
}

/// A number without trailing zeros: 3000, 0.5, 2.5.
fn fmt_num(x: f64) -> String {
    let s = format!("{x:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

fn polar_strip(t: &BallbarTrace, scale: &PolarScale) -> Vec<[f32; 2]> {
    t.angle_deg
        .iter()
        .zip(&t.deviation_um)
        .filter(|(a, d)| a.is_finite() && d.is_finite())
        .map(|(a, d)| scale.point(*a, *d))
        .collect()
}

/// A circle of radius `r` (mm) in 1° steps, y negated like the traces.
fn circle(r: f64) -> Vec<[f32; 2]> {
    (0..=360)
        .map(|d| {
            let a = f64::from(d).to_radians();
            [(r * a.cos()) as f32, (-r * a.sin()) as f32]
        })
        .collect()
}

fn axis_colour(axis: &str) -> Color {
    match axis {
        "x" => Color::from_rgb(214, 39, 40),
        "y" => Color::from_rgb(44, 160, 44),
        _ => Color::from_rgb(31, 119, 180),
    }
}

/// The `k`-th colour of a small qualitative palette (Tableau 10).
fn palette(k: usize) -> Color {
    const P: [[u8; 3]; 6] = [
        [214, 39, 40],
        [44, 160, 44],
        [31, 119, 180],
        [255, 127, 14],
        [148, 103, 189],
        [140, 86, 75],
    ];
    let [r, g, b] = P[k % P.len()];
    Color::from_rgb(r, g, b)
}

fn scale(c: Color, s: f64) -> Color {
    let [r, g, b, _] = c.to_array();
    let f = |v: u8| (f64::from(v) * s).round().clamp(0.0, 255.0) as u8;
    Color::from_rgb(f(r), f(g), f(b))
}

/// Blue for CCW, red for CW (as the PNG plot).
fn direction_colour(t: &BallbarTrace) -> Color {
    if t.direction.eq_ignore_ascii_case("cw") {
        Color::from_rgb(200, 30, 30)
    } else {
        Color::from_rgb(30, 80, 200)
    }
}

/// One static box of the machine picture.
struct Part {
    entity: String,
    label: String,
    centre: [f32; 3],
    size: [f32; 3],
    colour: Color,
    fill: FillMode,
}

/// The machine picture: boxes, moving carriages and the workpiece entity.
struct Layout {
    parts: Vec<Part>,
    /// (entity, axis, sign of its translation relative to the commanded coordinate).
    carriages: Vec<(String, Axis, f64)>,
    /// Entity of the workpiece.
    workpiece: String,
}

/// Strokes of a machine: middle and length of each axis, m.
struct Strokes {
    mid: [f64; 3],
    len: [f64; 3],
    min: [f64; 3],
}

impl Strokes {
    fn new(m: &MachineSummary) -> Self {
        let ok = |v: f64| if v.is_finite() { v } else { 0.0 };
        let min = m.strokes_m.map(|[a, b]| ok(a.min(b)));
        let max = m.strokes_m.map(|[a, b]| ok(a.max(b)));
        Strokes {
            mid: std::array::from_fn(|k| 0.5 * (min[k] + max[k])),
            len: std::array::from_fn(|k| (max[k] - min[k]).max(0.05)),
            min,
        }
    }
}

impl Layout {
    /// Each carriage's entity and axis with its box.
    fn carriage_parts(&self) -> impl Iterator<Item = (&str, Axis, &Part)> {
        self.carriages.iter().filter_map(|(entity, axis, _)| {
            let part = self.parts.iter().find(|p| &p.entity == entity)?;
            Some((entity.as_str(), *axis, part))
        })
    }

    /// The assemblies of `topology` as nested entities, their boxes placed so that with every
    /// axis at mid-stroke the stack under the workpiece and the head above the tool line up.
    fn new(m: &MachineSummary, topology: Topology) -> Self {
        let st = Strokes::new(m);
        let tool_len = if m.tool_length_m.is_finite() && m.tool_length_m > 0.0 {
            m.tool_length_m
        } else {
            0.1
        };
        let g = topology.ground_index();
        let chain = topology.chain();
        let axis_of = |e: &Element| match e {
            Element::Axis(a) => Some(*a),
            _ => None,
        };
        // Workpiece side from the ground outwards, tool side from the ground outwards.
        let w_axes: Vec<Axis> = chain[1..g].iter().rev().filter_map(axis_of).collect();
        let t_axes: Vec<Axis> = chain[g + 1..5].iter().filter_map(axis_of).collect();
        // The tool point with every axis at mid-stroke (scene coordinates): the axis
        // coordinates are the spindle's gauge line, the tool point one tool length below it
        // (`tool_a` = `position_a` − tool length along Z), where the tool path is drawn.
        let mut c = [0.0; 3];
        for a in &t_axes {
            c[a.index()] = st.mid[a.index()];
        }
        c[2] -= tool_len;
        let wp_top = c[2] - st.mid[2] + st.min[2];
        let mut layout = Layout {
            parts: Vec::new(),
            carriages: Vec::new(),
            workpiece: String::new(),
        };
        layout.workpiece_side(&w_axes, &st, c, wp_top);
        layout.tool_side(&t_axes, &st, c, tool_len);
        layout
    }

    fn workpiece_side(&mut self, w_axes: &[Axis], st: &Strokes, c: [f64; 3], wp_top: f64) {
        let n = w_axes.len() as f64;
        let slab = 0.05;
        // Base under the whole stack, static in the scene.
        self.parts.push(Part {
            entity: "/machine/base".into(),
            label: "bed (ground)".into(),
            centre: to_f32([c[0], c[1], wp_top - 0.06 - slab * n - 0.05]),
            size: to_f32([1.6 * st.len[0] + 0.3, 1.6 * st.len[1] + 0.3, 0.1]),
            colour: Color::from_rgb(110, 110, 110),
            fill: FillMode::TransparentFillMajorWireframe,
        });
        let mut entity = "/machine".to_string();
        // Scene origin of the current entity with every axis at mid-stroke.
        let mut origin = [0.0; 3];
        for (level, a) in w_axes.iter().enumerate() {
            let k = a.index();
            entity = format!("{entity}/{}_axis", a.letter().to_ascii_lowercase());
            origin[k] -= st.mid[k];
            let grow = 0.05 * (n - level as f64);
            // The carriage next to the workpiece is highest, right under it.
            let z = wp_top - 0.06 - slab * (n - 1.0 - level as f64 + 0.5);
            let centre = [c[0], c[1], z];
            self.parts.push(Part {
                entity: entity.clone(),
                label: format!("{} carriage (moves the workpiece)", a.letter()),
                centre: to_f32(sub(centre, origin)),
                size: to_f32([
                    0.7 * st.len[0] + 0.1 + grow,
                    0.7 * st.len[1] + 0.1 + grow,
                    slab,
                ]),
                colour: carriage_colour(*a),
                fill: FillMode::TransparentFillMajorWireframe,
            });
            self.carriages.push((entity.clone(), *a, -1.0));
        }
        self.workpiece = format!("{entity}/workpiece");
        self.parts.push(Part {
            entity: self.workpiece.clone(),
            label: "workpiece".into(),
            centre: to_f32(sub([c[0], c[1], wp_top - 0.03], origin)),
            size: to_f32([0.4 * st.len[0] + 0.05, 0.4 * st.len[1] + 0.05, 0.06]),
            colour: Color::from_rgb(230, 150, 40),
            fill: FillMode::Solid,
        });
    }

    fn tool_side(&mut self, t_axes: &[Axis], st: &Strokes, c: [f64; 3], tool_len: f64) {
        let mut entity = "/machine".to_string();
        let mut origin = [0.0; 3];
        let n = t_axes.len();
        for (level, a) in t_axes.iter().enumerate() {
            let k = a.index();
            entity = format!("{entity}/{}_axis", a.letter().to_ascii_lowercase());
            origin[k] += st.mid[k];
            // Counted from the tool: the carriage next to the tool is lowest.
            let from_tool = (n - 1 - level) as f64;
            let mut size = [0.15, 0.15, 0.1];
            for b in &t_axes[level + 1..] {
                if b.index() < 2 {
                    size[b.index()] = st.len[b.index()] + 0.15;
                }
            }
            let centre = [c[0], c[1], c[2] + tool_len + 0.05 + 0.1 * from_tool];
            self.parts.push(Part {
                entity: entity.clone(),
                label: format!("{} carriage (moves the tool)", a.letter()),
                centre: to_f32(sub(centre, origin)),
                size: to_f32(size),
                colour: carriage_colour(*a),
                fill: FillMode::TransparentFillMajorWireframe,
            });
            self.carriages.push((entity.clone(), *a, 1.0));
        }
        self.parts.push(Part {
            entity: format!("{entity}/tool"),
            label: "tool".into(),
            centre: to_f32(sub([c[0], c[1], c[2] + 0.5 * tool_len], origin)),
            size: to_f32([0.016, 0.016, tool_len]),
            colour: Color::from_rgb(60, 60, 60),
            fill: FillMode::Solid,
        });
    }
}

fn carriage_colour(a: Axis) -> Color {
    axis_colour(&a.letter().to_ascii_lowercase().to_string())
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn to_f32(a: [f64; 3]) -> [f32; 3] {
    a.map(|v| v as f32)
}

/// Band levels of one accelerometer axis for [`write_band_rrd`]: the band centres (Hz) and the
/// levels (dB re 1 m/s²) measured and of the model before and after a gap analysis.
pub struct AxisBands<'a> {
    /// Axis name (`ax`, `ay`, `az`).
    pub axis: &'a str,
    /// Band centres, Hz.
    pub centres_hz: &'a [f64],
    /// Measured levels, dB.
    pub measured_db: &'a [f64],
    /// The model's levels as given, dB.
    pub before_db: &'a [f64],
    /// The model's levels with the chosen effects, dB.
    pub after_db: &'a [f64],
}

/// Writes the band levels of a vibration gap to the Rerun recording `path`: per axis, the
/// residual (measured − model, dB) per band before and after as bar charts
/// (`/vibration/residual_db/<axis>/before`, `…/after`, abscissa the band centre in Hz), the
/// three level curves as 2D strips over log10 of frequency (`/vibration/levels_db/<axis>`), and
/// the report text (`/report`). Static data: a spectrum has no time axis.
pub fn write_band_rrd(
    path: &Path,
    recording_id: &str,
    report: &str,
    axes: &[AxisBands<'_>],
) -> Result<(), FileError> {
    atomically(path, |partial| {
        write_band_file(partial, recording_id, report, axes)
    })
}

/// [`write_band_rrd`] to `path` as it is written.
fn write_band_file(
    path: &Path,
    recording_id: &str,
    report: &str,
    axes: &[AxisBands<'_>],
) -> Result<(), FileError> {
    let err = |e: &dyn std::error::Error| FileError::output(path, e);
    let rec = rerun::RecordingStreamBuilder::new(APPLICATION_ID)
        .recording_id(recording_id)
        .enabled(true)
        .save(path)
        .map_err(|e| err(&e))?;
    rec.set_log_time_enabled(false);
    rec.set_log_tick_enabled(false);
    let log = |entity: String, what: &dyn rerun::AsComponents| {
        rec.log_static(entity, what).map_err(|e| err(&e))
    };
    log("/report".into(), &TextDocument::new(report))?;
    for a in axes {
        let residual = |model: &[f64]| -> Vec<f64> {
            a.measured_db
                .iter()
                .zip(model)
                .map(|(m, s)| m - s)
                .collect()
        };
        for (when, model, colour) in [
            ("before", a.before_db, Color::from_rgb(200, 40, 40)),
            ("after", a.after_db, Color::from_rgb(40, 80, 200)),
        ] {
            log(
                format!("/vibration/residual_db/{}/{when}", a.axis),
                &rerun::BarChart::new(residual(model).as_slice())
                    .with_abscissa(a.centres_hz)
                    .with_color(colour),
            )?;
        }
        let strip = |levels: &[f64]| -> Vec<[f32; 2]> {
            a.centres_hz
                .iter()
                .zip(levels)
                .map(|(f, l)| [f.log10() as f32, *l as f32])
                .collect()
        };
        log(
            format!("/vibration/levels_db/{}", a.axis),
            &LineStrips2D::new([strip(a.measured_db), strip(a.before_db), strip(a.after_db)])
                .with_colors([
                    Color::from_rgb(0, 0, 0),
                    Color::from_rgb(200, 40, 40),
                    Color::from_rgb(40, 80, 200),
                ])
                .with_labels(["measured", "model as given", "model with the effects"]),
        )?;
    }
    flush(&rec).map_err(|e| err(&e))?;
    rec.finalize_deferred_sinks();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_numbers() {
        assert_eq!(nice_floor(3.7), 2.0);
        assert_eq!(nice_floor(7500.0), 5000.0);
        assert_eq!(nice_floor(0.3), 0.2);
        assert_eq!(nice_ceil(3.7), 5.0);
        assert_eq!(nice_ceil(0.9), 1.0);
        assert_eq!(nice_ceil(2.0), 2.0);
        assert_eq!(fmt_num(3000.0), "3000");
        assert_eq!(fmt_num(2.5), "2.5");
    }

    #[test]
    fn vmc_layout_nests_workpiece_under_y_and_x() {
        let m = MachineSummary {
            name: "m".into(),
            topology: "WXYGZT".into(),
            strokes_m: [[0.0, 0.5], [0.0, 0.4], [0.0, 0.4]],
            tool_length_m: 0.1,
        };
        let t: Topology = "WXYGZT".parse().expect("topology");
        let l = Layout::new(&m, t);
        assert_eq!(l.workpiece, "/machine/y_axis/x_axis/workpiece");
        let carriages: Vec<(&str, f64)> = l
            .carriages
            .iter()
            .map(|(e, _, s)| (e.as_str(), *s))
            .collect();
        assert_eq!(
            carriages,
            [
                ("/machine/y_axis", -1.0),
                ("/machine/y_axis/x_axis", -1.0),
                ("/machine/z_axis", 1.0)
            ]
        );
        assert!(l.parts.iter().any(|p| p.entity == "/machine/z_axis/tool"));
    }

    /// The scene position of the point `local` of `entity` with the axes at `q`: every
    /// carriage on the entity's path translates it by its sign times its axis coordinate.
    fn scene(l: &Layout, entity: &str, local: [f64; 3], q: [f64; 3]) -> [f64; 3] {
        let mut p = local;
        for (e, a, sign) in &l.carriages {
            if entity == e || entity.starts_with(&format!("{e}/")) {
                p[a.index()] += sign * q[a.index()];
            }
        }
        p
    }

    /// The tool's tip is drawn on the tool path (which is logged in workpiece coordinates,
    /// the tool point `q − (0, 0, L)`), wherever the axes stand: the tool hung from the
    /// gauge line had been drawn a tool length above its own path.
    #[test]
    fn the_tool_tip_is_drawn_on_the_tool_path() {
        for topology in ["WXYGZT", "WGXYZT", "WZGXYT"] {
            let m = MachineSummary {
                name: "m".into(),
                topology: topology.into(),
                strokes_m: [[0.0, 0.5], [0.0, 0.4], [0.0, 0.4]],
                tool_length_m: 0.1,
            };
            let l = Layout::new(&m, topology.parse().expect("topology"));
            let tool = l
                .parts
                .iter()
                .find(|p| p.entity.ends_with("/tool"))
                .unwrap();
            let tip_local = [
                f64::from(tool.centre[0]),
                f64::from(tool.centre[1]),
                f64::from(tool.centre[2]) - 0.5 * f64::from(tool.size[2]),
            ];
            for q in [[0.25, 0.2, 0.2], [0.1, 0.35, 0.05], [0.5, 0.0, 0.4]] {
                let tip = scene(&l, &tool.entity, tip_local, q);
                let path = scene(&l, &l.workpiece, [q[0], q[1], q[2] - 0.1], q);
                for k in 0..3 {
                    assert!(
                        (tip[k] - path[k]).abs() < 1e-6,
                        "{topology} at {q:?}: tip {tip:?}, path {path:?}"
                    );
                }
            }
        }
    }

    /// Kwon's steps have no overshoot: 150 µm of lag at the start of a trace whose errors are a
    /// few µm. The view is scaled for the few µm, as the PNG is.
    #[test]
    fn a_polar_view_is_scaled_without_the_start_transient() {
        let n = 3600;
        let angle_deg: Vec<f64> = (0..n).map(|i| i as f64 * 0.1).collect();
        let deviation_um: Vec<f64> = angle_deg
            .iter()
            .map(|a| {
                if *a < 1.0 {
                    150.0
                } else {
                    3.0 * (2.0 * a.to_radians()).sin()
                }
            })
            .collect();
        let trace = BallbarTrace {
            label: "XY 150 mm CCW".into(),
            plane: "XY".into(),
            direction: "ccw".into(),
            radius_mm: 150.0,
            feed_mm_min: 1000.0,
            times_s: (0..n).map(|i| i as f64 * 0.01).collect(),
            angle_deg,
            deviation_um,
        };
        let g = PolarGroup {
            name: "xy_150_mm".into(),
            title: "Ball bar XY 150 mm".into(),
            radius_mm: 150.0,
            traces: vec![0],
        };
        let dev = group_deviation_um(&g, std::slice::from_ref(&trace));
        assert!((dev - 3.0).abs() < 1e-3, "{dev}");
        let scale = PolarScale::new(150.0, dev);
        assert_eq!(scale.div_um, 2.0);
        assert_eq!(scale.k_mm_per_um * 1e3, 10_000.0);
    }

    #[test]
    fn gantry_layout_has_fixed_workpiece() {
        let m = MachineSummary {
            name: "g".into(),
            topology: "WGXYZT".into(),
            strokes_m: [[0.0, 2.0], [0.0, 1.0], [0.0, 0.5]],
            tool_length_m: 0.1,
        };
        let t: Topology = "WGXYZT".parse().expect("topology");
        let l = Layout::new(&m, t);
        assert_eq!(l.workpiece, "/machine/workpiece");
        assert!(
            l.parts
                .iter()
                .any(|p| p.entity == "/machine/x_axis/y_axis/z_axis/tool")
        );
    }
}
