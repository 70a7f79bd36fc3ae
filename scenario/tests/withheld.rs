//! The scenario keys of the optional physics (`vmt_scenario::withheld` writes them): each
//! switches its effect on in the built model, absent it is off, and a bad value is refused at
//! its key, saying what is accepted.

use vmt_model::Axis;
use vmt_model::geometric::DefectShape;
use vmt_scenario::edit::Template;
use vmt_scenario::withheld::{WITHHELD, WithheldEffect, fragments, switch_on};
use vmt_scenario::{BUILTIN_DEFAULT, Scenario, builtin, parse};

fn builtin_template() -> Template {
    Template::parse(BUILTIN_DEFAULT, "vmc500.toml").unwrap()
}

fn load(text: &str) -> Scenario {
    parse(text, "s.toml", None).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

#[test]
fn the_builtin_machine_has_none_of_them() {
    let s = builtin().unwrap();
    let exec = s.execution.unwrap();
    for a in &exec.axes {
        assert!(!a.effects.any(), "{:?}", a.effects);
    }
    assert!(
        s.machine
            .volumetric
            .errors
            .guideways
            .iter()
            .all(Option::is_none)
    );
    let thermal = s.machine.thermal.unwrap();
    assert!(thermal.screws.iter().all(Option::is_none));
}

/// Every withheld effect, written by the helper at its typical size, builds into the model
/// value it names, on its axis only, with the size written.
#[test]
fn each_withheld_effect_switches_its_physics_on() {
    let t = builtin_template();
    for e in &WITHHELD {
        for axis in Axis::ALL {
            let text = switch_on(&t, e.key, axis, e.typical, Some(200.0)).unwrap();
            let s = load(&text);
            let exec = s.execution.as_ref().unwrap();
            let i = axis.index();
            for (k, a) in exec.axes.iter().enumerate() {
                if k != i {
                    assert!(!a.effects.any(), "{} on {axis} reached axis {k}", e.key);
                }
            }
            let fx = &exec.axes[i].effects;
            let guideway = &s.machine.volumetric.errors.guideways[i];
            let screw = &s.machine.thermal.as_ref().unwrap().screws[i];
            match e.key {
                "cogging" => {
                    let m = fx.motor.unwrap();
                    assert_eq!(m.cogging_periods_per_rev, 72);
                    assert_eq!(m.pole_pairs, 4);
                    assert!((m.cogging_n_m - 0.04).abs() < 1e-15);
                    assert!((m.ripple_fraction - 0.01).abs() < 1e-15);
                }
                "interpolation" => {
                    let sg = fx.motor_encoder_signals.unwrap();
                    assert!((sg.period_m - 0.01 / 2048.0).abs() < 1e-18);
                    assert!((sg.offset_cos - 0.01).abs() < 1e-15);
                    assert!((sg.amplitude_ratio - 1.01).abs() < 1e-15);
                }
                "rail_bump" | "rail_step" => {
                    let g = guideway.as_ref().unwrap();
                    let d = g.defects[0];
                    assert!((d.height_m - 2e-6).abs() < 1e-18 && (d.at_m - 0.2).abs() < 1e-15);
                    let across = if axis == Axis::Z { Axis::Y } else { Axis::Z };
                    assert_eq!(d.direction, across);
                    assert_eq!(
                        matches!(d.shape, DefectShape::Bump { .. }),
                        e.key == "rail_bump"
                    );
                }
                "screw_warming" => {
                    let sc = screw.unwrap();
                    assert!(
                        !sc.fixed_at_high_end,
                        "fixed at reference_mm = 0, the low end"
                    );
                    assert!((sc.warm.unwrap().rise_k - 2.0).abs() < 1e-15);
                    assert!((sc.nut_w_per_m_s - 300.0).abs() < 1e-9);
                }
                "nut_preload" => {
                    let n = fx.nut.unwrap();
                    assert_eq!(n.remaining_preload_n, 0.0);
                    assert!((n.stiffness_n_per_m - 800e6).abs() < 1e-3);
                }
                "gms_friction" => {
                    assert_eq!(fx.guide_gms.unwrap().elements, 4);
                    assert_eq!(fx.screw_gms.unwrap().elements, 4);
                    // At the contacts' own levels.
                    let d = &exec.axes[i].drive;
                    assert_eq!(fx.guide_gms.unwrap().curve, d.guide_friction);
                }
                other => panic!("no check for {other}"),
            }
            assert_eq!(
                WithheldEffect::named(e.key).unwrap().like_for(axis).len(),
                e.like.len()
            );
        }
    }
    // A rail defect needs its place; an unknown effect is named with the known ones.
    assert!(fragments(&t, "rail_bump", Axis::X, 2.0, None).is_err());
    let err = fragments(&t, "wobble", Axis::X, 1.0, None).unwrap_err();
    assert!(err.to_string().contains("nut_preload"), "{err}");
}

/// A bad value of each table is refused at its key, naming what is accepted.
#[test]
fn bad_values_are_refused_at_their_keys() {
    let t = builtin_template();
    let cases: [(&str, &str, &str, &str); 10] = [
        (
            "machine.axes.x.drive.motor",
            "slots = 36\npoles = 7\ncogging_n_m = 0.04\n",
            "machine.axes.x.drive.motor.poles",
            "even",
        ),
        (
            "machine.axes.x.drive.motor",
            "slots = 36\npoles = 8\ncogging_n_m = -0.1\n",
            "machine.axes.x.drive.motor.cogging_n_m",
            "from 0 to 1000",
        ),
        (
            "machine.axes.x.drive.guide_friction",
            "law = \"dahl\"\n",
            "machine.axes.x.drive.guide_friction.law",
            "\"gms\"",
        ),
        (
            "machine.axes.x.drive.screw_friction",
            "gms_elements = 3\n",
            "machine.axes.x.drive.screw_friction.gms_elements",
            "law = \"gms\" only",
        ),
        (
            "machine.axes.x.drive.nut",
            "preload_n = 1900.0\nstiffness_n_per_um = 800.0\nremaining_preload_n = 2000.0\n",
            "machine.axes.x.drive.nut.remaining_preload_n",
            "up to preload_n",
        ),
        (
            "machine.axes.y.drive.nut",
            "preload_n = 1900.0\nstiffness_n_per_um = 150.0\nremaining_preload_n = 0.0\n",
            "machine.axes.y.drive.nut.stiffness_n_per_um",
            "must be stiffer",
        ),
        (
            "machine.axes.x.drive.scale_signals",
            "signal_period_um = 20.0\n",
            "machine.axes.x.drive.scale_signals",
            "no linear scale",
        ),
        (
            "machine.axes.x.drive.encoder_signals",
            "signal_period_um = 20.0\n",
            "machine.axes.x.drive.encoder_signals",
            "periods_per_rev",
        ),
        (
            "machine.axes.x",
            "[guideway]\nblock_spacing_mm = 300.0\nblocks_centre_mm = [0.0, 0.0, 0.0]\n[[guideway.defects]]\nshape = \"bump\"\ndirection = \"x\"\nat_mm = 100.0\nheight_um = 2.0\nwidth_mm = 30.0\n",
            "machine.axes.x.guideway.defects[0].direction",
            "y or z",
        ),
        (
            "machine.thermal.screw.x",
            "span_mm = [100.0, 600.0]\nfixed_end = \"low\"\ndiameter_mm = 28.0\nconvection_w_per_m2_k = 15.0\nend_w_per_k = [2.0, 0.5]\nnut_w_per_mm_s = 0.3\nnut_length_mm = 100.0\nbearing_w_per_mm_s = 0.2\n",
            "machine.thermal.screw.x.span_mm",
            "stroke 0 to 500 mm",
        ),
    ];
    for (table, fragment, key, accepted) in cases {
        let text = t.with_fragment(table, fragment).unwrap();
        let e = parse(&text, "s.toml", None).expect_err(key);
        assert_eq!(e.key.as_deref(), Some(key), "{e}");
        assert!(e.message.contains(accepted), "{e}");
        assert!(e.position.is_some(), "located: {e}");
    }
}

/// A table that is there but sets nothing changes nothing: the explicit default law and a
/// guideway without defects build the same drives and chain as the built-in machine.
#[test]
fn explicit_defaults_build_the_same_machine() {
    let t = builtin_template();
    let text = t
        .with_fragment("machine.axes.x.drive.guide_friction", "law = \"lugre\"\n")
        .unwrap();
    let text = Template::parse(&text, "s.toml")
        .unwrap()
        .with_fragment(
            "machine.axes.x",
            "[guideway]\nblock_spacing_mm = 300.0\nblocks_centre_mm = [250.0, 200.0, -250.0]\n",
        )
        .unwrap();
    let (a, b) = (builtin().unwrap(), load(&text));
    assert_eq!(
        a.execution.unwrap().axes,
        b.execution.as_ref().unwrap().axes
    );
    let state = vmt_model::kinematics::AxisState::new(
        nalgebra::Vector3::new(0.33, 0.12, 0.2),
        vmt_model::Direction::Backward,
    );
    let cold = vmt_model::thermal_deformation::ThermalDeformation::default();
    assert_eq!(
        a.machine.volumetric.volumetric_error(&state, &cold),
        b.machine.volumetric.volumetric_error(&state, &cold)
    );
}
