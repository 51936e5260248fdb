// Hand-written, not generated: fixed-point sections and an input that drive the board's
// fixed-point kernel through every path (states and outputs saturating, output shifts below
// and above 32 bits), for examples/board_replay.rs and host-tests/firmware.rs, which must agree
// bit for bit and on every overflow flag.
/// Sections: a slow rotation whose states saturate, a triangular pair with output gain 2
/// (outputs saturate), a fast rotation with a 45-bit output shift, a rotation with a 34-bit output shift.
pub const STRESS_SECTIONS: [unlag::board::fixed::FixedSection; 4] = [
    unlag::board::fixed::FixedSection {
        a: [1_071_327_526, -53_611_060, 53_611_060, 1_071_327_526], // r 0.999, theta 0.05
        b: [1 << 24, 1 << 23],
        c: [1 << 28, 1 << 28],
        d: 1 << 28,
        shift: 30,
    },
    unlag::board::fixed::FixedSection {
        a: [966_367_642, 0, 536_870_912, -751_619_277], // p1 0.9, g 0.5, p2 -0.7
        b: [1 << 29, 0],
        c: [1 << 30, 1 << 30],
        d: 1 << 30,
        shift: 29,
    },
    unlag::board::fixed::FixedSection {
        a: [-516_132_844, -385_562_743, 385_562_743, -516_132_844], // r 0.6, theta 2.5
        b: [1 << 29, 1 << 29],
        c: [1 << 30, -(1 << 30)],
        d: 1 << 29,
        shift: 45,
    },
    unlag::board::fixed::FixedSection {
        a: [923_206_270, -285_581_165, 285_581_165, 923_206_270], // r 0.9, theta 0.3
        b: [1 << 30, 0],
        c: [1 << 30, 1 << 30],
        d: 1 << 30,
        shift: 34,
    },
];

/// Samples in the stress input.
pub const STRESS_LEN: usize = 4096;

/// Sample `k` of the stress input: runs of full scale (both signs) between stretches of
/// pseudo-random codes of every size, and zeros.
pub const fn stress_input(k: usize) -> i32 {
    // A 32-bit LCG of k (Numerical Recipes constants), shifted by a varying amount.
    let r = (k as u32).wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
    let r = r ^ (r >> 15);
    match (k / 256) % 4 {
        0 => {
            if (k / 64).is_multiple_of(2) {
                i32::MAX
            } else {
                i32::MIN
            }
        }
        1 => (r as i32) >> (k % 24),
        2 => 0,
        _ => r as i32,
    }
}

/// Direct-form sections for the same stress input (hand-written): a slow resonance (r 0.999,
/// theta 0.05, unit DC gain), a resonance with DC gain 3 (outputs saturate), a fast one
/// (r 0.6, theta 2.5), a slow one at half gain.
pub const DIRECT_STRESS_SECTIONS: [unlag::board::fixed::direct::DirectSection; 4] = [
    unlag::board::fixed::direct::DirectSection {
        b: [670_546, 1_341_093, 670_546],
        neg_a: [2_142_655_053, -1_071_595_414],
    },
    unlag::board::fixed::direct::DirectSection {
        b: [72_795_121, 145_590_242, 72_795_121],
        neg_a: [1_846_412_540, -869_730_877],
    },
    unlag::board::fixed::direct::DirectSection {
        b: [467_353_982, 934_707_963, 467_353_982],
        neg_a: [-1_032_265_688, -386_547_057],
    },
    unlag::board::fixed::direct::DirectSection {
        b: [386_545, 773_091, 386_545],
        neg_a: [2_039_701_457, -969_051_996],
    },
];
