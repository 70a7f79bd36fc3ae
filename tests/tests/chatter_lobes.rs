//! The time-domain milling simulation against the stability lobes: over a grid of spindle
//! speeds and depths, cuts clearly below the semi-discretization boundary stay stable and cuts
//! clearly above it chatter (the simulator's ground truth decides). "Clearly" is measured by
//! the monodromy's spectral radius ρ, the growth of a vibration per tooth period: near a lobe
//! peak ρ rises slowly with depth, and a cut at ρ = 1.01 needs seconds to grow out of its entry
//! transient, so points with 0.9 < ρ < 1.05 are not judged. Nor are cuts so deep that the
//! forced vibration alone throws the tool out of the cut (static deflection K_t·a·f_t/k above
//! half the feed per tooth f_t, a > 1.1 mm here): the lobes assume the tool stays in the cut,
//! and out of it the motion may settle on an orbit locked to the tooth passing (a/D = 0.5,
//! 17 000 rpm, 1.88 mm, ρ = 1.21: ±80 µm at the tooth period, no chatter marks) as well as
//! chatter. Saturated chatter that does not decay is chatter to the truth (see
//! `vmt_sim::milling::truth`), so where the deep cuts do chatter they are told apart.
//!
//! The system is the 1-DOF benchmark of Insperger & Stépán and Ding et al. at half immersion,
//! down milling. The simulator integrates the same mode exactly per step with the regenerative
//! chip of every tooth; the lobes come from vmt-chatter, which never calls the simulator.

use vmt_chatter::stability::sd::{MillingSd, SdSettings, critical_depth};
use vmt_chatter::stability::{MillingSystem, benchmark_1dof};
use vmt_model::cutting::{CutGeometry, MillingDirection, Mode, ToolDynamics};
use vmt_sim::milling::{AccelerometerParams, Feed, MillingDrive, MillingSetup, simulate_milling};

/// The simulator's cut for `system` at `depth` (m); Y is made rigid as in the 1-DOF model.
fn setup(system: &MillingSystem, depth: f64) -> MillingSetup {
    let rigid = Mode {
        natural_frequency_hz: 4_000.0,
        damping_ratio: 0.05,
        stiffness: 1e10,
    };
    MillingSetup {
        tool: system.tool,
        coefficients: system.coefficients,
        dynamics: ToolDynamics {
            x: system.dynamics.x.clone(),
            y: vec![rigid],
        },
        axial_mode: None,
        cut: CutGeometry {
            axial_depth: depth,
            radial_depth: system.radial_depth,
            direction: system.direction,
        },
        feed_per_tooth: 1e-4,
        accelerometer: AccelerometerParams::default(),
        step_s: 1e-5,
        seed: 11,
    }
}

fn chatters(system: &MillingSystem, rpm: f64, depth: f64) -> bool {
    let drive = MillingDrive {
        spindle_rpm: rpm,
        feed: Feed::PerTooth(1e-4),
        duration_s: 0.6,
        supervisor_window_s: 0.01,
    };
    let run = simulate_milling(&setup(system, depth), &drive).expect("the cut runs");
    run.ground_truth["chatter"]
        .as_bool()
        .expect("the truth says whether the cut chattered")
}

#[test]
fn cuts_below_the_sd_boundary_are_stable_and_cuts_above_it_chatter() {
    let settings = SdSettings::default();
    let (mut disagreements, mut judged) = (Vec::new(), [0, 0]);
    for immersion in [1.0, 0.5] {
        let system = benchmark_1dof(immersion, MillingDirection::Down);
        let deepest_judged = 0.5 * system.dynamics.x[0].stiffness / system.coefficients.tangential;
        for rpm in [
            6_000.0, 8_000.0, 11_000.0, 14_500.0, 17_000.0, 21_000.0, 24_000.0,
        ] {
            let critical = critical_depth(&system, rpm, 0.02, &settings)
                .expect("the SD runs")
                .expect("the benchmark chatters below 20 mm at every speed");
            let sd = MillingSd::new(&system, rpm, &settings).expect("the SD runs");
            for factor in [0.3, 0.5, 0.75, 1.3, 1.6, 2.0] {
                let depth = critical * factor;
                if depth > deepest_judged {
                    continue;
                }
                let rho = sd.spectral_radius(depth).expect("the SD runs");
                let expected = match rho {
                    r if r >= 1.05 => true,
                    r if r <= 0.9 => false,
                    _ => continue,
                };
                judged[usize::from(expected)] += 1;
                if chatters(&system, rpm, depth) != expected {
                    disagreements.push(format!(
                        "a/D {immersion}, {rpm} rpm, {:.3} mm ({factor} x SD {:.3} mm, rho \
                         {rho:.3}): simulator chatter = {}",
                        depth * 1e3,
                        critical * 1e3,
                        !expected
                    ));
                }
            }
        }
    }
    println!("judged (stable, chatter): {judged:?}");
    assert!(disagreements.is_empty(), "{disagreements:#?}");
    assert!(
        judged[0] >= 10 && judged[1] >= 10,
        "judged (stable, chatter): {judged:?}"
    );
}
