//! Time-domain milling: forces against Altintas' closed form, the feed-mark roughness of a rigid
//! tool, the single-degree-of-freedom chatter benchmark, determinism and bad inputs.

use vmt_model::cutting::{
    CutGeometry, CuttingCoefficients, CuttingError, EndMill, MillingDirection, Mode, ToolDynamics,
};
use vmt_sim::milling::{
    AccelerometerParams, Feed, MAX_DISKS, MillingDrive, MillingError, MillingSetup,
    simulate_milling,
};

/// Insperger–Stépán / Ding et al. benchmark: one mode along X (m = 0.03993 kg, 922 Hz,
/// ζ = 0.011), Y rigid, K_t = 6e8, K_n = 2e8 N/m², 2 straight teeth, slotting down milling.
fn benchmark(depth: f64) -> MillingSetup {
    MillingSetup {
        tool: EndMill {
            diameter: 0.01,
            teeth: 2,
            helix: 0.0,
            flute_length: 0.02,
            runout: 0.0,
            runout_angle: 0.0,
        },
        coefficients: CuttingCoefficients {
            tangential: 6e8,
            radial: 2e8,
            axial: 0.0,
            tangential_edge: 0.0,
            radial_edge: 0.0,
            axial_edge: 0.0,
        },
        dynamics: ToolDynamics {
            x: vec![Mode::from_mass(0.03993, 922.0, 0.011)],
            y: vec![rigid()],
        },
        axial_mode: None,
        cut: CutGeometry {
            axial_depth: depth,
            radial_depth: 0.01,
            direction: MillingDirection::Down,
        },
        feed_per_tooth: 1e-4,
        accelerometer: AccelerometerParams::default(),
        step_s: 1e-5,
        seed: 7,
    }
}

/// A mode stiff enough to be rigid at these forces (0.1 nm/N).
fn rigid() -> Mode {
    Mode {
        natural_frequency_hz: 4_000.0,
        damping_ratio: 0.05,
        stiffness: 1e10,
    }
}

fn drive(rpm: f64, duration_s: f64) -> MillingDrive {
    MillingDrive {
        spindle_rpm: rpm,
        feed: Feed::PerTooth(1e-4),
        duration_s,
        supervisor_window_s: 0.01,
    }
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|a| a * a).sum::<f64>() / v.len() as f64).sqrt()
}

fn channel<'a>(run: &'a vmt_sim::milling::MillingRun, stream: &str, name: &str) -> &'a [f64] {
    let s = run.streams.iter().find(|s| s.name == stream).unwrap();
    &s.channel(name).unwrap().values
}

/// A tool this stiff deflects by picometres: the forces are the rigid-tool forces.
fn rigid_setup(tool: EndMill, cut: CutGeometry) -> MillingSetup {
    MillingSetup {
        tool,
        coefficients: CuttingCoefficients {
            tangential: 8e8,
            radial: 3e8,
            axial: 1.5e8,
            tangential_edge: 2.5e4,
            radial_edge: 2e4,
            axial_edge: 1e4,
        },
        dynamics: ToolDynamics::symmetric(vec![rigid()]),
        cut,
        ..benchmark(1e-3)
    }
}

#[test]
fn average_forces_of_a_rigid_tool_match_altintas_closed_form() {
    let straight = EndMill {
        diameter: 0.016,
        teeth: 2,
        helix: 0.0,
        flute_length: 0.03,
        runout: 0.0,
        runout_angle: 0.0,
    };
    let slot = CutGeometry {
        axial_depth: 2e-3,
        radial_depth: 0.016,
        direction: MillingDirection::Down,
    };
    // Straight slotting, and a 30° helix at half immersion up milling (the helix spreads the
    // force over the disks but leaves the average unchanged). 12 000 rpm: a revolution is 500
    // steps of 10 µs; the last 20 of 40 revolutions are averaged.
    let helical = EndMill {
        teeth: 4,
        helix: 30f64.to_radians(),
        ..straight
    };
    let half_up = CutGeometry {
        radial_depth: 0.008,
        direction: MillingDirection::Up,
        ..slot
    };
    // A quarter immersion down milling: the entry at 120° falls between two memory bins.
    let three = EndMill {
        teeth: 3,
        ..straight
    };
    let quarter_down = CutGeometry {
        radial_depth: 0.004,
        ..slot
    };
    for (tool, cut) in [(straight, slot), (helical, half_up), (three, quarter_down)] {
        let setup = rigid_setup(tool, cut);
        let mut process = vmt_sim::milling::CuttingProcess::new(&setup).unwrap();
        let (rpm, ft) = (12_000.0, 1e-4);
        let feed_rate = ft * tool.teeth as f64 * rpm / 60.0;
        let mut sum = [0.0; 3];
        for n in 0..500 * 40 {
            let x = feed_rate * n as f64 * setup.step_s;
            let sample = process.step([x, 0.0], rpm);
            if n >= 500 * 20 {
                (0..3).for_each(|i| sum[i] += sample.force[i] / (500.0 * 20.0));
            }
        }
        let expected =
            vmt_model::cutting::forces::average_forces(&setup.coefficients, &tool, &cut, ft);
        let scale = expected.iter().map(|f| f.abs()).fold(0.0, f64::max);
        for i in 0..3 {
            assert!(
                (sum[i] - expected[i]).abs() < 0.01 * scale,
                "{} teeth: simulated {sum:?} N, closed form {expected:?} N",
                tool.teeth
            );
        }
    }
}

