//! `vmt program`: NC programs generated from test descriptions (ball-bar circles, ISO 230-4).

use crate::CliError;
use clap::Args;
use nalgebra::Vector3;
use std::path::PathBuf;
use vmt_scenario::Scenario;
use vmt_sim::interpolator::InterpolatorConfig;
use vmt_sim::nc::ballbar::{CircularTest, TestParameter, default_start_deg};
use vmt_sim::nc::{ArcDirection, Plane, parse};
use vmt_sim::simulate::{Job, SimError, check_travel, travel_extent};

/// Arguments of `vmt program ballbar`. Lengths in mm, feed in mm/min, angles in degrees.
#[derive(Args, Debug, Clone)]
pub struct BallbarArgs {
    /// Plane of the circle: XY (G17), ZX or XZ (G18), YZ (G19).
    #[arg(long, value_parser = parse_plane)]
    pub plane: Plane,
    /// Radius of the circle (the ball-bar length), mm: 50 to 600.
    #[arg(long)]
    pub radius_mm: f64,
    /// Path speed, mm/min (> 0).
    #[arg(long)]
    pub feed_mm_min: f64,
    /// Data arc, degrees: 360 for a full circle, or a partial arc such as 220 or 180.
    #[arg(long, default_value_t = 360.0)]
    pub arc_deg: f64,
    /// The runs in order, comma-separated: cw, ccw (or g2, g3).
    #[arg(long, value_delimiter = ',', default_value = "cw,ccw", value_parser = parse_direction)]
    pub directions: Vec<ArcDirection>,
    /// Centre of the circle, mm, as x,y,z: the tool point, as the program gives it (default:
    /// the tool point with every carriage at the middle of its stroke, the machine's tool length
    /// included; for the built-in machine X250 Y200 Z100).
    // No `num_args = 3`: clap counts `250,200,100` as one argument; the length is checked in
    // `center`.
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub center_mm: Option<Vec<f64>>,
    /// Angle where the data arc starts, degrees, from the plane's first axis (+X in XY, +Z in
    /// ZX, +Y in YZ) towards its second (default: 0 for a full circle or in XY; a partial arc in
    /// ZX or YZ lies over the top, symmetric about +Z: -arc/2 in ZX, 90 - arc/2 in YZ).
    #[arg(long, allow_negative_numbers = true)]
    pub start_deg: Option<f64>,
    /// Run-in and run-out arcs before and after the data arc, degrees.
    #[arg(long, default_value_t = vmt_sim::nc::ballbar::DEFAULT_OVERSHOOT_DEG)]
    pub overshoot_deg: f64,
    /// Radial feed-in onto and feed-out off the circle, mm.
    #[arg(long, default_value_t = vmt_sim::nc::ballbar::DEFAULT_FEED_IN_M * 1e3)]
    pub feed_in_mm: f64,
    /// Come down onto the start point from this height above it, mm (0 to 10; 0: straight
    /// there), so that the test starts with Z last moved down.
    #[arg(long, default_value_t = 0.0)]
    pub approach_from_above_mm: f64,
    /// The machine the program is for (scenario TOML; default: the built-in machine). Its
    /// strokes give the default centre, and a program leaving them is refused; without
    /// --scenario a program about an explicit --center-mm is not checked (the machine is
    /// unknown).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Write the program to this file (default: stdout).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

fn parse_plane(s: &str) -> Result<Plane, String> {
    use crate::plane::Plane as Name;
    Ok(match crate::plane::parse(s)? {
        Name::Xy => Plane::Xy,
        Name::Zx => Plane::Zx,
        Name::Yz => Plane::Yz,
    })
}

fn parse_direction(s: &str) -> Result<ArcDirection, String> {
    match s.trim().to_ascii_lowercase().as_str() {
        "cw" | "g2" => Ok(ArcDirection::Cw),
        "ccw" | "g3" => Ok(ArcDirection::Ccw),
        _ => Err(format!("`{s}`: a direction is cw or ccw")),
    }
}

/// The command-line option that sets `parameter`.
fn flag(parameter: TestParameter) -> &'static str {
    match parameter {
        TestParameter::Center => "--center-mm",
        TestParameter::Radius => "--radius-mm",
        TestParameter::Feed => "--feed-mm-min",
        TestParameter::Arc => "--arc-deg",
        TestParameter::Start => "--start-deg",
        TestParameter::Overshoot => "--overshoot-deg",
        TestParameter::Directions => "--directions",
        TestParameter::FeedIn => "--feed-in-mm",
        TestParameter::Approach => "--approach-from-above-mm",
    }
}

