//! Ball-bar jobs on the built-in machine: the default centre and start, the generator's keys in
//! [job], and a program job recording the ball bar between the program's DATA markers.

use nalgebra::Vector3;
use std::path::Path;
use vmt_scenario::{BUILTIN_DEFAULT, Scenario, ScenarioError, parse};
use vmt_sim::nc::ballbar::default_start_deg;
use vmt_sim::nc::{ArcDirection, CircularTest, Motion, Plane};
use vmt_sim::run::BallbarTrace;

/// The built-in [job]'s keys after `kind`.
const XY_JOB: &str = "plane = \"XY\"\ncenter_mm = [250.0, 200.0, 200.0]\nradius_mm = 150.0\n\
                      feed_mm_min = 1000.0\narc_deg = 360.0\ndirections = [\"cw\", \"ccw\"]\n";

/// The built-in scenario with its ball-bar job's keys replaced by `keys`.
fn with_job(keys: &str) -> String {
    assert!(BUILTIN_DEFAULT.contains(XY_JOB));
    BUILTIN_DEFAULT.replacen(XY_JOB, keys, 1)
}

fn load(text: &str, dir: Option<&Path>) -> Result<Scenario, ScenarioError> {
    parse(text, "s.toml", dir)
}

fn job_of(s: &Scenario) -> &vmt_sim::simulate::Job {
    &s.execution.as_ref().expect("a job").job
}

/// Every end point of the job's program, m.
fn ends(job: &vmt_sim::simulate::Job) -> Vec<Vector3<f64>> {
    job.program
        .blocks
        .iter()
        .filter_map(|b| match b.motion {
            Motion::Rapid { to } | Motion::Linear { to, .. } | Motion::Arc { to, .. } => Some(to),
            Motion::Dwell { .. } => None,
        })
        .collect()
}

/// The built-in machine's carriages travel X 0..500, Y 0..400, Z 0..400 mm with a 100 mm tool:
/// the default centre is the tool point at mid-stroke, (250, 200, 100) mm, and a 150 mm circle
/// in ZX or YZ fits (it was refused at Z 407 mm with the carriages' middle as the tool point).
#[test]
fn vertical_circles_fit_the_built_in_strokes_about_the_default_centre() {
    for plane in ["ZX", "YZ"] {
        for arc in ["360.0", "220.0", "180.0"] {
            let keys = format!(
                "plane = \"{plane}\"\nradius_mm = 150.0\nfeed_mm_min = 1000.0\narc_deg = {arc}\n"
            );
            let s = load(&with_job(&keys), None).unwrap_or_else(|e| panic!("{plane} {arc}: {e}"));
            let bar = &job_of(&s).ballbar[0];
            assert!((bar.center - Vector3::new(0.25, 0.2, 0.1)).norm() < 1e-15);
        }
    }
}

/// A partial arc in a vertical plane runs over the top by default: no point of its program
/// (feed-in, overshoots, data arc) lies more than 20° + 45° below the centre for 220°, and its
/// data arcs start and end 20° below the horizontal on either side.
#[test]
fn partial_vertical_arcs_run_over_the_top_unless_a_start_is_given() {
    let keys = "plane = \"ZX\"\nradius_mm = 150.0\nfeed_mm_min = 1000.0\narc_deg = 220.0\n";
    let s = load(&with_job(keys), None).unwrap();
    let job = job_of(&s);
    let c = Vector3::new(0.25, 0.2, 0.1);
    let lowest = ends(job).iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
    // The overshoot ends 65° below the horizontal, 1.5 mm outside the circle.
    let want = c.z - 0.1515 * 65f64.to_radians().sin();
    assert!((lowest - want).abs() < 1e-7, "{lowest} vs {want}");
    let bar = &job.ballbar[0];
    for (_, range) in &bar.data {
        let Motion::Arc { to, .. } = job.program.blocks[range.end - 1].motion else {
            panic!("a data arc");
        };
        assert!(
            (to.z - (c.z - 0.15 * 20f64.to_radians().sin())).abs() < 1e-7,
            "{to:?}"
        );
    }
    // An explicit start is honoured: 0° is +Z in ZX, so the arc from 0° ends at 220°, 40°
    // below the horizontal on -X.
    let s = load(&with_job(&format!("{keys}start_deg = 0.0\n")), None).unwrap();
    let job = job_of(&s);
    let (_, range) = &job.ballbar[0].data[1];
    let Motion::Arc { to, .. } = job.program.blocks[range.end - 1].motion else {
        panic!("a data arc");
    };
    let a = 220f64.to_radians();
    let want = c + 0.15 * Vector3::new(a.sin(), 0.0, a.cos());
    assert!((to - want).norm() < 1e-7, "{to:?} vs {want:?}");
}

