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

#[test]
fn default_centre_is_the_middle_of_the_built_in_strokes() {
    let o = vmt(&[
        "program",
        "ballbar",
        "--plane",
        "XY",
        "--radius-mm",
        "100",
        "--feed-mm-min",
        "800",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(
        text.contains("(centre X250.0000 Y200.0000 Z200.0000 mm; radius 100.0000 mm)"),
        "{text}"
    );
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