#[test]
fn with_run_out_beyond_half_the_feed_one_tooth_cuts_the_whole_revolution() {
    // Two straight teeth, radii R ± ρ with ρ = 60 µm > f_t/2 = 50 µm: the long tooth removes
    // the feed of a whole revolution (chip 2·f_t·sin φ), the short one never reaches the
    // surface. A fixed-delay chip model would give the short tooth a negative chip of
    // f_t - 2ρ only one pitch back and the long one f_t + 2ρ.
    let tool = EndMill {
        diameter: 0.01,
        teeth: 2,
        helix: 0.0,
        flute_length: 0.02,
        runout: 60e-6,
        runout_angle: 0.0,
    };
    let slot = CutGeometry {
        axial_depth: 1e-3,
        radial_depth: 0.01,
        direction: MillingDirection::Down,
    };
    let peak_and_idle = |tool: EndMill| {
        let setup = MillingSetup {
            coefficients: CuttingCoefficients {
                tangential: 6e8,
                radial: 2e8,
                axial: 0.0,
                tangential_edge: 0.0,
                radial_edge: 0.0,
                axial_edge: 0.0,
            },
            ..rigid_setup(tool, slot)
        };
        let mut process = vmt_sim::milling::CuttingProcess::new(&setup).unwrap();
        let (rpm, ft, rev) = (12_000.0, 1e-4, 500);
        let feed_rate = ft * 2.0 * rpm / 60.0;
        let (mut peak, mut idle) = (0.0_f64, 0);
        for n in 0..rev * 10 {
            let f = process.step([feed_rate * n as f64 * 1e-5, 0.0], rpm).force;
            if n >= rev * 5 {
                peak = peak.max(f[0].hypot(f[1]));
                idle += usize::from(f[0] == 0.0 && f[1] == 0.0);
            }
        }
        (peak, idle as f64 / (rev * 5) as f64)
    };
    let (peak, idle) = peak_and_idle(tool);
    let (peak0, idle0) = peak_and_idle(EndMill {
        runout: 0.0,
        ..tool
    });
    assert!(idle0 < 0.01, "without run-out idle {idle0}");
    assert!((idle - 0.5).abs() < 0.01, "with run-out idle {idle}");
    assert!(
        (peak / peak0 - 2.0).abs() < 0.02,
        "peak {peak} N vs {peak0} N"
    );
}

#[test]
fn a_rigid_tool_does_not_chatter_and_leaves_the_feed_mark_roughness() {
    let tool = EndMill {
        diameter: 0.01,
        teeth: 2,
        helix: 0.0,
        flute_length: 0.02,
        runout: 0.0,
        runout_angle: 0.0,
    };
    let cut = CutGeometry {
        axial_depth: 3e-3,
        radial_depth: 2e-3,
        direction: MillingDirection::Down,
    };
    let run = simulate_milling(&rigid_setup(tool, cut), &drive(12_000.0, 0.2)).unwrap();
    let truth = &run.ground_truth;
    assert_eq!(truth["chatter"], false, "{truth}");
    // Scallops of radius R at pitch f_t: Ra = f_t²/(18√3·R), Rz = f_t²/(8R).
    let (ft, r) = (1e-4, 0.005);
    let ra = ft * ft / (18.0 * 3f64.sqrt() * r);
    let rz = ft * ft / (8.0 * r);
    let s = &run.surface;
    assert!((s.ra_m / ra - 1.0).abs() < 0.02, "Ra {} vs {ra} m", s.ra_m);
    assert!((s.rz_m / rz - 1.0).abs() < 0.02, "Rz {} vs {rz} m", s.rz_m);
    assert!(s.sle_max_abs_m < 0.05 * rz, "SLE {} m", s.sle_max_abs_m);
}

