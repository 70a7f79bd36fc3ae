//! `vmt`: the virtual machine tool on the command line.

// The doc comments of the argument structs are clap's `--help` text, written for a terminal:
// `[dataset]` is a TOML table and `<id>` a placeholder there, not a link or an HTML tag.
#![allow(rustdoc::broken_intra_doc_links, rustdoc::invalid_html_tags)]

use clap::{Args, Parser, Subcommand};
use nalgebra::Vector3;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use vmt_model::kinematics::{Side, Topology};
use vmt_model::thermal::temperatures_at;
use vmt_model::thermal_deformation::REFERENCE_TEMPERATURE_C;
use vmt_scenario::Scenario;
use vmt_tools::map::{self, Plane};
use vmt_tools::plot::{self, Format};
use vmt_tools::program::{self, BallbarArgs};
use vmt_tools::{CliError, outputs, points, thermal};

/// vmt — a physics-based virtual three-axis machining centre.
///
/// Scenarios (TOML) describe a machine: its topology, strokes, the 21 geometric errors of
/// ISO 230-1 with forward/backward (backlash) values, and its thermal network. Without a
/// SCENARIO argument the built-in default machine is used (scenarios/vmc500.toml: a 500 x 400 x
/// 400 mm vertical machining centre).
#[derive(Parser)]
#[command(name = "vmt", version, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Volumetric error of the machine: at listed points, or as a map over a plane.
    ///
    /// Examples:
    ///   vmt volumetric --points points.csv            (built-in machine, CSV to stdout)
    ///   vmt volumetric my.toml --points p.csv --json --out errors.json
    ///   vmt volumetric --map --plane xy --at-mm 150 --out out/
    ///
    /// Points CSV columns: x_mm,y_mm,z_mm (required); direction_x,direction_y,direction_z
    /// (+1 forward / -1 backward approach, default +1); and optionally time_s (a time in the
    /// scenario's thermal run) or temp_<node>_c for every thermal node. Without those the
    /// machine is at 20 °C. Output: one row per point, dx_um,dy_um,dz_um (tool relative to the
    /// workpiece, actual minus nominal).
    #[command(verbatim_doc_comment)]
    Volumetric(VolumetricArgs),
    /// Run the scenario's thermal run (warm-up, cool-down, ambient drift, ISO 230-3): node
    /// temperatures and the thermal drift of the tool point, as CSV and an image.
    Thermal(ThermalArgs),
    /// List the 24 three-axis topologies (chains from workpiece W to tool T, G = ground).
    Topologies,
    /// Generate NC programs (G-code) for tests.
    #[command(subcommand)]
    Program(ProgramCommand),
    /// Run a scenario's job (a ball-bar test, a laser positioning test or a milling job) through
    /// the controller, drives and error chain; writes run.mcap, run.rrd and ground_truth.json,
    /// and a polar plot per circular test (ballbar_polar.png, or ballbar_polar_<n>_<plane>_<radius>mm.png
    /// for each test of a job of several) or laser_iso230_2.json for a positioning test.
    Run(RunArgs),
    /// The built-in machine runs the ISO 230-4 XY test (150 mm, 1000 mm/min, CW and CCW);
    /// writes the MCAP, the Rerun recording and the polar plot, diagnoses the traces and prints
    /// the diagnosis beside the run's ground truth. Takes no scenario: `vmt run SCENARIO
    /// --diagnose` does the same for a scenario of yours.
    Demo(DemoArgs),
    /// Diagnose ball-bar traces (ISO 230-4 figures and the machine errors behind them) or a
    /// laser positioning test (ISO 230-2 figures, trend, compensation table).
    ///
    /// FILE is a run of ours (run.mcap from `vmt run`; every circular test in it is diagnosed,
    /// or its laser readings evaluated, and compared with the run's ground truth) or an
    /// instrument's CSV export: a ball-bar trace with columns angle_deg,deviation_um,direction
    /// (cw/ccw) and optionally time_s, whose set-up is given with --radius-mm, --feed-mm-min and
    /// --plane; or laser readings with columns target_mm,direction (forward/backward),run and
    /// deviation_um (or reading_mm), the axis named with --axis.
    ///
    /// Examples:
    ///   vmt diagnose out/run.mcap --out out/diagnosis
    ///   vmt diagnose trace.csv --radius-mm 150 --feed-mm-min 1000 --plane XY
    ///   vmt diagnose laser.csv --axis X --out laser_report
    #[command(verbatim_doc_comment)]
    Diagnose(DiagnoseArgs),
    /// Simulate N random machines drawn from the scenario's [dataset] distributions: writes
    /// OUT/dataset.json (seed, scenario hash, labels format), OUT/runs/<id>/{run.mcap,
    /// labels.json,scenario.toml} and OUT/manifest.{csv,parquet}; continues where an interrupted
    /// invocation stopped, and refuses a folder made with another seed, scenario text or labels
    /// format (every folder of runs without dataset.json is of an older format). On a cluster,
    /// each task makes one shard (--shard, or the scheduler's environment) and `vmt dataset
    /// merge` writes the manifest; --emit writes the scheduler's launcher.
    ///
    /// Examples:
    ///   vmt dataset --scenario scenarios/dataset_xy.toml --count 500 --seed 1 --out ds
    ///   vmt dataset --scenario s.toml --count 1000000 --seed 1 --out /shared/ds --emit slurm > ds.sbatch
    ///   vmt dataset --scenario s.toml --count 100 --seed 1 --out ds --shard 2/4
    ///   vmt dataset merge ds
    #[command(verbatim_doc_comment)]
    Dataset(DatasetArgs),
    /// Diagnose every run of a dataset and compare with its truth: bias, RMS, 95th percentile,
    /// worst, share within tolerance, quiet runs (truth below half the threshold) and the
    /// false-positive rate among them, per figure (DIR/accuracy.{md,json}); warns when the
    /// dataset is unfinished (fewer runs than asked for, no manifest).
    Accuracy(AccuracyArgs),
    /// Stability lobes of a milling operation by semi-discretization (Insperger–Stépán) and
    /// the zero-order approximation (Altintas–Budak), side by side: OUT/lobes.csv (critical
    /// depth per speed by each method), OUT/sd_map.csv (spectral radius over speed × depth)
    /// and OUT/lobes.png.
    ///
    /// Examples:
    ///   vmt lobes                                  (1-DOF benchmark, a/D = 1, 0.5, 0.1, 0.05)
    ///   vmt lobes --immersion 0.05 --direction up --depth-max-mm 5
    ///   vmt lobes --scenario scenarios/milling_slot.toml --out slot_lobes
    #[command(verbatim_doc_comment)]
    Lobes(vmt_tools::lobes::LobesArgs),
    /// Milling chatter.
    #[command(subcommand)]
    Chatter(ChatterCommand),
    /// Sim-to-real gap: where a model disagrees with measured ball-bar runs, which unmodelled
    /// effect explains it (fitted on some runs, judged on held-out ones) and how much it buys.
    ///
    /// Examples:
    ///   vmt gap --model scenarios/vmc500.toml --real out/run.mcap --out gap
    ///   vmt gap --model my.toml --real cw.csv ccw.csv --radius-mm 150 --feed-mm-min 1000 --plane XY
    #[command(verbatim_doc_comment)]
    Gap(vmt_tools::gap::GapArgs),
    /// The withheld-effect check of `vmt gap`: every library effect withheld at three sizes,
    /// pairs, null and out-of-library cases; prints top-1 attribution, false attributions,
    /// held-out shrink and the confusion matrix.
    ///
    /// Example:
    ///   vmt gap-bench --out docs
    #[command(verbatim_doc_comment)]
    GapBench(vmt_tools::gap::BenchArgs),
}

