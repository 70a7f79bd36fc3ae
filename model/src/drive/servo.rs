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
//! Sampling limits the gains ([`sampled_loop_radius`]): linearised about rest (no friction,
//! backlash, saturation or quantisation), one period maps the state
//! `s = [x_m, v_m, x_c, v_c, F, I, x_m(prev)]` by a constant matrix: the controller above on
//! the two-mass drive (`M_m v̇_m = F − k(x_m − x_c) − c(v_m − v_c)`,
//! `m v̇_c = k(x_m − x_c) + c(v_m − v_c)`, `Tc Ḟ = F_ref − F`) integrated exactly under the held
//! `F_ref` (zero-order hold), the velocity from the motor encoder, the position from it or from
//! the scale. The loops are stable when no eigenvalue of that matrix lies outside the unit
//! circle. On a rigid drive of mass `M` without the current lag and the integral the velocity
//! loop reads `v[n+1] = v[n] − (K/2)(v[n] + v[n−1])`, `K = Kp·T/M`, stable for `K < 2` (the
//! backward difference averages the velocity over the last period); the screw's compliance
//! lowers the limit, as the motor alone answers the loop above the screw mode. The slope of the
//! screw's periodic lead error (a few per mille for micrometre errors) is left out of the screw
//! coupling. The check follows the physics, not the simulator: the plant's semi-implicit step
//! (`axis`) gives the loop about one plant step of phase lead, so a simulated loop stays stable
//! somewhat beyond the limit (the built-in X axis to about 2 kHz at two plant steps per period
//! against 1027 Hz), and a refused bandwidth would not show its instability in a run.

use super::axis::{DriveParams, Feedback};
use nalgebra::{SMatrix, Schur};

type RowVector7 = SMatrix<f64, 1, 7>;

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
    /// The excess-error alarm: the largest |following error| the control accepts before it
    /// stops the job (Fanuc's "excess error", Siemens' contour monitoring), m; `None` for the
    /// control's default ([`ServoParams::following_error_limit`]).
    pub following_error_limit_m: Option<f64>,
}

