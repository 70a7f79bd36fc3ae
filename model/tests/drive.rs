//! Feed-drive physics: LuGre friction laws, the integrator's stability limit, following error,
//! backlash in semi-closed loop.

use proptest::prelude::*;
use vmt_model::drive::axis::symplectic_euler_limit;
use vmt_model::drive::servo::{loops_are_stable, sampled_loop_radius};
use vmt_model::drive::{
    AxisCommand, DriveParams, Feedback, LuGre, LuGreParams, ReducedAxis, ScrewParams,
    ServoController, ServoParams,
};

const SERVO: f64 = 125e-6;
const SUBSTEPS: usize = 4;

fn guide_friction() -> LuGreParams {
    LuGreParams {
        sigma0_n_per_m: 2e7,
        sigma1_n_s_per_m: 3e4,
        sigma2_n_s_per_m: 200.0,
        coulomb_n: 50.0,
        static_n: 65.0,
        stribeck_m_s: 1e-3,
        stribeck_exponent: 2.0,
    }
}

/// A 250 kg table on a 10 mm-lead screw, 2 µm of backlash, semi-closed loop.
fn table_drive(backlash_m: f64) -> (DriveParams, ServoParams) {
    let params = DriveParams {
        motor_inertia_kg_m2: 0.003,
        screw: ScrewParams {
            lead_m: 0.01,
            stiffness_n_per_m: 1.8e8,
            damping_n_s_per_m: 2e4,
            backlash_m,
            cyclic_m: [0.0; 2],
        },
        carriage_mass_kg: 250.0,
        guide_friction: guide_friction(),
        screw_friction: LuGreParams {
            coulomb_n: 30.0,
            static_n: 40.0,
            ..guide_friction()
        },
        encoder_counts_per_rev: (1u32 << 20) as f64,
        torque_constant_n_m_per_a: 1.2,
        feedback: Feedback::MotorEncoder,
    };
    let servo = ServoParams {
        kv_per_s: 33.0,
        velocity_kp_n_s_per_m: 5.4e5,
        velocity_ti_s: 0.01,
        velocity_ff: 0.0,
        acceleration_ff: 0.0,
        current_time_constant_s: 0.5e-3,
        force_limit_n: 6000.0,
        following_error_limit_m: None,
    };
    (params, servo)
}

/// Runs the axis along `command(t)` for `duration` s; returns samples (t, motor position,
/// carriage position, following error) every servo period, positions at the period's end.
fn run(
    axis: &mut ReducedAxis,
    duration: f64,
    command: impl Fn(f64) -> AxisCommand,
) -> Vec<(f64, f64, f64, f64)> {
    let n = (duration / SERVO).round() as usize;
    let h = SERVO / SUBSTEPS as f64;
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let t = k as f64 * SERVO;
        let cmd = command(t);
        axis.control(&cmd, SERVO);
        for _ in 0..SUBSTEPS {
            axis.step(h, 0.0);
        }
        out.push((
            t,
            axis.drive.motor_position_m,
            axis.carriage.position_m,
            axis.drive.following_error_m(),
        ));
    }
    out
}

/// Constant-velocity ramp from rest (with a smooth 50 ms velocity ramp-up).
fn ramp(v: f64) -> impl Fn(f64) -> AxisCommand {
    move |t: f64| {
        let t0 = 0.05;
        if t < t0 {
            AxisCommand {
                position: 0.5 * v / t0 * t * t,
                velocity: v * t / t0,
                acceleration: v / t0,
            }
        } else {
            AxisCommand {
                position: 0.5 * v * t0 + v * (t - t0),
                velocity: v,
                acceleration: 0.0,
            }
        }
    }
}

