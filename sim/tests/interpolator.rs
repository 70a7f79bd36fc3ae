//! The interpolator against the physics and numbers it must get right: S-curve timing, exact
//! arcs in the three planes, corner speeds, dwells, limits, refusals.

use std::f64::consts::TAU;

use nalgebra::Vector3;
use proptest::prelude::*;
use vmt_sim::interpolator::{
    Interpolator, InterpolatorConfig, InterpolatorError, Limits, Setpoint,
    feed_limits::CENTRIPETAL_SHARE,
};
use vmt_sim::nc::program::{ArcDirection, Block, Motion, Plane, Program, SourceSpan, Spindle};

type V3 = Vector3<f64>;

fn v3(x: f64, y: f64, z: f64) -> V3 {
    Vector3::new(x, y, z)
}

fn limits() -> Limits {
    Limits {
        rapid_m_s: 0.5,
        max_feed_m_s: 1.0,
        path_accel_m_s2: 2.0,
        path_jerk_m_s3: 40.0,
        axis_velocity_m_s: [1.0; 3],
        axis_accel_m_s2: [5.0; 3],
        corner_tolerance_m: 10e-6,
    }
}

fn config() -> InterpolatorConfig {
    InterpolatorConfig::new(limits())
}

fn program(start: V3, motions: Vec<Motion>) -> Program {
    let blocks = motions
        .into_iter()
        .enumerate()
        .map(|(i, motion)| Block {
            motion,
            spindle: Spindle::Clockwise(6000.0),
            span: SourceSpan {
                line: i + 10,
                column: 1,
            },
        })
        .collect();
    Program { start, blocks }
}

fn line(to: V3, feed: f64) -> Motion {
    Motion::Linear { to, feed }
}

fn arc(to: V3, center: V3, plane: Plane, direction: ArcDirection, feed: f64) -> Motion {
    Motion::Arc {
        to,
        center,
        plane,
        direction,
        feed,
    }
}

fn run(program: &Program, config: &InterpolatorConfig) -> (Interpolator, Vec<Setpoint>) {
    let ipo = Interpolator::new(program, config).expect("valid program");
    let setpoints: Vec<Setpoint> = ipo.iter().collect();
    (ipo, setpoints)
}

/// Path speed |ṗ| at every IPO instant (where the fine interpolator returns the IPO sample).
fn ipo_speeds(ipo: &Interpolator, setpoints: &[Setpoint]) -> Vec<f64> {
    let ratio = (ipo.ipo_period_s() / ipo.servo_period_s()).round() as usize;
    setpoints
        .iter()
        .step_by(ratio)
        .map(|p| p.velocity.norm())
        .collect()
}

/// Largest |first difference| / T and |second difference| / T² of the IPO speeds: the path
/// acceleration and jerk of s(t).
fn accel_and_jerk(speeds: &[f64], period: f64) -> (f64, f64) {
    let accel = speeds
        .windows(2)
        .map(|w| (w[1] - w[0]).abs() / period)
        .fold(0.0, f64::max);
    let jerk = speeds
        .windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).abs() / (period * period))
        .fold(0.0, f64::max);
    (accel, jerk)
}

/// How far the servo-rate speed may exceed the IPO-level profile between two IPO samples (the
/// cubic fine interpolation's error, `j_max T_ipo² / 8`), m/s.
fn fine_slack(cfg: &InterpolatorConfig) -> f64 {
    cfg.limits.path_jerk_m_s3 * cfg.ipo_period_s.powi(2) / 8.0
}

/// Distance of `p` from the segment `a`–`b`.
fn distance_to_segment(p: &V3, a: &V3, b: &V3) -> f64 {
    let d = b - a;
    let t = ((p - a).dot(&d) / d.norm_squared()).clamp(0.0, 1.0);
    (p - (a + d * t)).norm()
}

/// Plane basis (u, v, n) as the program module defines the planes.
fn basis(plane: Plane) -> (V3, V3, V3) {
    let n = plane.normal();
    match plane {
        Plane::Xy => (V3::x(), V3::y(), n),
        Plane::Zx => (V3::z(), V3::x(), n),
        Plane::Yz => (V3::y(), V3::z(), n),
    }
}

// ---------------------------------------------------------------------------------------------
// A long line: cruise speed, S-curve time, limits, rest at the exact end.

