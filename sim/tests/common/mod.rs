//! A VMC-class machine's drives for the simulation tests.

use vmt_model::drive::{DriveParams, Feedback, LuGreParams, ScrewParams, ServoParams};
use vmt_sim::simulate::AxisDynamics;

/// Guideway friction of a roller guide: 50 N Coulomb, 65 N static, 1 mm/s Stribeck velocity.
pub fn guide_friction() -> LuGreParams {
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

/// One axis: 10 mm lead, 180 N/µm, the given backlash and Kv, semi-closed loop, no feed-forward.
pub fn axis(moving_mass_kg: f64, backlash_m: f64, kv_per_s: f64) -> AxisDynamics {
    let drive = DriveParams {
        motor_inertia_kg_m2: 0.003,
        screw: ScrewParams {
            lead_m: 0.01,
            stiffness_n_per_m: 1.8e8,
            damping_n_s_per_m: 2e4,
            backlash_m,
            cyclic_m: [0.0; 2],
        },
        carriage_mass_kg: moving_mass_kg,
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
        kv_per_s,
        velocity_kp_n_s_per_m: drive.total_mass_kg() * 377.0,
        velocity_ti_s: 0.01,
        velocity_ff: 0.0,
        acceleration_ff: 0.0,
        current_time_constant_s: 0.5e-3,
        force_limit_n: 8000.0,
        following_error_limit_m: None,
    };
    AxisDynamics {
        drive,
        servo,
        effects: Default::default(),
    }
}