proptest! {
    /// The screw's periodic lead error: the nut leads the motor by e(x) with the lead as its
    /// period and sqrt(e_c² + e_s²) as its amplitude, and the nut's velocity is the derivative
    /// of its position (central difference).
    #[test]
    fn a_lead_error_is_periodic_in_the_lead(
        x in -0.5..0.5f64,
        c in -5e-6..5e-6f64,
        s in -5e-6..5e-6f64,
        v in -0.1..0.1f64,
    ) {
        let screw = ScrewParams { cyclic_m: [c, s], ..table_drive(0.0).0.screw };
        let (nut, v_nut) = screw.nut(x, v);
        let (next, _) = screw.nut(x + screw.lead_m, v);
        prop_assert!((next - screw.lead_m - nut).abs() < 1e-15);
        prop_assert!((nut - x).abs() <= c.hypot(s) + 1e-18);
        let h = 1e-7;
        let slope = (screw.nut(x + h, 0.0).0 - screw.nut(x - h, 0.0).0) / (2.0 * h);
        prop_assert!((v_nut - v * slope).abs() < 1e-9 * (1.0 + v.abs()), "{v_nut} vs {}", v * slope);
        // Without a lead error the nut is where the motor is.
        let plain = ScrewParams { cyclic_m: [0.0; 2], ..screw };
        prop_assert_eq!(plain.nut(x, v), (x, v));
    }

    /// In steady sliding LuGre gives the Stribeck curve plus viscous friction.
    #[test]
    fn lugre_steady_sliding_is_the_stribeck_curve(v in prop_oneof![-0.2..-1e-5f64, 1e-5..0.2f64]) {
        let p = guide_friction();
        let mut c = LuGre::default();
        let mut f = 0.0;
        // The bristle state settles as exp(-|v| t / g(v)) with g(v) <= Fs/σ0: run 30 of those
        // time constants (the z update is exact for constant v, so the step may be long).
        let settle_s = 30.0 * p.static_n / (p.sigma0_n_per_m * v.abs());
        let n = 2000;
        for _ in 0..n {
            f = c.step(&p, v, settle_s / n as f64);
        }
        // The law written out, not through the crate: Fc + (Fs - Fc) exp(-(v/vs)²) + σ2 v.
        let expected = v.signum()
            * (p.coulomb_n + (p.static_n - p.coulomb_n) * (-(v / p.stribeck_m_s).powi(2)).exp())
            + p.sigma2_n_s_per_m * v;
        prop_assert!((f - expected).abs() < 1e-6 * expected.abs().max(1.0), "{f} vs {expected}");
        prop_assert!((p.steady_state_force(v) - expected).abs() < 1e-9 * expected.abs());
    }
}

/// The Stribeck curve at hand-computed points of the guideway contact (Fc 50 N, Fs 65 N,
/// vs 1 mm/s, σ2 200 N·s/m), and with exponent δ = 1 (the general power): at vs the rise has
/// fallen to 1/e, at vs/2 to e^(-1/4) (δ = 2) or e^(-1/2) (δ = 1), far above vs it is gone.
#[test]
fn stribeck_curve_at_hand_computed_points() {
    let p = guide_friction();
    let e = std::f64::consts::E;
    for (v, expected) in [
        (1e-3, 50.0 + 15.0 / e + 0.2),
        (-1e-3, -(50.0 + 15.0 / e + 0.2)),
        (0.5e-3, 50.0 + 15.0 * e.powf(-0.25) + 0.1),
        (0.2, 50.0 + 40.0),
    ] {
        let f = p.steady_state_force(v);
        assert!(
            (f - expected).abs() < 1e-9,
            "{v} m/s: {f} N against {expected} N"
        );
    }
    let linear = LuGreParams {
        stribeck_exponent: 1.0,
        ..p
    };
    let f = linear.steady_state_force(0.5e-3);
    let expected = 50.0 + 15.0 * e.powf(-0.5) + 0.1;
    assert!(
        (f - expected).abs() < 1e-9,
        "δ = 1: {f} N against {expected} N"
    );
    assert!((f - 59.198).abs() < 1e-3);
}

/// Where the Stribeck force is zero the bristles carry no load (g = 0, a = |v|/g infinite), so
/// the contact is viscous alone: `F = σ2 v` at any sliding speed, with no Coulomb or static
/// force (a purely viscous contact), and with no Coulomb force far above vs (the Stribeck term
/// underflows). A contact stepped 1 mm at 10 mm/s must not turn into a spring of stiffness σ0.
#[test]
fn lugre_without_stribeck_force_is_viscous_alone() {
    let viscous = LuGreParams {
        coulomb_n: 0.0,
        static_n: 0.0,
        ..guide_friction()
    };
    let no_coulomb = LuGreParams {
        coulomb_n: 0.0,
        ..guide_friction()
    };
    for (p, v) in [(viscous, 0.01), (viscous, -0.01), (no_coulomb, 50.0 * 1e-3)] {
        let mut c = LuGre::default();
        let mut f = 0.0;
        for _ in 0..1000 {
            f = c.step(&p, v, 1e-4);
        }
        let expected = p.sigma2_n_s_per_m * v;
        assert!((f - expected).abs() < 1e-9, "v {v}: {f} N vs {expected} N");
        assert_eq!(c.z_m, 0.0, "v {v}");
    }
    // At rest a load-free contact stays unloaded: z = 0 and no force (0 · ∞ read as no slip).
    let mut c = LuGre::default();
    assert_eq!(c.step(&viscous, 0.0, 1e-4), 0.0);
    assert_eq!(c.z_m, 0.0);
}

