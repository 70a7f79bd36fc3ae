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
        following_error_limit_m: None,
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
    run_with(plant, seconds, |_, _| {})
}

/// [`run`], calling `each(plant, k)` after servo period `k`.
fn run_with<P: Plant + ?Sized>(
    plant: &mut P,
    seconds: f64,
    mut each: impl FnMut(&P, usize),
) -> Vec<[f64; 3]> {
    let n = (seconds / SERVO) as usize;
    let h = SERVO / SUBSTEPS as f64;
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        plant.control(&circle(k as f64 * SERVO, 0.15, 1000.0 / 60_000.0), SERVO);
        for _ in 0..SUBSTEPS {
            plant.step(h);
        }
        out.push(plant.carriages().map(|c| c.position_m));
        each(plant, k);
    }
    out
}

/// The larger of `worst` and `e`, NaN if either is (`f64::max` would drop a NaN).
fn worse(worst: f64, e: f64) -> f64 {
    if e.is_nan() || e > worst { e } else { worst }
}

/// The largest difference of any axis between two runs, m.
fn largest_difference(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(p, q)| (0..3).map(move |i| (p[i] - q[i]).abs()))
        .fold(0.0, worse)
}

/// Standard gravity, m/s², written out here rather than taken from the code under test.
const G: f64 = 9.80665;

/// Fine plant steps per rapier macro step: the plant step is 125 µs / 2 = 62.5 µs and rapier
/// steps every 1 ms (`MULTIBODY_STEP_S`), so every 16 fine steps, every 8 servo periods.
const FINE_PER_MACRO: usize = 16;

/// The joint-space inverse mass (1/kg) and bias accelerations (m/s²) of the WXYGZT chain with
/// X's link (its carriage and the table) of `x_kg`, Y's carriage alone of `y_kg` and the head
/// of `z_kg`, worked by hand: the three joints are orthogonal prismatic joints, so the mass
/// matrix is diagonal; Y carries X, so Y's joint moves both links (`y_kg + x_kg`), X's joint
/// only its own; gravity (-Z) acts on the head's joint alone, `-z_kg g` over the head's mass.
fn wxygzt_dynamics(x_kg: f64, y_kg: f64, z_kg: f64) -> ([[f64; 3]; 3], [f64; 3]) {
    let inv = [
        [1.0 / x_kg, 0.0, 0.0],
        [0.0, 1.0 / (y_kg + x_kg), 0.0],
        [0.0, 0.0, 1.0 / z_kg],
    ];
    (inv, [0.0, 0.0, -z_kg * G / z_kg])
}

/// Where rapier's links of the WXYGZT chain belong for carriage coordinates `q` (machine
/// frame, m): X and Y move the workpiece (along `-q`), and X rides on Y, so X's link is at
/// `(-qx, -qy, 0)`, Y's at `(0, -qy, 0)`; the head is on the tool side at `(0, 0, qz)`.
fn wxygzt_links(q: [f64; 3]) -> [[f64; 3]; 3] {
    [[-q[0], -q[1], 0.0], [0.0, -q[1], 0.0], [0.0, 0.0, q[2]]]
}

/// How far the multibody's rapier state is from the hand-worked chain over a run: the worst
/// link position error at the macro steps (m), the worst relative inverse mass error, the
/// worst bias error (m/s²).
#[derive(Default, Debug)]
struct RapierCheck {
    link_m: f64,
    inv_mass_rel: f64,
    bias_m_s2: f64,
}

/// Runs `plant` for `seconds`, checking at every servo period that rapier has taken one macro
/// step per 16 fine steps and, right after each macro step, where its links are and which
/// dynamics it gave, against `expected` (inverse mass, bias).
fn run_checking_rapier(
    plant: &mut MultibodyPlant,
    seconds: f64,
    expected: ([[f64; 3]; 3], [f64; 3]),
) -> (Vec<[f64; 3]>, RapierCheck) {
    let mut check = RapierCheck::default();
    let samples = run_with(plant, seconds, |p, k| {
        let fine = (k + 1) * SUBSTEPS;
        assert_eq!(
            p.macro_steps(),
            (fine / FINE_PER_MACRO) as u64,
            "rapier's macro steps after {fine} fine steps"
        );
        if !fine.is_multiple_of(FINE_PER_MACRO) {
            return;
        }
        let want = wxygzt_links(p.carriages().map(|c| c.position_m));
        for (got, want) in p.link_translations_m().iter().zip(&want) {
            for (g, w) in got.iter().zip(want) {
                check.link_m = worse(check.link_m, (g - w).abs());
            }
        }
        let (inv, bias) = p.rapier_dynamics().expect("rapier has stepped");
        for (i, (row, want)) in inv.iter().zip(&expected.0).enumerate() {
            for (got, w) in row.iter().zip(want) {
                let e = (got - w).abs() / want[i];
                check.inv_mass_rel = worse(check.inv_mass_rel, e);
            }
            check.bias_m_s2 = worse(check.bias_m_s2, (bias[i] - expected.1[i]).abs());
        }
    });
    (samples, check)
}

