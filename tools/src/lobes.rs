//! `vmt lobes`: stability lobe diagrams by semi-discretization and by the zero-order
//! approximation, side by side, as CSV and as an image.
//!
//! Without a scenario the cases are the single-degree-of-freedom benchmark of Insperger &
//! Stépán and Ding et al. (m = 0.03993 kg, f_n = 922 Hz, ζ = 0.011, K_t = 6e8 N/m²,
//! K_n = 2e8 N/m², 2 teeth, down milling) at radial immersions a/D = 1, 0.5, 0.1 and 0.05.
//! With a scenario, the tool, material and engagement of its milling job (modes in X and Y).

use crate::error::CliError;
use crate::plot::{DrawResult, FONT, Figure, Format, register_font, render};
use indicatif::{ProgressBar, ProgressStyle};
use plotters::coord::Shift;
use plotters::prelude::*;
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use vmt_chatter::stability::sd::{MillingSd, SdSettings, StabilityMap};
use vmt_chatter::stability::zoa::{Lobes, ZoaSettings, feed_only_minimum_depth, lobes};
use vmt_chatter::stability::{Flexibility, MillingSystem, benchmark_1dof, grid};
use vmt_model::cutting::MillingDirection;

/// Arguments of `vmt lobes`.
#[derive(clap::Args, Debug)]
pub struct LobesArgs {
    /// A scenario with a `kind = "milling"` job: its tool, material and engagement. Without
    /// it, the 1-DOF benchmark at the immersions of --immersion.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Radial immersions a/D of the benchmark, comma-separated, each in (0, 1] (a scenario's
    /// engagement is its job's).
    #[arg(long, value_delimiter = ',', default_values_t = [1.0, 0.5, 0.1, 0.05], conflicts_with = "scenario")]
    pub immersion: Vec<f64>,
    /// Up or down milling of the benchmark (a scenario's is its job's).
    #[arg(long, value_enum, default_value_t = Direction::Down, conflicts_with = "scenario")]
    pub direction: Direction,
    /// Lowest spindle speed, rpm.
    #[arg(long, default_value_t = 5000.0)]
    pub speed_min_rpm: f64,
    /// Highest spindle speed, rpm.
    #[arg(long, default_value_t = 25000.0)]
    pub speed_max_rpm: f64,
    /// Number of speeds of the semi-discretization grid.
    #[arg(long, default_value_t = 200)]
    pub speeds: usize,
    /// Largest axial depth of the grid, mm; by default eight times the case's smallest ZOA
    /// critical depth, at most the flute length.
    #[arg(long)]
    pub depth_max_mm: Option<f64>,
    /// Number of depths of the semi-discretization grid.
    #[arg(long, default_value_t = 100)]
    pub depths: usize,
    /// Semi-discretization steps per tooth period.
    #[arg(long, default_value_t = SdSettings::default().steps)]
    pub sd_steps: usize,
    /// Output folder: lobes.csv, sd_map.csv and lobes.png (or .svg).
    #[arg(long, default_value = "out/lobes")]
    pub out: PathBuf,
    /// Image format.
    #[arg(long, value_enum, default_value_t = Format::Png)]
    pub format: Format,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Milling direction on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Direction {
    Up,
    Down,
}

/// One stability problem and its two diagrams.
pub struct Case {
    /// E.g. "a/D = 0.5, down milling".
    pub label: String,
    pub system: MillingSystem,
    pub zoa: Lobes,
    pub sd: StabilityMap,
}

impl Case {
    /// Smallest critical depth over the speed grid by each method (m): (SD, ZOA).
    pub fn minima(&self) -> (Option<f64>, Option<f64>) {
        let sd = self.sd.boundary().into_iter().flatten().reduce(f64::min);
        let zoa = self
            .sd
            .speeds_rpm
            .iter()
            .filter_map(|&n| self.zoa.critical_depth(n).map(|p| p.depth_m))
            .reduce(f64::min);
        (sd, zoa)
    }
}

/// The systems to analyse, with their labels.
fn systems(args: &LobesArgs) -> Result<Vec<(String, MillingSystem)>, CliError> {
    let Some(path) = &args.scenario else {
        let direction = match args.direction {
            Direction::Up => MillingDirection::Up,
            Direction::Down => MillingDirection::Down,
        };
        return args
            .immersion
            .iter()
            .map(|&r| {
                if !(r > 0.0 && r <= 1.0) {
                    return Err(CliError::Argument(format!(
                        "--immersion {r}: a radial immersion a/D must be in (0, 1]"
                    )));
                }
                let name = format!("{direction:?}").to_lowercase();
                Ok((
                    format!("1-DOF benchmark, a/D = {r}, {name} milling"),
                    benchmark_1dof(r, direction),
                ))
            })
            .collect();
    };
    let scenario = vmt_scenario::load(path)?;
    let Some(setup) = scenario
        .execution
        .and_then(|e| e.milling)
        .map(|job| job.setup)
    else {
        return Err(CliError::Argument(format!(
            "{}: the scenario has no milling job ([job] kind = \"milling\"); \
             see scenarios/milling_slot.toml",
            path.display()
        )));
    };
    let system = MillingSystem {
        tool: setup.tool,
        coefficients: setup.coefficients,
        dynamics: setup.dynamics,
        radial_depth: setup.cut.radial_depth,
        direction: setup.cut.direction,
        flexibility: Flexibility::Both,
    };
    let label = format!(
        "{}: a/D = {:.3}, {:?} milling",
        path.display(),
        setup.cut.immersion(&system.tool),
        setup.cut.direction
    );
    Ok(vec![(label, system)])
}

fn model_error(e: impl std::fmt::Display) -> CliError {
    CliError::Model(format!("stability: {e}"))
}

/// Refuses a --depth-max-mm beyond the flute length of `system`'s tool.
fn check_depth(args: &LobesArgs, system: &MillingSystem) -> Result<(), CliError> {
    let flute = system.tool.flute_length;
    match args.depth_max_mm {
        Some(mm) if mm * 1e-3 > flute => Err(CliError::Argument(format!(
            "--depth-max-mm {mm} is beyond the tool's flute length {} mm",
            flute * 1e3
        ))),
        _ => Ok(()),
    }
}

/// The depth grid of one case: up to --depth-max-mm (checked by [`check_depth`]), or eight
/// times the smallest ZOA depth over the speed range, never beyond the flute length.
fn depth_grid(
    args: &LobesArgs,
    system: &MillingSystem,
    zoa: &Lobes,
    speeds: &[f64],
) -> Result<Vec<f64>, CliError> {
    let flute = system.tool.flute_length;
    let max = match args.depth_max_mm {
        Some(mm) => mm * 1e-3,
        None => speeds
            .iter()
            .filter_map(|&n| zoa.critical_depth(n).map(|p| p.depth_m))
            .reduce(f64::min)
            .map_or(flute, |a| (8.0 * a).min(flute)),
    };
    grid("axial depth, m", max / args.depths as f64, max, args.depths).map_err(model_error)
}

/// Checks the grid options in the units typed, before anything is computed: the
/// semi-discretization costs speeds x depths eigenvalue problems of a matrix growing with
/// --sd-steps.
fn check(args: &LobesArgs) -> Result<(), CliError> {
    use crate::error::{check_count, check_positive, check_range};
    let rpm = (1.0, 200_000.0);
    let why = "spindle speeds of milling";
    check_range("--speed-min-rpm", args.speed_min_rpm, rpm, "rpm", why)?;
    check_range("--speed-max-rpm", args.speed_max_rpm, rpm, "rpm", why)?;
    if args.speed_min_rpm >= args.speed_max_rpm {
        return Err(CliError::Argument(format!(
            "--speed-min-rpm {} must be below --speed-max-rpm {} (the spindle speed range)",
            args.speed_min_rpm, args.speed_max_rpm
        )));
    }
    check_count(
        "--speeds",
        args.speeds,
        (2, 5000),
        "points of the speed grid",
    )?;
    check_count(
        "--depths",
        args.depths,
        (2, 2000),
        "points of the depth grid",
    )?;
    check_count(
        "--sd-steps",
        args.sd_steps,
        (2, 400),
        "steps per tooth period; the cost grows with their cube",
    )?;
    if let Some(mm) = args.depth_max_mm {
        check_positive("--depth-max-mm", mm, 1000.0, "mm", "an axial depth of cut")?;
    }
    Ok(())
}

/// The cases to analyse, every argument checked and the scenario read: what `command` does
/// before it makes the output folder.
pub fn prepare(args: &LobesArgs) -> Result<Vec<(String, MillingSystem)>, CliError> {
    check(args)?;
    let systems = systems(args)?;
    for (_, system) in &systems {
        check_depth(args, system)?;
    }
    Ok(systems)
}

/// Both diagrams of every case of [`prepare`]. The semi-discretization map runs over the
/// speeds in parallel.
pub fn compute(args: &LobesArgs) -> Result<Vec<Case>, CliError> {
    compute_cases(args, prepare(args)?)
}

fn compute_cases(
    args: &LobesArgs,
    systems: Vec<(String, MillingSystem)>,
) -> Result<Vec<Case>, CliError> {
    let speeds = grid(
        "spindle speed, rpm",
        args.speed_min_rpm,
        args.speed_max_rpm,
        args.speeds,
    )
    .map_err(model_error)?;
    let settings = SdSettings {
        steps: args.sd_steps,
    };
    let mut cases = Vec::new();
    for (label, system) in systems {
        let zoa = lobes(&system, &ZoaSettings::default()).map_err(model_error)?;
        let depths = depth_grid(args, &system, &zoa, &speeds)?;
        let bar = progress(args.quiet, speeds.len(), &label);
        let columns: Vec<Vec<f64>> = speeds
            .par_iter()
            .map(|&n| {
                let sd = MillingSd::new(&system, n, &settings)?;
                let column = depths
                    .iter()
                    .map(|&a| sd.spectral_radius(a))
                    .collect::<Result<Vec<f64>, _>>();
                bar.inc(1);
                column
            })
            .collect::<Result<_, _>>()
            .map_err(model_error)?;
        bar.finish_and_clear();
        let sd = StabilityMap {
            speeds_rpm: speeds.clone(),
            depths_m: depths,
            radius: columns.concat(),
        };
        cases.push(Case {
            label,
            system,
            zoa,
            sd,
        });
    }
    Ok(cases)
}

fn progress(quiet: bool, len: usize, label: &str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len as u64);
    if let Ok(style) = ProgressStyle::with_template("{msg} {bar:40} {pos}/{len} speeds ({eta})") {
        bar.set_style(style);
    }
    bar.set_message(label.to_string());
    bar
}