/// Before breakaway the contact is a spring of stiffness σ0 (pre-sliding): a 0.1 µm creep
/// gives σ0 · 0.1 µm of force.
#[test]
fn lugre_pre_sliding_is_a_spring_of_stiffness_sigma0() {
    let p = LuGreParams {
        sigma1_n_s_per_m: 0.0,
        ..guide_friction()
    };
    let mut c = LuGre::default();
    let v = 1e-6;
    let mut f = 0.0;
    for _ in 0..100 {
        f = c.step(&p, v, 1e-3);
    }
    // 0.1 µm creep at 1 µm/s; g(v) = Fs/σ0 = 3.25 µm, so the bristles are far from sliding.
    let spring = p.sigma0_n_per_m * 1e-7;
    assert!(
        (f - spring - p.sigma2_n_s_per_m * v).abs() < 0.02 * spring,
        "{f} vs {spring}"
    );
}

/// The semi-implicit Euler limit is where the integration of a damped oscillator turns unstable.
#[test]
fn symplectic_euler_limit_separates_stable_from_unstable() {
    for (k, c, m) in [(1.8e8, 2e4, 206.0), (2e7, 3e4, 250.0), (1e6, 0.0, 1.0)] {
        let h_max = symplectic_euler_limit(k, c, m);
        let grows = |h: f64| {
            let (mut x, mut v) = (1e-6, 0.0);
            (0..20_000).any(|_| {
                v += h * (-k * x - c * v) / m;
                x += h * v;
                x.abs() > 1e-3
            })
        };
        assert!(!grows(0.99 * h_max), "k {k}: stable below the limit");
        assert!(grows(1.01 * h_max), "k {k}: unstable above the limit");
    }
}

/// At constant velocity the following error of a P position loop is v / Kv (the integral of
/// the velocity loop takes up friction), within 1 %; with velocity feed-forward k it is
/// (1 - k) v / Kv.
#[test]
fn following_error_at_constant_velocity_is_v_over_kv() {
    let (p, s0) = table_drive(0.0);
    let (h_max, _) = p.largest_stable_step_s();
    assert!(SERVO / SUBSTEPS as f64 <= h_max);
    for (v, k) in [
        (1000.0 / 60_000.0, 0.0),
        (5000.0 / 60_000.0, 0.0),
        (5000.0 / 60_000.0, 0.5),
    ] {
        let s = ServoParams {
            velocity_ff: k,
            ..s0
        };
        let mut axis = ReducedAxis::new(p, s, 0.0);
        let samples = run(&mut axis, 0.6, ramp(v));
        let steady: Vec<f64> = samples.iter().filter(|x| x.0 > 0.4).map(|x| x.3).collect();
        let mean = steady.iter().sum::<f64>() / steady.len() as f64;
        let expected = (1.0 - k) * v / s.kv_per_s;
        assert!(
            (mean - expected).abs() < 0.01 * expected,
            "v {v}: {mean} vs {expected}"
        );
    }
}

/// Semi-closed loop: the controller positions the motor, so after a reversal the carriage is
/// off by the whole gap: b/2 behind going forward, b/2 ahead going backward, each plus the screw's
/// compression F/k under the guideway friction F it pushes against.
#[test]
fn backlash_shifts_the_carriage_by_the_gap_at_a_reversal() {
    let b = 4e-6;
    let (p, s) = table_drive(b);
    let v = 500.0 / 60_000.0;
    let forward = ramp(v);
    let mut axis = ReducedAxis::new(p, s, 0.0);
    // Forward for 0.5 s, hold, then back.
    let cmd = |t: f64| {
        if t < 0.5 {
            forward(t)
        } else if t < 1.0 {
            AxisCommand {
                position: forward(0.5).position,
                ..Default::default()
            }
        } else {
            let back = forward(t - 1.0);
            AxisCommand {
                position: forward(0.5).position - back.position,
                velocity: -back.velocity,
                acceleration: -back.acceleration,
            }
        }
    };
    let samples = run(&mut axis, 1.5, cmd);
    // Carriage minus motor position, once each motion has settled.
    let offset = |t0: f64, t1: f64| {
        let sel: Vec<_> = samples.iter().filter(|x| x.0 > t0 && x.0 < t1).collect();
        sel.iter().map(|x| x.2 - x.1).sum::<f64>() / sel.len() as f64
    };
    let compression = p.guide_friction.steady_state_force(v) / p.screw.stiffness_n_per_m;
    let fwd = offset(0.3, 0.5);
    let bwd = offset(1.3, 1.5);
    assert!(
        (fwd + b / 2.0 + compression).abs() < 0.02e-6,
        "forward offset {fwd:e}"
    );
    assert!(
        (bwd - b / 2.0 - compression).abs() < 0.02e-6,
        "backward offset {bwd:e}"
    );
}