#[derive(Subcommand)]
enum ChatterCommand {
    /// Detect chatter in an accelerometer log: run.mcap (its `accelerometer` stream, m/s², and
    /// the spindle speed, teeth and tool-point modes from its ground truth) or a CSV file with
    /// header time_s,ax,ay,az (time in s, strictly increasing and uniformly sampled; acceleration
    /// in m/s²; at least one of ax, ay, az; other columns ignored), or an instrument's export
    /// read through --columns and --units.
    ///
    /// Detectors: `kim` (Kim, Song & Koh 2015: Chebyshev band-pass, 50 ms block RMS against
    /// --limit, feed override = limit / RMS; the band from --band, --mode-hz or the run's
    /// weakest tool-point mode, else the paper's 6–7 kHz, and refused above the Nyquist
    /// frequency) and `better` (share of the short-time spectrum in the strongest line off the
    /// cut's forced comb, the spindle-rotation and tooth-passing harmonics where they land,
    /// aliases included; needs the spindle speed and teeth: for a CSV log give --spindle-rpm
    /// and --teeth). `both` runs what can run and says why the other cannot. Prints the
    /// decision, the detection time, the chatter frequency and the forced lines seen.
    ///
    /// Examples:
    ///   vmt chatter detect out/run.mcap
    ///   vmt chatter detect accel.csv --spindle-rpm 7500 --teeth 4 --limit 0.5 --csv windows.csv
    ///   vmt chatter detect export.csv --spindle-rpm 12000 --teeth 4 \
    ///     --columns "time_s=Time (s),ax=Accel X (m/s^2),ay=Accel Y (m/s^2),az=Accel Z (m/s^2)"
    #[command(verbatim_doc_comment)]
    Detect(vmt_tools::chatter::DetectArgs),
    /// Both detectors on a labelled set of simulated slots over spindle speeds and depths:
    /// accuracy, false positives, misses and latency.
    Bench(vmt_tools::chatter_bench::BenchArgs),
    /// Both detectors on a labelled set of simulated cuts, half of them with spindle run-out,
    /// each logged at several sample rates (default 200 cuts at 1.6, 8 and 20 kHz): accuracy,
    /// run-out cuts called chatter, misses and latency per rate. A slow sweep: 1 to 3 minutes
    /// on two cores (dev build).
    Rates(vmt_tools::chatter_bench::RatesArgs),
    /// Chatter suppression in the loop: no control, Kim's feed override, and the spindle speed
    /// moved to a stable lobe; chatter, removal rate and roughness side by side.
    Compensate(vmt_tools::chatter_bench::CompensateArgs),
}