impl ServoParams {
    /// The excess-error limit, m, with `fastest_m_s` the axis' fastest speed (m/s): the set
    /// one, else twice the lag of the P position loop at that speed, `2 v/Kv`, which a drive
    /// that follows its command does not reach (feed-forward only shortens the lag).
    pub fn following_error_limit(&self, fastest_m_s: f64) -> f64 {
        self.following_error_limit_m
            .unwrap_or(2.0 * fastest_m_s / self.kv_per_s)
    }
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

/// The spectral radius of the sampled position and velocity loops of `p` driving `drive`, run
/// every `period_s`, linearised about rest (module docs): below 1 the loops are stable, above
/// 1 a disturbance grows by this factor per period (an eigenvalue of exactly 1, a loop without
/// integral action or position gain, only drifts; see [`loops_are_stable`]). Infinite when the
/// numbers overflow.
pub fn sampled_loop_radius(p: &ServoParams, drive: &DriveParams, period_s: f64) -> f64 {
    let Some(a) =
        sampled_loop_matrix(p, drive, period_s).filter(|a| a.iter().all(|v| v.is_finite()))
    else {
        return f64::INFINITY;
    };
    match Schur::try_new(a, f64::EPSILON, 1000) {
        Some(schur) => schur
            .complex_eigenvalues()
            .iter()
            .map(|z| z.norm())
            .fold(0.0, f64::max),
        None => f64::INFINITY,
    }
}

/// The least damped oscillating pole of the sampled loops of `p` on `drive` at `period_s`
/// (linearised as for [`sampled_loop_radius`]): its frequency (Hz) and damping ratio, from the
/// discrete eigenvalue `z` as `s = ln(z)/T`, `ζ = −Re s/|s|` (negative: it grows). A loop
/// rings there when disturbed, and with `ζ < 0` it rings on until a nonlinearity (the force
/// limit, friction) bounds it. `None` when nothing oscillates or the matrix is beyond
/// evaluation.
pub fn least_damped_pole(
    p: &ServoParams,
    drive: &DriveParams,
    period_s: f64,
) -> Option<(f64, f64)> {
    let a = sampled_loop_matrix(p, drive, period_s).filter(|a| a.iter().all(|v| v.is_finite()))?;
    let schur = Schur::try_new(a, f64::EPSILON, 1000)?;
    schur
        .complex_eigenvalues()
        .iter()
        .filter(|z| z.im > 1e-12 && z.norm() > 0.0)
        .map(|z| {
            let s = z.ln() / period_s;
            (s.im / std::f64::consts::TAU, -s.re / s.norm())
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// Whether the loops of `p` on `drive` at `period_s` are stable: no eigenvalue beyond the unit
/// circle, rounding allowed for (1e-9, far below any growth that shows in a run).
pub fn loops_are_stable(p: &ServoParams, drive: &DriveParams, period_s: f64) -> bool {
    sampled_loop_radius(p, drive, period_s) <= 1.0 + 1e-9
}

/// The matrix that maps `[x_m, v_m, x_c, v_c, F, I, x_m(prev)]` over one servo period (module
/// docs), forces divided by the total mass so that the entries do not scale with it; None when
/// the drive's rates are beyond evaluation.
fn sampled_loop_matrix(
    p: &ServoParams,
    drive: &DriveParams,
    period_s: f64,
) -> Option<SMatrix<f64, 7, 7>> {
    let (t, tc) = (period_s, p.current_time_constant_s);
    let total = drive.total_mass_kg();
    let (mu_m, mu_c) = (
        drive.reflected_motor_mass_kg() / total,
        drive.carriage_mass_kg / total,
    );
    let (k, c) = (
        drive.screw.stiffness_n_per_m / total,
        drive.screw.damping_n_s_per_m / total,
    );
    // The plant over one period with F_ref held: exp of [[A, B], [0, 0]]·T gives Φ (top left)
    // and Γ (top of the last column); state [x_m, v_m, x_c, v_c, F], input F_ref.
    #[rustfmt::skip]
    let augmented = SMatrix::<f64, 6, 6>::from_row_slice(&[
        0.0, 1.0, 0.0, 0.0, 0.0, 0.0,
        -k / mu_m, -c / mu_m, k / mu_m, c / mu_m, 1.0 / mu_m, 0.0,
        0.0, 0.0, 0.0, 1.0, 0.0, 0.0,
        k / mu_c, c / mu_c, -k / mu_c, -c / mu_c, 0.0, 0.0,
        0.0, 0.0, 0.0, 0.0, -1.0 / tc, 1.0 / tc,
        0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
    ]) * t;
    // Rates beyond 1e12 per period (a current loop of 1e-16 s) are no drive's, and the matrix
    // exponential's squarings grow with them: such a drive reads as unevaluable.
    if augmented.iter().any(|v| !v.is_finite()) || augmented.amax() > 1e12 {
        return None;
    }
    let e = augmented.exp();
    // The controller as rows on the state: velocity error (regulating to rest, the position
    // from the motor encoder or the scale, the velocity from the motor encoder), force
    // reference, integral.
    let position = match drive.feedback {
        Feedback::MotorEncoder => 0,
        Feedback::LinearScale { .. } => 2,
    };
    let mut ev = RowVector7::zeros();
    ev[position] -= p.kv_per_s;
    ev[0] -= 1.0 / t;
    ev[6] += 1.0 / t;
    let kp = p.velocity_kp_n_s_per_m / total;
    let mut f_ref = ev * (kp * (1.0 + t / p.velocity_ti_s));
    f_ref[5] += kp / p.velocity_ti_s;
    let mut a = SMatrix::<f64, 7, 7>::zeros();
    for i in 0..5 {
        for j in 0..5 {
            a[(i, j)] = e[(i, j)];
        }
        a.set_row(i, &(a.row(i) + f_ref * e[(i, 5)]));
    }
    let mut integral = RowVector7::zeros();
    integral[5] = 1.0;
    a.set_row(5, &(integral + ev * t));
    a[(6, 0)] = 1.0;
    Some(a)
}