/// The table drive's servo with velocity bandwidth `hz` (Kp = M·2π·bw with M the drive's total
/// mass, as the scenario sets it), without a force limit.
fn servo_of_bandwidth(hz: f64, drive: &DriveParams) -> ServoParams {
    ServoParams {
        velocity_kp_n_s_per_m: drive.total_mass_kg() * std::f64::consts::TAU * hz,
        force_limit_n: f64::INFINITY,
        ..table_drive(0.0).1
    }
}

/// The table drive made rigid: a screw a million times stiffer, critically damped, so that motor
/// and carriage move as one mass.
fn rigid_drive() -> DriveParams {
    let p = table_drive(0.0).0;
    let k = 1.8e14;
    let (mm, mc) = (p.reflected_motor_mass_kg(), p.carriage_mass_kg);
    let reduced = mm * mc / (mm + mc);
    DriveParams {
        screw: ScrewParams {
            stiffness_n_per_m: k,
            damping_n_s_per_m: 2.0 * (k * reduced).sqrt(),
            ..p.screw
        },
        ..p
    }
}

/// The growth of a disturbance per servo period when `ServoController::update` runs the two-mass
/// drive (position from its feedback, velocity from the motor; no friction or backlash) through the current lag, the motion
/// between samples integrated by classical Runge-Kutta in 100 steps under the held force
/// reference: the ratio of the largest |x_m| in two windows 300 periods apart, to the power
/// 1/300.
fn growth_per_period(s: &ServoParams, d: &DriveParams) -> f64 {
    let (t, tc) = (SERVO, s.current_time_constant_s);
    let (mm, mc) = (d.reflected_motor_mass_kg(), d.carriage_mass_kg);
    let (k, c) = (d.screw.stiffness_n_per_m, d.screw.damping_n_s_per_m);
    // y = [x_m, v_m, x_c, v_c, F]
    let rate = |y: [f64; 5], r: f64| -> [f64; 5] {
        let screw = k * (y[0] - y[2]) + c * (y[1] - y[3]);
        [y[1], (y[4] - screw) / mm, y[3], screw / mc, (r - y[4]) / tc]
    };
    let mut y = [1e-6, 0.0, 1e-6, 0.0, 0.0];
    let mut ctrl = ServoController::default();
    let mut peaks = Vec::new();
    let h = t / 100.0;
    let position = match d.feedback {
        Feedback::MotorEncoder => 0,
        Feedback::LinearScale { .. } => 2,
    };
    for n in 0..700 {
        let r = ctrl.update(
            s,
            &AxisCommand::default(),
            y[position],
            y[0],
            d.total_mass_kg(),
            t,
        );
        for _ in 0..100 {
            let add = |a: [f64; 5], b: [f64; 5], f: f64| std::array::from_fn(|i| a[i] + f * b[i]);
            let k1 = rate(y, r);
            let k2 = rate(add(y, k1, h / 2.0), r);
            let k3 = rate(add(y, k2, h / 2.0), r);
            let k4 = rate(add(y, k3, h), r);
            y = std::array::from_fn(|i| {
                y[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
            });
        }
        if (380..400).contains(&n) || n >= 680 {
            peaks.push(y[0].abs());
        }
    }
    let (early, late) = peaks.split_at(20);
    let max = |w: &[f64]| w.iter().copied().fold(0.0, f64::max);
    (max(late) / max(early)).powf(1.0 / 300.0)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// On a rigid drive, the velocity loop alone (no lag, the integral and the position loop too
    /// slow to matter): `z² − (1 − K/2) z + K/2 = 0`, `K = Kp·T/M`, whose complex roots have
    /// modulus √(K/2): stable below K = 2, growing by √(K/2) per period above.
    #[test]
    fn sampled_velocity_loop_is_stable_below_k_of_two(k in 0.3..8.0f64) {
        let d = rigid_drive();
        let s = ServoParams {
            kv_per_s: 1e-3,
            velocity_kp_n_s_per_m: k * d.total_mass_kg() / SERVO,
            velocity_ti_s: 1e3,
            current_time_constant_s: 1e-6 * SERVO,
            ..servo_of_bandwidth(1.0, &d)
        };
        let rho = sampled_loop_radius(&s, &d, SERVO);
        if k < 1.95 {
            prop_assert!(rho < 1.0, "K {k}: {rho}");
        } else if k > 2.05 {
            prop_assert!((rho - (k / 2.0).sqrt()).abs() < 1e-4, "K {k}: {rho}");
        }
    }
}

/// The spectral radius of the linearised loops is the growth (or decay) per period of the
/// controller itself run in time on the two-mass drive, with the current lag and the integral:
/// the table's 60 Hz velocity loop decays, 1.5 kHz at 125 µs grows (the screw's compliance
/// brings the limit from about 1.24 kHz on a rigid drive down to about 1.03 kHz).
#[test]
fn sampled_loop_radius_is_the_growth_of_the_running_controller() {
    let d = table_drive(0.0).0;
    for (hz, stable) in [(60.0, true), (1500.0, false)] {
        let s = servo_of_bandwidth(hz, &d);
        let rho = sampled_loop_radius(&s, &d, SERVO);
        let seen = growth_per_period(&s, &d);
        eprintln!("{hz} Hz: radius {rho}, growth of the running controller {seen}");
        assert_eq!(
            loops_are_stable(&s, &d, SERVO),
            stable,
            "{hz} Hz: radius {rho}"
        );
        assert!(
            (seen - rho).abs() < 2e-3,
            "{hz} Hz: radius {rho}, seen {seen}"
        );
    }
    // Position from a linear scale on the carriage: the same agreement.
    let scale = DriveParams {
        feedback: Feedback::LinearScale { resolution_m: 0.0 },
        ..d
    };
    for hz in [60.0, 1500.0] {
        let s = servo_of_bandwidth(hz, &scale);
        let (rho, seen) = (
            sampled_loop_radius(&s, &scale, SERVO),
            growth_per_period(&s, &scale),
        );
        assert!(
            (seen - rho).abs() < 2e-3,
            "scale, {hz} Hz: radius {rho}, seen {seen}"
        );
    }
    // Between the two limits: stable on the rigid drive, unstable on the compliant one.
    let s = servo_of_bandwidth(1150.0, &d);
    assert!(loops_are_stable(&s, &rigid_drive(), SERVO));
    assert!(!loops_are_stable(&s, &d, SERVO));
}

/// The radius depends on the drive through its frequencies alone: masses, stiffness, damping and
/// gain scaled together by 10⁴ give the same radius. A loop without integral action and position
/// gain only drifts (an eigenvalue of 1) and passes; numbers that overflow the period's matrix
/// are refused, not looped over.
#[test]
fn sampled_loop_radius_scales_and_degenerates_cleanly() {
    let d = table_drive(0.0).0;
    let s = servo_of_bandwidth(900.0, &d);
    let f = 1e4;
    let heavy = DriveParams {
        motor_inertia_kg_m2: d.motor_inertia_kg_m2 * f,
        carriage_mass_kg: d.carriage_mass_kg * f,
        screw: ScrewParams {
            stiffness_n_per_m: d.screw.stiffness_n_per_m * f,
            damping_n_s_per_m: d.screw.damping_n_s_per_m * f,
            ..d.screw
        },
        ..d
    };
    let (a, b) = (
        sampled_loop_radius(&s, &d, SERVO),
        sampled_loop_radius(&servo_of_bandwidth(900.0, &heavy), &heavy, SERVO),
    );
    assert!((a - b).abs() < 1e-9, "{a} vs {b}");
    let drifting = ServoParams {
        kv_per_s: 0.0,
        velocity_ti_s: f64::INFINITY,
        ..s
    };
    assert!(loops_are_stable(&drifting, &d, SERVO));
    let overflow = ServoParams {
        current_time_constant_s: 1e-300,
        ..s
    };
    assert_eq!(sampled_loop_radius(&overflow, &d, SERVO), f64::INFINITY);
    let instant = ServoParams {
        current_time_constant_s: 1e-50,
        ..s
    };
    assert_eq!(sampled_loop_radius(&instant, &d, SERVO), f64::INFINITY);
}
