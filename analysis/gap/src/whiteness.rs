//! The Ljung–Box portmanteau test of whiteness (Ljung & Box, Biometrika 65, 1978):
//!
//! ```text
//! ρ_k = Σ_{i>k} (x_i - x̄)(x_{i-k} - x̄) / Σ_i (x_i - x̄)²      sample autocorrelation at lag k
//! Q   = n(n+2) Σ_{k=1..h} ρ_k² / (n - k)                       ~ χ²(h) for white noise
//! ```
//!
//! Independent series add their Q and their degrees of freedom. A small p-value says the
//! residual still holds structure: something the model misses, or that the fitted parts left.

use statrs::distribution::{ChiSquared, ContinuousCDF};

/// The outcome of a Ljung–Box test.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Whiteness {
    /// The statistic Q (summed over series).
    pub q: f64,
    /// Degrees of freedom (lags × series).
    pub dof: usize,
    /// P(χ²(dof) ≥ Q): the chance of a Q this large from white noise.
    pub p_value: f64,
}

impl Whiteness {
    /// White at significance level `alpha` (e.g. 0.01).
    pub fn is_white(&self, alpha: f64) -> bool {
        self.p_value >= alpha
    }
}

/// Q of one series with `lags` lags; `None` when the series is shorter than `2·lags` or constant.
pub fn ljung_box_q(x: &[f64], lags: usize) -> Option<f64> {
    let n = x.len();
    if lags == 0 || n < 2 * lags {
        return None;
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let d: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let c0: f64 = d.iter().map(|v| v * v).sum();
    if c0 <= 0.0 {
        return None;
    }
    let nf = n as f64;
    let q = (1..=lags)
        .map(|k| {
            let ck: f64 = d[k..].iter().zip(&d[..n - k]).map(|(a, b)| a * b).sum();
            (ck / c0).powi(2) / (nf - k as f64)
        })
        .sum::<f64>();
    Some(nf * (nf + 2.0) * q)
}

/// The test over several independent series; series too short for the lags are skipped.
/// `None` when none is long enough.
pub fn ljung_box(series: &[Vec<f64>], lags: usize) -> Option<Whiteness> {
    let qs: Vec<f64> = series.iter().filter_map(|s| ljung_box_q(s, lags)).collect();
    if qs.is_empty() {
        return None;
    }
    let q: f64 = qs.iter().sum();
    let dof = lags * qs.len();
    let chi = ChiSquared::new(dof as f64).ok()?;
    Some(Whiteness {
        q,
        dof,
        p_value: 1.0 - chi.cdf(q),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    fn noise(seed: u64, n: usize) -> Vec<f64> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let d = Normal::new(0.0, 1.0).unwrap();
        (0..n).map(|_| d.sample(&mut rng)).collect()
    }

    #[test]
    fn white_noise_passes_at_the_nominal_rate_and_a_random_walk_fails() {
        // Under the null the p-value is uniform: about 5 % of 200 series fall below 0.05.
        let rejected = (0..200)
            .filter(|s| !ljung_box(&[noise(*s, 720)], 20).unwrap().is_white(0.05))
            .count();
        assert!(
            (3..=20).contains(&rejected),
            "{rejected} of 200 rejected at 5 %"
        );
        let walk: Vec<f64> = noise(7, 720)
            .iter()
            .scan(0.0, |s, x| {
                *s += x;
                Some(*s)
            })
            .collect();
        assert!(ljung_box(&[walk], 20).unwrap().p_value < 1e-6);
    }

    #[test]
    fn q_of_a_perfect_alternation_is_the_closed_form() {
        // x = ±1 alternating: ρ_k = (-1)^k (n-k)/n, so Q = n(n+2) Σ (n-k)/n².
        let n = 100;
        let x: Vec<f64> = (0..n)
            .map(|i| if i % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let nf = n as f64;
        let expected = (nf + 2.0) / nf * (1..=5).map(|k| nf - k as f64).sum::<f64>();
        assert!((ljung_box_q(&x, 5).unwrap() - expected).abs() < 1e-9 * expected);
    }
}
