//! `exp` inline: the LuGre step takes one or two per contact, and the library call (with its
//! register spills) was a third of the drive's step.
//!
//! The usual table-driven method (Tang, ACM TOMS 15(2), 1989): `x = (32m + j)·ln2/32 + r` with
//! `|r| <= ln2/64`, so `exp(x) = 2^m · 2^(j/32) · exp(r)`. `2^(j/32) = S_j (1 + t_j)` is
//! tabulated as the nearest double `S_j` and its relative remainder `t_j`; `exp(r) - 1` is its
//! Taylor polynomial of degree 6 (remainder below `r^7/7! < 4e-18`). `ln2/32` is split in a
//! 29-bit head, whose multiples by `k` are exact, and a tail. Below `2^-20` in magnitude (a third
//! of the calls: the bristles of an axis at rest) `1 + x + x²/2` is as exact. The result is
//! within 0.52 ulp of `e^x`, as the library's is: the two differ by at most one ulp, in few
//! cases (tested).

/// `[t_j, S_j]` as bits, `S_j` less `j·2^47` so that adding `k·2^47` (k = 32m + j) puts the
/// exponent `m` in, `j` = 0..32. Computed with 60 significant digits.
const TABLE: [[u64; 2]; 32] = [
    [0x0000000000000000, 0x3ff0000000000000],
    [0x3c8cd2523567f613, 0x3fefd9b0d3158574],
    [0x3c979aa65d837b6d, 0x3fefb5586cf9890f],
    [0xbc9556522a2fbd0e, 0x3fef9301d0125b51],
    [0xbc801b15eaa59348, 0x3fef72b83c7d517b],
    [0x3c9aecf73e3a2f60, 0x3fef54873168b9aa],
    [0x3c968efde3a8a894, 0x3fef387a6e756238],
    [0x3c82f7e16d09ab31, 0x3fef1e9df51fdee1],
    [0x3c834d754db0abb6, 0x3fef06fe0a31b715],
    [0xbc924aedcc4b5068, 0x3feef1a7373aa9cb],
    [0x3c859f48a72a4c6d, 0x3feedea64c123422],
    [0x3c4363ed60c2ac11, 0x3feece086061892d],
    [0x3c7690cebb7aafb0, 0x3feebfdad5362a27],
    [0xbc78dec6bd0f385f, 0x3feeb42b569d4f82],
    [0x3c9063e1e21c5409, 0x3feeab07dd485429],
    [0xbc8c33c53bef4da8, 0x3feea47eb03a5585],
    [0xbc93b3efbf5e2228, 0x3feea09e667f3bcd],
    [0xbc781f647e5a3ecf, 0x3fee9f75e8ec5f74],
    [0xbc7b32dcb94da51d, 0x3feea11473eb0187],
    [0xbc9369b6f13b3734, 0x3feea589994cce13],
    [0x3c8db72fc1f0eab4, 0x3feeace5422aa0db],
    [0xbc5da9b88b6c1e29, 0x3feeb737b0cdc5e5],
    [0x3c71affc2b91ce27, 0x3feec49182a3f090],
    [0xbc91bbd1d3bcbb15, 0x3feed503b23e255d],
    [0x3c8c1a7792cb3387, 0x3feee89f995ad3ad],
    [0xbc68d6f438ad9334, 0x3feeff76f2fb5e47],
    [0x3c736eae30af0cb3, 0x3fef199bdd85529c],
    [0x3c676b2c6c921968, 0x3fef3720dcef9069],
    [0x3c74a385a63d07a7, 0x3fef5818dcfba487],
    [0xbc82d52107b43e1f, 0x3fef7c97337b9b5f],
    [0xbc8ff7128fd391f0, 0x3fefa4afa2a490da],
    [0x3c8a64a931d185ee, 0x3fefd0765b6e4540],
];
/// `32/ln2`.
const INV_LN2_32: f64 = f64::from_bits(0x40471547652b82fe);
/// `ln2/32` in a head of 29 significant bits and the tail.
const LN2_32_HI: f64 = f64::from_bits(0x3f962e42ff000000);
const LN2_32_LO: f64 = f64::from_bits(0xbd7718432a1b0e26);
/// `2^-20`: below it the Taylor polynomial of degree 2 is exact to the rounding.
const SMALL: f64 = 1.0 / 1_048_576.0;
/// `1.5·2^52`: adding it rounds to an integer, which the low bits of the sum then hold.
const SHIFT: f64 = 6755399441055744.0;

/// `e^x`. Outside ±700 (where `2^m` would leave the normal range) the library computes it.
#[inline]
pub(crate) fn exp(x: f64) -> f64 {
    if x.abs() < SMALL {
        // A third of the LuGre exponents (axes at rest): x³/6 < 2^-62 is below the rounding.
        return 1.0 + x * (1.0 + 0.5 * x);
    }
    if x.is_nan() || x.abs() > 700.0 {
        return x.exp();
    }
    let shifted = x * INV_LN2_32 + SHIFT;
    let k = shifted.to_bits();
    let kd = shifted - SHIFT;
    let r = (x - kd * LN2_32_HI) - kd * LN2_32_LO;
    let [tail, head] = TABLE[(k % 32) as usize];
    let scale = f64::from_bits(head.wrapping_add(k << 47));
    let r2 = r * r;
    let poly = r
        + r2 * (1.0 / 2.0 + r * (1.0 / 6.0))
        + r2 * r2 * (1.0 / 24.0 + r * (1.0 / 120.0) + r2 * (1.0 / 720.0));
    scale + scale * (f64::from_bits(tail) + poly)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in ulps between two positive doubles.
    fn ulps(a: f64, b: f64) -> u64 {
        a.to_bits().abs_diff(b.to_bits())
    }

    #[test]
    fn within_one_ulp_of_the_library() {
        let mut worst = 0;
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        for i in 0..2_000_000 {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            let u = (seed >> 11) as f64 / (1u64 << 53) as f64;
            // Uniform over the range, and log-uniform near 0 (the LuGre exponents).
            let x = if i % 2 == 0 {
                1400.0 * u - 700.0
            } else {
                -(10f64).powf(-20.0 + 23.0 * u)
            };
            worst = worst.max(ulps(exp(x), x.exp()));
        }
        assert!(worst <= 1, "{worst} ulps");
    }

    #[test]
    fn exact_where_the_library_is_and_outside_the_range() {
        for x in [
            0.0,
            -0.0,
            1e-300,
            -1e-300,
            -800.0,
            710.0,
            f64::NEG_INFINITY,
            f64::INFINITY,
        ] {
            assert_eq!(exp(x), x.exp(), "{x}");
        }
        assert!(exp(f64::NAN).is_nan());
        // The table: S_j is the double nearest 2^(j/32).
        for (j, [_, head]) in TABLE.iter().enumerate() {
            let s = f64::from_bits(head.wrapping_add((j as u64) << 47));
            assert!(ulps(s, (j as f64 / 32.0).exp2()) == 0, "{j}");
        }
    }
}