/// lobes.csv: per case and speed, the critical depth by each method.
pub fn lobes_csv(cases: &[Case]) -> String {
    let mut s = String::from(
        "case,speed_rpm,sd_critical_depth_mm,zoa_critical_depth_mm,zoa_chatter_hz,zoa_lobe\n",
    );
    for case in cases {
        for (&n, sd) in case.sd.speeds_rpm.iter().zip(case.sd.boundary()) {
            let zoa = case.zoa.critical_depth(n);
            let _ = writeln!(
                s,
                "\"{}\",{n},{},{},{},{}",
                case.label,
                sd.map_or(String::new(), |a| (a * 1e3).to_string()),
                zoa.map_or(String::new(), |p| (p.depth_m * 1e3).to_string()),
                zoa.map_or(String::new(), |p| p.chatter_hz.to_string()),
                zoa.map_or(String::new(), |p| p.lobe.to_string()),
            );
        }
    }
    s
}

/// sd_map.csv: the spectral radius of every grid point (below 1 is stable).
pub fn map_csv(cases: &[Case]) -> String {
    let mut s = String::from("case,speed_rpm,depth_mm,spectral_radius\n");
    for case in cases {
        for (i, &n) in case.sd.speeds_rpm.iter().enumerate() {
            for (k, &a) in case.sd.depths_m.iter().enumerate() {
                let _ = writeln!(s, "\"{}\",{n},{},{}", case.label, a * 1e3, case.sd.at(i, k));
            }
        }
    }
    s
}