/// The generator's settings are keys of [job], refused at their key with what is accepted.
#[test]
fn start_overshoot_and_feed_in_are_refused_at_their_keys() {
    let base = "plane = \"ZX\"\nradius_mm = 150.0\nfeed_mm_min = 1000.0\narc_deg = 180.0\n";
    for (extra, key, says) in [
        (
            "start_deg = 400.0",
            "job.start_deg",
            "start angle 400 deg: the start angle must be from -360 to 360 deg",
        ),
        (
            "overshoot_deg = -1.0",
            "job.overshoot_deg",
            "overshoot -1 deg: the overshoot must be >= 0 deg",
        ),
        (
            "overshoot_deg = 300.0",
            "job.overshoot_deg",
            "the data arc (180 deg) plus both overshoots at most 720 deg",
        ),
        (
            "feed_in_mm = 12.0",
            "job.feed_in_mm",
            "feed-in 12 mm: the feed-in must be 0 to 10 mm",
        ),
    ] {
        let text = with_job(&format!("{base}{extra}\n"));
        let e = load(&text, None).expect_err(extra);
        assert_eq!(e.key.as_deref(), Some(key), "{e}");
        let line = text.lines().position(|l| l == extra).unwrap() + 1;
        assert_eq!(e.position.map(|p| p.0), Some(line), "{e}");
        assert!(e.message.contains(says), "{e}");
    }
    // A circle leaving a stroke about the default centre names the radius: only a smaller
    // circle fits there.
    let e = load(&with_job(&base.replace("150.0", "250.0")), None).expect_err("too big");
    assert_eq!(e.key.as_deref(), Some("job.radius_mm"), "{e}");
    assert!(e.message.contains("beyond its stroke 0 to 400 mm"), "{e}");
}

/// The test `vmt program ballbar --plane ZX --radius-mm 150 --feed-mm-min 1000 --arc-deg 220`
/// writes for the built-in machine.
fn zx_220_test() -> CircularTest {
    let mut t = CircularTest::iso230_4(
        Plane::Zx,
        Vector3::new(0.25, 0.2, 0.1),
        0.15,
        1000.0 / 60_000.0,
    );
    t.arc_deg = 220.0;
    t.start_deg = default_start_deg(Plane::Zx, 220.0);
    t
}

/// The built-in scenario, its bar noise-free, running `p.nc` in `dir` as a program job.
fn program_scenario(dir: &Path, program: &str, bar: bool) -> String {
    std::fs::write(dir.join("p.nc"), program).unwrap();
    let text = BUILTIN_DEFAULT
        .replacen(
            &format!("kind = \"ballbar\"\n{XY_JOB}"),
            "kind = \"program\"\nprogram = \"p.nc\"\n",
            1,
        )
        .replacen("noise_um = 0.1", "noise_um = 0.0", 1)
        .replacen("resolution_um = 0.1", "resolution_um = 0.0", 1);
    if bar {
        text
    } else {
        let at = text.find("[instruments.ballbar]").unwrap();
        let end = text[at..].find("\n\n").map_or(text.len(), |e| at + e + 2);
        format!("{}{}", &text[..at], &text[end..])
    }
}

/// A program job records the ball bar on every circle between its DATA markers: one set-up,
/// as the ball-bar job has, for the CW and CCW runs on one circle.
#[test]
fn a_program_job_records_the_ball_bar_between_its_data_markers() {
    let dir = tempfile::tempdir().unwrap();
    let test = zx_220_test();
    let s = load(
        &program_scenario(dir.path(), &test.gcode(), true),
        Some(dir.path()),
    )
    .unwrap();
    let job = job_of(&s);
    assert_eq!(job.ballbar.len(), 1);
    let bar = &job.ballbar[0];
    assert_eq!(bar.plane, Plane::Zx);
    assert!((bar.center - test.center).norm() < 1e-12);
    assert_eq!(bar.radius_m, 0.15);
    assert_eq!(bar.feed_m_s, 1000.0 / 60_000.0);
    let dirs: Vec<ArcDirection> = bar.data.iter().map(|(d, _)| *d).collect();
    assert_eq!(dirs, vec![ArcDirection::Cw, ArcDirection::Ccw]);
    assert_eq!(Some(bar.data.clone()), test.data_blocks(&job.program));
}

