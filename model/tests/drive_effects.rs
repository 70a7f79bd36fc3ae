//! The optional physics of a feed drive (`vmt_model::drive::effects`) in the closed loop:
//! motor cogging against the servo's disturbance transfer function, the interpolation error a
//! loop carries into the axis, the lost motion of a nut that lost its preload, and the GMS law
//! in the drive. Each against a closed form written here.

use std::f64::consts::TAU;
use vmt_model::drive::encoder::EncoderSignals;
use vmt_model::drive::gms::GmsParams;
use vmt_model::drive::motor::MotorPulsation;
use vmt_model::drive::nut::PreloadedNut;
use vmt_model::drive::{
    AxisCommand, Drive, DriveEffects, DriveParams, Feedback, LuGreParams, ReducedAxis, ScrewParams,
    ServoParams,
};

const SERVO: f64 = 125e-6;

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

/// The built-in machine's X drive: a 250 kg table on a 10 mm-lead screw, velocity loop of
/// 60 Hz, Kv 33/s, current loop 0.5 ms; `friction` on both contacts.
fn table_drive(friction: LuGreParams, feedback: Feedback) -> (DriveParams, ServoParams) {
    let params = DriveParams {
        motor_inertia_kg_m2: 0.003,
        screw: ScrewParams {
            lead_m: 0.01,
            stiffness_n_per_m: 1.8e8,
            damping_n_s_per_m: 2e4,
            backlash_m: 0.0,
            cyclic_m: [0.0; 2],
        },
        carriage_mass_kg: 250.0,
        guide_friction: friction,
        screw_friction: LuGreParams {
            coulomb_n: friction.coulomb_n * 0.6,
            static_n: friction.static_n * 0.6,
            ..friction
        },
        encoder_counts_per_rev: (1u32 << 20) as f64,
        torque_constant_n_m_per_a: 1.2,
        feedback,
    };
    let servo = ServoParams {
        kv_per_s: 33.0,
        velocity_kp_n_s_per_m: params.total_mass_kg() * TAU * 60.0,
        velocity_ti_s: 0.01,
        velocity_ff: 0.0,
        acceleration_ff: 0.0,
        current_time_constant_s: 0.5e-3,
        force_limit_n: 8000.0,
        following_error_limit_m: None,
    };
    (params, servo)
}

fn axis(params: DriveParams, servo: ServoParams, effects: &DriveEffects) -> ReducedAxis {
    ReducedAxis {
        drive: Drive::new(params, servo, 0.0)
            .with_effects(effects)
            .unwrap(),
        carriage: Default::default(),
    }
}

/// A constant-velocity move (position and velocity commands from t = 0); samples of (time,
/// commanded position, carriage position, motor position) every servo period after `skip` s.
fn cruise(axis: &mut ReducedAxis, v: f64, skip: f64, duration: f64) -> Vec<[f64; 4]> {
    let n = (duration / SERVO).round() as usize;
    let mut out = Vec::new();
    for k in 0..n {
        let t = k as f64 * SERVO;
        let cmd = AxisCommand {
            position: v * t,
            velocity: v,
            acceleration: 0.0,
        };
        axis.control(&cmd, SERVO);
        axis.step(SERVO, 0.0);
        if t >= skip {
            out.push([
                t,
                v * t,
                axis.carriage.position_m,
                axis.drive.motor_position_m,
            ]);
        }
    }
    out
}

/// Amplitude and phase of the component of `y` at angular frequency `w` over the samples'
/// times `t` (least squares on cos, sin and a constant; a whole number of periods).
fn component(t: &[f64], y: &[f64], w: f64) -> (f64, f64) {
    let n = t.len() as f64;
    let mean = y.iter().sum::<f64>() / n;
    let (mut c, mut s) = (0.0, 0.0);
    for (ti, yi) in t.iter().zip(y) {
        c += (yi - mean) * (w * ti).cos();
        s += (yi - mean) * (w * ti).sin();
    }
    let (a, b) = (2.0 * c / n, 2.0 * s / n);
    (a.hypot(b), b.atan2(a))
}