#[test]
fn long_line_cruises_at_feed_and_takes_the_s_curve_time() {
    let cfg = config();
    let (a, j) = (cfg.limits.path_accel_m_s2, cfg.limits.path_jerk_m_s3);
    let (length, feed) = (0.5, 0.2);
    let start = v3(0.01, -0.02, 0.03);
    let end = start + v3(3.0, 2.0, 1.0).normalize() * length;
    let (ipo, sp) = run(&program(start, vec![line(end, feed)]), &cfg);

    // T_j = a/j = 50 ms (whole IPO periods); F/a = 100 ms >= T_j, so the profile is the
    // seven-phase double S: T = L/F + F/a + a/j.
    let t_j = a / j;
    assert!((ipo.jerk_window_s() - t_j).abs() < 1e-12);
    let expected = length / feed + feed / a + t_j;
    let (block, t0, t1) = ipo.block_times()[0];
    assert_eq!(block, 0);
    assert_eq!(t0, 0.0);
    assert!((t1 - expected).abs() < 1e-9, "{t1} vs {expected}");
    assert!(ipo.duration_s() >= t1 && ipo.duration_s() < t1 + ipo.ipo_period_s() + 1e-12);

    let speeds = ipo_speeds(&ipo, &sp);
    let vmax = speeds.iter().cloned().fold(0.0, f64::max);
    assert!((vmax - feed).abs() < 1e-12, "cruise {vmax}");
    let mid = ipo
        .setpoint((expected / 2.0 / ipo.servo_period_s()) as usize)
        .unwrap();
    assert!((mid.velocity.norm() - feed).abs() < 1e-12);
    assert!((mid.velocity.normalize() - (end - start).normalize()).norm() < 1e-12);

    let (accel, jerk) = accel_and_jerk(&speeds, ipo.ipo_period_s());
    println!(
        "long line: max path accel {accel} m/s² (limit {a}), max jerk {jerk} m/s³ (limit {j})"
    );
    assert!(accel <= a * (1.0 + 1e-9) && accel > 0.98 * a);
    assert!(jerk <= j * (1.0 + 1e-6) && jerk > 0.95 * j);
    // Servo rate: the feed-forward acceleration within the limit plus the fine interpolation
    // error; inside each IPO period the cubic's jerk within j_max; at the IPO instants the
    // acceleration steps by a fraction of j_max T_ipo.
    let servo_accel = sp.iter().map(|p| p.acceleration.norm()).fold(0.0, f64::max);
    assert!(servo_accel <= a + j * ipo.ipo_period_s(), "{servo_accel}");
    let ratio = (ipo.ipo_period_s() / ipo.servo_period_s()).round() as usize;
    let along = |p: &Setpoint| p.acceleration.dot(&(end - start).normalize());
    let (mut inner_jerk, mut knot_step) = (0.0f64, 0.0f64);
    for (k, w) in sp.windows(2).enumerate() {
        let step = (along(&w[1]) - along(&w[0])).abs();
        if (k + 1).is_multiple_of(ratio) {
            knot_step = knot_step.max(step);
        } else {
            inner_jerk = inner_jerk.max(step / ipo.servo_period_s());
        }
    }
    println!(
        "servo rate: jerk {inner_jerk} m/s³, acceleration step at IPO instants {knot_step} m/s²"
    );
    assert!(inner_jerk <= j * (1.0 + 1e-6));
    assert!(knot_step <= j * ipo.ipo_period_s());

    let first = sp.first().unwrap();
    let last = sp.last().unwrap();
    assert_eq!(first.position, start);
    assert_eq!(first.velocity.norm(), 0.0);
    assert_eq!(last.position, end);
    assert_eq!(last.velocity.norm(), 0.0);
    assert_eq!(last.acceleration.norm(), 0.0);
    for p in &sp {
        assert!(distance_to_segment(&p.position, &start, &end) < 1e-12);
        assert_eq!(p.block, Some(0));
        assert_eq!(p.spindle, Spindle::Clockwise(6000.0));
    }
}

#[test]
fn short_line_that_cannot_reach_its_feed_keeps_the_jerk_limit() {
    // A 5 mm line at 0.5 m/s: the raw profile would peak without cruise; the planner caps the
    // peak so that the filter still bounds the jerk.
    let cfg = config();
    let start = V3::zeros();
    let end = v3(0.005, 0.0, 0.0);
    let (ipo, sp) = run(&program(start, vec![line(end, 0.5)]), &cfg);
    let speeds = ipo_speeds(&ipo, &sp);
    let (accel, jerk) = accel_and_jerk(&speeds, ipo.ipo_period_s());
    println!("short line: max accel {accel}, max jerk {jerk}");
    assert!(accel <= cfg.limits.path_accel_m_s2 * (1.0 + 1e-9));
    assert!(jerk <= cfg.limits.path_jerk_m_s3 * (1.0 + 1e-6));
    assert_eq!(sp.last().unwrap().position, end);
}

// ---------------------------------------------------------------------------------------------
// Full circles in the three planes.

struct Circle {
    center: V3,
    radius: f64,
    plane: Plane,
    direction: ArcDirection,
}

impl Circle {
    fn start(&self) -> V3 {
        self.center + basis(self.plane).0 * self.radius
    }

    /// Unit tangent at the start in the direction of travel.
    fn start_tangent(&self) -> V3 {
        let v = basis(self.plane).1;
        match self.direction {
            ArcDirection::Ccw => v,
            ArcDirection::Cw => -v,
        }
    }

    fn motion(&self, feed: f64) -> Motion {
        arc(self.start(), self.center, self.plane, self.direction, feed)
    }

    /// In-plane radius error and out-of-plane offset of `p`, m.
    fn deviation(&self, p: &V3) -> f64 {
        let (u, v, n) = basis(self.plane);
        let r = p - self.center;
        let radial = (r.dot(&u).hypot(r.dot(&v)) - self.radius).abs();
        radial.max(r.dot(&n).abs())
    }

