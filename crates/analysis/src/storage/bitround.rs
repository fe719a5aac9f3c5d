//! Rounding recorded values to fewer mantissa bits, so that the file's compression can take
//! what is left ("bit rounding", `output.significant_bits`).
//!
//! A double is $x = \pm (1 + m / 2^{52})\, 2^e$ with a 52-bit mantissa $m$. Keeping $b$ bits
//! rounds $x$ to the nearest double whose $52 - b$ low mantissa bits are zero, ties to the one
//! whose kept part is even, which is IEEE 754's rounding applied at bit $b$:
//!
//! $$ |\mathrm{round}_b(x) - x| \le 2^{-(b+1)}\, 2^e \le 2^{-(b+1)} |x| . $$
//!
//! On the bit pattern $u$ of $x$, with $d = 52 - b$ dropped bits, this is
//! $(u + 2^{d-1} - 1 + \mathrm{bit}_d(u))\ \&\ \lnot(2^d - 1)$: a carry out of the mantissa raises
//! the exponent, which is the correct rounding up to the next power of two. The zeroed low
//! bytes are then all alike, and the shuffle filter followed by deflate (the file's own chain)
//! stores them in almost nothing; a reader needs no filter of its own, the values are plain
//! doubles.
//!
//! This is the BitRound of Klöwer, Razinger, Dominguez, Düben and Palmer, "Compressing
//! atmospheric data into its real information content", Nature Computational Science 1,
//! 713–724 (2021), also netCDF-C's `nc_def_var_quantize` (`NC_QUANTIZE_BITROUND`). Hand-written:
//! it is four integer operations per value, and the crates that provide it bring a codec
//! framework with them.
//!
//! Values that are not finite are left as they are (a NaN's payload could round to an
//! infinity), and so is a value whose rounding would overflow to infinity. Subnormal values keep
//! the same absolute bound, $2^{-(b+1)}\, 2^{-1022}$.

/// Rounds every value of `values` to `bits` mantissa bits (1 to 52; 52 leaves them as they are),
/// to nearest, ties to even.
pub fn round(values: &mut [f64], bits: u32) {
    assert!(
        (1..=52).contains(&bits),
        "mantissa bits {bits} not in 1..=52"
    );
    let drop = 52 - bits;
    if drop == 0 {
        return;
    }
    let half = (1u64 << (drop - 1)) - 1;
    let keep = !((1u64 << drop) - 1);
    for v in values.iter_mut() {
        if !v.is_finite() {
            continue;
        }
        let u = v.to_bits();
        let r = f64::from_bits((u + half + ((u >> drop) & 1)) & keep);
        if r.is_finite() {
            *v = r;
        }
    }
}

/// `values` rounded to `bits` mantissa bits by [`round`], copied; `None` (every bit kept) lends
/// them as they are.
pub fn rounded(values: &[f64], bits: Option<u32>) -> std::borrow::Cow<'_, [f64]> {
    match bits {
        Some(b) => {
            let mut v = values.to_vec();
            round(&mut v, b);
            std::borrow::Cow::Owned(v)
        }
        None => std::borrow::Cow::Borrowed(values),
    }
}

