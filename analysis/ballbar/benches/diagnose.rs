//! Diagnoses per second of one ISO 230-4 test: a 150 mm circle at 1000 mm/min, CW and CCW, 360°
//! each, sampled at 1 kHz (2 × 56 548 samples), with backlash, scale, squareness, servo mismatch
//! and 0.3 µm noise. One core. Goal (issue 4): at least 1000 diagnoses per second.
//!
//! Run: `cargo bench -p vmt-ballbar --bench diagnose -- --measurement-time 5` (criterion's
//! elem/s are diagnoses/s). Wall-clock figures swing with the load on the shared machine;
//! compare builds by instructions: `valgrind --tool=callgrind
//! --toggle-collect=vmt_ballbar::diagnosis::diagnose` on the bench binary with `--bench full
//! --profile-time 5`, the total divided by the number of diagnoses (calls of
//! `iso230_4::figures_with_trig`).
//!
//! Measured November 2026: 34.6 M instructions per diagnosis against 43.8 M for the build
//! before the estimators were cut (`--profile-time 12`, about 100 diagnoses); criterion 2.7 ms
//! (about 370/s) against 3.1 ms (325/s), medians of five runs alternating the two builds (load
//! average 0.4–1, another engineer's builds on the second core).
//!
//! The take-up of backlash (`take_up.rs`, with the search of its reach) added 7.7 %: 37.7 M
//! against 35.0 M.
//!
//! Where the instructions go: ISO figures 22 % (least-squares sums 5 %, bounds about both
//! centres 6 %, hysteresis path and blocks 9 %), vibration spectrum 14 % (the two 55 296-point
//! FFTs 9 %), trigonometry 10 %, the model's residuals 10 %, cyclic search 7 %, medians of the
//! steps and spikes near reversals 6 %, fit 5 %, moving means 4 %, start transient 4 %, noise
//! 3 %, trace checks, reversals and groups 9 %.
//!
//! The confidence intervals robust to a correlated residual (`Normal::robust_std_errors`, batch
//! means of the groups' scores) take 1.9 % of a diagnosis (perf, 25 November 2026: the blocks'
//! Gram matrix by one matrix product); 3.3–3.5 ms per diagnosis that morning, against 3.65 ms
//! for the build before on the same machine an hour earlier (the wall clock swings by 10 %,
//! 3.9–4.1 ms half an hour later). The cyclic errors' intervals (the amplitude's error at its
//! pitch by batch means, `features::robust_cyclic_error`) take 2.5 % more, most of it in `sincos`.
//!
//! What is left for 1000/s (about 10–13 M): every full-rate pass costs 10–30 instructions per
//! sample on plain x86-64 (SSE2), and about ten remain (trig, residual, ISO sums, bounds and
//! path, prefix sums, high-pass, FFT, checks, reversals, groups); they would have to be fused
//! into one blockwise sweep per trace, and the ISO figures and the fit share one pass.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use vmt_ballbar::synthetic::{Errors, test};
use vmt_ballbar::{Options, Plane, diagnose};

fn bench(c: &mut Criterion) {
    let e = Errors {
        backlash_um: [3.0, 1.0],
        scale_ppm: [20.0, -5.0],
        squareness_urad: 10.0,
        lag_ms: [30.3, 30.0],
        noise_um: 0.3,
        ..Default::default()
    };
    let traces = test(Plane::Xy, &e, 1);
    let mut g = c.benchmark_group("diagnose_iso230_4_150mm_1000mm_min");
    g.throughput(Throughput::Elements(1));
    for (name, options) in [
        ("full", Options::default()),
        (
            "without_cyclic_search",
            Options {
                cyclic: false,
                ..Options::default()
            },
        ),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| diagnose(&traces, &options).expect("diagnosis"))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