#[derive(Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
struct DatasetArgs {
    #[command(subcommand)]
    action: Option<DatasetAction>,
    /// Scenario file with a [dataset] section.
    #[arg(long, required = true)]
    scenario: Option<PathBuf>,
    /// Number of runs (ids 0 to N-1), at least 1.
    #[arg(long, required = true)]
    count: Option<u64>,
    /// Seed of the dataset; run i's seed is derived from it and i.
    #[arg(long, required = true)]
    seed: Option<u64>,
    /// Output folder (one folder all shards write into, on a cluster file system, or a folder
    /// per shard).
    #[arg(long, required = true)]
    out: Option<PathBuf>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
    /// Make only shard I of N: the runs i with i mod N = I (0 <= I < N). Without it, the
    /// shard is read from a Slurm array task's SLURM_ARRAY_TASK_ID and SLURM_ARRAY_TASK_COUNT
    /// (or _MIN/_MAX), or from a Kubernetes Indexed Job's JOB_COMPLETION_INDEX with --shards;
    /// the command says which it used. A shard writes no manifest: `vmt dataset merge` does.
    #[arg(long, value_name = "I/N", conflicts_with_all = ["shards", "emit"])]
    shard: Option<String>,
    /// Number of shards: the Kubernetes Job's completions (its pods read their index from
    /// JOB_COMPLETION_INDEX), or the launcher's for --emit (default: 1000 runs each, at most
    /// 1000 shards).
    #[arg(long, value_name = "N")]
    shards: Option<u64>,
    /// Print the scheduler's launcher of the dataset instead of simulating: `slurm`, an sbatch
    /// job array over the shards (run it with bash to submit the array and the merge job after
    /// it), or `k8s`, an Indexed Job manifest with its merge Job.
    #[arg(long, value_enum)]
    emit: Option<EmitTo>,
    /// With --emit: shards running at once (the array's % cap, the Job's parallelism);
    /// default 100.
    #[arg(long, value_name = "M", requires = "emit")]
    max_parallel: Option<u64>,
    /// With --emit: cores of each task (its threads).
    #[arg(long, value_name = "C", requires = "emit", default_value_t = 1)]
    cpus_per_task: u64,
    /// With --emit k8s: the container image, with vmt on its PATH (default vmt:<version>).
    #[arg(long, requires = "emit")]
    image: Option<String>,
}

/// The scheduler `vmt dataset --emit` writes for.
#[derive(Clone, Copy, clap::ValueEnum)]
enum EmitTo {
    /// A Slurm job array (sbatch script).
    Slurm,
    /// A Kubernetes Indexed Job (YAML manifest).
    K8s,
}

