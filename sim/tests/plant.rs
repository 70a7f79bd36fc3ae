//! The two plant fidelities against each other and against the topology's mechanics.

use vmt_model::drive::{
    AxisCommand, Drive, DriveParams, Feedback, LuGreParams, ScrewParams, ServoParams,
};
use vmt_sim::plant::{AxisLayout, MultibodyPlant, Plant, ReducedPlant, layout};

const SERVO: f64 = 125e-6;
const SUBSTEPS: usize = 2;

fn drive(mass: f64, backlash: f64, q0: f64) -> Drive {
    let friction = LuGreParams {
        sigma0_n_per_m: 2e7,
        sigma1_n_s_per_m: 3e4,
        sigma2_n_s_per_m: 200.0,
        coulomb_n: 50.0,
        static_n: 65.0,
        stribeck_m_s: 1e-3,
        stribeck_exponent: 2.0,
    };
    let params = DriveParams {
        motor_inertia_kg_m2: 0.003,
        screw: ScrewParams {
            lead_m: 0.01,
            stiffness_n_per_m: 1.8e8,
            damping_n_s_per_m: 2e4,
            backlash_m: backlash,
            cyclic_m: [0.0; 2],
        },
        carriage_mass_kg: mass,
        guide_friction: friction,
        screw_friction: LuGreParams {
            coulomb_n: 30.0,
            static_n: 40.0,
            ..friction
        },
        encoder_counts_per_rev: (1u32 << 20) as f64,
        torque_constant_n_m_per_a: 1.2,
        feedback: Feedback::MotorEncoder,
    };
    let total = params.total_mass_kg();
    let servo = ServoParams {
        kv_per_s: 33.0,
        velocity_kp_n_s_per_m: total * 377.0,
        velocity_ti_s: 0.01,
        velocity_ff: 0.0,
        acceleration_ff: 0.0,
        current_time_constant_s: 0.5e-3,
        force_limit_n: 8000.0,
    };
    Drive::new(params, servo, q0)
}

fn machine(backlash: f64) -> ([Drive; 3], [AxisLayout; 3]) {
    let moving = [250.0, 450.0, 180.0];
    let l = layout(&"WXYGZT".parse().unwrap(), moving).unwrap();
    let q0 = [0.25, 0.2, 0.2];
    (
        std::array::from_fn(|i| drive(moving[i], backlash, q0[i])),
        l,
    )
}

/// A circle of radius r in XY about (0.25, 0.2) at speed v, starting at angle 0 from rest
/// with a 0.1 s speed ramp.
fn circle(t: f64, r: f64, v: f64) -> [AxisCommand; 3] {
    let ramp = 0.1;
    let (s, ds, dds) = if t < ramp {
        (0.5 * v / ramp * t * t, v * t / ramp, v / ramp)
    } else {
        (0.5 * v * ramp + v * (t - ramp), v, 0.0)
    };
    let a = s / r;
    let (sa, ca) = a.sin_cos();
    let w = ds / r;
    [
        AxisCommand {
            position: 0.25 + r * (ca - 1.0),
            velocity: -r * sa * w,
            acceleration: -r * (sa * dds / r + ca * w * w),
        },
        AxisCommand {
            position: 0.2 + r * sa,
            velocity: r * ca * w,
            acceleration: r * (ca * dds / r - sa * w * w),
        },
        AxisCommand {
            position: 0.2,
            velocity: 0.0,
            acceleration: 0.0,
        },
    ]
}

fn run(plant: &mut dyn Plant, seconds: f64) -> Vec<[f64; 3]> {
    let n = (seconds / SERVO) as usize;
    let h = SERVO / SUBSTEPS as f64;
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        plant.control(&circle(k as f64 * SERVO, 0.15, 1000.0 / 60_000.0), SERVO);
        for _ in 0..SUBSTEPS {
            plant.step(h);
        }
        out.push(plant.carriages().map(|c| c.position_m));
    }
    out
}

/// On a rigid structure the multibody and the reduced plant give the same carriage motion
/// within 0.05 µm (the ball-bar trace is a function of these positions).
#[test]
fn multibody_and_reduced_plants_agree_within_0_05_um() {
    let (drives, l) = machine(2e-6);
    let h = SERVO / SUBSTEPS as f64;
    let mut reduced = ReducedPlant::new(drives, &l);
    let mut multibody = MultibodyPlant::new(drives, &l, h).unwrap();
    let a = run(&mut reduced, 2.0);
    let b = run(&mut multibody, 2.0);
    let worst = a
        .iter()
        .zip(&b)
        .flat_map(|(p, q)| (0..3).map(move |i| (p[i] - q[i]).abs()))
        .fold(0.0, f64::max);
    assert!(worst < 0.05e-6, "largest difference {worst:e} m");
    // And the machine really moved along the circle.
    let last = a[a.len() - 1];
    assert!((last[1] - 0.2).abs() > 0.01);
}

/// Gravity holds the vertical head on one flank of its gap: moving up or down, its carriage
/// hangs b/2 below the motor plus the sag (m·g ± friction)/k; X, without gravity, changes flank.
#[test]
fn gravity_makes_the_z_backlash_one_sided() {
    let b = 4e-6;
    let (drives, l) = machine(b);
    let mut plant = ReducedPlant::new(drives, &l);
    // Move to (x, z), hold, and return the carriage-minus-motor offsets of X and Z.
    let mut go = |x: f64, z: f64| {
        for _ in 0..(0.6 / SERVO) as usize {
            let c = [
                AxisCommand {
                    position: x,
                    ..Default::default()
                },
                AxisCommand {
                    position: 0.2,
                    ..Default::default()
                },
                AxisCommand {
                    position: z,
                    ..Default::default()
                },
            ];
            plant.control(&c, SERVO);
            for _ in 0..SUBSTEPS {
                plant.step(SERVO / SUBSTEPS as f64);
            }
        }
        [0, 2].map(|i| plant.carriages()[i].position_m - plant.drive(i).motor_position_m)
    };
    let up = go(0.2502, 0.2002);
    let down = go(0.25, 0.2);
    let k = 1.8e8;
    let (weight, stiction) = (180.0 * vmt_sim::plant::GRAVITY_M_S2, 65.0);
    for z in [up[1], down[1]] {
        let lo = -b / 2.0 - (weight + stiction) / k;
        let hi = -b / 2.0 - (weight - stiction) / k;
        assert!(
            (lo - 1e-8..=hi + 1e-8).contains(&z),
            "Z offset {z:e} outside [{lo:e}, {hi:e}]"
        );
    }
    assert!((up[1] - down[1]).abs() < b / 4.0, "Z stays on its flank");
    assert!(
        (up[0] - down[0]).abs() > b,
        "X changes flank: {:e} -> {:e}",
        up[0],
        down[0]
    );
}
