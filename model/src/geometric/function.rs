//! Error functions of one axis position: Legendre series over the stroke, or tables.
//!
//! Both are the forms in which geometric errors reach a controller: a least-squares polynomial
//! fitted to laser measurements (Legendre polynomials are orthogonal over the stroke, so the
//! coefficients are independent: c0 offset, c1 linear slope, c2 bow, ...), or the compensation
//! table itself, sampled at increasing positions and interpolated between them.

use thiserror::Error;

/// A real function of one axis coordinate (m) giving one error component (m or rad).
#[derive(Clone, Debug, PartialEq, Default)]
pub enum ErrorFunction {
    /// Identically zero.
    #[default]
    Zero,
    /// A Legendre series over an interval.
    Legendre(LegendreSeries),
    /// A table of points with interpolation.
    Table(ErrorTable),
}

impl ErrorFunction {
    /// The value at axis coordinate `q` (m).
    #[inline]
    pub fn eval(&self, q: f64) -> f64 {
        match self {
            ErrorFunction::Zero => 0.0,
            ErrorFunction::Legendre(s) => s.eval(q),
            ErrorFunction::Table(t) => t.eval(q),
        }
    }

    /// Whether the function is identically zero.
    pub fn is_zero(&self) -> bool {
        match self {
            ErrorFunction::Zero => true,
            ErrorFunction::Legendre(s) => s.coefficients.iter().all(|c| *c == 0.0),
            ErrorFunction::Table(t) => t.values.iter().all(|v| *v == 0.0),
        }
    }
}

/// What is wrong with the data of an error function.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum FunctionError {
    /// The interval is empty, reversed or not finite.
    #[error("the interval [{lo}, {hi}] is not an increasing pair of finite numbers")]
    BadInterval {
        /// Lower end.
        lo: f64,
        /// Upper end.
        hi: f64,
    },
    /// A coefficient or table value is NaN or infinite.
    #[error("value {index} is {value}; only finite numbers are accepted")]
    NotFinite {
        /// Position of the value in its list (0-based).
        index: usize,
        /// The value.
        value: f64,
    },
    /// Table positions are not strictly increasing.
    #[error("table positions must increase strictly: row {index} has {value} after {previous}")]
    NotIncreasing {
        /// Row (0-based).
        index: usize,
        /// Its position.
        value: f64,
        /// The previous position.
        previous: f64,
    },
    /// Fewer than two table rows.
    #[error("a table needs at least 2 rows, found {0}")]
    TooShort(usize),
    /// Positions and values differ in length.
    #[error("a table has {positions} positions but {values} values")]
    LengthMismatch {
        /// Number of positions.
        positions: usize,
        /// Number of values.
        values: usize,
    },
}

/// `e(q) = Σ c_n P_n(ξ)`, `ξ = (2q - q_min - q_max) / (q_max - q_min)`, `P_n` Legendre polynomials.
#[derive(Clone, Debug, PartialEq)]
pub struct LegendreSeries {
    pub(super) coefficients: Vec<f64>,
    pub(super) q_min: f64,
    pub(super) q_max: f64,
    /// ξ = q·scale + offset.
    pub(super) scale: f64,
    pub(super) offset: f64,
    /// Recurrence factors (2n+1)/(n+1) and n/(n+1), precomputed so evaluation has no division.
    pub(super) recurrence: Vec<(f64, f64)>,
}

impl LegendreSeries {
    /// A series with `coefficients` (c0, c1, ...) over `[q_min, q_max]` (m).
    pub fn new(coefficients: Vec<f64>, q_min: f64, q_max: f64) -> Result<Self, FunctionError> {
        if !(q_min.is_finite() && q_max.is_finite() && q_min < q_max) {
            return Err(FunctionError::BadInterval {
                lo: q_min,
                hi: q_max,
            });
        }
        check_finite(&coefficients)?;
        let recurrence = (0..coefficients.len())
            .map(|n| {
                let n = n as f64;
                ((2.0 * n + 1.0) / (n + 1.0), n / (n + 1.0))
            })
            .collect();
        Ok(Self {
            scale: 2.0 / (q_max - q_min),
            offset: -(q_min + q_max) / (q_max - q_min),
            coefficients,
            q_min,
            q_max,
            recurrence,
        })
    }

    /// The coefficients c0, c1, ...
    pub fn coefficients(&self) -> &[f64] {
        &self.coefficients
    }

    /// The value at `q` by the three-term recurrence `(n+1)P_{n+1} = (2n+1)ξP_n - nP_{n-1}`.
    #[inline]
    pub fn eval(&self, q: f64) -> f64 {
        let xi = q * self.scale + self.offset;
        let mut sum = 0.0;
        let (mut p_prev, mut p) = (0.0, 1.0);
        for (c, (a, b)) in self.coefficients.iter().zip(&self.recurrence) {
            sum += c * p;
            let p_next = a * xi * p - b * p_prev;
            p_prev = p;
            p = p_next;
        }
        sum
    }
}

/// How a table is interpolated between its rows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Interpolation {
    /// Straight lines between rows, as controller compensation tables apply them.
    #[default]
    Linear,
    /// Monotone piecewise-cubic Hermite (Fritsch–Carlson PCHIP): smooth, no overshoot.
    Pchip,
}

/// A table of error values at strictly increasing axis positions.
///
/// Outside its rows the table holds its end values; scenario loading refuses tables that do not
/// cover the stroke, so evaluation never relies on that.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorTable {
    pub(super) positions: Vec<f64>,
    pub(super) values: Vec<f64>,
    pub(super) slopes: Vec<f64>,
    pub(super) interpolation: Interpolation,
}

