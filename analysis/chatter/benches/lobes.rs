//! Stability-map timing: the first-order SD map of the 1-DOF benchmark (Insperger & Stépán;
//! down milling at a/D = 1, 0.5 and 0.05) over 200 speeds (5–25 krpm) × 100 depths
//! (0.05–10 mm) with the default 80 steps per tooth period, and the ZOA lobes. Goal: each SD
//! map under 2 s on one core. Measured November 2026 on the 2-core machine otherwise idle:
//! 1.36 s (a/D = 1), 0.98 s (0.5), 0.76 s (0.05).
//!
//! Run: `cargo bench -p vmt-chatter --bench lobes`.

use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use vmt_chatter::stability::sd::{SdSettings, stability_map};
use vmt_chatter::stability::zoa::{ZoaSettings, lobes};
use vmt_chatter::stability::{benchmark_1dof, grid};
use vmt_model::cutting::MillingDirection;

fn bench(c: &mut Criterion) {
    let speeds = grid("speed", 5e3, 25e3, 200).expect("valid grid");
    let depths = grid("depth", 0.05e-3, 10e-3, 100).expect("valid grid");
    let mut group = c.benchmark_group("lobes");
    group.sample_size(10);
    for immersion in [1.0, 0.5, 0.05] {
        let system = benchmark_1dof(immersion, MillingDirection::Down);
        group.bench_function(format!("sd_map_200x100_aD{immersion}"), |b| {
            b.iter(|| stability_map(black_box(&system), &speeds, &depths, &SdSettings::default()))
        });
    }
    let system = benchmark_1dof(0.5, MillingDirection::Down);
    group.bench_function("zoa_lobes", |b| {
        b.iter(|| lobes(black_box(&system), &ZoaSettings::default()))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