    fn angle(&self, p: &V3) -> f64 {
        let (u, v, _) = basis(self.plane);
        let r = p - self.center;
        r.dot(&v).atan2(r.dot(&u))
    }
}

/// Unwrapped angle swept by the setpoints of `block`, rad (positive counter-clockwise about the
/// plane normal).
fn swept_angle(circle: &Circle, setpoints: &[Setpoint], block: usize) -> f64 {
    // From the start point, through every setpoint of the block, to the end point (the block's
    // first and last setpoints are up to one servo tick away from them).
    let ends = circle.angle(&circle.start());
    let angles = setpoints
        .iter()
        .filter(|p| p.block == Some(block))
        .map(|p| circle.angle(&p.position));
    let mut sweep = 0.0;
    let mut last = ends;
    for a in angles.chain([ends]) {
        let mut d = a - last;
        d -= TAU * (d / TAU).round();
        sweep += d;
        last = a;
    }
    sweep
}

#[test]
fn full_circles_from_rest_are_exact_in_all_planes_and_both_directions() {
    let cfg = config();
    let (radius, feed) = (0.05, 0.1);
    for plane in [Plane::Xy, Plane::Zx, Plane::Yz] {
        for direction in [ArcDirection::Ccw, ArcDirection::Cw] {
            let circle = Circle {
                center: v3(0.1, 0.2, 0.3),
                radius,
                plane,
                direction,
            };
            let (ipo, sp) = run(&program(circle.start(), vec![circle.motion(feed)]), &cfg);
            let worst = sp
                .iter()
                .map(|p| circle.deviation(&p.position))
                .fold(0.0, f64::max);
            assert!(
                worst < 1e-9,
                "{plane:?} {direction:?}: off the circle by {worst} m"
            );
            let sweep = swept_angle(&circle, &sp, 0);
            let expected = match direction {
                ArcDirection::Ccw => TAU,
                ArcDirection::Cw => -TAU,
            };
            assert!(
                (sweep - expected).abs() < 1e-9,
                "{plane:?} {direction:?}: {sweep}"
            );
            // F²/R = 0.2 m/s² is far below the axis limits: the circle runs at F (exactly at the
            // IPO instants; between them the cubic fine interpolation may overshoot by a
            // fraction of j_max T_ipo²).
            let vmax = ipo_speeds(&ipo, &sp).into_iter().fold(0.0, f64::max);
            assert!((vmax - feed).abs() < 1e-12, "{plane:?}: top speed {vmax}");
            let servo_max = sp.iter().map(|p| p.velocity.norm()).fold(0.0, f64::max);
            assert!(servo_max - feed < fine_slack(&cfg), "{servo_max}");
            // Starts along the tangent in the programmed direction.
            let early = sp.iter().find(|p| p.velocity.norm() > 1e-4).unwrap();
            assert!((early.velocity.normalize() - circle.start_tangent()).norm() < 1e-2);
            assert_eq!(sp.last().unwrap().position, circle.start());
            let (_, _, t1) = ipo.block_times()[0];
            let overhead = t1 - TAU * radius / feed;
            let s_curve = feed / cfg.limits.path_accel_m_s2 + ipo.jerk_window_s();
            assert!((overhead - s_curve).abs() < 1e-9, "{overhead} vs {s_curve}");
        }
    }
}

/// A full circle entered and left along tangent lines, so that it runs at constant speed.
fn circle_with_lead_in(circle: &Circle, feed: f64, lead: f64) -> Program {
    let t = circle.start_tangent();
    let start = circle.start() - t * lead;
    program(
        start,
        vec![
            line(circle.start(), feed),
            circle.motion(feed),
            line(circle.start() + t * lead, feed),
        ],
    )
}

#[test]
fn circle_runs_at_feed_when_the_centripetal_acceleration_is_within_the_limits() {
    let cfg = config();
    let circle = Circle {
        center: V3::zeros(),
        radius: 0.1,
        plane: Plane::Xy,
        direction: ArcDirection::Ccw,
    };
    let feed = 0.3; // F²/R = 0.9 m/s² < 0.9 × 5 m/s²
    let (_, sp) = run(&circle_with_lead_in(&circle, feed, 0.1), &cfg);
    let on_arc: Vec<&Setpoint> = sp.iter().filter(|p| p.block == Some(1)).collect();
    assert!(on_arc.len() > 1000);
    for p in &on_arc {
        assert!(
            (p.velocity.norm() - feed).abs() < 1e-9,
            "{}",
            p.velocity.norm()
        );
        assert!(circle.deviation(&p.position) < 1e-9);
        let centripetal = p.acceleration.norm();
        assert!((centripetal - feed * feed / circle.radius).abs() < 1e-6);
    }
    // The tangent junctions keep the speed: no dip at the circle's ends.
    let min = on_arc
        .iter()
        .map(|p| p.velocity.norm())
        .fold(f64::MAX, f64::min);
    assert!((min - feed).abs() < 1e-9);
}

