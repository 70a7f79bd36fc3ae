//! Detection cost per second of signal (20 kHz, three axes, a 4-tooth cutter at 7500 rev/min:
//! tooth passing 500 Hz): Kim's band-pass + block RMS, and the spectral detector (2048-sample
//! frames, hop 512, the forced comb found and masked). Real time needs each well under 1 s per
//! second of signal.
//!
//! Run: `cargo bench -p vmt-chatter --bench detect`.

use criterion::{Criterion, criterion_group, criterion_main};
use std::f64::consts::TAU;
use std::hint::black_box;
use vmt_chatter::detect::kim::{self, KimSettings};
use vmt_chatter::detect::spectral::{self, SpectralSettings};

fn bench(c: &mut Criterion) {
    let fs = 20_000.0;
    let axes: Vec<Vec<f64>> = (0..3)
        .map(|k| {
            (0..20_000)
                .map(|i| {
                    let t = i as f64 / fs;
                    (1..20)
                        .map(|h| (TAU * 500.0 * h as f64 * t + k as f64).sin() / h as f64)
                        .sum::<f64>()
                        + 0.3 * (TAU * 3130.0 * t).sin()
                })
                .collect()
        })
        .collect();
    let slices: Vec<&[f64]> = axes.iter().map(Vec::as_slice).collect();
    let mut group = c.benchmark_group("detect_1s_3axes");
    group.bench_function("kim", |b| {
        b.iter(|| kim::detect(black_box(&slices), fs, &KimSettings::with_limit(1.0)))
    });
    let s = SpectralSettings::new(7500.0, 4);
    group.bench_function("spectral", |b| {
        b.iter(|| spectral::detect(black_box(&slices), fs, &s))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
