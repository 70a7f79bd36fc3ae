//! Diagnoses per second of one ISO 230-4 test: a 150 mm circle at 1000 mm/min, CW and CCW, 360°
//! each, sampled at 1 kHz (2 × 56 549 samples), with backlash, scale, squareness, servo mismatch
//! and 0.3 µm noise. One core. Goal (issue 4): at least 1000 diagnoses per second.
//!
//! Run: `cargo bench -p vmt-ballbar --bench diagnose -- --measurement-time 5` (criterion's
//! elem/s are diagnoses/s).
//!
//! Measured November 2026 on the shared 2-core machine under load (load average 5–10): about
//! 39 diagnoses/s wall clock (25 ms each, the process getting a fifth to a third of a core);
//! in CPU time about 6 ms per diagnosis (≈ 170/s per core-second), against about 22 ms before
//! the rewrite of issue 4 (17–18/s wall clock then).
//!
//! After the perf-diagnose pass (same machine, load average 4–5; CPU time of the thread over
//! 300 diagnoses, five alternating runs of the old and new build; instructions counted by
//! `valgrind --tool=callgrind --toggle-collect=vmt_ballbar::diagnosis::diagnose`): about
//! 4.5 ms CPU per diagnosis against 6.5 ms for the old build in the same runs (≈ 220/s per
//! core-second), 55 M instructions against 69 M. Wall-clock criterion figures swing by ±50 %
//! with the load and were no guide. The goal of 1000/s is still not met: the time is spread
//! over a dozen full-rate passes over columns of 450 kB each that stream from the L3 cache
//! (tabulated trig 9 %, residual 9 %, hysteresis 8 %, the 56 250-point FFTs 9 %, moving means
//! 4 %, ISO sums and bounds 7 %, medians 9 %, cyclic search 4 %); the rest would need the
//! passes fused into one blockwise sweep per trace.
//!
//! After the second perf-diagnose pass (same machine, load average 2–6; same method): about
//! 4.2 ms CPU per diagnosis against 5.4 ms for the build before it in the same runs (medians of
//! five alternating runs; the pairs differ by 0.3–1.9 ms), 47.7 M instructions against 55.3 M;
//! criterion 4.6 ms wall clock (215/s) on the less loaded machine. Gained by: the hysteresis
//! evaluated only in the blocks of samples whose bound can beat the largest difference found
//! (9.4 M to 4.4 M instructions), the ISO bounds and those blocks' extremes in one pass, the
//! tabulated trig in blocks whose loops run on vectors (6.0 M to 4.2 M), one median of the
//! spectrum (the strongest line's) instead of one per trace; every figure bit-identical. The
//! build targets plain x86-64 (SSE2): loops with selects or table look-ups stay scalar. Where
//! the instructions now go: ISO figures 20 % (sums 4 %, bounds 6 %, hysteresis path, sort and
//! blocks 9 %), FFTs 9 %, the rest of the vibration search 5 %, trig 9 %, residual evaluation
//! 10 %, moving means 6 %, medians of the noise and the start transient 11 %, cyclic search
//! 7 %, fit 5 %, validation and reversals 5 %. The goal of 1000/s is still not met.
//!
//! After the third pass (perf-diagnose2; instructions counted as above with `--profile-time
//! 20`, 58–85 diagnoses, the one-time set-up spread over them): 43.7 M instructions per
//! diagnosis against 46.7 M for the build before it; criterion 3.89 ms (257/s) against
//! 3.86 ms (259/s) for the build before it in the same session (load average 2–3: no
//! difference in wall-clock time). Gained by: the model's residuals in a loop without branches or
//! selects that runs on vectors (4.0 M to 3.3 M), the trace checks and the reversal search by
//! branch-free counts, the hysteresis path's sort passed over when the path is sorted already,
//! the spectrum's strongest line and the signatures' ranges by comparisons in vector
//! registers. ISO figures bit-identical, findings within 1e-14. Tried and left out (no gain in
//! instructions): the ISO bounds by four-lane minima and maxima, the fit's normal equations by
//! the matrix library's product. On plain x86-64 (SSE2) a vector loop still costs 20–30
//! instructions per sample for the residual and the trig (register copies of the two-operand
//! forms), so what is left is in full-rate passes that each cost that much: trig 8 %,
//! residual 8 %, moving means 6 %, ISO sums, bounds and hysteresis path 20 %, the two
//! 56 250-point FFTs 9 % (a 55 296 = 2¹¹·3³ point one costs 30 % less), medians of the noise
//! and the start transient 12 %, cyclic search 8 %. 1000/s (≈ 10 M instructions) needs those
//! passes cut, not sped up: the medians and the spectrum on fewer values, the ISO sums in
//! lanes (not bit-identical), one fused sweep per trace.

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
