//! Centred moving means of a series from its prefix sums: one pass over the series serves
//! every window width, and a mean is two loads wherever it is wanted (the smoothed residual
//! is only read near reversals and at the start of a run).
//!
//! The window of half-width h holds the samples i − h … i + h, shrinking at the ends of the
//! series. The prefix sums of a residual (a few µm over some 10⁵ samples) stay below about
//! 10⁵ µm, so a mean carries an absolute rounding error of some 1e-11 µm.

/// Running sums advanced side by side over consecutive stretches of a series in
/// [`PrefixSums::new`]: one running sum waits on the latency of each addition, independent
/// ones overlap.
const CHAINS: usize = 4;

/// `Σ x[..i]` for i = 0…n of a series x of n values.
#[derive(Clone, Debug)]
pub struct PrefixSums(Vec<f64>);

impl PrefixSums {
    /// The prefix sums of `x`: `CHAINS` stretches summed side by side, then each stretch
    /// offset by the total of those before it.
    pub fn new(x: &[f64]) -> Self {
        let n = x.len();
        let mut s = crate::samples::filled(n + 1);
        s[0] = 0.0;
        let m = n / CHAINS;
        let mut sums = [0.0; CHAINS];
        if m > 0 {
            let xs: [&[f64]; CHAINS] = std::array::from_fn(|j| &x[j * m..(j + 1) * m]);
            let mut outs = s[1..=CHAINS * m].chunks_exact_mut(m);
            let os: [&mut [f64]; CHAINS] = std::array::from_fn(|_| outs.next().unwrap_or_default());
            for i in 0..m {
                for j in 0..CHAINS {
                    sums[j] += xs[j][i];
                    os[j][i] = sums[j];
                }
            }
        }
        for b in CHAINS * m..n {
            sums[CHAINS - 1] += x[b];
            s[b + 1] = sums[CHAINS - 1];
        }
        let mut offset = 0.0;
        for j in 1..CHAINS {
            offset += sums[j - 1];
            let end = if j + 1 == CHAINS { n } else { (j + 1) * m };
            for v in &mut s[j * m + 1..=end] {
                *v += offset;
            }
        }
        Self(s)
    }

    /// Number of values summed.
    pub fn len(&self) -> usize {
        self.0.len() - 1
    }

    /// Whether no values are summed.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The mean of the values `a..b` (a < b).
    #[inline]
    pub fn mean_of(&self, a: usize, b: usize) -> f64 {
        (self.0[b] - self.0[a]) / (b - a) as f64
    }

    /// The centred moving mean of half-width `half` at sample `i`.
    #[inline]
    pub fn mean(&self, i: usize, half: usize) -> f64 {
        self.mean_of(i.saturating_sub(half), (i + half + 1).min(self.len()))
    }

    /// `x` minus its centred moving mean of half-width `half` (x the series summed), into a
    /// buffer from the pool: the interior by the reciprocal of the full width in a loop that
    /// runs on vectors, the ends (where the window shrinks) by [`PrefixSums::mean`].
    pub fn high_pass(&self, x: &[f64], half: usize) -> Vec<f64> {
        let n = x.len();
        let mut out = crate::samples::filled(n);
        let full = 2 * half + 1;
        if n <= full {
            for (i, o) in out.iter_mut().enumerate() {
                *o = x[i] - self.mean(i, half);
            }
            return out;
        }
        let inv = 1.0 / full as f64;
        let (s, len) = (&self.0, n - 2 * half);
        let (hi, lo) = (&s[full..full + len], &s[..len]);
        let (xs, o) = (&x[half..half + len], &mut out[half..half + len]);
        for k in 0..len {
            o[k] = xs[k] - (hi[k] - lo[k]) * inv;
        }
        for i in (0..half).chain(n - half..n) {
            out[i] = x[i] - self.mean(i, half);
        }
        out
    }

    /// Returns the buffer to the pool.
    pub fn recycle(self) {
        crate::samples::recycle(self.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Means and high-pass values agree with direct sums over each window.
        #[test]
        fn means_match_direct_sums(
            x in proptest::collection::vec(-10.0..10.0f64, 1..400), half in 0usize..40,
        ) {
            let p = PrefixSums::new(&x);
            let hp = p.high_pass(&x, half);
            for i in 0..x.len() {
                let (a, b) = (i.saturating_sub(half), (i + half + 1).min(x.len()));
                let direct = x[a..b].iter().sum::<f64>() / (b - a) as f64;
                prop_assert!((p.mean(i, half) - direct).abs() < 1e-12);
                prop_assert!((hp[i] - (x[i] - direct)).abs() < 1e-12);
            }
        }
    }
}