impl ErrorTable {
    /// A table of `values` at `positions` (m), strictly increasing, at least two rows.
    pub fn new(
        positions: Vec<f64>,
        values: Vec<f64>,
        interpolation: Interpolation,
    ) -> Result<Self, FunctionError> {
        if positions.len() != values.len() {
            return Err(FunctionError::LengthMismatch {
                positions: positions.len(),
                values: values.len(),
            });
        }
        if positions.len() < 2 {
            return Err(FunctionError::TooShort(positions.len()));
        }
        check_finite(&positions)?;
        check_finite(&values)?;
        if let Some(i) = (1..positions.len()).find(|&i| positions[i] <= positions[i - 1]) {
            return Err(FunctionError::NotIncreasing {
                index: i,
                value: positions[i],
                previous: positions[i - 1],
            });
        }
        let slopes = match interpolation {
            Interpolation::Linear => Vec::new(),
            Interpolation::Pchip => pchip_slopes(&positions, &values),
        };
        Ok(Self {
            positions,
            values,
            slopes,
            interpolation,
        })
    }

    /// The row positions (m).
    pub fn positions(&self) -> &[f64] {
        &self.positions
    }

    /// The row values.
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// The interpolated value at `q`.
    #[inline]
    pub fn eval(&self, q: f64) -> f64 {
        let n = self.positions.len();
        if q <= self.positions[0] {
            return self.values[0];
        }
        if q >= self.positions[n - 1] {
            return self.values[n - 1];
        }
        // saturating: a NaN `q` gives the first segment instead of a panic.
        let i = self
            .positions
            .partition_point(|&p| p <= q)
            .saturating_sub(1);
        let (q0, q1) = (self.positions[i], self.positions[i + 1]);
        let (v0, v1) = (self.values[i], self.values[i + 1]);
        let weights = SegmentWeights::new(q, q0, q1, self.interpolation);
        let slopes = match self.interpolation {
            Interpolation::Linear => (0.0, 0.0),
            Interpolation::Pchip => (self.slopes[i], self.slopes[i + 1]),
        };
        weights.apply(v0, v1, slopes.0, slopes.1)
    }
}

/// Interpolation weights of a point within one table segment `[q0, q1]`: linear, or the cubic
/// Hermite basis h00, h10, h01, h11 (Fritsch–Carlson PCHIP uses the latter).
#[derive(Clone, Copy, Debug)]
pub(super) struct SegmentWeights {
    w0: f64,
    w1: f64,
    d0: f64,
    d1: f64,
}

impl SegmentWeights {
    #[inline]
    pub(super) fn new(q: f64, q0: f64, q1: f64, interpolation: Interpolation) -> Self {
        let h = q1 - q0;
        let s = (q - q0) / h;
        match interpolation {
            Interpolation::Linear => Self {
                w0: 1.0 - s,
                w1: s,
                d0: 0.0,
                d1: 0.0,
            },
            Interpolation::Pchip => {
                let s2 = s * s;
                let s3 = s2 * s;
                Self {
                    w0: 2.0 * s3 - 3.0 * s2 + 1.0,
                    w1: -2.0 * s3 + 3.0 * s2,
                    d0: h * (s3 - 2.0 * s2 + s),
                    d1: h * (s3 - s2),
                }
            }
        }
    }

    /// The interpolated value from the end values and end slopes.
    #[inline]
    pub(super) fn apply(&self, v0: f64, v1: f64, d0: f64, d1: f64) -> f64 {
        self.w0 * v0 + self.w1 * v1 + self.d0 * d0 + self.d1 * d1
    }
}

/// Fritsch–Carlson slopes: harmonic mean of the neighbouring secants where they agree in sign,
/// zero at local extrema, one-sided three-point formula at the ends (limited for monotonicity).
fn pchip_slopes(q: &[f64], v: &[f64]) -> Vec<f64> {
    let n = q.len();
    let h: Vec<f64> = q.windows(2).map(|w| w[1] - w[0]).collect();
    let delta: Vec<f64> = (0..n - 1).map(|i| (v[i + 1] - v[i]) / h[i]).collect();
    if n == 2 {
        return vec![delta[0], delta[0]];
    }
    let mut d = vec![0.0; n];
    for i in 1..n - 1 {
        if delta[i - 1] * delta[i] > 0.0 {
            let w1 = 2.0 * h[i] + h[i - 1];
            let w2 = h[i] + 2.0 * h[i - 1];
            d[i] = (w1 + w2) / (w1 / delta[i - 1] + w2 / delta[i]);
        }
    }
    d[0] = pchip_end(h[0], h[1], delta[0], delta[1]);
    d[n - 1] = pchip_end(h[n - 2], h[n - 3], delta[n - 2], delta[n - 3]);
    d
}

fn pchip_end(h0: f64, h1: f64, d0: f64, d1: f64) -> f64 {
    let d = ((2.0 * h0 + h1) * d0 - h0 * d1) / (h0 + h1);
    if d.signum() != d0.signum() {
        0.0
    } else if d0.signum() != d1.signum() && d.abs() > 3.0 * d0.abs() {
        3.0 * d0
    } else {
        d
    }
}

fn check_finite(values: &[f64]) -> Result<(), FunctionError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(FunctionError::NotFinite {
            index,
            value: values[index],
        }),
        None => Ok(()),
    }
}
