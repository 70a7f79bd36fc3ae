//! Friction signatures emerging from the simulated drives: stick-slip at creep feeds and the
//! reversal spikes (quadrant glitches) of a circular test.

mod common;

use nalgebra::Vector3;
use vmt_model::drive::LuGreParams;
use vmt_model::machine::Machine;
use vmt_sim::ballbar::BallbarSpec;
use vmt_sim::interpolator::{InterpolatorConfig, Limits};
use vmt_sim::nc::{ArcDirection, CircularTest, Plane, parse};
use vmt_sim::plant::Fidelity;
use vmt_sim::run::{BallbarTrace, Run};
use vmt_sim::simulate::{AxisDynamics, BallbarSetup, Job, SimSettings, simulate};

const SERVO_HZ: f64 = 8000.0;

fn machine() -> Machine {
    let mut m = vmt_scenario::builtin().unwrap().machine;
    // A geometrically perfect machine, so that only the drives shape the motion.
    m.volumetric.errors = vmt_model::geometric::GeometricErrors::zero();
    m.thermal = None;
    m
}

fn run(
    axes: &[AxisDynamics; 3],
    program: &str,
    start: Vector3<f64>,
    bar: Vec<BallbarSetup>,
) -> Run {
    let job = Job {
        program: parse(program, start).unwrap(),
        ballbar: bar,
        laser: None,
    };
    let settings = SimSettings {
        fidelity: Fidelity::Reduced,
        plant_substeps: 2,
        log_rate_hz: SERVO_HZ,
        seed: 7,
    };
    let ipo = InterpolatorConfig::new(Limits::default());
    simulate(&machine(), axes, &ipo, &job, &settings, "", &mut |_| {}).unwrap()
}

/// Drives without backlash, all with Kv = 33 1/s (equal gains: no servo-mismatch ellipse).
fn matched_axes() -> [AxisDynamics; 3] {
    [
        common::axis(250.0, 0.0, 33.0),
        common::axis(450.0, 0.0, 33.0),
        common::axis(180.0, 0.0, 33.0),
    ]
}

/// Plain (box) slideways under the 250 kg X table: lubricated cast iron with μs ≈ 0.2 and
/// μk ≈ 0.12 under 2.45 kN gives Fs = 500 N and Fc = 300 N; the friction falls to Coulomb
/// within vs = 0.2 mm/s (mixed lubrication, Armstrong-Hélouvry 1991: vs of 0.01 to 1 mm/s);
/// the bristles take 2.5 µm of pre-sliding to reach Fs (σ0 = Fs / 2.5 µm = 2e8 N/m).
fn box_slideway() -> LuGreParams {
    LuGreParams {
        sigma0_n_per_m: 2e8,
        coulomb_n: 300.0,
        static_n: 500.0,
        stribeck_m_s: 0.2e-3,
        ..common::guide_friction()
    }
}

/// Carriage speed over the constant-feed phase of a 1-axis X move at `feed_mm_min`, from the
/// true carriage positions at the servo rate, relative to the commanded speed.
fn carriage_speed(feed_mm_min: f64, seconds: f64) -> Vec<f64> {
    let mut axes = matched_axes();
    axes[0].drive.guide_friction = box_slideway();
    // A long slender screw: 50 N/µm (a 32 mm screw over 1 m with its nut and bearings).
    axes[0].drive.screw.stiffness_n_per_m = 5e7;
    let to_mm = 100.0 + feed_mm_min * seconds / 60.0;
    let program = format!("G1 X{to_mm:.4} F{feed_mm_min}");
    let r = run(&axes, &program, Vector3::new(0.1, 0.2, 0.2), vec![]);
    let x = &r.streams[0].channel("position_x").unwrap().values;
    let command = &r.streams[0].channel("command_x").unwrap().values;
    let v_cmd = feed_mm_min / 60_000.0;
    // Skip 0.5 s of start (acceleration, integrator wind-up) and the last 0.2 s of the
    // program (braking), and the wait for the axes to be in position after it.
    let end = command
        .windows(2)
        .rposition(|w| w[1] != w[0])
        .map_or(command.len(), |i| i + 1);
    let (a, b) = ((0.5 * SERVO_HZ) as usize, end - (0.2 * SERVO_HZ) as usize);
    x[a..b]
        .windows(2)
        .map(|w| (w[1] - w[0]) * SERVO_HZ / v_cmd)
        .collect()
}

