//! One feed drive: servo motor, ball screw with backlash, carriage, friction on both sides.
//!
//! A two-mass model in the linear coordinates of the axis (m, m/s, N):
//!
//! ```text
//! M_m dv_m/dt = F_mot - F_screw - F_fm(v_m)        motor side: rotor, coupling and screw
//! m   dv_c/dt = F_screw - F_fc(v_c) + F_ext        carriage: table/saddle/head with its load
//! dF_mot/dt   = (F_ref - F_mot) / Tc               current loop, first-order lag
//! ```
//!
//! `M_m = J (2π/lead)²` is the motor inertia J (kg·m²) reflected to the carriage, `F_screw` the
//! screw-nut force with its backlash gap ([`ScrewParams`]), `F_fm` the LuGre friction of the
//! screw bearings and nut acting on the motor side, `F_fc` the LuGre friction of the guideways on
//! the carriage ([`LuGre`]), `F_ext` gravity and process forces on the carriage. Feedback is the
//! motor encoder (semi-closed loop, the usual case, in which the gap is not seen by the control)
//! or a linear scale on the carriage (closed loop), quantised to its resolution.
//!
//! Integrator: semi-implicit (symplectic) Euler over a fixed step `h`: forces from the state at
//! the start of the step, then velocities, then positions; the current lag and the LuGre
//! bristles are integrated exactly over the step. For a mode of frequency ω and damping ratio ζ
//! this is stable for `h < (2/ω)(√(1+ζ²) - ζ)`; [`DriveParams::largest_stable_step_s`] applies it
//! to the screw mode (k on the reduced mass of motor and carriage) and to the stuck bristles of
//! both contacts (σ0 on the mass they hold), and a step beyond it is refused. The constants of
//! a step (the current-lag factor `1 - exp(-h/Tc)`, `h/M_m` and `h/m`) are computed once per
//! step size and parameter set, not every step.

use super::friction::{LuGre, LuGreParams};
use super::servo::{AxisCommand, ServoController, ServoParams};
use super::transmission::ScrewParams;

/// Where the position loop takes its feedback.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Feedback {
    /// Semi-closed loop: the motor's rotary encoder.
    MotorEncoder,
    /// Closed loop: a linear scale on the carriage with the given resolution, m.
    LinearScale {
        /// Scale resolution, m.
        resolution_m: f64,
    },
}

/// Physical parameters of one feed drive, SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveParams {
    /// Rotor, coupling and screw inertia about the screw axis, kg·m².
    pub motor_inertia_kg_m2: f64,
    /// Ball screw and nut.
    pub screw: ScrewParams,
    /// Mass of the carriage and everything it carries, kg.
    pub carriage_mass_kg: f64,
    /// Friction of the guideways on the carriage.
    pub guide_friction: LuGreParams,
    /// Friction of the screw bearings and nut, on the motor side.
    pub screw_friction: LuGreParams,
    /// Motor encoder counts per revolution.
    pub encoder_counts_per_rev: f64,
    /// Motor torque constant, N·m/A (for the current channel).
    pub torque_constant_n_m_per_a: f64,
    /// Position feedback.
    pub feedback: Feedback,
}

impl DriveParams {
    /// Motor inertia reflected to the carriage, `J (2π/lead)²`, kg.
    pub fn reflected_motor_mass_kg(&self) -> f64 {
        self.motor_inertia_kg_m2 / self.screw.m_per_rad().powi(2)
    }

    /// Motor-side plus carriage mass, kg.
    pub fn total_mass_kg(&self) -> f64 {
        self.reflected_motor_mass_kg() + self.carriage_mass_kg
    }

    /// Motor current (A) for a motor force `force_n` (N, linear coordinates).
    pub fn current_a(&self, force_n: f64) -> f64 {
        force_n * self.screw.m_per_rad() / self.torque_constant_n_m_per_a
    }

    /// Resolution of the motor encoder in carriage travel, m.
    pub fn encoder_resolution_m(&self) -> f64 {
        self.screw.lead_m / self.encoder_counts_per_rev
    }