#[test]
fn circle_feed_is_reduced_when_the_centripetal_acceleration_would_exceed_the_limits() {
    let cfg = config();
    for plane in [Plane::Xy, Plane::Zx, Plane::Yz] {
        let circle = Circle {
            center: v3(0.0, 0.05, 0.0),
            radius: 0.02,
            plane,
            direction: ArcDirection::Cw,
        };
        let feed = 0.6; // F²/R = 18 m/s² > 5 m/s²
        let (_, sp) = run(&circle_with_lead_in(&circle, feed, 0.1), &cfg);
        let a_axis = cfg.limits.axis_accel_m_s2[0];
        let reduced = (CENTRIPETAL_SHARE * a_axis * circle.radius).sqrt();
        let on_arc: Vec<&Setpoint> = sp.iter().filter(|p| p.block == Some(1)).collect();
        for p in &on_arc {
            assert!(
                (p.velocity.norm() - reduced).abs() < 1e-9,
                "{}",
                p.velocity.norm()
            );
            assert!(circle.deviation(&p.position) < 1e-9);
        }
        let worst_axis = sp
            .iter()
            .flat_map(|p| p.acceleration.iter().map(|a| a.abs()).collect::<Vec<_>>())
            .fold(0.0, f64::max);
        println!("{plane:?}: arc speed {reduced} m/s, largest axis acceleration {worst_axis}");
        assert!(worst_axis <= a_axis + cfg.limits.path_jerk_m_s3 * cfg.ipo_period_s);
        let sweep = swept_angle(&circle, &sp, 1);
        assert!((sweep + TAU).abs() < 1e-9, "{sweep}");
    }
}

// ---------------------------------------------------------------------------------------------
// Corners.

fn corner_program(feed: f64) -> (Program, V3) {
    let corner = v3(0.1, 0.0, 0.0);
    let p = program(
        V3::zeros(),
        vec![line(corner, feed), line(v3(0.1, 0.1, 0.0), feed)],
    );
    (p, corner)
}

/// The servo ticks where the block changes from 0 to 1, and the setpoints around it.
fn around_corner(sp: &[Setpoint]) -> (usize, &Setpoint, &Setpoint) {
    let k = sp.iter().position(|p| p.block == Some(1)).unwrap();
    (k, &sp[k - 1], &sp[k])
}

#[test]
fn exact_stop_stops_at_the_corner() {
    let cfg = InterpolatorConfig {
        exact_stop: true,
        ..config()
    };
    let (prog, corner) = corner_program(0.1);
    let (ipo, sp) = run(&prog, &cfg);
    // The next block starts at rest exactly on the corner; one servo tick earlier the tail of
    // the S-curve is within a few picometres of it.
    let (_, before, after) = around_corner(&sp);
    assert_eq!(after.position, corner);
    assert_eq!(after.velocity.norm(), 0.0);
    assert!((before.position - corner).norm() < 1e-10);
    assert!(before.velocity.norm() < 1e-6);
    let times = ipo.block_times();
    assert!(times[0].2 <= times[1].1);
    for p in &sp {
        let on = distance_to_segment(&p.position, &V3::zeros(), &corner).min(distance_to_segment(
            &p.position,
            &corner,
            &v3(0.1, 0.1, 0.0),
        ));
        assert!(on < 1e-12);
    }
}

/// The documented junction speed of a 90° corner in XY (see `junction`).
fn corner_rule(limits: &Limits, ipo_period_s: f64) -> (f64, f64) {
    let a_u = limits.axis_accel_m_s2[0] * 2f64.sqrt(); // A_x / |û_x|, û = (−1, 1, 0)/√2
    let jump = limits.axis_accel_m_s2[0] * ipo_period_s; // A_x T / |Δt_x|, |Δt_x| = 1
    let sin_half = (0.5f64).sqrt();
    let deviation = (a_u * limits.corner_tolerance_m * sin_half / (1.0 - sin_half)).sqrt();
    (jump, deviation)
}

#[test]
fn continuous_corner_is_passed_at_the_junction_speed_without_rounding() {
    for tolerance in [10e-6, 0.1e-6] {
        let cfg = InterpolatorConfig {
            limits: Limits {
                corner_tolerance_m: tolerance,
                ..limits()
            },
            ..config()
        };
        let (jump, deviation) = corner_rule(&cfg.limits, cfg.ipo_period_s);
        let v_j = jump.min(deviation);
        let (prog, corner) = corner_program(0.1);
        let (_, sp) = run(&prog, &cfg);
        let (_, before, after) = around_corner(&sp);
        println!(
            "tolerance {tolerance}: jump rule {jump}, deviation rule {deviation}, \
             corner speed {} / {}",
            before.velocity.norm(),
            after.velocity.norm()
        );
        assert!((before.velocity.norm() - v_j).abs() < 1e-9 * v_j.max(1.0));
        assert!((after.velocity.norm() - v_j).abs() < 1e-9 * v_j.max(1.0));
        // The axis velocities jump by v_j per axis (at most A_i T_ipo) at the corner.
        let dv = after.velocity - before.velocity;
        assert!((dv.x + v_j).abs() < 1e-9 && (dv.y - v_j).abs() < 1e-9);
        assert!(dv.x.abs() <= cfg.limits.axis_accel_m_s2[0] * cfg.ipo_period_s * (1.0 + 1e-9));
        // The corner is not rounded: the path reaches the corner point exactly.
        let closest = sp
            .iter()
            .map(|p| (p.position - corner).norm())
            .fold(f64::MAX, f64::min);
        assert!(closest <= v_j * cfg.servo_period_s);
        for p in &sp {
            let on = distance_to_segment(&p.position, &V3::zeros(), &corner).min(
                distance_to_segment(&p.position, &corner, &v3(0.1, 0.1, 0.0)),
            );
            assert!(on < 1e-12, "deviation {on}");
        }
    }
}

