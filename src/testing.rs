//! Fixtures shared by the unit tests: deterministic noise, no crate and no OS entropy.

/// `n` samples of unit-variance noise, close enough to Gaussian (the sum of 12 uniforms less
/// 6) from an LCG seeded with `seed`.
pub(crate) fn gaussian(n: usize, seed: u64) -> Vec<f64> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            (0..12)
                .map(|_| {
                    s = s
                        .wrapping_mul(6_364_136_223_846_793_005)
                        .wrapping_add(1_442_695_040_888_963_407);
                    (s >> 11) as f64 / (1u64 << 53) as f64
                })
                .sum::<f64>()
                - 6.0
        })
        .collect()
}