#[derive(Subcommand)]
enum DatasetAction {
    /// Merge the shards of a dataset: checks that the folders hold one dataset (scenario text,
    /// seed, count, labels format) and every run once and whole, names the missing runs (by
    /// index and shard) and the damaged ones, then writes the manifest (CSV and Parquet). The
    /// merged folder is byte-identical to a one-machine run's.
    ///
    /// Examples:
    ///   vmt dataset merge ds                       (one folder all shards wrote into, in place)
    ///   vmt dataset merge ds-0 ds-1 ds-2 --out ds  (a folder per shard)
    #[command(verbatim_doc_comment)]
    Merge(MergeArgs),
}

#[derive(Args)]
struct MergeArgs {
    /// The shards' dataset folders (one, merged in place, when all shards wrote into it).
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// The folder to merge them into (runs are hard-linked where the file system allows).
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(Args)]
struct AccuracyArgs {
    /// A dataset folder written by `vmt dataset`.
    dir: PathBuf,
}

#[derive(Args)]
struct DiagnoseArgs {
    /// A run (MCAP) or a CSV trace file.
    file: PathBuf,
    /// Nominal radius (bar length) of a CSV trace, mm (1 to 1500).
    #[arg(long)]
    radius_mm: Option<f64>,
    /// Programmed feed of a CSV trace, mm/min (1 to 120 000).
    #[arg(long)]
    feed_mm_min: Option<f64>,
    /// Test plane of a CSV trace: XY, ZX or YZ. These three apply to ball-bar CSVs only.
    #[arg(long)]
    plane: Option<String>,
    /// Axis name of a laser positioning CSV (for the report; an MCAP run names its axis).
    #[arg(long)]
    axis: Option<String>,
    /// Also write report.txt, report.md, report.json and the plots into this folder. Report
    /// files of vmt's own that an earlier diagnosis left there and this one does not write
    /// (diagnosis_<n>.png, positioning.png, chatter.csv) are removed and listed.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
    /// Also compute the minimum-zone circular deviation.
    #[arg(long)]
    minimum_zone: bool,
    /// A CSV export's columns and units.
    #[command(flatten)]
    import: vmt_tools::import::ImportArgs,
}

fn diagnose_cmd(args: DiagnoseArgs) -> Result<(), CliError> {
    use vmt_tools::diagnose::FileKind;
    let import = args.import.parse()?;
    let kind = vmt_tools::diagnose::file_kind(&args.file, &import)?;
    let what = match kind {
        FileKind::Mcap => "an MCAP run, which records its own set-up",
        FileKind::LaserCsv => "a laser positioning CSV",
        FileKind::BallbarCsv => "a ball-bar CSV",
    };
    let flags: Vec<&str> = [
        ("--radius-mm", args.radius_mm.is_some()),
        ("--feed-mm-min", args.feed_mm_min.is_some()),
        ("--plane", args.plane.is_some()),
    ]
    .into_iter()
    .filter_map(|(n, given)| given.then_some(n))
    .collect();
    if !flags.is_empty() && kind != FileKind::BallbarCsv {
        return Err(CliError::Argument(format!(
            "{} is {what}: {} apply to ball-bar CSV traces only",
            args.file.display(),
            flags.join(", ")
        )));
    }
    if args.axis.is_some() && kind != FileKind::LaserCsv {
        return Err(CliError::Argument(format!(
            "{} is {what}: --axis applies to laser positioning CSVs only",
            args.file.display()
        )));
    }
    let csv =
        vmt_tools::diagnose::csv_setup(args.radius_mm, args.feed_mm_min, args.plane.as_deref())?;
    if let Some(p) = vmt_tools::positioning::read(&args.file, args.axis.as_deref(), &import)? {
        return positioning_report(&p, args.json, args.out.as_deref());
    }
    let options = vmt_ballbar::Options {
        minimum_zone: args.minimum_zone,
        ..Default::default()
    };
    let d = vmt_tools::diagnose::diagnose_file(&args.file, csv, &import, &options)?;
    if args.json {
        vmt_tools::outln!("{:#}", vmt_tools::diagnose::json(&d))?;
    } else {
        vmt_tools::out!("{}", vmt_tools::diagnose::text(&d))?;
    }
    if let Some(dir) = &args.out {
        wrote_report(dir, vmt_tools::diagnose::write(&d, dir)?)?;
    }
    Ok(())
}