/// Against the disturbance transfer function of the cascade on a rigid axis: a force `F_d`
/// on the motor side moves it by `x/F_d = 1 / (M s² + Kp (1 + 1/(Ti s)) (s + Kv) / (1 + Tc s))`
/// (P position loop, PI velocity loop, first-order current loop, M the total mass). The
/// cogging force `2πA/lead · sin(N k x)` at a slow, steady speed is a sinusoid of frequency
/// `N v / lead` (10 Hz here, far below the screw mode at 150 Hz: the axis is rigid there), so
/// the carriage's ripple is its amplitude times |x/F_d|. Sampling (8 kHz) and the screw's
/// compliance shift it by about a per cent.
#[test]
fn cogging_ripple_follows_the_disturbance_transfer_function() {
    let (params, servo) = table_drive(LuGreParams::NONE, Feedback::MotorEncoder);
    let motor = MotorPulsation {
        cogging_n_m: 0.1,
        cogging_periods_per_rev: 72,
        cogging_phase_rad: 0.0,
        pole_pairs: 4,
        ripple_fraction: 0.0,
        ripple_harmonic: 6,
        ripple_phase_rad: 0.0,
    };
    let effects = DriveEffects {
        motor: Some(motor),
        ..Default::default()
    };
    for f_hz in [5.0, 10.0, 20.0] {
        let v = f_hz * params.screw.lead_m / 72.0;
        let mut a = axis(params, servo, &effects);
        // 2 s to settle, then 40 periods.
        let samples = cruise(&mut a, v, 2.0, 2.0 + 40.0 / f_hz);
        let t: Vec<f64> = samples.iter().map(|s| s[0]).collect();
        let dev: Vec<f64> = samples.iter().map(|s| s[2] - s[1]).collect();
        let w = TAU * f_hz;
        let (amplitude, _) = component(&t, &dev, w);
        let s = nalgebra::Complex::new(0.0, w);
        let m = params.total_mass_kg();
        let (kp, ti, kv, tc) = (
            servo.velocity_kp_n_s_per_m,
            servo.velocity_ti_s,
            servo.kv_per_s,
            servo.current_time_constant_s,
        );
        let loop_force = kp * (1.0 + 1.0 / (ti * s)) * (s + kv) / (1.0 + tc * s);
        let gain = 1.0 / (m * s * s + loop_force).norm();
        let expected = motor.cogging_n_m * TAU / params.screw.lead_m * gain;
        assert!(
            (amplitude / expected - 1.0).abs() < 0.03,
            "{f_hz} Hz: {amplitude:e} m against {expected:e} m"
        );
    }
}

/// Against the interpolation error itself: a loop closed on a scale whose signals are
/// distorted follows the reading, so far below its bandwidth the carriage stands off by minus
/// the error, `x_c ≈ x_cmd − v/Kv − e(x_c)`. A magnetic scale of 1 mm pitch at 0.1 mm/s: the
/// error's harmonics at 0.1 and 0.2 Hz against a position loop of Kv = 33/s, which passes them
/// as `T = Kv/(s + Kv)`, short of all by |1 − T| = 1.9 and 3.8 %: within 5 % of the error's RMS.
#[test]
fn a_loop_on_distorted_signals_carries_minus_their_error() {
    let (params, servo) = table_drive(
        LuGreParams::NONE,
        Feedback::LinearScale { resolution_m: 1e-9 },
    );
    let signals = EncoderSignals {
        period_m: 1e-3,
        offset_cos: 0.01,
        offset_sin: -0.008,
        amplitude_ratio: 1.015,
        phase_error_rad: 1f64.to_radians(),
    };
    let effects = DriveEffects {
        scale_signals: Some(signals),
        ..Default::default()
    };
    let v = 1e-4;
    let mut a = axis(params, servo, &effects);
    let samples = cruise(&mut a, v, 1.0, 11.0);
    let lag = v / servo.kv_per_s;
    let (mut residual, mut error) = (0.0, 0.0);
    for s in &samples {
        let e = signals.error_m(s[2]);
        let dev = s[2] - (s[1] - lag);
        residual += (dev + e).powi(2);
        error += e * e;
    }
    let ratio = (residual / error).sqrt();
    assert!(
        ratio < 0.05,
        "the carriage departs from −e by {ratio} of e's RMS"
    );
    // And the error is the micrometres it should be: λ/2π · 1.3 % ≈ 2 µm RMS or so.
    let rms = (error / samples.len() as f64).sqrt();
    assert!(rms > 1e-6 && rms < 4e-6, "{rms}");
    // Without the distortion the same move has no such departure.
    let mut plain = axis(params, servo, &DriveEffects::default());
    let samples = cruise(&mut plain, v, 1.0, 3.0);
    let worst = samples
        .iter()
        .map(|s| (s[2] - (s[1] - lag)).abs())
        .fold(0.0, f64::max);
    assert!(worst < 2e-8, "{worst}");
}