#[test]
fn reversal_stops() {
    let cfg = config();
    let a = v3(0.05, 0.0, 0.0);
    let p = program(V3::zeros(), vec![line(a, 0.1), line(V3::zeros(), 0.1)]);
    let (_, sp) = run(&p, &cfg);
    let (_, _, after) = around_corner(&sp);
    assert_eq!(after.position, a);
    assert_eq!(after.velocity.norm(), 0.0);
}

// ---------------------------------------------------------------------------------------------
// Dwell, ticks, end.

#[test]
fn dwell_holds_position_for_its_duration() {
    let cfg = config();
    let a = v3(0.02, 0.01, 0.0);
    let p = program(
        V3::zeros(),
        vec![
            line(a, 0.05),
            Motion::Dwell { seconds: 0.5 },
            line(v3(0.0, 0.03, 0.0), 0.05),
        ],
    );
    let (ipo, sp) = run(&p, &cfg);
    let dwelling: Vec<&Setpoint> = sp.iter().filter(|p| p.block == Some(1)).collect();
    assert_eq!(dwelling.len(), (0.5 / cfg.servo_period_s).round() as usize);
    for d in &dwelling {
        assert_eq!(d.position, a);
        assert_eq!(d.velocity, V3::zeros());
        assert_eq!(d.acceleration, V3::zeros());
    }
    let (block, t0, t1) = ipo.block_times()[1];
    assert_eq!(block, 1);
    assert!((t1 - t0 - 0.5).abs() < 1e-12);
    assert!((dwelling[0].time_s - t0).abs() < 1e-12);
}

#[test]
fn ticks_duration_and_the_end_agree() {
    let cfg = config();
    let (prog, _) = corner_program(0.1);
    let ipo = Interpolator::new(&prog, &cfg).unwrap();
    let n = ipo.iter().count();
    assert_eq!(n, ipo.servo_ticks());
    assert!(((n - 1) as f64 * ipo.servo_period_s() - ipo.duration_s()).abs() < 1e-12);
    assert!(ipo.setpoint(n - 1).is_some());
    assert!(ipo.setpoint(n).is_none());
    assert!(ipo.setpoint(usize::MAX).is_none());
    let last = ipo.setpoint(n - 1).unwrap();
    assert_eq!(last.position, v3(0.1, 0.1, 0.0));
    assert!((last.time_s - ipo.duration_s()).abs() < 1e-12);
}

#[test]
fn empty_program_is_one_setpoint_at_rest() {
    let start = v3(0.1, 0.2, 0.3);
    let ipo = Interpolator::new(&program(start, vec![]), &config()).unwrap();
    assert_eq!(ipo.duration_s(), 0.0);
    let sp: Vec<Setpoint> = ipo.iter().collect();
    assert_eq!(sp.len(), 1);
    assert_eq!(sp[0].position, start);
    assert_eq!(sp[0].block, None);
}

#[test]
fn same_program_gives_the_same_bytes() {
    let circle = Circle {
        center: V3::zeros(),
        radius: 0.03,
        plane: Plane::Zx,
        direction: ArcDirection::Ccw,
    };
    let prog = circle_with_lead_in(&circle, 0.2, 0.02);
    let a: Vec<Setpoint> = Interpolator::new(&prog, &config())
        .unwrap()
        .iter()
        .collect();
    let b: Vec<Setpoint> = Interpolator::new(&prog, &config())
        .unwrap()
        .iter()
        .collect();
    // Every field of every setpoint, the floats by their bits.
    let bits = |p: &Setpoint| -> Vec<u64> {
        std::iter::once(p.time_s)
            .chain(p.position.iter().copied())
            .chain(p.velocity.iter().copied())
            .chain(p.acceleration.iter().copied())
            .map(f64::to_bits)
            .collect()
    };
    assert!(a.len() > 1000, "{} setpoints", a.len());
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(bits(x), bits(y));
        assert_eq!((x.block, x.spindle), (y.block, y.spindle));
    }
}

// ---------------------------------------------------------------------------------------------
// Refusals and degenerate blocks.

