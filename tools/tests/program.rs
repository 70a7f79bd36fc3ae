//! `vmt program ballbar` end to end: the program it prints parses and holds the requested
//! circles; bad arguments are refused with the option's name and exit code 2.

use nalgebra::Vector3;
mod common;

use common::{stderr, vmt};
use vmt_sim::nc::{ArcDirection, Motion, Plane, ballbar::CircularTest, parse};

const BASE: &[&str] = &[
    "program",
    "ballbar",
    "--plane",
    "XY",
    "--radius-mm",
    "150",
    "--feed-mm-min",
    "1000",
    "--arc-deg",
    "360",
    "--directions",
    "cw,ccw",
    "--center-mm",
    "250,200,150",
];

#[test]
fn printed_program_parses_and_holds_the_requested_circles() {
    let o = vmt(BASE);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    let center = Vector3::new(0.25, 0.2, 0.15);
    let test = CircularTest::iso230_4(Plane::Xy, center, 0.15, 1000.0 / 6e4);
    assert_eq!(
        text,
        test.gcode(),
        "the CLI defaults are the ISO 230-4 defaults"
    );
    let program = parse(&text, test.start_point()).unwrap();
    let arcs = test.data_blocks(&program).unwrap();
    let dirs: Vec<ArcDirection> = arcs.iter().map(|(d, _)| *d).collect();
    assert_eq!(dirs, vec![ArcDirection::Cw, ArcDirection::Ccw]);
    for (_, range) in arcs {
        for k in range {
            let Motion::Arc {
                center: c,
                to,
                feed,
                ..
            } = program.blocks[k].motion
            else {
                panic!("block {k} is not an arc");
            };
            assert!((c - center).norm() < 1e-9);
            assert!(((to - c).norm() - 0.15).abs() < 1e-7);
            assert!((feed - 1000.0 / 6e4).abs() < 1e-12);
        }
    }
}

#[test]
fn partial_arc_in_a_vertical_plane_to_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sub/zx.nc");
    let out_s = out.display().to_string();
    let o = vmt(&[
        "program",
        "ballbar",
        "--plane",
        "xz",
        "--radius-mm",
        "100",
        "--feed-mm-min",
        "500",
        "--arc-deg",
        "220",
        "--start-deg",
        "-110",
        "--overshoot-deg",
        "2",
        "--directions",
        "ccw",
        "--center-mm",
        "250,200,200",
        "--out",
        &out_s,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("wrote"));
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("G21 G90 G94 G18\nF500\n"), "{text}");
    let mut test =
        CircularTest::iso230_4(Plane::Zx, Vector3::new(0.25, 0.2, 0.2), 0.1, 500.0 / 6e4);
    test.arc_deg = 220.0;
    test.start_deg = -110.0;
    test.overshoot_deg = 2.0;
    test.directions = vec![ArcDirection::Ccw];
    assert_eq!(text, test.gcode());
    let program = parse(&text, test.start_point()).unwrap();
    // One CCW run: 220° written as two 110° blocks.
    assert_eq!(
        test.data_blocks(&program).unwrap(),
        vec![(ArcDirection::Ccw, 3..5)]
    );
}

/// `vmt program ballbar` with `args` after `ballbar`: the program, or the failed output.
fn program(args: &[&str]) -> Result<String, std::process::Output> {
    let o = vmt(&[&["program", "ballbar"], args].concat());
    if o.status.success() {
        Ok(String::from_utf8(o.stdout).unwrap())
    } else {
        Err(o)
    }
}

/// The built-in machine's carriages travel Z 0..400 mm with a 100 mm tool: the default centre
/// is the tool point at mid-stroke, Z 100 mm (Z 200 mm, the carriage's middle, put a vertical
/// 150 mm circle up to Z 451.5 mm).
#[test]
fn default_centre_is_the_tool_point_at_the_middle_of_the_built_in_strokes() {
    let text = program(&[
        "--plane",
        "XY",
        "--radius-mm",
        "100",
        "--feed-mm-min",
        "800",
    ])
    .unwrap();
    assert!(
        text.contains("(centre X250.0000 Y200.0000 Z100.0000 mm; radius 100.0000 mm)"),
        "{text}"
    );
    // The vertical circles of the review fit now.
    for arc in ["360", "220", "180"] {
        for plane in ["ZX", "YZ"] {
            let args = [
                "--plane",
                plane,
                "--radius-mm",
                "150",
                "--feed-mm-min",
                "1000",
            ];
            let got = program(&[&args[..], &["--arc-deg", arc]].concat());
            assert!(got.is_ok(), "{plane} {arc}: {}", stderr(&got.unwrap_err()));
        }
    }
}

/// A partial arc in ZX or YZ lies over the top, symmetric about +Z, unless --start-deg says
/// otherwise; a full circle and XY start at 0°.
#[test]
fn partial_vertical_arcs_lie_over_the_top_by_default() {
    for (plane, arc, start, from) in [
        ("ZX", "180", None, "-90"),
        ("ZX", "220", None, "-110"),
        ("YZ", "180", None, "0"),
        ("YZ", "220", None, "-20"),
        ("XY", "180", None, "0"),
        ("ZX", "360", None, "0"),
        ("ZX", "180", Some("0"), "0"),
        ("YZ", "220", Some("-40"), "-40"),
    ] {
        let mut args = vec![
            "--plane",
            plane,
            "--radius-mm",
            "150",
            "--feed-mm-min",
            "1000",
        ];
        args.extend(["--arc-deg", arc]);
        if let Some(s) = start {
            args.extend(["--start-deg", s]);
        }
        let text = program(&args).unwrap_or_else(|o| panic!("{args:?}: {}", stderr(&o)));
        let want = format!("data arc {arc} deg from {from} deg;");
        assert!(text.contains(&want), "{args:?}: {text}");
    }
}

