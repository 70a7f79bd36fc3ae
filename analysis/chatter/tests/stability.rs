use nalgebra::DMatrix;
use vmt_chatter::stability::sd::{PeriodicDelaySystem, sd_spectral_radius};

struct Hayes;
impl PeriodicDelaySystem for Hayes {
    fn delay(&self) -> f64 {
        1.0
    }
    fn delayed_outputs(&self) -> DMatrix<f64> {
        DMatrix::identity(1, 1)
    }
    fn mean_coefficients(&self, _: f64, _: f64) -> (DMatrix<f64>, DMatrix<f64>) {
        (
            DMatrix::from_element(1, 1, -1.0),
            DMatrix::from_element(1, 1, -1.0),
        )
    }
}

struct Mathieu {
    mid: u8,
    b0: f64,
}
impl PeriodicDelaySystem for Mathieu {
    fn delay(&self) -> f64 {
        std::f64::consts::TAU
    }
    fn delayed_outputs(&self) -> DMatrix<f64> {
        DMatrix::from_row_slice(1, 2, &[1.0, 0.0])
    }
    fn mean_coefficients(&self, t0: f64, t1: f64) -> (DMatrix<f64>, DMatrix<f64>) {
        let cos = match self.mid {
            0 => (0.5 * (t0 + t1)).cos(),
            1 => (t1.sin() - t0.sin()) / (t1 - t0),
            2 => t0.cos(),
            _ => t1.cos(),
        };
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -(3.0 + 2.0 * cos), -0.1]);
        (a, DMatrix::from_row_slice(2, 1, &[0.0, self.b0]))
    }
}

#[test]
fn explore() {
    use vmt_chatter::stability::{
        benchmark_1dof,
        sd::{SdSettings, critical_depth},
        zoa::{ZoaSettings, feed_only_minimum_depth, lobes},
    };
    use vmt_model::cutting::MillingDirection;
    for imm in [1.0, 0.5, 0.1, 0.05] {
        let sys = benchmark_1dof(imm, MillingDirection::Down);
        let l = lobes(&sys, &ZoaSettings::default()).unwrap();
        let mut zmin = (f64::INFINITY, 0.0);
        for i in 0..=400 {
            let n = 5000.0 + 50.0 * i as f64;
            if let Some(p) = l.critical_depth(n) {
                if p.depth_m < zmin.0 {
                    zmin = (p.depth_m, n);
                }
            }
        }
        println!(
            "imm {imm} zoa min {:?} closed {:?}",
            zmin,
            feed_only_minimum_depth(&sys)
        );
        for n in [8000.0, 12000.0, 15000.0, 20000.0] {
            let t = std::time::Instant::now();
            let a40 = critical_depth(&sys, n, 0.02, &SdSettings { steps: 40 }).unwrap();
            let dt = t.elapsed();
            let a160 = critical_depth(&sys, n, 0.02, &SdSettings { steps: 160 }).unwrap();
            println!(
                "  n {n} sd40 {a40:?} sd160 {a160:?} zoa {:?} ({dt:?})",
                l.critical_depth(n).map(|p| p.depth_m)
            );
        }
    }
}