#[test]
fn invalid_configs_are_refused_with_clear_errors() {
    let bad_servo = InterpolatorConfig {
        servo_period_s: 300e-6,
        ..config()
    };
    let err = bad_servo.validate().unwrap_err();
    assert!(matches!(
        err,
        InterpolatorError::ServoPeriodNotDivisor { .. }
    ));
    assert!(err.to_string().contains("does not divide"), "{err}");

    let zero_jerk = InterpolatorConfig {
        limits: Limits {
            path_jerk_m_s3: 0.0,
            ..limits()
        },
        ..config()
    };
    let err = zero_jerk.validate().unwrap_err();
    assert!(err.to_string().contains("limits.path_jerk_m_s3"), "{err}");

    let nan_accel = InterpolatorConfig {
        limits: Limits {
            axis_accel_m_s2: [5.0, f64::NAN, 5.0],
            ..limits()
        },
        ..config()
    };
    let err = nan_accel.validate().unwrap_err();
    assert!(err.to_string().contains("axis_accel_m_s2[1] (Y)") && err.to_string().contains("NaN"));

    let huge_jerk = InterpolatorConfig {
        limits: Limits {
            path_jerk_m_s3: 1e6,
            ..limits()
        },
        ..config()
    };
    let err = huge_jerk.validate().unwrap_err();
    assert!(
        matches!(err, InterpolatorError::JerkWindowTooShort { .. }),
        "{err}"
    );

    let (prog, _) = corner_program(0.1);
    assert!(Interpolator::new(&prog, &bad_servo).is_err());
    assert!(config().validate().is_ok());
}

#[test]
fn invalid_blocks_name_their_line() {
    let zero_feed = program(V3::zeros(), vec![line(v3(0.1, 0.0, 0.0), 0.0)]);
    let err = Interpolator::new(&zero_feed, &config()).unwrap_err();
    assert!(
        err.to_string().contains("line 10") && err.to_string().contains("feed"),
        "{err}"
    );

    let off_circle = program(
        V3::zeros(),
        vec![
            line(v3(0.01, 0.0, 0.0), 0.1),
            arc(
                v3(0.0, 0.02, 0.0),
                V3::zeros(),
                Plane::Xy,
                ArcDirection::Ccw,
                0.1,
            ),
        ],
    );
    let err = Interpolator::new(&off_circle, &config()).unwrap_err();
    assert!(
        matches!(err, InterpolatorError::ArcRadiusMismatch { line: 11, .. }),
        "{err}"
    );
    assert_eq!(err.line(), Some(11));
    // In mm at six significant digits, not in m with every digit of a float.
    assert!(
        err.to_string().contains(
            "the arc starts 10 mm from its centre but ends 20 mm from it; the difference may be \
             at most 0.01 mm"
        ),
        "{err}"
    );

    let nan = program(V3::zeros(), vec![line(v3(f64::NAN, 0.0, 0.0), 0.1)]);
    let err = Interpolator::new(&nan, &config()).unwrap_err();
    assert!(err.to_string().contains("line 10"), "{err}");

    let negative_dwell = program(V3::zeros(), vec![Motion::Dwell { seconds: -1.0 }]);
    assert!(Interpolator::new(&negative_dwell, &config()).is_err());

    // Too long a program is refused at the block that passes the limit: a creeping move, and
    // a long dwell after a short move.
    let creep = program(
        V3::zeros(),
        vec![line(v3(0.01, 0.0, 0.0), 0.1), line(v3(0.2, 0.0, 0.0), 1e-6)],
    );
    let err = Interpolator::new(&creep, &config()).unwrap_err();
    assert!(
        matches!(err, InterpolatorError::ProgramTooLong { line: 11, .. }),
        "{err}"
    );
    assert_eq!(err.line(), Some(11));
    assert!(err.to_string().contains("longer than the 16777 s"), "{err}");
    let dwell = program(
        V3::zeros(),
        vec![
            line(v3(0.01, 0.0, 0.0), 0.1),
            Motion::Dwell { seconds: 1e6 },
        ],
    );
    let err = Interpolator::new(&dwell, &config()).unwrap_err();
    assert!(err.to_string().contains("block at line 11"), "{err}");
}

#[test]
fn zero_length_blocks_are_skipped() {
    let a = v3(0.05, 0.0, 0.0);
    let with = program(
        V3::zeros(),
        vec![
            line(V3::zeros(), 0.1),
            line(a, 0.1),
            line(a, 0.1),
            Motion::Rapid { to: a },
            line(v3(0.05, 0.05, 0.0), 0.1),
        ],
    );
    let without = program(
        V3::zeros(),
        vec![line(a, 0.1), line(v3(0.05, 0.05, 0.0), 0.1)],
    );
    let (ipo, sp) = run(&with, &config());
    let (reference, _) = run(&without, &config());
    assert_eq!(ipo.duration_s(), reference.duration_s());
    let blocks: Vec<usize> = ipo.block_times().iter().map(|b| b.0).collect();
    assert_eq!(blocks, vec![1, 4]);
    assert!(sp.iter().all(|p| {
        p.position
            .iter()
            .chain(p.velocity.iter())
            .all(|v| v.is_finite())
    }));
}

// ---------------------------------------------------------------------------------------------
// Random programs: on the path, within every limit.

#[derive(Clone, Debug)]
enum Shape {
    Line(V3),
    /// Plane, direction, radius, start-angle offset of the centre, sweep (0 = full turn), rise.
    Arc(Plane, ArcDirection, f64, f64, f64, f64),
    Rapid(V3),
    Dwell(f64),
}

/// The programmed geometry of one block, for checking setpoints against it.
#[derive(Clone, Debug)]
enum Reference {
    Line(V3, V3),
    Helix {
        center: V3,
        plane: Plane,
        radius: f64,
        start_angle: f64,
        sweep: f64,
        rise: f64,
    },
    Point(V3),
}