/// On a rigid structure the multibody and the reduced plant give the same carriage motion to
/// rounding (module docs of `plant::multibody`: with a constant mass matrix and bias the
/// carriages follow the reduced plant's equations; measured 5.8e-15 m over this 2 s circle,
/// bound 1e-12 m, far inside the 0.05 µm), and rapier really carries the links: it
/// steps every 1 ms, its links sit where the carriages are after every step (measured
/// 1.4e-16 m), and the inverse mass and gravity bias it reports are those of the hand-worked
/// WXYGZT chain (measured 8.7e-16 relative, 5.3e-15 m/s²). Without rapier the agreement alone
/// would pass: the fine steps start from the layout's masses and gravity, which are the same.
/// (Rounding that moved a motor encoder count would show as a few nm, as in the ball-bar
/// test's longer runs: that would be the bound's limit, not a physical difference.)
#[test]
fn multibody_and_reduced_plants_agree_and_rapier_carries_the_links() {
    let (drives, l) = machine(2e-6);
    let h = SERVO / SUBSTEPS as f64;
    let mut reduced = ReducedPlant::new(drives, &l);
    let mut multibody = MultibodyPlant::new(drives, &l, h).unwrap();
    let a = run(&mut reduced, 2.0);
    let expected = wxygzt_dynamics(250.0, 200.0, 180.0);
    let (b, rapier) = run_checking_rapier(&mut multibody, 2.0, expected);
    eprintln!("{rapier:?}");
    // 2 s of 62.5 µs steps, 16 to a macro step.
    assert_eq!(multibody.macro_steps(), 2000);
    assert!(rapier.link_m < 1e-12, "links {:e} m off", rapier.link_m);
    assert!(
        rapier.inv_mass_rel < 1e-12,
        "inverse mass {:e} off",
        rapier.inv_mass_rel
    );
    assert!(
        rapier.bias_m_s2 < 1e-9,
        "bias {:e} m/s² off",
        rapier.bias_m_s2
    );
    let worst = largest_difference(&a, &b);
    eprintln!("largest difference {worst:e} m");
    assert!(worst < 1e-12, "largest difference {worst:e} m");
    // And the machine really moved along the circle.
    let last = a[a.len() - 1];
    assert!((last[1] - 0.2).abs() > 0.01);
}

/// The multibody moves rapier's links, not the layout's masses: with Y's carriage made 200 kg
/// heavier in rapier than the moving mass its drive and the reduced plant are built for,
/// rapier reports Y's joint at 650 kg and the plants part (measured 0.38 µm in 0.5 s); with
/// gravity left out of the layout (which is all the reduced plant knows of it), rapier still
/// pulls the head down, and the head hangs on the lower flank of its gap, b/2 plus the screw's
/// sag (m g ± stiction)/k below where the reduced plant holds it (measured 11.15 µm).
#[test]
fn multibody_follows_rapiers_masses_and_gravity_not_the_layouts() {
    let (drives, l) = machine(2e-6);
    let h = SERVO / SUBSTEPS as f64;
    let seconds = 0.5;
    let a = run(&mut ReducedPlant::new(drives, &l), seconds);

    let mut heavy = l;
    heavy[1].link_mass_kg += 200.0;
    let mut plant = MultibodyPlant::new(drives, &heavy, h).unwrap();
    let (b, rapier) =
        run_checking_rapier(&mut plant, seconds, wxygzt_dynamics(250.0, 400.0, 180.0));
    eprintln!("heavy Y: {rapier:?}");
    assert!(rapier.inv_mass_rel < 1e-12, "{rapier:?}");
    let gap = largest_difference(&a, &b);
    eprintln!("heavy Y: largest difference {gap:e} m");
    assert!(gap > 0.1e-6, "largest difference {gap:e} m");

    let mut weightless = l;
    weightless[2].gravity_n = 0.0;
    let a = run(&mut ReducedPlant::new(drives, &weightless), seconds);
    let mut plant = MultibodyPlant::new(drives, &weightless, h).unwrap();
    let (b, rapier) =
        run_checking_rapier(&mut plant, seconds, wxygzt_dynamics(250.0, 200.0, 180.0));
    eprintln!("no gravity in the layout: {rapier:?}");
    assert!(rapier.bias_m_s2 < 1e-9, "{rapier:?}");
    let sag = a[a.len() - 1][2] - b[b.len() - 1][2];
    eprintln!("head {sag:e} m lower in the multibody");
    // 2 µm backlash, 180 N/µm screw, 65 N guideway stiction (`drive`), 180 kg head.
    let (backlash, k, stiction) = (2e-6, 1.8e8, 65.0);
    let lo = backlash / 2.0 + (180.0 * G - stiction) / k;
    let hi = backlash / 2.0 + (180.0 * G + stiction) / k;
    assert!(
        (lo - 1e-8..=hi + 1e-8).contains(&sag),
        "head {sag:e} m lower in the multibody, outside [{lo:e}, {hi:e}]"
    );
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