    /// The largest step (s) for which the semi-implicit Euler integration of the stiffest mode
    /// is stable, and the name of that mode.
    pub fn largest_stable_step_s(&self) -> (f64, &'static str) {
        let mm = self.reflected_motor_mass_kg();
        let m = self.carriage_mass_kg;
        let reduced = mm * m / (mm + m);
        let modes = [
            (
                "screw axial mode",
                self.screw.stiffness_n_per_m,
                self.screw.damping_n_s_per_m,
                reduced,
            ),
            (
                "guideway friction bristles",
                self.guide_friction.sigma0_n_per_m,
                self.guide_friction.sigma1_n_s_per_m + self.guide_friction.sigma2_n_s_per_m,
                m,
            ),
            (
                "screw friction bristles",
                self.screw_friction.sigma0_n_per_m,
                self.screw_friction.sigma1_n_s_per_m + self.screw_friction.sigma2_n_s_per_m,
                mm,
            ),
        ];
        modes
            .into_iter()
            .filter(|(_, k, _, _)| *k > 0.0)
            .map(|(name, k, c, mass)| (symplectic_euler_limit(k, c, mass), name))
            .fold(
                (f64::INFINITY, "none"),
                |a, b| if b.0 < a.0 { b } else { a },
            )
    }
}

/// Stability limit of semi-implicit Euler for `mass·x'' = -k x - c x'`, s.
pub fn symplectic_euler_limit(k: f64, c: f64, mass: f64) -> f64 {
    let omega = (k / mass).sqrt();
    let zeta = c / (2.0 * (k * mass).sqrt());
    2.0 / omega * ((1.0 + zeta * zeta).sqrt() - zeta)
}

/// Position, velocity and friction state of a carriage.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct CarriageState {
    /// Position, m.
    pub position_m: f64,
    /// Velocity, m/s.
    pub velocity_m_s: f64,
    /// Guideway friction bristles.
    pub friction: LuGre,
    /// Guideway friction force of the last step, N.
    pub friction_force_n: f64,
}

/// The motor side of a drive and its controller.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Drive {
    /// Physical parameters.
    pub params: DriveParams,
    /// Controller settings.
    pub servo: ServoParams,
    controller: ServoController,
    /// Motor angle as carriage travel, m.
    pub motor_position_m: f64,
    /// Motor velocity as carriage speed, m/s.
    pub motor_velocity_m_s: f64,
    /// Motor force after the current loop, N.
    pub motor_force_n: f64,
    /// Screw friction bristles.
    screw_friction: LuGre,
    /// Screw friction force of the last step, N.
    pub screw_friction_force_n: f64,
    /// Force the screw exerted on the carriage in the last step, N.
    pub screw_force_n: f64,
    /// Constants of the last step size.
    step: MotorStep,
}

/// The constants of a step of `h` seconds: the current-lag factor `1 - exp(-h/Tc)`, and
/// `h/M_m` and `h/m` for the velocity updates of the motor side (reflected motor mass `M_m`)
/// and of a lumped carriage (mass `m`), s/kg. Kept with the values they were computed from
/// (`h`, `Tc`, `J`, lead, `m`), so that a change of any of them recomputes them.
#[derive(Clone, Copy, Debug, PartialEq)]
struct MotorStep {
    key: Option<[f64; 5]>,
    lag: f64,
    h_over_motor_mass: f64,
    h_over_carriage_mass: f64,
}

impl MotorStep {
    /// Not computed yet.
    const NONE: MotorStep = MotorStep {
        key: None,
        lag: 0.0,
        h_over_motor_mass: 0.0,
        h_over_carriage_mass: 0.0,
    };

    /// The constants for a step of `h` (s), recomputed only if `h` or a parameter changed.
    #[inline]
    fn get(&mut self, h: f64, params: &DriveParams, servo: &ServoParams) -> &MotorStep {
        let key = Some([
            h,
            servo.current_time_constant_s,
            params.motor_inertia_kg_m2,
            params.screw.lead_m,
            params.carriage_mass_kg,
        ]);
        if key != self.key {
            *self = MotorStep {
                key,
                lag: 1.0 - (-h / servo.current_time_constant_s).exp(),
                h_over_motor_mass: h / params.reflected_motor_mass_kg(),
                h_over_carriage_mass: h / params.carriage_mass_kg,
            };
        }
        self
    }
}

impl Drive {
    /// A drive at rest with the motor at `motor_position_m` (m).
    pub fn new(params: DriveParams, servo: ServoParams, motor_position_m: f64) -> Self {
        Self {
            params,
            servo,
            controller: ServoController::default(),
            motor_position_m,
            motor_velocity_m_s: 0.0,
            motor_force_n: 0.0,
            screw_friction: LuGre::default(),
            screw_friction_force_n: 0.0,
            screw_force_n: 0.0,
            step: MotorStep::NONE,
        }
    }