impl Reference {
    fn distance(&self, p: &V3) -> f64 {
        match self {
            Reference::Line(a, b) => distance_to_segment(p, a, b),
            Reference::Point(a) => (p - a).norm(),
            Reference::Helix {
                center,
                plane,
                radius,
                start_angle,
                sweep,
                rise,
            } => {
                let (u, v, n) = basis(*plane);
                let r = p - center;
                let radial = (r.dot(&u).hypot(r.dot(&v)) - radius).abs();
                let angle = r.dot(&v).atan2(r.dot(&u)) - start_angle;
                let base = (angle * sweep.signum()).rem_euclid(TAU);
                let axial = [base - TAU, base, base + TAU]
                    .into_iter()
                    .filter(|psi| *psi > -1e-6 && *psi < sweep.abs() + 1e-6)
                    .map(|psi| (r.dot(&n) - rise * psi / sweep.abs()).abs())
                    .fold(f64::MAX, f64::min);
                radial.max(axial)
            }
        }
    }
}

fn step(size: f64) -> impl Strategy<Value = V3> {
    (-size..size, -size..size, -size..size).prop_map(|(x, y, z)| v3(x, y, z))
}

fn shape() -> impl Strategy<Value = Shape> {
    let plane = prop_oneof![Just(Plane::Xy), Just(Plane::Zx), Just(Plane::Yz)];
    let dir = prop_oneof![Just(ArcDirection::Ccw), Just(ArcDirection::Cw)];
    let sweep = prop_oneof![Just(0.0), 0.2..6.0f64];
    prop_oneof![
        6 => step(0.05).prop_map(Shape::Line),
        6 => (plane, dir, 0.003..0.05f64, 0.0..TAU, sweep, -0.01..0.01f64)
            .prop_map(|(p, d, r, a, s, h)| Shape::Arc(p, d, r, a, s, h)),
        1 => step(0.05).prop_map(Shape::Rapid),
        1 => (0.0..0.05f64).prop_map(Shape::Dwell),
    ]
}

/// Short segments with small direction changes, as a CAM polyline.
fn polyline() -> impl Strategy<Value = Vec<(Shape, f64)>> {
    (
        prop::collection::vec((0.0..0.4f64, -0.3..0.3f64, 5e-5..2e-3f64), 10..80),
        0.05..0.5f64,
    )
        .prop_map(|(turns, feed)| {
            let (mut heading, mut climb) = (0.0f64, 0.0f64);
            turns
                .into_iter()
                .map(|(turn, tilt, length)| {
                    heading += turn;
                    climb = (climb + tilt).clamp(-1.0, 1.0);
                    let d = v3(
                        heading.cos() * climb.cos(),
                        heading.sin() * climb.cos(),
                        climb.sin(),
                    );
                    (Shape::Line(d * length), feed)
                })
                .collect()
        })
}

/// Random but consistent limits: windows of 1 to 100 IPO periods, axes slower or faster than
/// the path.
fn random_limits() -> impl Strategy<Value = (Limits, bool)> {
    (
        (0.5..5.0f64, 1.0..100.0f64, 1e-7..1e-4f64, any::<bool>()),
        (0.05..1.0f64, 0.05..1.0f64, 0.05..1.0f64),
        (0.5..10.0f64, 0.5..10.0f64, 0.5..10.0f64),
    )
        .prop_map(
            |((accel, window, tolerance, exact_stop), (vx, vy, vz), (ax, ay, az))| {
                let limits = Limits {
                    rapid_m_s: 0.5,
                    max_feed_m_s: 0.3,
                    path_accel_m_s2: accel,
                    path_jerk_m_s3: accel / (window * 1e-3),
                    axis_velocity_m_s: [vx, vy, vz],
                    axis_accel_m_s2: [ax, ay, az],
                    corner_tolerance_m: tolerance,
                };
                (limits, exact_stop)
            },
        )
}

/// Builds the motion from `from`, its reference geometry, its commanded speed and its end.
fn realise(shape: &Shape, from: V3, feed: f64, limits: &Limits) -> (Motion, Reference, f64, V3) {
    let feed_clamped = feed.min(limits.max_feed_m_s);
    match shape {
        Shape::Line(d) => {
            let to = from + d;
            (line(to, feed), Reference::Line(from, to), feed_clamped, to)
        }
        Shape::Rapid(d) => {
            let to = from + d;
            (
                Motion::Rapid { to },
                Reference::Line(from, to),
                limits.rapid_m_s,
                to,
            )
        }
        Shape::Dwell(seconds) => (
            Motion::Dwell { seconds: *seconds },
            Reference::Point(from),
            0.0,
            from,
        ),
        Shape::Arc(plane, direction, radius, offset, sweep, rise) => {
            let (u, v, n) = basis(*plane);
            let e = |angle: f64| u * angle.cos() + v * angle.sin();
            let center = from - e(*offset) * *radius;
            let signed = match direction {
                ArcDirection::Ccw => 1.0,
                ArcDirection::Cw => -1.0,
            };
            let (to, sweep) = if *sweep == 0.0 {
                (from + n * *rise, signed * TAU)
            } else {
                let to = center + e(offset + signed * sweep) * *radius + n * *rise;
                (to, signed * sweep)
            };
            let motion = arc(to, center, *plane, *direction, feed);
            let reference = Reference::Helix {
                center,
                plane: *plane,
                radius: *radius,
                start_angle: *offset,
                sweep,
                rise: *rise,
            };
            (motion, reference, feed_clamped, to)
        }
    }
}