/// The bound on the relative error [`round`] makes on a normal double with `bits` mantissa bits,
/// $2^{-(b+1)}$ (a subnormal has the absolute bound $2^{-(b+1)}\, 2^{-1022}$ instead).
pub fn relative_bound(bits: u32) -> f64 {
    0.5f64.powi(bits as i32 + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The oracle: the nearest double with `bits` mantissa bits by floating-point arithmetic.
    /// With $2^e \le |x| < 2^{e+1}$ and $s = 2^{e-b}$, $x / s$ lies in $[2^b, 2^{b+1})$ and is
    /// exact (a power-of-two scaling of a normal double), `round_ties_even` is exact, and so is
    /// the product by $s$.
    fn nearest(x: f64, bits: u32) -> f64 {
        let e = ((x.to_bits() >> 52) & 0x7ff) as i32 - 1023;
        let s = 2f64.powi(e - bits as i32);
        (x / s).round_ties_even() * s
    }

    /// A deterministic stream of bit patterns (splitmix64).
    fn patterns(n: usize) -> impl Iterator<Item = u64> {
        let mut z = 0x9e37_79b9_7f4a_7c15u64;
        (0..n).map(move |_| {
            z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut x = z;
            x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            x ^ (x >> 31)
        })
    }

    #[test]
    fn rounds_to_the_nearest_double_with_that_many_bits_ties_to_even() {
        // Normal doubles of every exponent from 2^-60 to 2^60, both signs, random mantissas,
        // and for each bit count the halfway cases (exactly one dropped half) of both parities.
        for bits in [1, 2, 7, 10, 23, 30, 36, 51] {
            let drop = 52 - bits;
            let mut xs = Vec::new();
            for (k, p) in patterns(20_000).enumerate() {
                let exp = 1023 - 60 + (k as u64 % 121);
                let sign = (p >> 63) << 63;
                let mantissa = p & ((1u64 << 52) - 1);
                xs.push(f64::from_bits(sign | (exp << 52) | mantissa));
                let tie = (mantissa & !((1u64 << drop) - 1)) | (1u64 << (drop - 1));
                xs.push(f64::from_bits(sign | (exp << 52) | tie));
            }
            let mut rounded = xs.clone();
            round(&mut rounded, bits);
            for (&x, &r) in xs.iter().zip(&rounded) {
                assert_eq!(
                    r.to_bits(),
                    nearest(x, bits).to_bits(),
                    "{x:e} at {bits} bits"
                );
                // The bound of the module documentation, exactly (no tolerance: both sides are
                // exact doubles and the difference of two doubles this close is exact).
                assert!((r - x).abs() <= relative_bound(bits) * x.abs(), "{x:e}");
                assert_eq!(r.to_bits() & ((1u64 << drop) - 1), 0);
            }
        }
    }

    /// A second oracle, on the integer magnitude: quotient and remainder by the dropped bits'
    /// weight, rounded up past half or at half with an odd quotient. It covers what the
    /// floating-point oracle cannot: subnormals, zero and the binade below `f64::MAX`.
    fn nearest_magnitude(x: f64, bits: u32) -> f64 {
        let d = 52 - bits;
        let sign = x.to_bits() & (1 << 63);
        let m = x.to_bits() & !(1 << 63);
        let (mut q, r, half) = (m >> d, m & ((1 << d) - 1), 1u64 << (d - 1));
        if r > half || (r == half && q & 1 == 1) {
            q += 1;
        }
        let y = f64::from_bits(sign | (q << d));
        if y.is_finite() { y } else { x }
    }

    #[test]
    fn subnormals_and_the_largest_doubles_round_as_their_integer_magnitudes_do() {
        for bits in [1, 5, 20, 36, 51] {
            let mut xs = Vec::new();
            for p in patterns(20_000) {
                let sign = (p >> 63) << 63;
                // Subnormal, smallest normal binades and the top binade (biased exponent 2046).
                for exp in [0u64, 1, 2, 2045, 2046] {
                    xs.push(f64::from_bits(sign | (exp << 52) | (p & ((1 << 52) - 1))));
                }
            }
            xs.extend([f64::MAX, -f64::MAX, f64::MIN_POSITIVE, -0.0, 0.0]);
            let mut rounded = xs.clone();
            round(&mut rounded, bits);
            for (&x, &r) in xs.iter().zip(&rounded) {
                let want = nearest_magnitude(x, bits);
                assert_eq!(r.to_bits(), want.to_bits(), "{x:e} at {bits} bits");
                assert!(r.is_finite());
            }
        }
    }

    #[test]
    fn all_bits_zero_and_the_values_that_cannot_be_rounded_are_left_alone() {
        let mut v = vec![0.1, -0.0, 0.0, f64::NAN, f64::INFINITY, f64::MAX, 1e-310];
        let before = v.clone();
        round(&mut v, 52);
        assert_eq!(
            v.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            before.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
        round(&mut v, 10);
        assert_eq!(v[0], nearest(0.1, 10));
        assert_eq!(v[1].to_bits(), (-0.0f64).to_bits());
        assert_eq!(v[2].to_bits(), 0);
        assert!(v[3].is_nan());
        assert_eq!(v[4], f64::INFINITY);
        // f64::MAX would round up to infinity: kept.
        assert_eq!(v[5], f64::MAX);
        // A subnormal keeps the absolute bound of the smallest normal binade.
        assert!((v[6] - 1e-310).abs() <= relative_bound(10) * f64::MIN_POSITIVE);
        // A carry out of the mantissa gives the next power of two.
        let mut w = [f64::from_bits(0x3fff_ffff_ffff_ffff)];
        round(&mut w, 20);
        assert_eq!(w[0], 2.0);
    }
}