    /// The quantised position feedback and motor encoder reading for a carriage at
    /// `carriage_m`, m.
    pub fn feedback(&self, carriage_m: f64) -> (f64, f64) {
        let q = self.params.encoder_resolution_m();
        let encoder = (self.motor_position_m / q).floor() * q;
        let position = match self.params.feedback {
            Feedback::MotorEncoder => encoder,
            Feedback::LinearScale { resolution_m } => {
                (carriage_m / resolution_m).floor() * resolution_m
            }
        };
        (position, encoder)
    }

    /// One servo period of the controller; returns the force reference, N.
    pub fn control(&mut self, cmd: &AxisCommand, carriage_m: f64, period_s: f64) -> f64 {
        let (position, encoder) = self.feedback(carriage_m);
        let mass = self.params.total_mass_kg();
        self.controller
            .update(&self.servo, cmd, position, encoder, mass, period_s)
    }

    /// The controller's last following error (command minus feedback), m.
    pub fn following_error_m(&self) -> f64 {
        self.controller.following_error_m
    }

    /// The controller's last force reference, N.
    pub fn force_reference_n(&self) -> f64 {
        self.controller.force_reference_n
    }

    /// The force the screw exerts on `carriage` now, N.
    #[inline]
    pub fn screw_force(&self, carriage: &CarriageState) -> f64 {
        self.params.screw.force(
            self.motor_position_m,
            self.motor_velocity_m_s,
            carriage.position_m,
            carriage.velocity_m_s,
        )
    }

    /// Advances the motor side by `h` (s) against the screw force `screw_force_n` (N, the force
    /// on the carriage; the motor feels its reaction).
    #[inline]
    pub fn step_motor(&mut self, h: f64, screw_force_n: f64) {
        let c = self.step.get(h, &self.params, &self.servo);
        let (lag, h_over_mm) = (c.lag, c.h_over_motor_mass);
        self.motor_force_n += (self.controller.force_reference_n - self.motor_force_n) * lag;
        let friction =
            self.screw_friction
                .step(&self.params.screw_friction, self.motor_velocity_m_s, h);
        self.motor_velocity_m_s += (self.motor_force_n - screw_force_n - friction) * h_over_mm;
        self.motor_position_m += h * self.motor_velocity_m_s;
        self.screw_friction_force_n = friction;
        self.screw_force_n = screw_force_n;
    }
}

/// The net force on a carriage over a step of `h` (s): screw force, guideway friction (its
/// bristles advance) and the external force, N.
#[inline]
pub fn carriage_force(
    params: &DriveParams,
    carriage: &mut CarriageState,
    screw_force_n: f64,
    external_n: f64,
    h: f64,
) -> f64 {
    let friction = carriage
        .friction
        .step(&params.guide_friction, carriage.velocity_m_s, h);
    carriage.friction_force_n = friction;
    screw_force_n - friction + external_n
}

/// A drive and its carriage integrated together: the reduced plant of one axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReducedAxis {
    /// Motor side and controller.
    pub drive: Drive,
    /// The carriage.
    pub carriage: CarriageState,
}

impl ReducedAxis {
    /// An axis at rest with the carriage at `position_m`, the motor centred in the gap.
    pub fn new(params: DriveParams, servo: ServoParams, position_m: f64) -> Self {
        Self {
            drive: Drive::new(params, servo, position_m),
            carriage: CarriageState {
                position_m,
                ..Default::default()
            },
        }
    }

    /// One servo period of the controller.
    pub fn control(&mut self, cmd: &AxisCommand, period_s: f64) {
        self.drive.control(cmd, self.carriage.position_m, period_s);
    }

    /// Advances motor and carriage by `h` (s) with `external_n` (N) on the carriage.
    #[inline]
    pub fn step(&mut self, h: f64, external_n: f64) {
        let screw = self.drive.screw_force(&self.carriage);
        let p = &self.drive.params;
        let force = carriage_force(p, &mut self.carriage, screw, external_n, h);
        self.drive.step_motor(h, screw);
        // step_motor has just refreshed the constants for this h.
        self.carriage.velocity_m_s += force * self.drive.step.h_over_carriage_mass;
        self.carriage.position_m += h * self.carriage.velocity_m_s;
    }
}