/// (Half the peak-to-peak ripple, lowest speed, slips per second) of relative speeds `v`; a
/// slip is a rise through twice the commanded speed.
fn ripple(v: &[f64]) -> (f64, f64, f64) {
    let (lo, hi) = v
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    let slips = v.windows(2).filter(|w| w[0] <= 2.0 && w[1] > 2.0).count();
    (
        0.5 * (hi - lo),
        lo,
        slips as f64 * SERVO_HZ / v.len() as f64,
    )
}

/// A carriage pulled through a spring k (the screw) over friction whose steady curve falls with
/// speed slides steadily only while the curve's negative slope is smaller than the damping,
/// -dF/dv < c (Armstrong-Hélouvry, Dupont & Canudas de Wit, Automatica 30(7), 1994, §4.3). At
/// 10 mm/min (v/vs = 0.83) the Stribeck curve of [`box_slideway`] falls at
/// 2 (Fs - Fc) (v/vs) exp(-(v/vs)²) / vs = 8.3e5 N·s/m, forty times the screw's 2e4 N·s/m: the
/// table sticks, the screw winds up until the bristles break away, the table jumps ahead and
/// sticks again. At 1000 mm/min (v/vs = 83) the slope is nil and the table slides smoothly.
/// With LuGre bristles the drive must also be compliant enough for the slip to develop: the
/// linearised steady sliding is unstable for k + c·a < σ0·|v g'/g| (a = |v|/g, g the steady
/// bristle deflection), 5.2e7 < 6.9e7 N/m here — hence the long screw (a 180 N/µm one creeps).
#[test]
fn stribeck_friction_makes_stick_slip_at_10_mm_min_gone_at_1000() {
    let (slow, slow_min, slips) = ripple(&carriage_speed(10.0, 2.5));
    let (fast, fast_min, _) = ripple(&carriage_speed(1000.0, 1.5));
    eprintln!(
        "10 mm/min: ripple ±{:.0} %, lowest {slow_min:.2}, {slips:.1} slips/s; \
         1000 mm/min: ripple ±{:.4} %, lowest {fast_min:.4}",
        100.0 * slow,
        100.0 * fast
    );
    // Stick-slip: the speed swings by more than ±50 % of the feed, the table comes to rest
    // (below 10 % of the feed) in every cycle, and it slips several times a second.
    assert!(
        slow > 0.5 && slow_min < 0.1 && slips > 5.0,
        "{slow} {slow_min} {slips}"
    );
    // Smooth sliding: within ±5 % of the feed.
    assert!(fast < 0.05 && fast_min > 0.95, "{fast} {fast_min}");
}

/// A CCW arc of radius 50 mm at `feed_mm_min` through the X reversal at 0° (data from -30°
/// to +30°), on `axes`; the trace without the transducer's 0.1 µm quantisation.
fn reversal_arc(axes: &[AxisDynamics; 3], feed_mm_min: f64) -> BallbarTrace {
    let center = Vector3::new(0.25, 0.2, 0.2);
    let mut test = CircularTest::iso230_4(Plane::Xy, center, 0.05, feed_mm_min / 60_000.0);
    test.start_deg = -30.0;
    test.arc_deg = 60.0;
    test.overshoot_deg = 15.0;
    test.directions = vec![ArcDirection::Ccw];
    let text = test.gcode();
    let program = parse(&text, test.start_point()).unwrap();
    let bar = BallbarSetup {
        name: None,
        spec: BallbarSpec {
            resolution_m: 0.0,
            ..BallbarSpec::default()
        },
        center,
        radius_m: test.radius_m,
        plane: Plane::Xy,
        feed_m_s: test.feed_m_s,
        data: test.data_blocks(&program).unwrap(),
        circle: None,
    };
    let r = run(axes, &text, test.start_point(), vec![bar]);
    r.ballbar.into_iter().next().unwrap()
}