/// Figures of one checked run.
struct Checked {
    worst_distance: f64,
    path_accel: f64,
    path_jerk: f64,
}

/// Interpolates `shapes` and checks every setpoint: on the programmed geometry of its block,
/// blocks in order, speed within the block's feed, axis velocities and accelerations within
/// their limits, path acceleration and jerk (at the IPO instants) within theirs, the end exact.
fn check(shapes: &[(Shape, f64)], cfg: &InterpolatorConfig) -> Result<Checked, TestCaseError> {
    let l = &cfg.limits;
    let start = v3(0.01, 0.02, 0.03);
    let mut from = start;
    let (mut motions, mut references, mut speeds) = (Vec::new(), Vec::new(), Vec::new());
    for (shape, feed) in shapes {
        let (motion, reference, speed, to) = realise(shape, from, *feed, l);
        motions.push(motion);
        references.push(reference);
        speeds.push(speed);
        from = to;
    }
    let (ipo, sp) = run(&program(start, motions), cfg);
    let slack = fine_slack(cfg);
    let accel_slack = l.path_jerk_m_s3 * cfg.ipo_period_s;
    let mut last_block = 0;
    let mut worst_distance: f64 = 0.0;
    for p in &sp {
        let Some(block) = p.block else {
            continue; // only zero-length blocks: nothing moves
        };
        prop_assert!(block >= last_block);
        last_block = block;
        worst_distance = worst_distance.max(references[block].distance(&p.position));
        prop_assert!(
            p.velocity.norm() <= speeds[block] + slack,
            "{}",
            p.velocity.norm()
        );
        for i in 0..3 {
            prop_assert!(p.velocity[i].abs() <= l.axis_velocity_m_s[i] + slack);
            prop_assert!(
                p.acceleration[i].abs() <= l.axis_accel_m_s2[i] + accel_slack,
                "axis {i} acceleration {}",
                p.acceleration[i]
            );
        }
    }
    prop_assert!(worst_distance < 1e-9, "off the path by {worst_distance} m");
    prop_assert!((sp.last().unwrap().position - from).norm() < 1e-12);
    let (path_accel, path_jerk) = accel_and_jerk(&ipo_speeds(&ipo, &sp), ipo.ipo_period_s());
    prop_assert!(
        path_accel <= l.path_accel_m_s2 * (1.0 + 1e-6),
        "path acceleration {path_accel}"
    );
    prop_assert!(
        path_jerk <= l.path_jerk_m_s3 * (1.0 + 1e-6),
        "path jerk {path_jerk}"
    );
    Ok(Checked {
        worst_distance,
        path_accel,
        path_jerk,
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 40, ..ProptestConfig::default() })]

    #[test]
    fn random_programs_stay_on_the_path_within_the_limits(
        shapes in prop::collection::vec((shape(), 0.01..0.4f64), 1..6),
        (limits, exact_stop) in random_limits(),
    ) {
        let cfg = InterpolatorConfig { limits, exact_stop, ..config() };
        check(&shapes, &cfg)?;
    }

    #[test]
    fn dense_polylines_stay_on_the_path_within_the_limits(
        shapes in polyline(),
        (limits, exact_stop) in random_limits(),
    ) {
        let cfg = InterpolatorConfig { limits, exact_stop, ..config() };
        check(&shapes, &cfg)?;
    }
}

#[test]
fn mixed_program_stays_on_the_path_within_the_limits() {
    let shapes = vec![
        (Shape::Line(v3(0.05, 0.0, 0.0)), 0.2),
        (
            Shape::Arc(Plane::Xy, ArcDirection::Ccw, 0.02, 0.0, 0.0, 0.0),
            0.2,
        ),
        (
            Shape::Arc(Plane::Zx, ArcDirection::Cw, 0.01, 0.3, 2.0, 0.005),
            0.1,
        ),
        (Shape::Rapid(v3(0.0, 0.0, 0.02)), 0.0),
        (Shape::Dwell(0.1), 0.0),
        (Shape::Line(v3(-0.03, 0.02, -0.01)), 0.3),
        (
            Shape::Arc(Plane::Yz, ArcDirection::Ccw, 0.015, 1.0, 4.0, 0.0),
            0.25,
        ),
    ];
    let cfg = config();
    let figures = check(&shapes, &cfg).unwrap();
    println!(
        "mixed program: largest distance from the programmed path {:e} m, path acceleration \
         {} m/s² (limit {}), path jerk {} m/s³ (limit {})",
        figures.worst_distance,
        figures.path_accel,
        cfg.limits.path_accel_m_s2,
        figures.path_jerk,
        cfg.limits.path_jerk_m_s3
    );
    assert!(figures.path_jerk > 0.9 * cfg.limits.path_jerk_m_s3);
}
