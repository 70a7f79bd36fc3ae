//! Physics a feed drive may carry beyond its base model (`axis`): each off unless configured,
//! and then costing nothing in the drive's step.
//!
//! - [`MotorPulsation`] (`motor`): cogging and torque ripple of the servo motor, a force on the
//!   motor side.
//! - [`EncoderSignals`] (`encoder`): the interpolation error of the motor encoder's sin/cos
//!   signals (its reading, position and velocity feedback) or of the linear scale's (position
//!   feedback).
//! - [`PreloadedNut`] (`nut`): the nut's Hertzian halves with the preload it has left, in
//!   place of the screw's linear spring.
//! - [`GmsParams`] (`gms`): the Generalized Maxwell-Slip law in place of LuGre, per contact
//!   (guideways, screw and bearings).

use super::axis::DriveParams;
use super::encoder::EncoderSignals;
use super::gms::{Gms, GmsParams};
use super::motor::{LinearPulsation, MotorPulsation};
use super::nut::{NutSeries, PreloadedNut};

/// The optional physics of one drive; `Default` is none of it.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct DriveEffects {
    /// Cogging and torque ripple of the motor.
    pub motor: Option<MotorPulsation>,
    /// Interpolation error of the motor encoder's signals.
    pub motor_encoder_signals: Option<EncoderSignals>,
    /// Interpolation error of the linear scale's signals (closed loop only).
    pub scale_signals: Option<EncoderSignals>,
    /// A preloaded double nut in place of the nut's share of the linear screw spring.
    pub nut: Option<PreloadedNut>,
    /// The GMS law in place of LuGre on the guideways.
    pub guide_gms: Option<GmsParams>,
    /// The GMS law in place of LuGre in the screw and its bearings.
    pub screw_gms: Option<GmsParams>,
}

impl DriveEffects {
    /// Whether any effect is configured.
    pub fn any(&self) -> bool {
        *self != Self::default()
    }

    /// A description of the first effect that does not fit `params`, if any.
    pub fn check(&self, params: &DriveParams) -> Result<(), String> {
        if let Some(m) = &self.motor {
            m.check().map_err(|e| format!("motor: {e}"))?;
        }
        if let Some(s) = &self.motor_encoder_signals {
            s.check()
                .map_err(|e| format!("motor encoder signals: {e}"))?;
        }
        if let Some(s) = &self.scale_signals {
            s.check().map_err(|e| format!("scale signals: {e}"))?;
            if matches!(params.feedback, super::Feedback::MotorEncoder) {
                return Err(
                    "scale signals: the axis has no linear scale (its feedback is the motor encoder)"
                        .into(),
                );
            }
        }
        if let Some(n) = &self.nut {
            n.check(params.screw.stiffness_n_per_m)
                .map_err(|e| format!("nut: {e}"))?;
        }
        Ok(())
    }

    /// The largest stable step (s) of the drive with these effects, and its mode
    /// ([`DriveParams::largest_stable_step_s`]): with a preloaded nut the screw mode is bounded
    /// by the shaft and bearings alone, the stiffest the series can be. The GMS contacts stick
    /// with the stiffness and damping of the LuGre ones.
    pub fn largest_stable_step_s(&self, params: &DriveParams) -> (f64, &'static str) {
        let mut p = *params;
        if let Some(n) = &self.nut {
            p.screw.stiffness_n_per_m = n
                .in_series(params.screw.stiffness_n_per_m)
                .rest_stiffness_n_per_m();
        }
        p.largest_stable_step_s()
    }
}

/// The effects of a drive as it runs: their constants and states.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct ActiveEffects {
    pub(crate) motor: Option<LinearPulsation>,
    pub(crate) motor_encoder: Option<EncoderSignals>,
    pub(crate) scale: Option<EncoderSignals>,
    pub(crate) nut: Option<NutSeries>,
    pub(crate) guide_gms: Option<Gms>,
    pub(crate) screw_gms: Option<Gms>,
}

impl ActiveEffects {
    pub(crate) fn new(e: &DriveEffects, params: &DriveParams) -> Self {
        Self {
            motor: e.motor.map(|m| m.on_lead(params.screw.lead_m)),
            motor_encoder: e.motor_encoder_signals,
            scale: e.scale_signals,
            nut: e.nut.map(|n| n.in_series(params.screw.stiffness_n_per_m)),
            guide_gms: e.guide_gms.map(Gms::new),
            screw_gms: e.screw_gms.map(Gms::new),
        }
    }
}
