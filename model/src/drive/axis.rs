//! One feed drive: servo motor, ball screw with backlash, carriage, friction on both sides.
//!
//! A two-mass model in the linear coordinates of the axis (m, m/s, N), as in Altintas, Verl,
//! Brecher, Uriarte & Pritschow, "Machine tool feed drives", CIRP Annals 60(2), 2011:
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
//! Optional physics ([`DriveEffects`], off by default) enters at four places: the motor's
//! cogging and torque ripple add to `F_mot` in the motor side's equation; the interpolation
//! error of an encoder's signals adds to its reading before it is quantised; a preloaded
//! double nut replaces the nut's share of the screw spring in `F_screw`; the GMS law replaces
//! LuGre in `F_fm` or `F_fc`. Each is a branch on an empty option when it is off.
//!
//! Integrator: semi-implicit (symplectic) Euler over a fixed step `h`: the screw force from the
//! positions at the start of the step, the current lag and the LuGre bristles integrated exactly
//! over the step (their end-of-step force enters the velocity update), then velocities, then
//! positions. For a mode of frequency ω and damping ratio ζ
//! this is stable for `h < (2/ω)(√(1+ζ²) - ζ)`; [`DriveParams::largest_stable_step_s`] applies it
//! to the screw mode (k on the reduced mass of motor and carriage) and to the stuck bristles of
//! both contacts (σ0 on the mass they hold), and a step beyond it is refused. The constants of
//! a step (the current-lag factor `1 - exp(-h/Tc)`, `h/M_m`, `h/m` and the friction contacts'
//! [`LuGreStep`]) are computed once per step size, not every step; the parameters are fixed
//! when the drive is built.

use super::effects::{ActiveEffects, DriveEffects};
use super::friction::{LuGre, LuGreParams, LuGreStep, exp};
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

/// The motor side of a drive and its controller. The parameters are fixed at construction
/// (read them with [`Drive::params`] and [`Drive::servo`]): the constants derived from them are
/// computed once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Drive {
    params: DriveParams,
    servo: ServoParams,
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
    /// [`DriveParams::total_mass_kg`], kg.
    total_mass_kg: f64,
    /// [`DriveParams::encoder_resolution_m`], m.
    encoder_resolution_m: f64,
    /// Constants of the last step size.
    step: StepConstants,
    /// Optional physics ([`Drive::with_effects`]), none by default.
    effects: ActiveEffects,
}

/// The constants of a step of `h` seconds: the current-lag factor `1 - exp(-h/Tc)`, `h/M_m`
/// and `h/m` for the velocity updates of the motor side (reflected motor mass `M_m`) and of a
/// lumped carriage (mass `m`), s/kg, and those of the two friction contacts.
#[derive(Clone, Copy, Debug, PartialEq)]
struct StepConstants {
    /// The step they are for, s (NaN: none yet).
    h: f64,
    lag: f64,
    h_over_motor_mass: f64,
    h_over_carriage_mass: f64,
    screw_friction: LuGreStep,
    guide_friction: LuGreStep,
}