fn median_between(t: &BallbarTrace, lo: f64, hi: f64) -> f64 {
    let mut v: Vec<f64> = t
        .angle_deg
        .iter()
        .zip(&t.deviation_um)
        .filter(|(a, _)| (lo..hi).contains(*a))
        .map(|(_, d)| *d)
        .collect();
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// (Height, µm, and full width at half height, degrees) of the outward reversal spike after
/// 0°. Friction also steps the trace across the reversal (the screw's wind-up F/k changes
/// sign), so the spike is measured above the higher of the levels before (-3° to 0°) and after
/// it (15° to 25°): the step itself never counts as spike.
fn spike(t: &BallbarTrace) -> (f64, f64) {
    let base = median_between(t, -3.0, 0.0).max(median_between(t, 15.0, 25.0));
    let d = &t.deviation_um;
    let ipk = (0..d.len())
        .filter(|&k| (0.0..20.0).contains(&t.angle_deg[k]))
        .max_by(|&i, &j| d[i].total_cmp(&d[j]))
        .unwrap();
    let h = d[ipk] - base;
    let above = |k: usize| d[k] - base > 0.5 * h;
    let first = (0..ipk).rev().find(|&k| !above(k)).map_or(0, |k| k + 1);
    let last = (ipk..d.len()).find(|&k| !above(k)).unwrap_or(d.len()) - 1;
    (h, t.angle_deg[last] - t.angle_deg[first])
}

/// At the X reversal of a circle the guideway and screw friction reverse: the carriage stops
/// while the command moves on, the velocity loop's integrator must wind up twice the friction
/// force before the axis follows again, and the position loop then recovers the lag (time
/// constant 1/Kv = 30 ms): the trace bulges outwards (the quadrant glitch). That takes roughly
/// a fixed time once the reversal acceleration v²/r is large enough, so the angle swept
/// meanwhile, (v/r)·t, grows with the feed. Without backlash and geometric errors only
/// friction makes the spike: with friction removed it vanishes.
#[test]
fn reversal_spike_widens_with_feed() {
    let axes = matched_axes();
    let spikes: Vec<(f64, f64)> = [500.0, 2000.0, 5000.0]
        .into_iter()
        .map(|f| spike(&reversal_arc(&axes, f)))
        .collect();
    eprintln!("(height µm, width deg) at 500, 2000, 5000 mm/min: {spikes:.2?}");
    for (h, _) in &spikes {
        assert!(*h > 0.5, "a spike of {h} µm");
    }
    for w in spikes.windows(2) {
        assert!(
            w[1].1 > 1.3 * w[0].1,
            "the width grows with feed: {spikes:?}"
        );
    }
    // Once the reversal acceleration v²/r is large, the time the glitch lasts, t = w·r/v, is
    // about fixed: the widths at 2000 and 5000 mm/min last within 20 % of one time, and the
    // width grows about as the feed (2.5 times for a fixed time; over 2 asked).
    let duration_ms = |(_, w): (f64, f64), feed: f64| w.to_radians() * 50.0 / (feed / 60_000.0);
    let (t2, t5) = (
        duration_ms(spikes[1], 2000.0),
        duration_ms(spikes[2], 5000.0),
    );
    assert!((t5 / t2 - 1.0).abs() < 0.2, "{t2} ms and {t5} ms");
    assert!(spikes[2].1 > 2.0 * spikes[1].1, "{spikes:?}");
    let mut frictionless = axes;
    for a in &mut frictionless {
        a.drive.guide_friction = LuGreParams::NONE;
        a.drive.screw_friction = LuGreParams::NONE;
    }
    let (h, _) = spike(&reversal_arc(&frictionless, 2000.0));
    assert!(h < 0.1 * spikes[1].0, "without friction: {h} µm");
}

/// A program ends with its axes in position: the controller holds the last setpoint until every
/// following error is within 1 µm (as a CNC completes M30 after its in-position check), and the
/// log runs on until then. The carriage is still tens of µm behind when the setpoints end.
#[test]
fn a_program_ends_with_the_axes_in_position() {
    let r = run(
        &matched_axes(),
        "G1 X120 F3000",
        Vector3::new(0.1, 0.2, 0.2),
        vec![],
    );
    let servo = &r.streams[0];
    let command = &servo.channel("command_x").unwrap().values;
    let end = command
        .windows(2)
        .rposition(|w| w[1] != w[0])
        .map_or(0, |i| i + 1);
    let error = |a: &str, i: usize| {
        servo
            .channel(&format!("following_error_{a}"))
            .unwrap()
            .values[i]
    };
    assert!(
        error("x", end).abs() > 5e-6,
        "{} m at the last setpoint",
        error("x", end)
    );
    let last = servo.times_s.len() - 1;
    for a in ["x", "y", "z"] {
        assert!(
            error(a, last).abs() <= vmt_sim::simulate::IN_POSITION_M,
            "{a}: {}",
            error(a, last)
        );
    }
    let waited = servo.times_s[last] - servo.times_s[end];
    assert!(
        waited > 0.01 && waited < vmt_sim::simulate::SETTLE_LIMIT_S,
        "{waited} s"
    );
}