#[test]
fn the_single_mode_benchmark_is_stable_at_0_15_mm_and_chatters_at_0_6_mm() {
    // ZOA at 15 000 rpm: critical depth 0.373 mm, chatter at 927 Hz (minimum of the lobes
    // 0.30 mm; semi-discretization about 0.32 mm).
    let stable = simulate_milling(&benchmark(0.15e-3), &drive(15_000.0, 0.3)).unwrap();
    let chatter = simulate_milling(&benchmark(0.6e-3), &drive(15_000.0, 0.3)).unwrap();
    let (s, c) = (&stable.ground_truth, &chatter.ground_truth);
    assert_eq!(s["chatter"], false, "{s}");
    assert!(s["chatter_frequency_hz"].is_null());
    assert_eq!(c["chatter"], true, "{c}");
    let onset = c["chatter_onset_s"].as_f64().unwrap();
    assert!(onset < 0.1, "onset {onset} s");
    let f = c["chatter_frequency_hz"].as_f64().unwrap();
    assert!((f - 927.0).abs() < 15.0, "chatter at {f} Hz");
    // Chatter throws the tool out of the cut: the vibration is of the order of the feed, the
    // stable cut's a few µm of forced response.
    let amp = |run: &vmt_sim::milling::MillingRun| {
        let ux = channel(run, "cutting", "ux");
        let tail = &ux[ux.len() / 2..];
        tail.iter().fold(0.0_f64, |m, v| m.max(*v)) - tail.iter().fold(0.0_f64, |m, v| m.min(*v))
    };
    let (a_s, a_c) = (amp(&stable), amp(&chatter));
    assert!(a_s < 20e-6 && a_c > 100e-6, "peak-to-peak {a_s} m, {a_c} m");
    // The accelerometers see it, and the wall is rougher.
    let (rs, rc) = (
        rms(channel(&stable, "accelerometer", "ax")),
        rms(channel(&chatter, "accelerometer", "ax")),
    );
    assert!(rc > 5.0 * rs, "RMS ax {rs}, {rc} m/s²");
    let (ra_s, ra_c) = (stable.surface.ra_m, chatter.surface.ra_m);
    assert!(ra_c > 3.0 * ra_s, "Ra {ra_s} m, {ra_c} m");
}

#[test]
fn the_benchmark_boundary_agrees_with_semi_discretization_within_ten_per_cent() {
    // Critical depths of this benchmark by first-order semi-discretization (60 steps per tooth
    // period, Insperger–Stépán 2002), mm: 10 000 rpm 0.328, 15 000 rpm 0.389, 18 000 rpm 0.695
    // (on a steep flank: 0.511 at 17 500 rpm, 1.03 at 18 500 rpm). 10 % below each the 1 s cut
    // is stable, 10 % above it chatters.
    for (rpm, critical_mm) in [(10_000.0, 0.328), (15_000.0, 0.389), (18_000.0, 0.695)] {
        for (factor, chatters) in [(0.9, false), (1.1, true)] {
            let depth = critical_mm * factor * 1e-3;
            let run = simulate_milling(&benchmark(depth), &drive(rpm, 1.0)).unwrap();
            let truth = &run.ground_truth;
            assert_eq!(truth["chatter"], chatters, "{rpm} rpm, {depth} m: {truth}");
        }
    }
}

#[test]
fn the_same_seed_gives_the_same_run_and_another_seed_other_noise() {
    let setup = benchmark(0.3e-3);
    let d = drive(15_000.0, 0.05);
    let a = simulate_milling(&setup, &d).unwrap();
    let b = simulate_milling(&setup, &d).unwrap();
    assert_eq!(a, b);
    let c = simulate_milling(&MillingSetup { seed: 8, ..setup }, &d).unwrap();
    assert_eq!(channel(&a, "cutting", "fx"), channel(&c, "cutting", "fx"));
    assert_ne!(
        channel(&a, "accelerometer", "ax"),
        channel(&c, "accelerometer", "ax")
    );
}

