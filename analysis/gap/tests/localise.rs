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
    // X backlash: a step of b at 0° and 180°, where X reverses (taken up over 0.51°); the
    // radial residual is ±(b/2)·sign(sin θ)·cos θ away from the take-up, of even harmonics
    // only, reversing with direction.
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
    reversal_concentrations(&l, "X", "Y");
    // Y backlash, ±(b/2)·sign(cos θ)·sin θ: the same harmonics and reversing share, its steps
    // at 90° and 270°; only the reversal windows tell the axes apart.
    let l = localise(&Errors {
        backlash_um: [0.0, 6.0],
        ..base()
    });
    reversal_concentrations(&l, "Y", "X");
}

/// The reversal windows (±5°) of a backlash of 6 µm on `stepping`: the residual's energy
/// density is (b/2)² cos²(θ − θ_r) about that axis' reversals θ_r, but for the take-up of the
/// gap over the first √(2b/R) = 0.51° after each reversal inside the runs, where the residual
/// runs through zero from one flank to the other (the runs start and end at 0°, on a flank).
/// A play operator on the nominal circle, summed at 1e-4° steps, puts 5.550 % of the signal
/// into the window at 0° ((w + sin 2w / 2)/π = 5.5415 % for a sudden step), 5.398 % into one
/// that holds a take-up, and (w − sin 2w / 2)/π = 0.0141 % into the other axis' windows,
/// against w/π = 2.7778 % of white noise. With the signal's 4.493 µm² (4.5 for a sudden step)
/// and the two noises' and roundings' 0.1817 µm², the concentrations are
/// (4.493 · 0.05550 + 0.1817 · 0.027778) / 4.675 / 0.027778 = 1.959 at 0°, 1.907 with a
/// take-up and (4.493 · 0.000141 + 0.1817 · 0.027778) / 4.675 / 0.027778 = 0.044. (The
/// localisation measures 1.943 and 1.895, 0.6 to 0.8 % below.)
fn reversal_concentrations(l: &Localisation, stepping: &str, other: &str) {
    for (axis, on_axis, band) in [(stepping, true, 0.03), (other, false, 0.02)] {
        let windows: Vec<&Place> = l
            .by_reversal
            .iter()
            .filter(|p| p.name.starts_with(&format!("{axis} reversal at")))
            .collect();
        assert_eq!(windows.len(), 2, "{:?}", l.by_reversal);
        for p in windows {
            let c = p.concentration();
            let expected = match (on_axis, p.name.ends_with(" at 0°")) {
                (false, _) => 0.044,
                (true, true) => 1.959,
                (true, false) => 1.907,
            };
            assert!(
                (c - expected).abs() < band,
                "{}: {c}, expected {expected}",
                p.name
            );
        }
    }
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
    // The share from the injected law. The pivot drifts 8 µm in X over the test, s = 0..1; the
    // bar reads -8 s cos θ' with θ' the tool's angle, which lags the logged angle θ by
    // φ = 30 ms · 1000 mm/min / 150 mm = 1/300 rad along the motion (scale and lag are in both
    // traces and otherwise cancel): cos θ' = cos θ + φ sin 2πu in both runs (u = 0..1 over a
    // run, θ = ∓2πu). CW: s = u/2, g = -4u (cos 2πu + φ sin 2πu); CCW: s = (1+u)/2,
    // g = -4(1+u)(cos 2πu + φ sin 2πu) µm. Drift is each run's least-squares slope in time:
    // with v = u - 1/2, var v = 1/12, and over u = 0..1 ∫u cos 2πu = 0, ∫u² cos 2πu = 1/(2π²),
    // ∫u sin 2πu = ∫u² sin 2πu = -1/(2π):
    //   cov(g, v) = -2/π² + φ/π = -0.201581 (CW), -2/π² + 3φ/π = -0.199459 (CCW);
    //   trend mean square 12 cov² = 0.48762 + 0.47740 = 0.96502 µm².
    // Mean squares 16 ∫w² (cos² 2πu + φ sin 4πu), w = u or 1 + u, with ∫u² sin 4πu = -1/(4π):
    //   CW 16/6 + 1/π² - 4φ/π = 2.76375, CCW 56/3 + 1/π² - 12φ/π = 18.75526 µm²,
    // plus per run the difference of two noises of 0.3 µm and two 0.1 µm roundings,
    // 2·0.09 + 2·0.01/12 = 0.18167 µm². Share = 0.96502 / 21.8823 = 0.0441 (0.0450 without
    // the lag's φ, whose sine terms weigh in at first order in u where the cosine's cancel).
    // The noise moves each cov(g, v) by √(0.18167 / 12 / 56548) = 5.2e-4 µm, the share by 1.6e-4:
    // five of those is the band.
    let drift = share(&d.by_time, "drift");
    assert!((drift - 0.0441).abs() < 8e-4, "drift share {drift}");
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

/// A run of `n` evenly spaced samples on the 300° arc 0…300°, the residual `r(θ)` plus white
/// noise of `sigma` µm.
fn arc(n: usize, sigma: f64, r: impl Fn(f64) -> f64) -> TracePair {
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let angle_deg: Vec<f64> = (0..n).map(|i| (300 * i) as f64 / (n - 1) as f64).collect();
    let residual_um = angle_deg
        .iter()
        .map(|a| {
            let e: f64 = StandardNormal.sample(&mut rng);
            r(a.to_radians()) + sigma * e
        })
        .collect();
    // The clock only serves the drift split here: 1 ms a sample.
    let time_s = (0..n).map(|i| i as f64 * 1e-3).collect();
    TracePair {
        label: "XY 300° arc CCW".into(),
        plane: Plane::Xy,
        sense: vmt_ballbar::Sense::Ccw,
        radius_mm: 150.0,
        feed_mm_min: 1000.0,
        angle_deg,
        time_s,
        residual_um,
    }
}

fn harmonic_shares(pair: TracePair) -> (Vec<f64>, f64) {
    let ms = pair.mean_square();
    let l = Localisation::of(&[pair], &Options::default()).expect("localised");
    assert_eq!(l.by_harmonic.len(), 10, "{:?}", l.by_harmonic);
    assert!(
        !l.concentrations
            .iter()
            .any(|p| p.kind == "harmonic" && p.share < 0.1),
        "{:?}",
        l.concentrations
    );
    (l.by_harmonic.iter().map(|p| p.share).collect(), ms)
}

/// On a 300° arc (accepted as a full circle) the Fourier columns are not orthogonal. The mix
/// `0.5 + 2 cos 3θ + cos 6θ` is (its three parts are orthogonal over 0…300°, as sin 3Θ =
/// sin 6Θ = sin 9Θ = 0; on 3000 samples to 1/n): its energies 0.25, 2 and 0.5 µm² of 2.75 must
/// come back as the shares of orders 0, 3 and 6 (to 5e-3 µm², the sum over the samples against
/// the integral) and nothing elsewhere. With 0.3 µm of white noise added the orders
/// and the rest must still add up to the residual's mean square (the shares are fractions of
/// it, not of their own sum) and the injected orders hold their energies. Before the split
/// counted the overlaps, the fitted parts of noise on such an arc summed to 5 to 300 times
/// their projection (by seed), the orders 0–8 taking shares far above their 17/3000, and on
/// this seed order 0 came out at 0.16 µm².
#[test]
fn harmonic_shares_on_a_300_degree_arc_add_up_and_match_the_injected_orders() {
    let mix = |t: f64| 0.5 + 2.0 * (3.0 * t).cos() + (6.0 * t).cos();
    let injected = [(0, 0.25), (3, 2.0), (6, 0.5)];
    let (shares, ms) = harmonic_shares(arc(3000, 0.0, mix));
    assert!((ms - 2.75).abs() < 5e-3, "mean square {ms}");
    for (k, share) in shares.iter().enumerate() {
        match injected.iter().find(|(o, _)| *o == k) {
            Some((_, e)) => {
                let got = share * ms;
                assert!((got - e).abs() < 5e-3, "order {k}: {got} µm² against {e}");
            }
            None => assert!(share.abs() < 1e-9, "order {k}: {share}"),
        }
    }

    let (shares, ms) = harmonic_shares(arc(3000, 0.3, mix));
    let sum: f64 = shares.iter().sum();
    assert!(
        (sum - 1.0).abs() < 1e-9,
        "shares add up to {sum}: {shares:?}"
    );
    // The noise's coefficients, enlarged on the arc (the columns' condition number is about
    // 30), move each order by a few 0.01 µm² (order 0 by 0.05 on this seed).
    for (k, e) in injected {
        let got = shares[k] * ms;
        assert!((got - e).abs() < 0.08, "order {k}: {got} µm² against {e}");
    }
    // The rest is the noise: 0.09 µm² less the 17 of 3000 degrees of freedom the fit takes.
    let rest = shares[9] * ms;
    assert!((rest - 0.09).abs() < 0.01, "rest {rest} µm²");

    // Noise alone: the orders 0…8 hold 17 columns' worth, 17/3000 of it on average.
    let (shares, _) = harmonic_shares(arc(3000, 1.0, |_| 0.0));
    let orders: f64 = shares[..9].iter().sum();
    assert!(
        orders.abs() < 4.0 * 17.0 / 3000.0,
        "orders 0-8: {orders} {shares:?}"
    );
    assert!((orders + shares[9] - 1.0).abs() < 1e-9);
}
