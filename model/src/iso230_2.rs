//! The figures of ISO 230-2:2014 (*Determination of accuracy and repeatability of positioning
//! of numerically controlled axes*), shared by the simulator's ground truth and the analysis of
//! measured runs, so that both state the same quantity.
//!
//! With `x_ij = P_ij − P_i` the deviation at target `i` (position `P_i`) in run `j` (`n` runs), per
//! direction of approach (↑ forward, ↓ backward):
//!
//! ```text
//! x̄_i↑ = (1/n) Σ_j x_ij↑                          mean unidirectional positional deviation
//! x̄_i  = (x̄_i↑ + x̄_i↓) / 2                        mean bidirectional positional deviation
//! B_i  = x̄_i↑ − x̄_i↓                              reversal value at a position
//! s_i↑ = sqrt(Σ_j (x_ij↑ − x̄_i↑)² / (n − 1))      unidirectional standard uncertainty estimator
//! R_i↑ = 4 s_i↑                                   unidirectional repeatability
//! R_i  = max(2 s_i↑ + 2 s_i↓ + |B_i|, R_i↑, R_i↓)  bidirectional repeatability
//! B    = max_i |B_i|,  B̄ = mean_i B_i              reversal value, mean reversal value
//! R↑   = max_i R_i↑,  R = max_i R_i
//! E↑   = max_i x̄_i↑ − min_i x̄_i↑                   unidirectional systematic positioning error
//! E    = max(x̄_i↑, x̄_i↓) − min(x̄_i↑, x̄_i↓)          bidirectional systematic positioning error
//! M    = max_i x̄_i − min_i x̄_i                     mean bidirectional positioning error
//! A↑   = max(x̄_i↑ + 2 s_i↑) − min(x̄_i↑ − 2 s_i↑)   unidirectional accuracy
//! A    = max(x̄_i↑ + 2 s_i↑, x̄_i↓ + 2 s_i↓) − min(x̄_i↑ − 2 s_i↑, x̄_i↓ − 2 s_i↓)
//! ```
//!
//! All deviations and figures in µm, positions in mm.

use serde::Serialize;

/// Direction of approach to a target.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Approach {
    /// Positive direction (ISO ↑).
    Forward,
    /// Negative direction (ISO ↓).
    Backward,
}

impl Approach {
    /// `forward` or `backward`.
    pub fn name(self) -> &'static str {
        match self {
            Approach::Forward => "forward",
            Approach::Backward => "backward",
        }
    }
}

/// One deviation `x_ij` of a positioning test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Deviation {
    /// Target index `i`, 0-based.
    pub target: usize,
    /// Direction of approach.
    pub approach: Approach,
    /// Deviation `x_ij = P_ij − P_i`, µm.
    pub deviation_um: f64,
}

/// ISO 230-2:2014 figures of a positioning test, µm (see the module docs).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Iso230_2 {
    /// Target positions, mm.
    pub targets_mm: Vec<f64>,
    /// x̄_i↑, µm.
    pub mean_forward_um: Vec<f64>,
    /// x̄_i↓, µm.
    pub mean_backward_um: Vec<f64>,
    /// s_i↑, µm.
    pub s_forward_um: Vec<f64>,
    /// s_i↓, µm.
    pub s_backward_um: Vec<f64>,
    /// B_i, µm.
    pub reversal_um: Vec<f64>,
    /// B, µm.
    pub b_um: f64,
    /// B̄, µm.
    pub b_mean_um: f64,
    /// E↑, µm.
    pub e_forward_um: f64,
    /// E↓, µm.
    pub e_backward_um: f64,
    /// E, µm.
    pub e_um: f64,
    /// M, µm.
    pub m_um: f64,
    /// R↑, µm.
    pub r_forward_um: f64,
    /// R↓, µm.
    pub r_backward_um: f64,
    /// R, µm.
    pub r_um: f64,
    /// A↑, µm.
    pub a_forward_um: f64,
    /// A↓, µm.
    pub a_backward_um: f64,
    /// A, µm.
    pub a_um: f64,
}

/// Mean and sample standard deviation (`n − 1`; 0 for a single value).
fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n.max(1.0);
    let ss = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>();
    (mean, (ss / (n - 1.0).max(1.0)).sqrt())
}

/// `max(hi) − min(lo)`.
fn span<'a>(hi: impl Iterator<Item = &'a f64>, lo: impl Iterator<Item = &'a f64>) -> f64 {
    hi.copied().fold(f64::NEG_INFINITY, f64::max) - lo.copied().fold(f64::INFINITY, f64::min)
}

