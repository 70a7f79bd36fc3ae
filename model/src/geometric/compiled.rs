//! The six error functions of one axis and direction, arranged to be evaluated together.
//!
//! Measured error functions of one axis share their domain: a compensation table has one
//! position column for all six errors, and Legendre fits are made over the same stroke. The
//! expensive part of an evaluation — the Legendre basis P_0..P_N(ξ), or locating the table
//! segment and its interpolation weights — is then done once for the six components. Functions
//! that do not share a domain are evaluated one by one. Results equal [`ErrorFunction::eval`]
//! to rounding.

use super::function::{ErrorFunction, Interpolation, SegmentWeights};

/// The six functions of an axis for one direction, in evaluation form.
#[derive(Clone, Debug, PartialEq, Default)]
pub(super) enum Compiled {
    /// Every function is zero.
    #[default]
    Zero,
    /// Legendre series over one interval (zero functions have zero coefficients).
    Legendre {
        scale: f64,
        offset: f64,
        recurrence: Vec<(f64, f64)>,
        /// Coefficient n of the six components.
        coefficients: Vec<[f64; 6]>,
    },
    /// Tables with one position column (zero functions have zero values).
    Table {
        positions: Vec<f64>,
        /// Spacing when the positions are evenly spaced, for direct indexing.
        uniform: Option<f64>,
        values: Vec<[f64; 6]>,
        slopes: Vec<[f64; 6]>,
        interpolation: Interpolation,
    },
    /// No shared domain: each function on its own.
    Separate(Box<[ErrorFunction; 6]>),
}

impl Compiled {
    /// Arranges `functions` for joint evaluation.
    pub(super) fn new(functions: [&ErrorFunction; 6]) -> Self {
        let nonzero: Vec<&ErrorFunction> =
            functions.iter().copied().filter(|f| !f.is_zero()).collect();
        match nonzero.first() {
            None => Compiled::Zero,
            Some(ErrorFunction::Legendre(first)) => {
                let same = nonzero.iter().all(|f| {
                    matches!(f, ErrorFunction::Legendre(s) if s.q_min == first.q_min && s.q_max == first.q_max)
                });
                if same {
                    Self::legendre(functions)
                } else {
                    Self::separate(functions)
                }
            }
            Some(ErrorFunction::Table(first)) => {
                let same = nonzero.iter().all(|f| {
                    matches!(f, ErrorFunction::Table(t) if t.positions == first.positions && t.interpolation == first.interpolation)
                });
                if same {
                    Self::table(functions, first.positions.clone(), first.interpolation)
                } else {
                    Self::separate(functions)
                }
            }
            Some(ErrorFunction::Zero) => Self::separate(functions),
        }
    }

    fn separate(functions: [&ErrorFunction; 6]) -> Self {
        Compiled::Separate(Box::new(functions.map(Clone::clone)))
    }

    fn legendre(functions: [&ErrorFunction; 6]) -> Self {
        let series: Vec<_> = functions
            .iter()
            .filter_map(|f| match f {
                ErrorFunction::Legendre(s) => Some(s),
                _ => None,
            })
            .collect();
        let longest = series.iter().max_by_key(|s| s.coefficients.len()).copied();
        let Some(longest) = longest else {
            return Compiled::Zero;
        };
        let mut coefficients = vec![[0.0; 6]; longest.coefficients.len()];
        for (k, f) in functions.iter().enumerate() {
            if let ErrorFunction::Legendre(s) = f {
                for (n, c) in s.coefficients.iter().enumerate() {
                    coefficients[n][k] = *c;
                }
            }
        }
        Compiled::Legendre {
            scale: longest.scale,
            offset: longest.offset,
            recurrence: longest.recurrence.clone(),
            coefficients,
        }
    }

    fn table(
        functions: [&ErrorFunction; 6],
        positions: Vec<f64>,
        interpolation: Interpolation,
    ) -> Self {
        let n = positions.len();
        let mut values = vec![[0.0; 6]; n];
        let mut slopes = vec![[0.0; 6]; n];
        for (k, f) in functions.iter().enumerate() {
            if let ErrorFunction::Table(t) = f {
                for i in 0..n {
                    values[i][k] = t.values[i];
                    slopes[i][k] = t.slopes.get(i).copied().unwrap_or(0.0);
                }
            }
        }
        let h = (positions[n - 1] - positions[0]) / (n - 1) as f64;
        let even = positions
            .windows(2)
            .all(|w| ((w[1] - w[0]) - h).abs() <= 1e-9 * h);
        Compiled::Table {
            positions,
            uniform: even.then_some(h),
            values,
            slopes,
            interpolation,
        }
    }

    /// The six values at `q`.
    #[inline]
    pub(super) fn eval(&self, q: f64) -> [f64; 6] {
        match self {
            Compiled::Zero => [0.0; 6],
            Compiled::Legendre {
                scale,
                offset,
                recurrence,
                coefficients,
            } => {
                let xi = q * scale + offset;
                let mut out = [0.0; 6];
                let (mut p_prev, mut p) = (0.0, 1.0);
                for (c, (a, b)) in coefficients.iter().zip(recurrence) {
                    for k in 0..6 {
                        out[k] += c[k] * p;
                    }
                    let p_next = a * xi * p - b * p_prev;
                    p_prev = p;
                    p = p_next;
                }
                out
            }
            Compiled::Table {
                positions,
                uniform,
                values,
                slopes,
                interpolation,
            } => {
                let n = positions.len();
                if q <= positions[0] {
                    return values[0];
                }
                if q >= positions[n - 1] {
                    return values[n - 1];
                }
                let i = segment(positions, *uniform, q);
                let w = SegmentWeights::new(q, positions[i], positions[i + 1], *interpolation);
                let (v0, v1, d0, d1) = (&values[i], &values[i + 1], &slopes[i], &slopes[i + 1]);
                std::array::from_fn(|k| w.apply(v0[k], v1[k], d0[k], d1[k]))
            }
            Compiled::Separate(f) => std::array::from_fn(|k| f[k].eval(q)),
        }
    }
}

/// The segment `i` with `positions[i] <= q < positions[i + 1]`, for `q` strictly inside.
#[inline]
fn segment(positions: &[f64], uniform: Option<f64>, q: f64) -> usize {
    let last = positions.len() - 2;
    match uniform {
        Some(h) => {
            // Direct index, corrected by one where rounding puts q across a row.
            let mut i = (((q - positions[0]) / h) as usize).min(last);
            if q < positions[i] {
                i -= 1;
            } else if i < last && q >= positions[i + 1] {
                i += 1;
            }
            i
        }
        // saturating: a NaN `q` gives the first segment instead of a panic.
        None => positions.partition_point(|&p| p <= q).saturating_sub(1),
    }
}