/// The summary printed to the terminal: the smallest critical depth by each method and their
/// difference, with why the methods differ.
pub fn summary(cases: &[Case]) -> String {
    let mut s = String::from(
        "case                                          SD min (mm)  ZOA min (mm)  ZOA-SD\n",
    );
    let mm = |a: Option<f64>| a.map_or("stable".into(), |a| format!("{:.4}", a * 1e3));
    for case in cases {
        let (sd, zoa) = case.minima();
        let diff = match (sd, zoa) {
            (Some(sd), Some(zoa)) => format!("{:+.1} %", 100.0 * (zoa - sd) / sd),
            _ => "-".into(),
        };
        let _ = writeln!(
            s,
            "{:<46}{:>11}{:>14}{:>8}",
            case.label,
            mm(sd),
            mm(zoa),
            diff
        );
        if let Some(closed) = feed_only_minimum_depth(&case.system) {
            let _ = writeln!(
                s,
                "  ZOA closed-form minimum for one mode in X: {:.4} mm",
                closed * 1e3
            );
        }
    }
    s.push_str(
        "The ZOA keeps only the average of the periodic directional coefficients over a tooth \
         period; semi-discretization keeps their time variation. They agree where the tooth is \
         in the cut most of the period (slotting, half immersion) and part at low immersion, \
         where the cutting force is a train of short pulses: SD then shows the period-doubling \
         (flip) lobes and the raised boundary between them that the ZOA cannot.\n",
    );
    s
}