/// A ball bar given to a program without DATA markers records nothing, and the job says so;
/// a data arc that is not one circle, or runs faster than the controller allows, is refused at
/// its line.
#[test]
fn a_program_job_says_when_its_bar_records_nothing_and_refuses_bad_data_arcs() {
    let dir = tempfile::tempdir().unwrap();
    let plain = "G21 G90 G94 G17\nF1000\nG1 X250 Y200 Z100\nM30\n";
    for (bar, notes) in [(true, 1), (false, 0)] {
        let s = load(&program_scenario(dir.path(), plain, bar), Some(dir.path())).unwrap();
        let e = s.execution.unwrap();
        assert!(e.job.ballbar.is_empty());
        assert_eq!(e.notes.len(), notes, "{:?}", e.notes);
        if bar {
            let says = "[instruments.ballbar] records nothing: p.nc marks no data arc";
            assert!(e.notes[0].starts_with(says), "{:?}", e.notes);
        }
    }

    let program = zx_220_test().gcode();
    let first_data = program
        .lines()
        .position(|l| l == "(DATA CW START)")
        .unwrap()
        + 2;
    let mut lines: Vec<String> = program.lines().map(str::to_string).collect();
    let arc = lines[first_data - 1].clone();
    let straight = format!("G1 {}", &arc[3..arc.find(" I").unwrap()]);
    let faster = format!("F20000 {arc}");
    for (by, says) in [
        (straight.as_str(), "not a G2/G3 move"),
        (
            faster.as_str(),
            "a test feed of 20000 mm/min is not accepted",
        ),
    ] {
        lines[first_data - 1] = by.to_string();
        let text = program_scenario(dir.path(), &(lines.join("\n") + "\n"), true);
        let e = load(&text, Some(dir.path())).expect_err(says);
        assert!(e.file.ends_with("p.nc"), "{e}");
        assert_eq!(e.position.map(|p| p.0), Some(first_data), "{e}");
        assert!(e.message.contains(says), "{e}");
    }
}

/// `a`'s deviations less `b`'s at the same angles (linear between `b`'s samples), µm: the
/// largest, each sample's difference taken at the best of that angle and one sample of `b`
/// either side (an event as fast as a sample period, a slip at a reversal, may fall one sample
/// apart in the two runs), and the RMS difference at the same angles.
fn differences_um(a: &BallbarTrace, b: &BallbarTrace) -> (f64, f64) {
    let sign = if a.direction == "cw" { -1.0 } else { 1.0 };
    let at = |deg: f64| {
        let k = b.angle_deg.partition_point(|&x| sign * x < sign * deg);
        let k = k.clamp(1, b.angle_deg.len() - 1);
        let (x0, x1) = (b.angle_deg[k - 1], b.angle_deg[k]);
        let (y0, y1) = (b.deviation_um[k - 1], b.deviation_um[k]);
        (
            y0 + (y1 - y0) * ((deg - x0) / (x1 - x0)).clamp(0.0, 1.0),
            x1 - x0,
        )
    };
    let (mut largest, mut sum_sq) = (0.0f64, 0.0);
    for (&deg, &d) in a.angle_deg.iter().zip(&a.deviation_um) {
        let (same, spacing) = at(deg);
        sum_sq += (d - same).powi(2);
        let shifted = [deg - spacing, deg + spacing].map(|x| (d - at(x).0).abs());
        largest = largest.max(shifted.into_iter().fold((d - same).abs(), f64::min));
    }
    (largest, (sum_sq / a.angle_deg.len() as f64).sqrt())
}