/// Against the closed form of a reversal through a nut that lost its preload: in steady
/// sliding the screw carries the guideway friction `F = Fc + σ2 v` (far above vs), so the
/// nut stands off the carriage by the series' stretch at `±F`, and the two directions differ
/// by `2 c F^(2/3) + 2F/k_r` (c from the nut's catalogue rigidity at its original preload,
/// k_r the shaft and bearings), where the intact nut gives `2F/k`.
#[test]
fn a_nut_without_preload_adds_an_elastic_lost_motion() {
    let friction = LuGreParams {
        sigma2_n_s_per_m: 0.0,
        ..guide_friction()
    };
    let (params, servo) = table_drive(friction, Feedback::MotorEncoder);
    let nut = PreloadedNut {
        preload_n: 1900.0,
        stiffness_n_per_m: 800e6,
        remaining_preload_n: 0.0,
    };
    let stretch = |effects: &DriveEffects, v: f64| {
        let mut a = axis(params, servo, effects);
        let samples = cruise(&mut a, v, 1.5, 2.0);
        samples.iter().map(|s| s[3] - s[2]).sum::<f64>() / samples.len() as f64
    };
    let v = 0.02;
    let soft = DriveEffects {
        nut: Some(nut),
        ..Default::default()
    };
    let lost = stretch(&soft, v) - stretch(&soft, -v);
    let f = friction.coulomb_n;
    let c = 3.0 * nut.preload_n.cbrt() / nut.stiffness_n_per_m;
    let rest = 1.0 / (1.0 / params.screw.stiffness_n_per_m - 1.0 / nut.stiffness_n_per_m);
    let expected = 2.0 * c * f.powf(2.0 / 3.0) + 2.0 * f / rest;
    assert!(
        (lost / expected - 1.0).abs() < 0.01,
        "{lost:e} m against {expected:e} m"
    );
    let intact = stretch(&DriveEffects::default(), v) - stretch(&DriveEffects::default(), -v);
    let linear = 2.0 * f / params.screw.stiffness_n_per_m;
    assert!(
        (intact / linear - 1.0).abs() < 0.01,
        "{intact:e} {linear:e}"
    );
    // A micrometre more than the intact nut's at the built-in machine's friction.
    assert!(lost - intact > 0.8e-6, "{lost:e} {intact:e}");
}

/// The GMS law at the model's levels in the drive: in steady sliding the screw carries the
/// Stribeck curve plus the viscous term, as with LuGre, so the stand-off of the nut from the
/// carriage (the screw's stretch F/k) is the same to a part in a thousand; only pre-sliding
/// differs.
#[test]
fn the_gms_law_carries_the_same_sliding_friction_as_lugre() {
    let (params, servo) = table_drive(guide_friction(), Feedback::MotorEncoder);
    let gms = DriveEffects {
        guide_gms: Some(GmsParams::matching(&params.guide_friction, 4, None).unwrap()),
        screw_gms: Some(GmsParams::matching(&params.screw_friction, 4, None).unwrap()),
        ..Default::default()
    };
    for v in [-0.03, 0.002, 0.03] {
        let stretch = |effects: &DriveEffects| {
            let mut a = axis(params, servo, effects);
            let samples = cruise(&mut a, v, 1.5, 2.0);
            samples.iter().map(|s| s[3] - s[2]).sum::<f64>() / samples.len() as f64
        };
        let (lugre, with_gms) = (stretch(&DriveEffects::default()), stretch(&gms));
        let expected = params.guide_friction.steady_state_force(v) / params.screw.stiffness_n_per_m;
        assert!(
            (lugre / expected - 1.0).abs() < 1e-3,
            "{v}: LuGre {lugre:e} {expected:e}"
        );
        assert!(
            (with_gms / expected - 1.0).abs() < 1e-3,
            "{v}: GMS {with_gms:e} {expected:e}"
        );
    }
}