/// The circle's centre, m, and the machine the program is checked against: `--center-mm`, or
/// the tool point at the middle of the strokes of `--scenario`'s machine or the built-in one;
/// the machine is `None` when neither `--scenario` nor the default centre names one.
fn center(args: &BallbarArgs) -> Result<(Vector3<f64>, Option<Scenario>), CliError> {
    let scenario = args
        .scenario
        .as_deref()
        .map(vmt_scenario::load)
        .transpose()?;
    match &args.center_mm {
        Some(c) if c.len() == 3 => Ok((Vector3::new(c[0], c[1], c[2]) * 1e-3, scenario)),
        Some(_) => Err(CliError::Argument(
            "--center-mm takes three numbers, x,y,z in mm".into(),
        )),
        None => {
            let s = match scenario {
                Some(s) => s,
                None => vmt_scenario::builtin()?,
            };
            Ok((s.machine.mid_stroke_tool_point(), Some(s)))
        }
    }
}

/// The circular test the arguments describe, validated, and within the strokes of the machine
/// when it is known.
pub fn ballbar_test(args: &BallbarArgs) -> Result<CircularTest, CliError> {
    let (center, machine) = center(args)?;
    let test = CircularTest {
        plane: args.plane,
        center,
        radius_m: args.radius_mm * 1e-3,
        feed_m_s: args.feed_mm_min / 6e4,
        arc_deg: args.arc_deg,
        start_deg: args
            .start_deg
            .unwrap_or_else(|| default_start_deg(args.plane, args.arc_deg)),
        directions: args.directions.clone(),
        feed_in_m: args.feed_in_mm * 1e-3,
        overshoot_deg: args.overshoot_deg,
        approach_from_above_m: args.approach_from_above_mm * 1e-3,
    };
    test.validate()
        .map_err(|e| CliError::Argument(format!("{} ({})", e, flag(e.parameter))))?;
    if let Some(s) = &machine {
        within_strokes(&test, s)?;
    }
    Ok(test)
}

/// Refuses `test` when its program (feed-in, overshoots, data arc, approach), interpolated as
/// the scenario's controller would (the defaults without one), leaves a stroke of its machine:
/// the check `vmt run` makes.
fn within_strokes(test: &CircularTest, scenario: &Scenario) -> Result<(), CliError> {
    let program = parse(&test.gcode(), test.start_point())
        .map_err(|e| CliError::Argument(format!("the generated program: {e}")))?;
    let job = Job {
        program,
        ballbar: Vec::new(),
        laser: None,
    };
    let ipo = scenario
        .execution
        .as_ref()
        .map_or_else(InterpolatorConfig::default, |e| e.controller);
    let machine = &scenario.machine;
    let refused =
        |e: SimError| CliError::Argument(format!("the test cannot run on {}: {e}", machine.name));
    match check_travel(machine, &ipo, &job) {
        Ok(()) => Ok(()),
        Err(SimError::Stroke {
            axis,
            min_mm,
            max_mm,
            ..
        }) => {
            let (lo, hi) = travel_extent(machine, &ipo, &job).map_err(refused)?;
            let i = axis.index();
            Err(CliError::Argument(format!(
                "the test (circle, feed-in and overshoots) takes the {axis} axis from {:.3} to \
                 {:.3} mm, beyond its stroke {min_mm} to {max_mm} mm on {}: move the centre \
                 (--center-mm, the tool point) or shorten --radius-mm",
                lo[i] * 1e3,
                hi[i] * 1e3,
                machine.name
            )))
        }
        Err(e) => Err(refused(e)),
    }
}

/// The G-code of the ball-bar test the arguments describe (see `vmt_sim::nc::ballbar` for the
/// program layout), or what is wrong with the arguments.
pub fn ballbar_program(args: &BallbarArgs) -> Result<String, CliError> {
    Ok(ballbar_test(args)?.gcode())
}

/// `vmt program ballbar`: writes the program to `--out` (and says so) or to stdout.
pub fn ballbar(args: &BallbarArgs) -> Result<(), CliError> {
    let text = ballbar_program(args)?;
    match &args.out {
        Some(path) => {
            if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir).map_err(|e| CliError::output(dir, e))?;
            }
            std::fs::write(path, text).map_err(|e| CliError::output(path, e))?;
            crate::outln!("wrote {}", path.display())?;
        }
        None => crate::out!("{text}")?,
    }
    Ok(())
}