impl Iso230_2 {
    /// The figures of `deviations` at `targets_mm`. Every target needs at least one deviation
    /// per direction (two for a standard deviation); the caller checks this (see the analysis
    /// crate `vmt-positioning`), deviations of unknown targets are ignored.
    pub fn evaluate(targets_mm: &[f64], deviations: &[Deviation]) -> Self {
        let m = targets_mm.len();
        let stats = |approach: Approach| -> (Vec<f64>, Vec<f64>) {
            // One pass sorts the deviations by target, so that many targets stay linear.
            let mut at: Vec<Vec<f64>> = vec![Vec::new(); m];
            for d in deviations.iter().filter(|d| d.approach == approach) {
                if let Some(v) = at.get_mut(d.target) {
                    v.push(d.deviation_um);
                }
            }
            at.iter().map(|v| mean_sd(v)).unzip()
        };
        let (up, su) = stats(Approach::Forward);
        let (down, sd) = stats(Approach::Backward);
        let b: Vec<f64> = up.iter().zip(&down).map(|(u, d)| u - d).collect();
        let r_i: Vec<f64> = (0..m)
            .map(|i| (2.0 * su[i] + 2.0 * sd[i] + b[i].abs()).max(4.0 * su[i].max(sd[i])))
            .collect();
        let max = |v: &[f64]| v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let plus = |x: &[f64], s: &[f64], k: f64| -> Vec<f64> {
            x.iter().zip(s).map(|(x, s)| x + k * s).collect()
        };
        let bi: Vec<f64> = up.iter().zip(&down).map(|(u, d)| 0.5 * (u + d)).collect();
        let (up_hi, up_lo) = (plus(&up, &su, 2.0), plus(&up, &su, -2.0));
        let (dn_hi, dn_lo) = (plus(&down, &sd, 2.0), plus(&down, &sd, -2.0));
        Self {
            targets_mm: targets_mm.to_vec(),
            b_um: b.iter().map(|v| v.abs()).fold(0.0, f64::max),
            b_mean_um: b.iter().sum::<f64>() / m.max(1) as f64,
            e_forward_um: span(up.iter(), up.iter()),
            e_backward_um: span(down.iter(), down.iter()),
            e_um: span(up.iter().chain(&down), up.iter().chain(&down)),
            m_um: span(bi.iter(), bi.iter()),
            r_forward_um: 4.0 * max(&su),
            r_backward_um: 4.0 * max(&sd),
            r_um: max(&r_i),
            a_forward_um: span(up_hi.iter(), up_lo.iter()),
            a_backward_um: span(dn_hi.iter(), dn_lo.iter()),
            a_um: span(up_hi.iter().chain(&dn_hi), up_lo.iter().chain(&dn_lo)),
            mean_forward_um: up,
            mean_backward_um: down,
            s_forward_um: su,
            s_backward_um: sd,
            reversal_um: b,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figures_of_a_known_set() {
        // Two targets, three runs: forward deviations 1, 2, 3 and 4, 4, 4; backward 0, 0, 0 and
        // 6, 7, 8 (µm).
        let data = [
            (0, Approach::Forward, [1.0, 2.0, 3.0]),
            (1, Approach::Forward, [4.0, 4.0, 4.0]),
            (0, Approach::Backward, [0.0, 0.0, 0.0]),
            (1, Approach::Backward, [6.0, 7.0, 8.0]),
        ];
        let devs: Vec<Deviation> = data
            .iter()
            .flat_map(|&(target, approach, v)| {
                v.map(|deviation_um| Deviation {
                    target,
                    approach,
                    deviation_um,
                })
            })
            .collect();
        let f = Iso230_2::evaluate(&[0.0, 100.0], &devs);
        assert_eq!(f.mean_forward_um, [2.0, 4.0]);
        assert_eq!(f.mean_backward_um, [0.0, 7.0]);
        assert_eq!(f.s_forward_um, [1.0, 0.0]);
        assert_eq!(f.reversal_um, [2.0, -3.0]);
        assert_eq!(f.b_um, 3.0);
        assert_eq!(f.b_mean_um, -0.5);
        assert_eq!(f.e_forward_um, 2.0);
        assert_eq!(f.e_um, 7.0);
        // Bidirectional means 1 and 5.5.
        assert_eq!(f.m_um, 4.5);
        assert_eq!(f.r_forward_um, 4.0);
        // R_1 = max(2 + 0 + 2, 4, 0) = 4; R_2 = max(0 + 2 + 3, 0, 4) = 5.
        assert_eq!(f.r_um, 5.0);
        // A = max(2+2, 4, 0, 7+2) - min(2-2, 4, 0, 7-2) = 9.
        assert_eq!(f.a_um, 9.0);
        assert_eq!(f.a_forward_um, 4.0);
    }
}