/// The program `vmt program ballbar` writes, run as a program job, gives the traces of the
/// equivalent ball-bar job: the same labels, as many samples within one, and deviations within
/// numerical noise at the same angles (the program job first travels to the start from the
/// carriages' zero, so its samples fall at other instants on the circle). The bar is
/// noise-free and unquantised here, so that the traces compare the machine's motion.
#[test]
fn a_written_program_gives_the_ball_bar_jobs_traces() {
    let dir = tempfile::tempdir().unwrap();
    let keys = "plane = \"ZX\"\nradius_mm = 150.0\nfeed_mm_min = 1000.0\narc_deg = 220.0\n";
    let job_text = with_job(keys)
        .replacen("noise_um = 0.1", "noise_um = 0.0", 1)
        .replacen("resolution_um = 0.1", "resolution_um = 0.0", 1);
    let program_text = program_scenario(dir.path(), &zx_220_test().gcode(), true);
    let run = |text: &str| {
        let s = load(text, Some(dir.path())).unwrap();
        let e = s.execution.as_ref().unwrap();
        e.simulate(&s.machine, text, &mut |_| {}).unwrap().ballbar
    };
    let (from_job, from_program) = (run(&job_text), run(&program_text));
    assert_eq!(from_job.len(), 2);
    assert_eq!(from_program.len(), 2);
    for (a, b) in from_job.iter().zip(&from_program) {
        assert_eq!(a.label, b.label);
        assert!(
            a.angle_deg.len().abs_diff(b.angle_deg.len()) <= 1,
            "{}",
            a.label
        );
        let span = a.deviation_um.iter().fold(0.0f64, |m, d| m.max(d.abs()));
        let (largest, rms) = differences_um(a, b);
        assert!(
            span > 10.0,
            "{}: the machine's errors show, {span} µm",
            a.label
        );
        // Measured: 0.11 and 0.10 µm largest, 0.06 µm RMS (CW, CCW), below the bar's 0.1 µm
        // resolution, which the comparison leaves out. Z's slip at its reversal (1.7 µm within
        // a sample period) falls one sample apart in the two runs since the axes are
        // fine-interpolated by axis (commands that differ by picometres): 1.67 µm at the same
        // angle, hence the largest within a sample either side.
        assert!(
            largest < 0.15 && rms < 0.08,
            "{}: {largest}, {rms} µm",
            a.label
        );
    }
}

/// A list of radii runs a test at each about the same centre, in turn: each test's data arcs
/// are arcs of its own radius about that centre (checked on the program's arc blocks, not on
/// what the job builder says of them), in the directions given, and later tests' arcs come
/// after earlier ones' in the program.
#[test]
fn a_list_of_radii_runs_a_test_at_each_about_one_centre() {
    let keys = "plane = \"XY\"\ncenter_mm = [250.0, 200.0, 200.0]\nradius_mm = [150.0, 75.0]\n\
                feed_mm_min = 1000.0\ndirections = [\"cw\", \"ccw\"]\n";
    let s = load(&with_job(keys), None).unwrap();
    let job = job_of(&s);
    assert_eq!(job.ballbar.len(), 2);
    let mut last_end = 0;
    for (bar, radius) in job.ballbar.iter().zip([0.15, 0.075]) {
        assert!((bar.radius_m - radius).abs() < 1e-15);
        let dirs: Vec<ArcDirection> = bar.data.iter().map(|(d, _)| *d).collect();
        assert_eq!(dirs, [ArcDirection::Cw, ArcDirection::Ccw]);
        assert_data_arcs(job, bar, (0.25, 0.2), radius, &mut last_end);
    }
}

/// Checks on the program's blocks that every data arc of test `bar` is an arc block about
/// `centre` (X, Y, m) of `radius` (m) in its run's direction, and that its runs come after
/// `last_end` (the end of the data blocks checked so far, moved on): the tests run in turn.
fn assert_data_arcs(
    job: &vmt_sim::simulate::Job,
    bar: &vmt_sim::simulate::BallbarSetup,
    (cx, cy): (f64, f64),
    radius: f64,
    last_end: &mut usize,
) {
    for (dir, range) in &bar.data {
        assert!(range.start >= *last_end, "the tests run in turn");
        *last_end = range.end;
        for b in &job.program.blocks[range.clone()] {
            let Motion::Arc {
                to,
                center,
                direction,
                ..
            } = b.motion
            else {
                panic!("a data block that is no arc: {:?}", b.motion);
            };
            assert_eq!(direction, *dir);
            let off = Vector3::new(center.x - cx, center.y - cy, 0.0);
            assert!(off.norm() < 1e-9, "{center:?}");
            let r = (to - center).xy().norm();
            assert!((r - radius).abs() < 1e-9, "{r} against {radius}");
        }
    }
}

