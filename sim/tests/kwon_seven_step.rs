//! The shipped scenario `scenarios/kwon_seven_step.toml`: Kwon's seven steps as one job.

use std::path::PathBuf;
use vmt_sim::interpolator::Interpolator;
use vmt_sim::nc::{ArcDirection, Motion, Plane};

fn scenario() -> vmt_scenario::Scenario {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenarios/kwon_seven_step.toml");
    vmt_scenario::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// Seven ball-bar set-ups (bar length, plane, feed as in Kwon's Fig. 23), each with a CW and a
/// CCW data arc whose blocks are arcs of that direction in that plane, every point of them one
/// bar length from the set-up's centre ball.
#[test]
fn kwon_scenario_has_seven_steps_in_both_directions() {
    let s = scenario();
    let job = &s.execution.as_ref().expect("a job").job;
    assert!(job.laser.is_none());
    let want = [
        (Plane::Xy, 150.0, 500.0),
        (Plane::Xy, 150.0, 500.0),
        (Plane::Xy, 100.0, 500.0),
        (Plane::Xy, 250.0, 500.0),
        (Plane::Xy, 100.0, 4000.0),
        (Plane::Zx, 150.0, 500.0),
        (Plane::Yz, 150.0, 500.0),
    ];
    assert_eq!(job.ballbar.len(), 7);
    for (k, (b, (plane, bar_mm, feed))) in job.ballbar.iter().zip(want).enumerate() {
        assert_eq!(b.name.as_deref(), Some(format!("step {}", k + 1).as_str()));
        assert_eq!(b.plane, plane, "step {}", k + 1);
        assert!((b.radius_m * 1e3 - bar_mm).abs() < 1e-9, "step {}", k + 1);
        assert!((b.feed_m_s * 6e4 - feed).abs() < 1e-9, "step {}", k + 1);
        let dirs: Vec<ArcDirection> = b.data.iter().map(|(d, _)| *d).collect();
        assert_eq!(
            dirs,
            [ArcDirection::Cw, ArcDirection::Ccw],
            "step {}",
            k + 1
        );
        for (d, range) in &b.data {
            for block in &job.program.blocks[range.clone()] {
                let Motion::Arc {
                    to,
                    plane: p,
                    direction,
                    ..
                } = &block.motion
                else {
                    panic!(
                        "step {}: block at line {} is no arc",
                        k + 1,
                        block.span.line
                    );
                };
                assert_eq!((*p, *direction), (plane, *d), "step {}", k + 1);
                assert!(((to - b.center).norm() - b.radius_m).abs() < 1e-7);
            }
        }
    }
    // Steps 1 and 2 differ only in height; step 4's bar is inclined from the step-3 centre ball.
    assert!(((job.ballbar[1].center - job.ballbar[0].center).z - 0.1).abs() < 1e-12);
    assert_eq!(job.ballbar[3].center, job.ballbar[2].center);
}

/// The joined program stays inside the built-in machine's strokes all the way (the check the
/// simulation makes before it runs), and lasts about 17 minutes of machine time.
#[test]
fn kwon_program_fits_the_machine() {
    let s = scenario();
    let exec = s.execution.as_ref().expect("a job");
    let ipo = Interpolator::new(&exec.job.program, &exec.controller).unwrap();
    let tcp = s.machine.volumetric.kinematics.tool_offset;
    // Every 8th servo tick (1 ms): the strokes are far from being grazed between two of them.
    for k in (0..ipo.servo_ticks()).step_by(8) {
        let sp = ipo.setpoint(k).unwrap();
        let q = sp.position - tcp;
        assert_eq!(
            s.machine.outside_stroke(&q),
            None,
            "t = {} s: {q:?}",
            sp.time_s
        );
    }
    let minutes = ipo.duration_s() / 60.0;
    assert!((15.0..20.0).contains(&minutes), "{minutes} min");
}
