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