impl StepConstants {
    fn new(h: f64, params: &DriveParams, servo: &ServoParams) -> Self {
        Self {
            h,
            lag: 1.0 - (-h / servo.current_time_constant_s).exp(),
            h_over_motor_mass: h / params.reflected_motor_mass_kg(),
            h_over_carriage_mass: h / params.carriage_mass_kg,
            screw_friction: LuGreStep::new(&params.screw_friction, h),
            guide_friction: LuGreStep::new(&params.guide_friction, h),
        }
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
            total_mass_kg: params.total_mass_kg(),
            encoder_resolution_m: params.encoder_resolution_m(),
            step: StepConstants::new(f64::NAN, &params, &servo),
            effects: ActiveEffects::default(),
        }
    }

    /// This drive with the optional physics of `effects` (none by default: see
    /// [`DriveEffects`]); an error names an effect that does not fit the drive.
    pub fn with_effects(mut self, effects: &DriveEffects) -> Result<Self, String> {
        effects.check(&self.params)?;
        self.effects = ActiveEffects::new(effects, &self.params);
        Ok(self)
    }

    /// Physical parameters.
    pub fn params(&self) -> &DriveParams {
        &self.params
    }

    /// Controller settings.
    pub fn servo(&self) -> &ServoParams {
        &self.servo
    }

    /// The quantised position feedback and motor encoder reading for a carriage at
    /// `carriage_m`, m.
    #[inline]
    pub fn feedback(&self, carriage_m: f64) -> (f64, f64) {
        let q = self.encoder_resolution_m;
        let motor = match &self.effects.motor_encoder {
            None => self.motor_position_m,
            Some(s) => self.motor_position_m + s.error_m(self.motor_position_m),
        };
        let encoder = floor(motor / q) * q;
        let position = match self.params.feedback {
            Feedback::MotorEncoder => encoder,
            Feedback::LinearScale { resolution_m } => {
                let scale = match &self.effects.scale {
                    None => carriage_m,
                    Some(s) => carriage_m + s.error_m(carriage_m),
                };
                floor(scale / resolution_m) * resolution_m
            }
        };
        (position, encoder)
    }

    /// One servo period of the controller; returns the force reference, N.
    pub fn control(&mut self, cmd: &AxisCommand, carriage_m: f64, period_s: f64) -> f64 {
        let (position, encoder) = self.feedback(carriage_m);
        self.controller.update(
            &self.servo,
            cmd,
            position,
            encoder,
            self.total_mass_kg,
            period_s,
        )
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
        let (x_m, v_m) = (self.motor_position_m, self.motor_velocity_m_s);
        let (x_c, v_c) = (carriage.position_m, carriage.velocity_m_s);
        match &self.effects.nut {
            None => self.params.screw.force(x_m, v_m, x_c, v_c),
            Some(nut) => self.params.screw.force_through(nut, x_m, v_m, x_c, v_c),
        }
    }

    /// Advances the motor side by `h` (s) against the screw and the guideway friction of
    /// `carriage` by the same step (its bristles advance; its motion is the caller's), and
    /// returns the net force on the carriage: screw force, guideway friction and `external_n`
    /// (N). The screw force is from the positions at the start of the step, the motor force and
    /// the friction from the current lag and the bristles advanced over it (see the module doc).
    #[inline]
    pub fn step(&mut self, h: f64, carriage: &mut CarriageState, external_n: f64) -> f64 {
        Self::step_all([(self, carriage)], [external_n], h)[0]
    }

    /// [`Drive::step`] for several drives and their carriages, stage by stage across them so
    /// that their independent friction chains overlap in the pipeline.
    #[inline]
    pub fn step_all<const N: usize>(
        axes: [(&mut Drive, &mut CarriageState); N],
        external_n: [f64; N],
        h: f64,
    ) -> [f64; N] {
        let mut nut = [(0.0, 0.0); N];
        for ((x, v), (_, c)) in nut.iter_mut().zip(&axes) {
            (*x, *v) = (c.position_m, c.velocity_m_s);
        }
        Self::step_all_at_nut(axes, nut, external_n, h)
    }

    /// [`Drive::step_all`] for carriages whose ball nut is not where their guideway friction
    /// acts (a carriage that tilts on its guide blocks): the screw stretches to the nut's
    /// position and velocity `nut` (m, m/s, axis coordinates), the friction slides at the
    /// carriage's velocity.
    #[inline]
    pub fn step_all_at_nut<const N: usize>(
        mut axes: [(&mut Drive, &mut CarriageState); N],
        nut: [(f64, f64); N],
        external_n: [f64; N],
        h: f64,
    ) -> [f64; N] {
        for (d, _) in axes.iter_mut().filter(|(d, _)| h != d.step.h) {
            d.step = StepConstants::new(h, &d.params, &d.servo);
        }
        // Plain loops: array::map and from_fn leave their closures out of line here.
        let (mut screw, mut guide_slip, mut screw_slip) =
            ([0.0; N], [(0.0, 0.0); N], [(0.0, 0.0); N]);
        for (i, (d, c)) in axes.iter().enumerate() {
            let (x, v) = nut[i];
            let (x_m, v_m) = (d.motor_position_m, d.motor_velocity_m_s);
            screw[i] = match &d.effects.nut {
                None => d.params.screw.force(x_m, v_m, x, v),
                Some(n) => d.params.screw.force_through(n, x_m, v_m, x, v),
            };
            guide_slip[i] = d.step.guide_friction.slip(c.velocity_m_s);
            screw_slip[i] = d.step.screw_friction.slip(d.motor_velocity_m_s);
        }
        let (mut guide_decay, mut screw_decay) = ([0.0; N], [0.0; N]);
        for i in 0..N {
            guide_decay[i] = exp(-guide_slip[i].1);
            screw_decay[i] = exp(-screw_slip[i].1);
        }
        let mut net = [0.0; N];
        for (i, (d, c)) in axes.into_iter().enumerate() {
            let (guide_step, screw_step) = (&d.step.guide_friction, &d.step.screw_friction);
            let guide = match &mut d.effects.guide_gms {
                None => guide_step.settle(
                    &mut c.friction,
                    c.velocity_m_s,
                    guide_slip[i],
                    guide_decay[i],
                ),
                Some(g) => g.advance(c.velocity_m_s, h),
            };
            c.friction_force_n = guide;
            let friction = match &mut d.effects.screw_gms {
                None => screw_step.settle(
                    &mut d.screw_friction,
                    d.motor_velocity_m_s,
                    screw_slip[i],
                    screw_decay[i],
                ),
                Some(g) => g.advance(d.motor_velocity_m_s, h),
            };
            d.finish_step(h, screw[i], friction);
            net[i] = screw[i] - guide + external_n[i];
        }
        net
    }

    /// The motor side's step with the screw force and the screw friction of the step, N.
    #[inline]
    fn finish_step(&mut self, h: f64, screw: f64, friction: f64) {
        let c = &self.step;
        self.motor_force_n += (self.controller.force_reference_n - self.motor_force_n) * c.lag;
        let driving = match &self.effects.motor {
            None => self.motor_force_n,
            Some(p) => self.motor_force_n + p.force_n(self.motor_position_m, self.motor_force_n),
        };
        self.motor_velocity_m_s += (driving - screw - friction) * c.h_over_motor_mass;
        self.motor_position_m += h * self.motor_velocity_m_s;
        self.screw_friction_force_n = friction;
        self.screw_force_n = screw;
    }
}