/// Lists the report files `vmt diagnose --out DIR` wrote, and removes what an earlier diagnosis
/// left in DIR that this one did not write (a ball-bar test of seven traces after one of two
/// kept `diagnosis_3.png` to `diagnosis_7.png`; a laser report after a ball-bar one kept its
/// plots).
fn wrote_report(dir: &Path, files: Vec<PathBuf>) -> Result<(), CliError> {
    for f in &files {
        vmt_tools::errln!("wrote {}", f.display());
    }
    let removed = outputs::remove_stale(dir, &files, outputs::is_diagnosis_file)?;
    note_removed(dir, &removed);
    Ok(())
}

/// Prints (and with `out`, writes) the report of a positioning test.
fn positioning_report(
    p: &vmt_tools::positioning::Positioning,
    json: bool,
    out: Option<&Path>,
) -> Result<(), CliError> {
    if json {
        vmt_tools::outln!("{:#}", vmt_tools::positioning::json(p))?;
    } else {
        vmt_tools::out!("{}", vmt_tools::positioning::text(p))?;
    }
    if let Some(dir) = out {
        wrote_report(dir, vmt_tools::positioning::write(p, dir)?)?;
    }
    Ok(())
}

#[derive(Subcommand)]
enum ProgramCommand {
    /// A ball-bar circular test (ISO 230-4): feed-in, overshoot, data arc, overshoot, feed-out,
    /// for each direction; the data arcs lie between (DATA CW START) and (DATA CW END) comments,
    /// where the ball bar records when the program runs as a scenario's kind = "program" job.
    ///
    /// Example:
    ///   vmt program ballbar --plane XY --radius-mm 150 --feed-mm-min 1000 --directions cw,ccw
    #[command(verbatim_doc_comment)]
    Ballbar(BallbarArgs),
}

#[derive(Args)]
struct VolumetricArgs {
    /// Scenario file (TOML); the built-in default machine when omitted.
    scenario: Option<PathBuf>,
    /// CSV file of points to evaluate.
    #[arg(long, conflicts_with = "map", required_unless_present = "map")]
    points: Option<PathBuf>,
    /// Write JSON instead of CSV (with --points).
    #[arg(long, requires = "points")]
    json: bool,
    /// Map the error over a plane, for forward and backward approach.
    #[arg(long)]
    map: bool,
    /// Plane of the map: xy, xz (= zx) or yz, any case, or G17, G18, G19.
    #[arg(long, default_value = "xy", requires = "map")]
    plane: Plane,
    /// Coordinate of the axis normal to the plane, mm (within its stroke).
    #[arg(long, allow_negative_numbers = true, required_if_eq("map", "true"))]
    at_mm: Option<f64>,
    /// Grid points per side of the map.
    #[arg(long, default_value_t = 41, requires = "map")]
    grid: usize,
    /// Image format of the map.
    #[arg(long, value_enum, default_value = "png", requires = "map")]
    format: Format,
    /// Evaluate the map at this time of the thermal run, h (default: the machine at 20 °C).
    #[arg(long, requires = "map")]
    time_h: Option<f64>,
    /// Output: a file with --points (default stdout); a folder with --map (default `out`).
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(Args)]
struct ThermalArgs {
    /// Scenario file (TOML); the built-in default machine when omitted.
    scenario: Option<PathBuf>,
    /// Tool position whose drift is reported, mm, as x,y,z.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "250,200,200",
        allow_negative_numbers = true
    )]
    probe_mm: Vec<f64>,
    /// Sampling interval of the report, s.
    #[arg(long, default_value_t = 60.0)]
    every_s: f64,
    /// Image format.
    #[arg(long, value_enum, default_value = "png")]
    format: Format,
    /// Output folder.
    #[arg(long, default_value = "out")]
    out: PathBuf,
}

