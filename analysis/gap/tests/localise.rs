//! Localisation of the residual between "measured" traces (synthetic, from displacement laws,
//! with an effect the model lacks) and "simulated" ones (the same laws without it, another
//! noise seed): each effect must land where its physics puts it.

use vmt_ballbar::Plane;
use vmt_ballbar::synthetic::{Errors, test};
use vmt_gap::{GapError, Localisation, Options, Place, TracePair};

fn base() -> Errors {
    Errors {
        scale_ppm: [10.0, -5.0],
        lag_ms: [30.0, 30.0],
        noise_um: 0.3,
        ..Default::default()
    }
}

fn localise(measured: &Errors) -> Localisation {
    let m = test(Plane::Xy, measured, 11);
    let s = test(Plane::Xy, &base(), 12);
    let pairs: Vec<TracePair> = m
        .iter()
        .zip(&s)
        .map(|(m, s)| TracePair::align(m, s).expect("same test"))
        .collect();
    Localisation::of(&pairs, &Options::default()).expect("localised")
}

fn share(places: &[Place], name: &str) -> f64 {
    places
        .iter()
        .find(|p| p.name.contains(name))
        .map_or(0.0, |p| p.share)
}

#[test]
fn servo_mismatch_is_second_order_and_reverses_with_direction() {
    // Δτ = 1 ms at 1000 mm/min: ±(FΔτ/2) sin 2θ = ±8.3 µm, sign flips between CW and CCW.
    let l = localise(&Errors {
        lag_ms: [31.0, 30.0],
        ..base()
    });
    assert!(
        share(&l.by_harmonic, "order 2") > 0.95,
        "{:?}",
        l.by_harmonic
    );
    assert!(
        share(&l.by_direction, "reversing") > 0.95,
        "{:?}",
        l.by_direction
    );
    assert!(
        (l.rms_um - 8.33 / 2f64.sqrt()).abs() < 0.3,
        "rms {}",
        l.rms_um
    );
    assert!(l.concentrations.iter().any(|p| p.kind == "direction"));
}

#[test]
fn squareness_is_second_order_and_common_to_both_directions() {
    let l = localise(&Errors {
        squareness_urad: 40.0,
        ..base()
    });
    assert!(
        share(&l.by_harmonic, "order 2") > 0.95,
        "{:?}",
        l.by_harmonic
    );
    assert!(
        share(&l.by_direction, "common") > 0.95,
        "{:?}",
        l.by_direction
    );
}

#[test]
fn backlash_steps_at_the_axis_reversals() {
    // X backlash: a step of b at 0° and 180°, where X reverses; the radial residual is
    // ±(b/2)·sign(sin θ)·cos θ, of even harmonics only, reversing with direction.
    let l = localise(&Errors {
        backlash_um: [6.0, 0.0],
        ..base()
    });
    let odd: f64 = [1, 3, 5, 7]
        .iter()
        .map(|k| share(&l.by_harmonic, &format!("order {k}")))
        .sum();
    assert!(odd < 1e-3, "{:?}", l.by_harmonic);
    assert!(
        share(&l.by_harmonic, "order 2") > 0.6,
        "{:?}",
        l.by_harmonic
    );
    assert!(
        share(&l.by_direction, "reversing") > 0.95,
        "{:?}",
        l.by_direction
    );
}

#[test]
fn a_drifting_pivot_shows_as_drift_in_time() {
    let l = localise(&Errors {
        pivot_drift_um: [0.0, 0.0],
        ..base()
    });
    let d = localise(&Errors {
        pivot_um: [0.0, 0.0],
        pivot_drift_um: [8.0, 0.0],
        ..base()
    });
    assert!(share(&d.by_time, "drift") > 3.0 * share(&l.by_time, "drift"));
    assert!(d.by_time.iter().map(|p| p.share).sum::<f64>() > 0.999);
}

#[test]
fn a_model_that_matches_leaves_white_noise_and_no_concentration() {
    let l = localise(&base());
    // Two noise seeds of 0.3 µm: the residual's RMS is √2·0.3 µm (rounding adds ~0.03 µm).
    assert!(
        (l.rms_um - 0.3 * 2f64.sqrt()).abs() < 0.03,
        "rms {}",
        l.rms_um
    );
    assert!(l.concentrations.is_empty(), "{:?}", l.concentrations);
    let w = l.whiteness.expect("long enough");
    assert!(w.is_white(0.001), "{w:?}");
    // Quadrant shares follow the sample shares.
    for q in &l.by_quadrant {
        assert!((q.concentration() - 1.0).abs() < 0.2, "{q:?}");
    }
}

#[test]
fn shares_of_every_decomposition_add_up_to_one() {
    let l = localise(&Errors {
        backlash_um: [3.0, 1.0],
        squareness_urad: 20.0,
        ..base()
    });
    for places in [
        &l.by_run,
        &l.by_quadrant,
        &l.by_reversal,
        &l.by_direction,
        &l.by_harmonic,
        &l.by_time,
    ] {
        let sum: f64 = places.iter().map(|p| p.share).sum();
        assert!((sum - 1.0).abs() < 1e-9, "{places:?}");
    }
}

#[test]
fn another_test_is_refused_by_name() {
    let m = test(Plane::Xy, &base(), 1);
    let mut other = test(Plane::Xy, &base(), 2);
    other[0].radius_mm = 100.0;
    // The same angular speed, so that its times agree with it.
    other[0].feed_mm_min *= 100.0 / 150.0;
    let e = TracePair::align(&m[0], &other[0]).unwrap_err();
    assert!(
        matches!(
            e,
            GapError::Mismatch {
                what: "radius_mm",
                ..
            }
        ),
        "{e}"
    );
    assert!(
        e.to_string().contains("150") && e.to_string().contains("100"),
        "{e}"
    );
    let mut feed = test(Plane::Xy, &base(), 2);
    feed[0].feed_mm_min = 500.0;
    assert!(matches!(
        TracePair::align(&m[0], &feed[0]),
        Err(GapError::Mismatch {
            what: "feed_mm_min",
            ..
        })
    ));
    let plane = test(Plane::Zx, &base(), 2);
    assert!(matches!(
        TracePair::align(&m[0], &plane[0]),
        Err(GapError::Mismatch { what: "plane", .. })
    ));
    assert!(matches!(
        TracePair::align(&m[0], &m[1]),
        Err(GapError::Mismatch {
            what: "direction",
            ..
        })
    ));
}
