//! `vmt lobes`: files written, the SD and ZOA columns against the library, and bad arguments
//! refused by name.

mod common;

use common::{stderr, vmt};
use vmt_chatter::stability::benchmark_1dof;
use vmt_chatter::stability::sd::{SdSettings, critical_depth};
use vmt_model::cutting::MillingDirection;

#[test]
fn lobes_writes_both_diagrams_and_the_image() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let o = vmt(&[
        "lobes",
        "--immersion",
        "0.5",
        "--speeds",
        "11",
        "--depths",
        "40",
        "--speed-min-rpm",
        "10000",
        "--speed-max-rpm",
        "20000",
        "--depth-max-mm",
        "4",
        "--quiet",
        "--out",
        out,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.path().join("lobes.png").metadata().unwrap().len() > 10_000);
    let csv = std::fs::read_to_string(dir.path().join("lobes.csv")).unwrap();
    let mut rows = csv.lines();
    assert_eq!(
        rows.next(),
        Some("case,speed_rpm,sd_critical_depth_mm,zoa_critical_depth_mm,zoa_chatter_hz,zoa_lobe")
    );
    let rows: Vec<Vec<&str>> = rows.map(|r| r.rsplitn(6, ',').collect()).collect();
    assert_eq!(rows.len(), 11);
    // 12 000 rpm: the grid's boundary (depth steps of 0.1 mm, linear in the radius between
    // them) is within half a step of the library's bisection.
    let row = rows
        .iter()
        .find(|r| r[4] == "12000")
        .expect("a row at 12000 rpm");
    let grid_mm: f64 = row[3].parse().unwrap();
    let sys = benchmark_1dof(0.5, MillingDirection::Down);
    let exact = critical_depth(&sys, 12_000.0, 0.004, &SdSettings::default())
        .unwrap()
        .unwrap();
    assert!(
        (grid_mm - exact * 1e3).abs() < 0.05,
        "{grid_mm} mm vs {exact} m"
    );
    let map = std::fs::read_to_string(dir.path().join("sd_map.csv")).unwrap();
    assert_eq!(map.lines().count(), 1 + 11 * 40);
}

/// Bad arguments are refused by name, and before the output folder is made: a refused
/// command leaves no empty folder behind (the folder was made first, as `vmt gap` once did).
#[test]
fn bad_lobe_arguments_are_refused_by_name_leaving_no_folder() {
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("never");
    let out = folder.to_str().unwrap();
    let refused = |args: &[&str], expected: &str| {
        let o = vmt(&[&["lobes"], args, &["--out", out]].concat());
        assert!(!o.status.success(), "{args:?} accepted");
        let e = stderr(&o);
        assert!(e.contains(expected), "{args:?}: `{expected}` not in {e}");
        assert!(!folder.exists(), "{args:?} was refused but made {out}");
    };
    refused(&["--immersion", "1.5"], "--immersion 1.5");
    refused(
        &["--immersion", "1", "--depth-max-mm", "60"],
        "flute length 50 mm",
    );
    refused(
        &["--speed-min-rpm", "9000", "--speed-max-rpm", "8000"],
        "spindle speed",
    );
    refused(&["--speeds", "1"], "--speeds 1");
    refused(&["--depth-max-mm", "nan"], "--depth-max-mm");
    refused(
        &["--scenario", "../scenarios/vmc500.toml"],
        "no milling job",
    );
    refused(&["--scenario", "../scenarios/missing.toml"], "missing.toml");
    // A scenario's depth limit is its tool's flute (30 mm for the shipped slot).
    refused(
        &[
            "--scenario",
            "../scenarios/milling_slot.toml",
            "--depth-max-mm",
            "40",
        ],
        "flute length 30 mm",
    );
    // A scenario's engagement is its job's: the benchmark's options are refused beside it,
    // not ignored.
    for (option, value) in [("--immersion", "0.5"), ("--direction", "up")] {
        let o = vmt(&[
            "lobes",
            "--scenario",
            "../scenarios/milling_slot.toml",
            option,
            value,
            "--out",
            out,
        ]);
        assert_eq!(o.status.code(), Some(2));
        let e = stderr(&o);
        assert!(
            e.contains("'--scenario <SCENARIO>' cannot be used with") && e.contains(option),
            "{e}"
        );
        assert!(!folder.exists(), "{option} was refused but made {out}");
    }
}
