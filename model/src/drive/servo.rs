//! The axis controller: a cascade of position, velocity and current loops (e.g. Altintas,
//! "Manufacturing Automation", 2nd ed., ch. 5; Ellis, "Control System Design Guide").
//!
//! Evaluated once per servo period `T` (s) on the sampled, quantised feedback:
//!
//! ```text
//! e      = x_cmd - x_fb                                   position error (following error), m
//! v_ref  = Kv·e + k_vff·v_cmd                             P position loop + velocity feed-forward
//! v_fb   = (x_enc[n] - x_enc[n-1]) / T                    motor velocity from the encoder
//! I     += (v_ref - v_fb)·T                               (held while the force saturates)
//! F_ref  = Kp·((v_ref - v_fb) + I/Ti) + k_aff·M·a_cmd      PI velocity loop + acceleration FF
//! F_ref  = clamp(F_ref, ±F_max)                           torque (force) saturation
//! ```
//!
//! `Kv` is the position loop gain (1/s), `Kp` the velocity loop gain (N per m/s), `Ti` its
//! integral time (s), `M` the total reflected mass (kg), `F_max` the motor's peak torque as a
//! linear force (N). Forces are in the linear coordinates of the axis (torque · 2π / lead). The
//! current loop is a first-order lag of time constant `Tc` (s) between `F_ref` and the motor
//! force, integrated exactly by the plant. At constant velocity the integral removes the velocity
//! error, so the following error is `e = (1 - k_vff)·v / Kv`.
//!
//! Sampling limits the gains ([`sampled_loop_radius`]): linearised about rest on a rigid drive
//! of mass `M` (no friction, saturation or quantisation), one period maps the state
//! `s = [x, v, F, I, x_prev]` by a constant matrix, the controller above with the plant
//! `ẋ = v, M v̇ = F, Tc Ḟ = F_ref − F` integrated exactly under the held `F_ref` (zero-order
//! hold). The loops are stable when every eigenvalue of that matrix lies inside the unit
//! circle. Without the current lag and the integral the velocity loop alone reads
//! `v[n+1] = v[n] − (K/2)(v[n] + v[n−1])`, `K = Kp·T/M`, stable for `K < 2` (the backward
//! difference averages the velocity over the last period).

use nalgebra::{Matrix4, Matrix5, RowVector5, Vector3};

/// Controller settings of one axis, SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServoParams {
    /// Position loop gain Kv, 1/s.
    pub kv_per_s: f64,
    /// Velocity loop proportional gain Kp, N·s/m.
    pub velocity_kp_n_s_per_m: f64,
    /// Velocity loop integral time Ti, s.
    pub velocity_ti_s: f64,
    /// Velocity feed-forward factor, 0 to 1.
    pub velocity_ff: f64,
    /// Acceleration (torque) feed-forward factor, 0 to 1.
    pub acceleration_ff: f64,
    /// Current loop time constant Tc, s.
    pub current_time_constant_s: f64,
    /// Peak motor force (torque · 2π / lead), N.
    pub force_limit_n: f64,
}

/// Commanded motion of one axis for one servo period.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct AxisCommand {
    /// Position, m.
    pub position: f64,
    /// Velocity, m/s.
    pub velocity: f64,
    /// Acceleration, m/s².
    pub acceleration: f64,
}

/// The controller's state between servo periods.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct ServoController {
    integral: f64,
    last_encoder: Option<f64>,
    /// Last position error (following error), m.
    pub following_error_m: f64,
    /// Last force reference, N.
    pub force_reference_n: f64,
}

impl ServoController {
    /// One servo period: from the command and the quantised feedback (position feedback and
    /// motor encoder, m) to the force reference (N). `mass_kg` scales the acceleration FF.
    pub fn update(
        &mut self,
        p: &ServoParams,
        cmd: &AxisCommand,
        position_feedback_m: f64,
        motor_encoder_m: f64,
        mass_kg: f64,
        period_s: f64,
    ) -> f64 {
        let e = cmd.position - position_feedback_m;
        let v_ref = p.kv_per_s * e + p.velocity_ff * cmd.velocity;
        let v_fb = match self.last_encoder {
            Some(last) => (motor_encoder_m - last) / period_s,
            None => 0.0,
        };
        self.last_encoder = Some(motor_encoder_m);
        let ev = v_ref - v_fb;
        let integral = self.integral + ev * period_s;
        let unclamped = p.velocity_kp_n_s_per_m * (ev + integral / p.velocity_ti_s)
            + p.acceleration_ff * mass_kg * cmd.acceleration;
        let force = unclamped.clamp(-p.force_limit_n, p.force_limit_n);
        // Conditional integration: no wind-up while the motor is saturated.
        if force == unclamped {
            self.integral = integral;
        }
        self.following_error_m = e;
        self.force_reference_n = force;
        force
    }
}

/// The spectral radius of the sampled position and velocity loops of `p` run every `period_s`
/// on a rigid drive of total mass `mass_kg`, linearised about rest (module docs): below 1 the
/// loops are stable, and a disturbance decays by this factor per period.
pub fn sampled_loop_radius(p: &ServoParams, mass_kg: f64, period_s: f64) -> f64 {
    let (t, tc) = (period_s, p.current_time_constant_s);
    // Plant over one period with F_ref held: exp of the augmented matrix [[A, B], [0, 0]] · T
    // gives Φ (top left) and Γ (top of the last column).
    #[rustfmt::skip]
    let augmented = Matrix4::new(
        0.0, 1.0, 0.0, 0.0,
        0.0, 0.0, 1.0 / mass_kg, 0.0,
        0.0, 0.0, -1.0 / tc, 1.0 / tc,
        0.0, 0.0, 0.0, 0.0,
    ) * t;
    let e = augmented.exp();
    let phi = e.fixed_view::<3, 3>(0, 0);
    let gamma: Vector3<f64> = e.fixed_view::<3, 1>(0, 3).into();
    // The controller as rows on s = [x, v, F, I, x_prev]: the velocity error (regulating to
    // rest), the force reference, the integral.
    let ev = RowVector5::new(-p.kv_per_s - 1.0 / t, 0.0, 0.0, 0.0, 1.0 / t);
    let kp = p.velocity_kp_n_s_per_m;
    let f_ref = ev * (kp * (1.0 + t / p.velocity_ti_s))
        + RowVector5::new(0.0, 0.0, 0.0, kp / p.velocity_ti_s, 0.0);
    let mut a = Matrix5::zeros();
    for i in 0..3 {
        for j in 0..3 {
            a[(i, j)] = phi[(i, j)];
        }
        a.set_row(i, &(a.row(i) + f_ref * gamma[i]));
    }
    a.set_row(3, &(RowVector5::new(0.0, 0.0, 0.0, 1.0, 0.0) + ev * t));
    a[(4, 0)] = 1.0;
    a.complex_eigenvalues()
        .iter()
        .map(|z| z.norm())
        .fold(0.0, f64::max)
}