/// `vmt lobes`: computes, writes lobes.csv, sd_map.csv and the image, prints the summary.
/// The output folder is made after the arguments and the scenario are checked, so that a
/// refused command leaves no empty folder, and before the diagrams are computed.
pub fn command(args: &LobesArgs) -> Result<(), CliError> {
    let systems = prepare(args)?;
    crate::out::output_dir(&args.out)?;
    let cases = compute_cases(args, systems)?;
    for (name, text) in [
        ("lobes.csv", lobes_csv(&cases)),
        ("sd_map.csv", map_csv(&cases)),
    ] {
        let path = args.out.join(name);
        std::fs::write(&path, text).map_err(|e| CliError::output(&path, e))?;
    }
    let image = args.out.join(format!("lobes.{}", args.format.extension()));
    draw(&cases, &image, args.format)?;
    crate::out!("{}", summary(&cases))?;
    crate::outln!(
        "wrote {}, {} and {}",
        args.out.join("lobes.csv").display(),
        args.out.join("sd_map.csv").display(),
        image.display()
    )?;
    Ok(())
}

/// Draws every case in its own panel: the SD map's unstable cells shaded, its boundary, and
/// the ZOA lobes over them.
pub fn draw(cases: &[Case], path: &Path, format: Format) -> Result<(), CliError> {
    register_font();
    let cols = if cases.len() > 1 { 2 } else { 1 };
    let rows = cases.len().div_ceil(cols);
    let size = (800 * cols as u32, 560 * rows as u32);
    struct Panels<'a> {
        cases: &'a [Case],
        rows: usize,
        cols: usize,
    }
    impl Figure for Panels<'_> {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
            draw_on(root, self.cases, self.rows, self.cols)
        }
    }
    render(&Panels { cases, rows, cols }, path, format, size)
}

fn draw_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    cases: &[Case],
    rows: usize,
    cols: usize,
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    for (panel, case) in root.split_evenly((rows, cols)).iter().zip(cases) {
        draw_case(panel, case)?;
    }
    Ok(())
}

fn draw_case<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, case: &Case) -> DrawResult<DB> {
    let map = &case.sd;
    let krpm: Vec<f64> = map.speeds_rpm.iter().map(|n| n / 1e3).collect();
    let mm: Vec<f64> = map.depths_m.iter().map(|a| a * 1e3).collect();
    let (x0, x1) = (krpm[0], krpm[krpm.len() - 1]);
    let y1 = mm[mm.len() - 1];
    let mut chart = ChartBuilder::on(area)
        .caption(&case.label, (FONT, 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(x0..x1, 0.0..y1)?;
    chart
        .configure_mesh()
        .x_desc("spindle speed (krpm)")
        .y_desc("axial depth (mm)")
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    let (dx, dy) = ((x1 - x0) / (krpm.len() - 1) as f64, y1 / mm.len() as f64);
    let unstable = RGBColor(250, 205, 205).filled();
    chart.draw_series(
        (0..krpm.len())
            .flat_map(|i| (0..mm.len()).map(move |k| (i, k)))
            .filter(|&(i, k)| map.at(i, k) >= 1.0)
            .map(|(i, k)| {
                let (x, y) = (krpm[i], mm[k]);
                Rectangle::new(
                    [(x - dx / 2.0, y - dy / 2.0), (x + dx / 2.0, y + dy / 2.0)],
                    unstable,
                )
            }),
    )?;
    let red = RGBColor(178, 24, 43);
    let boundary: Vec<(f64, f64)> = krpm
        .iter()
        .zip(map.boundary())
        .map(|(&x, a)| (x, a.map_or(y1, |a| a * 1e3)))
        .collect();
    chart
        .draw_series(LineSeries::new(boundary, red.stroke_width(2)))?
        .label("semi-discretization (unstable shaded)")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], red.stroke_width(2)));
    let blue = RGBColor(33, 102, 172);
    for (j, curve) in case.zoa.curves.iter().enumerate() {
        let pts = curve
            .iter()
            .filter(|p| (x0..=x1).contains(&(p.speed_rpm / 1e3)) && p.depth_m * 1e3 <= y1)
            .map(|p| (p.speed_rpm / 1e3, p.depth_m * 1e3));
        let series = chart.draw_series(LineSeries::new(pts, blue.stroke_width(1)))?;
        if j == 0 {
            series
                .label("zero-order approximation")
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], blue.stroke_width(1))
                });
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .label_font((FONT, 13))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}