/// `x.floor()` without a library call: the x86-64 baseline has no rounding instruction
/// (SSE4.1), so `f64::floor` is a function call. Exact for every `f64` (the truncation is exact
/// below 2^52 in magnitude, where the rest are integers already; -0.0 and NaN pass through).
#[inline]
fn floor(x: f64) -> f64 {
    if x.is_nan() || x.abs() >= 4_503_599_627_370_496.0 {
        return x;
    }
    let t = x as i64 as f64;
    if t == x {
        x
    } else if t > x {
        t - 1.0
    } else {
        t
    }
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
        Self::step_all(std::array::from_mut(self), h, [external_n]);
    }

    /// [`ReducedAxis::step`] for several axes, stage by stage ([`Drive::step_all`]).
    #[inline]
    pub fn step_all<const N: usize>(axes: &mut [ReducedAxis; N], h: f64, external_n: [f64; N]) {
        let pairs = axes.each_mut().map(|a| (&mut a.drive, &mut a.carriage));
        let force = Drive::step_all(pairs, external_n, h);
        for (a, f) in axes.iter_mut().zip(force) {
            // The drive's step has just refreshed the constants for this h.
            a.carriage.velocity_m_s += f * a.drive.step.h_over_carriage_mass;
            a.carriage.position_m += h * a.carriage.velocity_m_s;
        }
    }
}