#[derive(Args)]
struct RunArgs {
    /// Scenario file (TOML); the built-in default machine when omitted.
    scenario: Option<PathBuf>,
    /// Output folder. Files of vmt's own that an earlier run left there and this run does not
    /// write are removed once the run's files are complete (a note lists them).
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Plant fidelity, overriding the scenario: reduced, multibody or compliant (the multibody
    /// on compliant guide blocks; needs the carriages).
    #[arg(long)]
    fidelity: Option<String>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
    /// Evaluate what the run recorded into OUT/diagnosis: ball-bar traces and a positioning
    /// test as `vmt diagnose` does on its MCAP, a milling run's accelerometers as `vmt chatter
    /// detect` does (report.txt and chatter.csv).
    #[arg(long)]
    diagnose: bool,
}

#[derive(Args)]
struct DemoArgs {
    /// Output folder, as for `vmt run --out` (an earlier run's files of vmt's own that the
    /// demo does not write are removed).
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Plant fidelity: reduced, multibody or compliant.
    #[arg(long)]
    fidelity: Option<String>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

fn run_job(args: RunArgs) -> Result<(), CliError> {
    let text = match &args.scenario {
        Some(p) => std::fs::read_to_string(p)
            .map_err(|e| CliError::input(&p.display().to_string(), None, e.to_string()))?,
        None => vmt_scenario::BUILTIN_DEFAULT.to_string(),
    };
    let scenario = load(args.scenario.as_deref())?;
    let fidelity = match args.fidelity.as_deref() {
        None => None,
        Some("reduced") => Some(vmt_sim::plant::Fidelity::Reduced),
        Some("multibody") => Some(vmt_sim::plant::Fidelity::Multibody),
        Some("compliant") => Some(vmt_sim::plant::Fidelity::Compliant),
        Some(other) => {
            return Err(CliError::Argument(format!(
                "--fidelity {other}: accepted: reduced, multibody, compliant"
            )));
        }
    };
    vmt_tools::out::output_dir(&args.out)?;
    let (run, written) =
        vmt_tools::job::execute_and_write(&scenario, &text, fidelity, args.quiet, &args.out)?;
    vmt_tools::outln!(
        "{} ({} plant, seed {})",
        run.scenario_name,
        run.fidelity,
        run.seed
    )?;
    let figures = vmt_tools::job::summary_figures(&run);
    if !figures.is_empty() {
        vmt_tools::outln!("{figures}")?;
    }
    for line in vmt_tools::job::truth_summary(&run.ground_truth) {
        vmt_tools::outln!("{line}")?;
    }
    for f in &written.files {
        vmt_tools::outln!("wrote {}", f.display())?;
    }
    // An earlier run's files go once this run's are complete: a run that fails leaves the
    // earlier one whole.
    let mut removed = outputs::remove_stale(&args.out, &written.files, outputs::is_run_file)?;
    let diagnosed = if args.diagnose {
        diagnose_run(&run, &args.out)
    } else {
        outputs::clear_diagnosis(&args.out)
    };
    match diagnosed {
        Ok(stale) => removed.extend(stale),
        Err(e) => {
            // A failed diagnosis leaves no earlier one beside this run either (where it can be
            // removed: the diagnosis' own error is the one to report); the note says why before
            // the error that follows it.
            removed.extend(outputs::clear_diagnosis(&args.out).unwrap_or_default());
            vmt_tools::errln!(
                "note: the run's files are complete in {}; its diagnosis failed (below)",
                args.out.display()
            );
            note_removed(&args.out, &removed);
            return Err(e);
        }
    }
    note_removed(&args.out, &removed);
    Ok(())
}

/// `vmt run --diagnose` after the run's files are written: prints the diagnosis and the files
/// it wrote into DIR/diagnosis, or a note when the run recorded nothing to diagnose; returns
/// what an earlier run left there that this one did not write, removed.
fn diagnose_run(run: &vmt_sim::run::Run, dir: &Path) -> Result<Vec<PathBuf>, CliError> {
    let Some(d) = vmt_tools::job::diagnose(run, dir)? else {
        vmt_tools::errln!(
            "note: --diagnose: the run recorded no ball-bar traces, laser readings or accelerometers to diagnose"
        );
        return outputs::clear_diagnosis(dir);
    };
    vmt_tools::outln!()?;
    vmt_tools::out!("{}", d.text)?;
    for f in &d.files {
        vmt_tools::outln!("wrote {}", f.display())?;
    }
    outputs::remove_stale(
        &dir.join(outputs::DIAGNOSIS),
        &d.files,
        outputs::is_diagnosis_file,
    )
}

/// The note for the files removed from `dir`, if any.
fn note_removed(dir: &Path, removed: &[PathBuf]) {
    if let Some(note) = outputs::removed_note(dir, removed) {
        vmt_tools::errln!("note: {note}");
    }
}

/// `vmt dataset`: a merge, a launcher, or the dataset (a shard of it).
fn dataset(a: DatasetArgs) -> Result<(), CliError> {
    if let Some(DatasetAction::Merge(m)) = &a.action {
        return vmt_tools::dataset::merge(&m.parts, m.out.as_deref());
    }
    // clap requires these without a subcommand.
    let (Some(scenario), Some(count), Some(seed), Some(out)) =
        (&a.scenario, a.count, a.seed, &a.out)
    else {
        return Err(CliError::Argument(
            "vmt dataset needs --scenario, --count, --seed and --out".into(),
        ));
    };
    let make = vmt_tools::dataset::Make {
        request: vmt_dataset::Request {
            scenario,
            count,
            seed,
            out,
            quiet: a.quiet,
            shard: None,
        },
        shard: a.shard.as_deref(),
        shards: a.shards,
    };
    match a.emit {
        None => vmt_tools::dataset::command(&make),
        Some(to) => vmt_tools::dataset::emit(&vmt_tools::dataset::Emit {
            make,
            scheduler: match to {
                EmitTo::Slurm => vmt_dataset::launch::Scheduler::Slurm,
                EmitTo::K8s => vmt_dataset::launch::Scheduler::Kubernetes,
            },
            parallel: a.max_parallel,
            cpus: a.cpus_per_task,
            image: a.image.as_deref(),
        }),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Volumetric(args) => volumetric(args),
        Command::Thermal(args) => thermal_run(args),
        Command::Program(ProgramCommand::Ballbar(args)) => program::ballbar(&args),
        Command::Run(args) => run_job(args),
        Command::Demo(args) => run_job(RunArgs {
            scenario: None,
            out: args.out,
            fidelity: args.fidelity,
            quiet: args.quiet,
            diagnose: true,
        }),
        Command::Diagnose(args) => diagnose_cmd(args),
        Command::Dataset(a) => dataset(a),
        Command::Accuracy(a) => vmt_tools::accuracy::command(&a.dir),
        Command::Lobes(a) => vmt_tools::lobes::command(&a),
        Command::Chatter(ChatterCommand::Detect(a)) => vmt_tools::chatter::command(&a),
        Command::Chatter(ChatterCommand::Bench(a)) => vmt_tools::chatter_bench::bench(&a),
        Command::Chatter(ChatterCommand::Rates(a)) => vmt_tools::chatter_bench::rates(&a),
        Command::Chatter(ChatterCommand::Compensate(a)) => vmt_tools::chatter_bench::compensate(&a),
        Command::Gap(a) => vmt_tools::gap::command(&a),
        Command::GapBench(a) => vmt_tools::gap::bench_command(&a),
        Command::Topologies => topologies(),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            vmt_tools::errln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

fn load(scenario: Option<&Path>) -> Result<Scenario, CliError> {
    Ok(match scenario {
        Some(p) => vmt_scenario::load(p)?,
        None => vmt_scenario::builtin()?,
    })
}

fn create(path: &Path) -> Result<BufWriter<File>, CliError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| CliError::output(dir, e))?;
    }
    File::create(path)
        .map(BufWriter::new)
        .map_err(|e| CliError::output(path, e))
}

fn volumetric(args: VolumetricArgs) -> Result<(), CliError> {
    let scenario = load(args.scenario.as_deref())?;
    if let Some(path) = &args.points {
        let pts = points::read(path, &scenario.machine)?;
        let errors = points::evaluate(&scenario, &pts)?;
        return match &args.out {
            Some(out) => {
                let mut w = create(out)?;
                points::write(&mut w, &errors, args.json)
                    .and_then(|_| w.flush())
                    .map_err(|e| CliError::output(out, e))
            }
            None => {
                let mut w = std::io::stdout().lock();
                points::write(&mut w, &errors, args.json).map_err(CliError::stdout)
            }
        };
    }
    let at_mm = args
        .at_mm
        .ok_or_else(|| CliError::Argument("--map needs --at-mm".into()))?;
    let temps = map_temperatures(&scenario, args.time_h)?;
    let m = map::compute(
        &scenario.machine,
        args.plane,
        at_mm * 1e-3,
        args.grid,
        &temps,
    )?;
    let dir = args.out.unwrap_or_else(|| PathBuf::from("out"));
    let stem = format!(
        "volumetric_{}_{}{:.0}mm",
        args.plane,
        m.plane.normal.letter().to_ascii_lowercase(),
        at_mm
    );
    let csv_path = dir.join(format!("{stem}.csv"));
    let mut w = create(&csv_path)?;
    m.write_csv(&mut w)
        .and_then(|_| w.flush())
        .map_err(|e| CliError::output(&csv_path, e))?;
    let image = dir.join(format!("{stem}.{}", args.format.extension()));
    plot::draw_map(&m, &image, args.format)?;
    vmt_tools::outln!(
        "{}: volumetric error on the {} plane at {} = {at_mm} mm",
        scenario.machine.name,
        args.plane,
        m.plane.normal
    )?;
    for (k, name) in ["X", "Y", "Z"].iter().enumerate() {
        vmt_tools::outln!("  max |Δ{name}| = {:8.3} µm", m.max_abs(k) * 1e6)?;
    }
    vmt_tools::outln!("wrote {}\nwrote {}", csv_path.display(), image.display())?;
    Ok(())
}

fn map_temperatures(scenario: &Scenario, time_h: Option<f64>) -> Result<Vec<f64>, CliError> {
    let n = scenario
        .machine
        .thermal
        .as_ref()
        .map_or(0, |t| t.network.node_count());
    let Some(h) = time_h else {
        return Ok(vec![REFERENCE_TEMPERATURE_C; n]);
    };
    if !(0.0..=points::MAX_TIME_S / 3600.0).contains(&h) {
        return Err(CliError::Argument(format!(
            "--time-h {h}: a time from 0 to {:.0} h is accepted",
            points::MAX_TIME_S / 3600.0
        )));
    }
    let (Some(t), Some(run)) = (&scenario.machine.thermal, &scenario.thermal_run) else {
        return Err(CliError::Argument(
            "--time-h needs a scenario with a thermal model and [thermal_run]".into(),
        ));
    };
    let hours = run.schedule.duration_s() / 3600.0;
    if h > hours {
        return Err(CliError::Argument(format!(
            "--time-h {h}: the scenario's thermal run lasts {hours} h; a time within it is accepted (extend [thermal_run] to look later)"
        )));
    }
    let temps = temperatures_at(&t.network, &run.schedule, run.step_s, &[h * 3600.0])
        .map_err(|e| CliError::Model(e.to_string()))?;
    Ok(temps.into_iter().next().unwrap_or_default())
}

fn thermal_run(args: ThermalArgs) -> Result<(), CliError> {
    let scenario = load(args.scenario.as_deref())?;
    let [x, y, z] = args.probe_mm[..] else {
        return Err(CliError::Argument(format!(
            "--probe-mm {:?}: three numbers x,y,z in mm are accepted",
            args.probe_mm
        )));
    };
    let probe = Vector3::new(x, y, z) * 1e-3;
    let h = thermal::run(&scenario, probe, args.every_s)?;
    let csv_path = args.out.join("thermal_run.csv");
    let mut w = create(&csv_path)?;
    h.write_csv(&mut w)
        .and_then(|_| w.flush())
        .map_err(|e| CliError::output(&csv_path, e))?;
    let image = args
        .out
        .join(format!("thermal_run.{}", args.format.extension()));
    h.draw(&image, args.format)?;
    let taus: Vec<String> = h
        .time_constants_s
        .iter()
        .map(|t| format!("{:.2}", t / 3600.0))
        .collect();
    vmt_tools::outln!(
        "{}: thermal run of {:.1} h",
        scenario.machine.name,
        h.times_s.last().copied().unwrap_or(0.0) / 3600.0
    )?;
    vmt_tools::outln!("  time constants of the network (h): {}", taus.join(", "))?;
    let (worst, at) = h.largest_drift;
    vmt_tools::outln!(
        "  largest drift of the tool point at the probe: {:.2} µm (at {:.2} h; over every {} s step of the run)",
        worst * 1e6,
        at / 3600.0,
        scenario.thermal_run.as_ref().map_or(0.0, |r| r.step_s)
    )?;
    vmt_tools::outln!("wrote {}\nwrote {}", csv_path.display(), image.display())?;
    Ok(())
}

fn topologies() -> Result<(), CliError> {
    vmt_tools::outln!(
        "The 24 topologies of a three-axis machine, workpiece (W) to tool (T), G = ground:"
    )?;
    for t in Topology::all() {
        let side = |s: Side| {
            let axes: Vec<String> = t
                .axis_order()
                .iter()
                .filter(|a| t.axis_side(**a) == s)
                .map(|a| a.to_string())
                .collect();
            if axes.is_empty() {
                "-".to_string()
            } else {
                axes.join(" ")
            }
        };
        vmt_tools::outln!(
            "  {t}   workpiece carried by: {:6} tool carried by: {}",
            side(Side::Workpiece),
            side(Side::Tool)
        )?;
    }
    Ok(())
}