#[test]
fn a_supervisor_moving_the_spindle_to_a_stable_speed_ends_the_chatter() {
    // 0.6 mm chatters at 15 000 rpm; at 22 000 rpm the ZOA limit is 3 mm.
    let mut calls = 0;
    let mut supervisor = |w: &vmt_sim::milling::AccelWindow<'_>| {
        calls += 1;
        assert_eq!(w.ax.len(), 200);
        let moved = rms(w.ax) > 100.0 || w.spindle_rpm > 20_000.0;
        vmt_sim::milling::SupervisorCommand {
            feed_override: 1.0,
            spindle_rpm: if moved { 22_000.0 } else { 15_000.0 },
        }
    };
    let run = vmt_sim::milling::simulate_milling_with(
        &benchmark(0.6e-3),
        &drive(15_000.0, 0.4),
        &mut supervisor,
    )
    .unwrap();
    assert_eq!(calls, 40);
    let t = &run.ground_truth;
    let switch = t["supervisor_commands"][0]["time_s"].as_f64().unwrap();
    let intervals = t["chatter_intervals_s"].as_array().unwrap();
    let end = intervals[0][1].as_f64();
    assert!(end.is_some_and(|e| e > switch && e < switch + 0.15), "{t}");
    let f = t["chatter_frequency_hz"].as_f64().unwrap();
    assert!((900.0..1000.0).contains(&f), "chatter at {f} Hz");
}

#[test]
fn bad_inputs_are_refused_one_clear_error_each() {
    let good = benchmark(0.3e-3);
    let zero_teeth = MillingSetup {
        tool: EndMill {
            teeth: 0,
            ..good.tool
        },
        ..good.clone()
    };
    assert_eq!(
        vmt_sim::milling::CuttingProcess::new(&zero_teeth).err(),
        Some(MillingError::Cutting(CuttingError::ZeroTeeth))
    );
    let negative_damping = MillingSetup {
        dynamics: ToolDynamics {
            x: vec![Mode::from_mass(0.03993, 922.0, -0.011)],
            y: vec![rigid()],
        },
        ..good.clone()
    };
    assert_eq!(
        negative_damping.validate(),
        Err(MillingError::Cutting(CuttingError::DampingOutOfRange {
            mode: 0,
            value: -0.011
        }))
    );
    let deep = MillingSetup {
        cut: CutGeometry {
            axial_depth: 0.025,
            ..good.cut
        },
        ..good.clone()
    };
    let err = deep.validate().unwrap_err().to_string();
    assert!(
        err.contains("25 mm is beyond the flute length 20 mm"),
        "{err}"
    );
    // 4 kHz needs h ≤ 12.5 µs: 20 µs is refused, and the largest step that also divides the
    // 50 µs output period is 50/4 = 12.5 µs.
    let coarse = MillingSetup {
        step_s: 2e-5,
        ..good.clone()
    };
    let err = coarse.validate().unwrap_err();
    assert_eq!(
        err,
        MillingError::StepTooCoarse {
            step_s: 2e-5,
            highest_mode_hz: 4_000.0,
            largest_step_s: 1.25e-5
        }
    );
    assert!(
        err.to_string()
            .contains("largest accepted step is 0.0000125 s"),
        "{err}"
    );
    let odd = MillingSetup {
        step_s: 1.1e-5,
        ..good.clone()
    };
    assert!(matches!(
        odd.validate(),
        Err(MillingError::StepNotFraction { .. })
    ));
    // The axial disks follow from the helix lag a_p·tan β / R, which grows without bound as
    // the helix nears 90°: at 0.3 mm deep with a 5 mm radius, 89.9° needs 985 disks and is
    // accepted, 89.999° needs about 98 500 and is refused before any memory is laid out.
    let helix = |deg: f64| MillingSetup {
        tool: EndMill {
            helix: deg.to_radians(),
            ..good.tool
        },
        ..good.clone()
    };
    let dense = helix(89.9);
    dense.validate().unwrap();
    assert_eq!(dense.disks(), 985);
    let steep = helix(89.999);
    let err = vmt_sim::milling::CuttingProcess::new(&steep).err();
    assert!(
        matches!(
            err,
            Some(MillingError::TooManyDisks { disks, max: MAX_DISKS, .. }) if disks > 9e4
        ),
        "{err:?}"
    );
    let err = steep.validate().unwrap_err().to_string();
    assert!(
        err.contains("at most 1000 disks are accepted (a helix lag of 2000°)"),
        "{err}"
    );
    let bad_drive = MillingDrive {
        spindle_rpm: -100.0,
        ..drive(15_000.0, 0.1)
    };
    let err = simulate_milling(&good, &bad_drive).unwrap_err().to_string();
    assert!(err.contains("spindle speed (rpm) = -100"), "{err}");
}