/// A circle leaving a stroke of a known machine (--scenario, or the built-in one the default
/// centre comes from) is refused with the axis, the travel and the stroke; without either the
/// machine is unknown and the program is written.
#[test]
fn a_circle_beyond_the_strokes_of_a_known_machine_is_refused() {
    let scenario = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/vmc500.toml");
    let zx = ["--plane", "ZX", "--feed-mm-min", "1000"];
    let centre = ["--center-mm", "250,200,200", "--radius-mm", "150"];
    for (args, says) in [
        (
            [&zx[..], &["--radius-mm", "250"]].concat(),
            "takes the Z axis from -50.000 to 450.000 mm, beyond its stroke 0 to 400 mm on \
             VMC-500 (built-in default)",
        ),
        (
            [&zx[..], &centre, &["--scenario", scenario]].concat(),
            "takes the Z axis from 150.000 to 450.000 mm, beyond its stroke 0 to 400 mm",
        ),
    ] {
        let o = program(&args).expect_err(says);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains(says), "{args:?}: {}", stderr(&o));
        assert!(
            stderr(&o)
                .contains("move the centre (--center-mm, the tool point) or shorten --radius-mm"),
            "{}",
            stderr(&o)
        );
    }
    assert!(program(&[&zx[..], &centre].concat()).is_ok());
}

/// The program `vmt program ballbar` writes is the program of the equivalent scenario ball-bar
/// job, and run as a program job its DATA markers give the job's ball-bar set-up (the traces
/// then agree: `scenario/tests/ballbar_jobs.rs`).
#[test]
fn a_written_program_runs_as_the_equivalent_ball_bar_job() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p.nc");
    let args = [
        "--plane",
        "YZ",
        "--radius-mm",
        "150",
        "--feed-mm-min",
        "1000",
    ];
    let o = vmt(&[
        &["program", "ballbar"],
        &args[..],
        &["--arc-deg", "180", "--out", out.to_str().unwrap()],
    ]
    .concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let builtin = vmt_scenario::BUILTIN_DEFAULT;
    let xy = "plane = \"XY\"\ncenter_mm = [250.0, 200.0, 200.0]\nradius_mm = 150.0\n\
              feed_mm_min = 1000.0\narc_deg = 360.0\ndirections = [\"cw\", \"ccw\"]\n";
    let yz = "plane = \"YZ\"\nradius_mm = 150.0\nfeed_mm_min = 1000.0\narc_deg = 180.0\n";
    let job = |text: &str| {
        let s = vmt_scenario::parse(text, "s.toml", Some(dir.path())).unwrap();
        s.execution.unwrap().job
    };
    let from_job = job(&builtin.replacen(xy, yz, 1));
    let from_program = job(&builtin.replacen(
        &format!("kind = \"ballbar\"\n{xy}"),
        "kind = \"program\"\nprogram = \"p.nc\"\n",
        1,
    ));
    let motions = |j: &vmt_sim::simulate::Job| -> Vec<Motion> {
        j.program.blocks.iter().map(|b| b.motion.clone()).collect()
    };
    assert_eq!(motions(&from_job), motions(&from_program));
    let (a, b) = (&from_job.ballbar, &from_program.ballbar);
    assert_eq!((a.len(), b.len()), (1, 1));
    let (a, b) = (&a[0], &b[0]);
    assert_eq!(
        (a.plane, a.radius_m, a.feed_m_s),
        (b.plane, b.radius_m, b.feed_m_s)
    );
    assert!((a.center - b.center).norm() < 1e-12);
    assert_eq!(a.data, b.data);
    assert_eq!(a.spec, b.spec);
}

#[test]
fn bad_arguments_are_refused_with_exit_code_2() {
    let with = |flag: &str, value: &str| {
        let mut args: Vec<&str> = BASE.to_vec();
        let k = args.iter().position(|a| *a == flag).unwrap();
        args[k + 1] = value;
        vmt(&args)
    };
    for (flag, value, expected) in [
        (
            "--radius-mm",
            "20",
            "radius 20 mm: a ball bar measures circles of 50 to 600 mm radius (--radius-mm)",
        ),
        (
            "--feed-mm-min",
            "0",
            "feed 0 mm/min: the feed must be from 0.1 to 100000 mm/min (--feed-mm-min)",
        ),
        (
            "--feed-mm-min",
            "1e308",
            "feed 1e308 mm/min: the feed must be from 0.1 to 100000 mm/min (--feed-mm-min)",
        ),
        (
            "--center-mm",
            "1e308,0,0",
            "centre (1e308, 0, 0) mm: every coordinate must be a number from -10000 to 10000 mm",
        ),
        (
            "--arc-deg",
            "400",
            "data arc 400 deg: the data arc must be from 90 to 360 deg (a shorter arc cannot tell the circle's centre from its radius) (--arc-deg)",
        ),
        ("--directions", "cw,up", "a direction is cw or ccw"),
        ("--plane", "XW", "the plane is XY, ZX (or XZ) or YZ"),
    ] {
        let o = with(flag, value);
        assert_eq!(o.status.code(), Some(2), "{flag} {value}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(expected),
            "{flag} {value}: {}",
            stderr(&o)
        );
        assert!(o.stdout.is_empty(), "nothing is printed for {flag} {value}");
    }
}
