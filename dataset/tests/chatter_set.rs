//! A few cuts of the labelled chatter set (`vmt chatter rates` runs all 200 at three rates):
//! labels from the simulator's tool motion, verdicts of the spectral detector from the
//! accelerometers at 1.6 and 20 kHz. The cuts are the set's hard ones: flip chatter at 1.5
//! times the tooth-passing frequency (on the spindle-rotation comb, with and without run-out),
//! chatter a few Hz off a spindle order, and stable cuts with run-out.

use vmt_chatter::detect::spectral::{self, SpectralSettings};
use vmt_dataset::chatter::{Cut, SetSpec, TEETH, simulate};

fn cut(spindle_rpm: f64, depth_mm: f64, runout_um: f64) -> Cut {
    Cut {
        index: 0,
        spindle_rpm,
        depth_mm,
        runout_um,
        runout_angle_deg: 40.0,
        seed: 7,
    }
}

#[test]
fn hard_cuts_of_the_set_are_labelled_and_told_at_low_and_high_rates() {
    let spec = SetSpec {
        rates_hz: vec![1600.0, 20_000.0],
        ..SetSpec::default()
    };
    // (cut, whether it chatters by the truth; the detector's chatter line at 600-650 Hz).
    let cases = [
        // 6315.79 rev/min: f_tp = 421 Hz; period doubling at 1.5·f_tp = 631.6 Hz, the 6th
        // spindle order, which run-out also drives.
        (cut(120_000.0 / 19.0, 2.5, 0.0), true),
        (cut(120_000.0 / 19.0, 2.5, 10.0), true),
        // 5842 rev/min: chatter at 626 Hz; at 20 kHz the 199th order folds to 623.7 Hz.
        (cut(5842.1, 3.5, 0.0), true),
        // Stable with run-out: its spindle-order lines are forced.
        (cut(9000.0, 2.0, 12.0), false),
        (cut(3000.0, 1.0, 8.0), false),
    ];
    for (c, chatter) in cases {
        let l = simulate(&c, &spec).unwrap();
        assert_eq!(l.onset_s.is_some(), chatter, "{c:?}: truth {:?}", l.onset_s);
        for run in &l.runs {
            let s = SpectralSettings::new(c.spindle_rpm, TEETH as u32);
            let r = spectral::detect(&run.slices(), run.sample_rate_hz, &s).unwrap();
            assert_eq!(
                r.verdict.chatter, chatter,
                "{c:?} at {} Hz: {:?}",
                run.sample_rate_hz, r.verdict
            );
            if chatter {
                let f = r.verdict.chatter_frequency_hz.unwrap();
                assert!((600.0..650.0).contains(&f), "{c:?}: {f} Hz");
            } else {
                assert!(
                    r.seen.iter().any(|l| !l.line.tooth_passing),
                    "{c:?}: no run-out line seen"
                );
            }
        }
    }
}