/// A radius list that is empty, too long or holds a circle that leaves the strokes is refused
/// at its key (the element's for a bad radius).
#[test]
fn a_bad_radius_list_is_refused_at_its_key() {
    let job = |radii: &str| {
        with_job(&format!(
            "plane = \"XY\"\nradius_mm = {radii}\nfeed_mm_min = 1000.0\n"
        ))
    };
    let e = load(&job("[]"), None).expect_err("empty");
    assert_eq!(e.key.as_deref(), Some("job.radius_mm"), "{e}");
    assert!(e.message.contains("a list of 1 to 8 radii"), "{e}");
    let e = load(&job(&format!("{:?}", vec![50.0; 9])), None).expect_err("nine");
    assert!(e.message.contains("9 radii are not accepted"), "{e}");
    let e = load(&job("[100.0, 0.0]"), None).expect_err("zero");
    assert_eq!(e.key.as_deref(), Some("job.radius_mm[1]"), "{e}");
    let e = load(&job("[100.0, 250.0]"), None).expect_err("too big");
    assert_eq!(e.key.as_deref(), Some("job.radius_mm"), "{e}");
    assert!(e.message.contains("beyond its stroke"), "{e}");
}

/// A list of centres runs every radius about each centre in turn, the bar set up anew at each
/// with its own pivot offset: checked on the program's arc blocks (their centres and radii),
/// not on what the job builder says of them, and on each test's bar.
#[test]
fn a_list_of_centres_runs_every_radius_about_each_with_its_own_set_up() {
    let keys = "plane = \"XY\"\ncenter_mm = [[250.0, 200.0, 200.0], [330.0, 240.0, 200.0]]\n\
                radius_mm = [100.0, 50.0]\nfeed_mm_min = 1000.0\ndirections = [\"cw\", \"ccw\"]\n";
    let text = with_job(keys).replacen(
        "setup_eccentricity_um = [3.0, -2.0, 0.0]\n",
        "setup_eccentricity_um = [[3.0, -2.0, 0.0], [-4.0, 1.0, 0.0]]\n",
        1,
    );
    let s = load(&text, None).unwrap();
    let job = job_of(&s);
    let expected = [
        ((0.25, 0.2), 0.1, (3.0, -2.0)),
        ((0.25, 0.2), 0.05, (3.0, -2.0)),
        ((0.33, 0.24), 0.1, (-4.0, 1.0)),
        ((0.33, 0.24), 0.05, (-4.0, 1.0)),
    ];
    assert_eq!(job.ballbar.len(), expected.len());
    let mut last_end = 0;
    for (bar, ((cx, cy), radius, (ex, ey))) in job.ballbar.iter().zip(expected) {
        let e = bar.spec.setup_eccentricity_m * 1e6;
        assert!((e.x - ex).abs() < 1e-9 && (e.y - ey).abs() < 1e-9, "{e:?}");
        assert_data_arcs(job, bar, (cx, cy), radius, &mut last_end);
    }
}

/// A centre list that is too long, mixes numbers and points, or holds a circle past a stroke,
/// and set-up offsets that are not one per centre, are refused at their keys.
#[test]
fn a_bad_centre_list_is_refused_at_its_key() {
    let job = |centres: &str| {
        with_job(&format!(
            "plane = \"XY\"\ncenter_mm = {centres}\nradius_mm = 100.0\nfeed_mm_min = 1000.0\n"
        ))
    };
    let e = load(&job(&format!("{:?}", vec![[250.0, 200.0, 200.0]; 5])), None).expect_err("five");
    assert_eq!(e.key.as_deref(), Some("job.center_mm"), "{e}");
    assert!(e.message.contains("a list of 1 to 4"), "{e}");
    let e = load(&job("[[250.0, 200.0, 200.0], 1.0]"), None).expect_err("mixed");
    assert!(e.message.contains("numbers and points mixed"), "{e}");
    let e = load(&job("[[250.0, 200.0, 200.0], [250.0, 200.0]]"), None).expect_err("short");
    assert!(e.message.contains("[x, y, z]"), "{e}");
    let e = load(&job("[[250.0, 200.0, 200.0], [450.0, 200.0, 200.0]]"), None)
        .expect_err("past the X stroke");
    assert!(e.message.contains("beyond its stroke"), "{e}");
    let two = job("[[250.0, 200.0, 200.0], [300.0, 200.0, 200.0]]").replacen(
        "setup_eccentricity_um = [3.0, -2.0, 0.0]\n",
        "setup_eccentricity_um = [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]\n",
        1,
    );
    let e = load(&two, None).expect_err("three offsets, two centres");
    assert_eq!(
        e.key.as_deref(),
        Some("instruments.ballbar.setup_eccentricity_um"),
        "{e}"
    );
    assert!(e.message.contains("one per centre of the job (2)"), "{e}");
}
