//! A deterministic, portable pseudo-random number generator for the seeded FMUs (docs/README.md §2,
//! "seeded randomness (parameter `seed`) so runs are reproducible").
//!
//! # Algorithm
//!
//! The generator is **xoshiro256\*\*** 1.0 (Blackman & Vigna, 2018), a 256-bit state
//! `s = [s0, s1, s2, s3]` of `u64` words advanced with wrapping 64-bit arithmetic:
//!
//! ```text
//! output = rotl(s1 · 5, 7) · 9
//! t  = s1 << 17
//! s2 ^= s0;  s3 ^= s1;  s1 ^= s2;  s0 ^= s3;  s2 ^= t;  s3 = rotl(s3, 45)
//! ```
//!
//! A `u64` seed is expanded into the four state words by four successive outputs of
//! **SplitMix64** (Steele, Lea & Flood, 2014) started at the seed:
//!
//! ```text
//! z = (x += 0x9E3779B97F4A7C15)
//! z = (z ^ (z >> 30)) · 0xBF58476D1CE4E5B9
//! z = (z ^ (z >> 27)) · 0x94D049BB133111EB
//! output = z ^ (z >> 31)
//! ```
//!
//! so every seed (including 0) gives a valid, non-zero state.
//!
//! # Derived distributions
//!
//! * `uniform()` = `(next_u64() >> 11) · 2⁻⁵³`: the 53 high bits as a double in `[0, 1)`.
//! * `uniform_range(a, b)` = `a + (b − a) · uniform()`.
//! * `gaussian()`: the Marsaglia **polar method**. Draw `v1 = 2 uniform() − 1`,
//!   `v2 = 2 uniform() − 1` until `0 < s = v1² + v2² < 1`, then return
//!   `v1 · √(−2 ln s / s)`. The second deviate of the pair (`v2 · …`) is discarded so that the
//!   whole generator state is the four `u64` words (nothing cached). The draw is split in
//!   two: [`RandomGenerator::polar_point`] consumes the uniforms and returns the accepted
//!   `(v1, s)`, [`PolarPoint::deviate`] is the transform, a pure function of it. So several
//!   deviates (of one stream or of several) may draw their points first and transform them
//!   together ([`deviates_into`]): the same numbers bit for bit, with the independent
//!   logarithms side by side instead of one after the other.
//!
//! # Portability
//!
//! The integer part is exact everywhere. The floating-point part uses only IEEE-754 basic
//! operations (`+ − × ÷ √`, all correctly rounded, and Rust never contracts them into fused
//! multiply–adds) and a logarithm implemented here with those operations ([`portable_ln`])
//! instead of the platform's `libm`, whose last bit may differ between systems. Hence the
//! same seed gives bit-identical samples on every platform.
//!
//! # Saving and restoring
//!
//! [`RandomGenerator::state`] returns the four state words and
//! [`RandomGenerator::from_state`] rebuilds a generator that continues bit-for-bit, which is
//! what an FMU needs for `fmi2GetFMUstate`/`fmi2SetFMUstate` or serialisation.

use crate::ParameterError;

/// SplitMix64 increment (the golden ratio in 64-bit fixed point).
const SPLITMIX_INCREMENT: u64 = 0x9E37_79B9_7F4A_7C15;

/// One SplitMix64 step: advances `x` and returns the next output.
pub fn splitmix64(x: &mut u64) -> u64 {
    *x = x.wrapping_add(SPLITMIX_INCREMENT);
    let mut z = *x;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Natural logarithm of a positive, finite, normal `x` with only IEEE-754 basic operations,
/// so that it is bit-identical on every platform (accurate to a few units in the last place).
///
/// `x = m · 2^e` with `m ∈ [√½, √2)`, then `ln x = e ln 2 + 2 atanh(u)`, `u = (m − 1)/(m + 1)`
/// (`|u| ≤ 0.1716`), with the odd series `atanh u = u + u³/3 + u⁵/5 + …` summed to `u²⁷`
/// (truncation below 10⁻¹⁹ relative). `ln 2` is split into a high part exact in 32 bits and a
/// low correction. Returns NaN for `x ≤ 0`, non-finite or subnormal `x` (never reached by
/// [`RandomGenerator::gaussian`], whose argument is at least 2⁻¹⁰⁴).
pub fn portable_ln(x: f64) -> f64 {
    if !(x.is_finite() && x >= f64::MIN_POSITIVE) {
        return f64::NAN;
    }
    ln_normal(x)
}

/// [`portable_ln`] of a positive, finite, normal `x`, without the check (the caller
/// guarantees the range), so that a batch of them is straight-line code.
#[inline(always)]
fn ln_normal(x: f64) -> f64 {
    const LN2_HIGH: f64 = 0.693_147_180_369_123_8; // 0x3FE62E42FEE00000
    const LN2_LOW: f64 = 1.908_214_929_270_587_7e-10; // ln 2 − LN2_HIGH
    let bits = x.to_bits();
    let mut exponent = ((bits >> 52) & 0x7FF) as i64 - 1023;
    // Mantissa in [1, 2).
    let mut mantissa = f64::from_bits((bits & 0x000F_FFFF_FFFF_FFFF) | 0x3FF0_0000_0000_0000);
    if mantissa >= std::f64::consts::SQRT_2 {
        mantissa *= 0.5;
        exponent += 1;
    }
    let u = (mantissa - 1.0) / (mantissa + 1.0);
    let u2 = u * u;
    // Horner form of 1 + u²/3 + u⁴/5 + … + u²⁶/27.
    let mut series = 1.0 / 27.0;
    let mut k = 25.0;
    while k >= 1.0 {
        series = series * u2 + 1.0 / k;
        k -= 2.0;
    }
    let e = exponent as f64;
    e * LN2_HIGH + (2.0 * u * series + e * LN2_LOW)
}

/// xoshiro256\*\* seeded by SplitMix64: see the module documentation for the exact
/// algorithm. Clone it to save it; [`Self::state`]/[`Self::from_state`] to serialise it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RandomGenerator {
    state: [u64; 4],
}

impl RandomGenerator {
    /// A generator whose state is four successive SplitMix64 outputs started at `seed`.
    pub fn new(seed: u64) -> Self {
        let mut x = seed;
        let state = [
            splitmix64(&mut x),
            splitmix64(&mut x),
            splitmix64(&mut x),
            splitmix64(&mut x),
        ];
        Self { state }
    }

    /// An independent generator for sub-stream `stream` of `seed` (e.g. one per sensor
    /// channel, or the noise and the outliers of one channel): seeded with
    /// `splitmix64` applied to `seed ^ splitmix64(stream)`, so streams of the same seed
    /// (and equal streams of different seeds) start from unrelated states.
    pub fn for_stream(seed: u64, stream: u64) -> Self {
        let mut s = stream;
        let mixed_stream = splitmix64(&mut s);
        Self::new(seed ^ mixed_stream)
    }

    /// Rebuilds a generator from a saved [`Self::state`]. The all-zero state (which
    /// xoshiro can never leave, and no seed produces) is rejected as parameter `rng_state`.
    pub fn from_state(state: [u64; 4]) -> Result<Self, ParameterError> {
        if state == [0; 4] {
            return Err(ParameterError::new(
                "rng_state",
                "the all-zero xoshiro256** state is not valid",
            ));
        }
        Ok(Self { state })
    }

    /// The four state words, for saving; [`Self::from_state`] restores them.
    pub fn state(&self) -> [u64; 4] {
        self.state
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        let s = &mut self.state;
        let result = s[1].wrapping_mul(5).rotate_left(7).wrapping_mul(9);
        let t = s[1] << 17;
        s[2] ^= s[0];
        s[3] ^= s[1];
        s[1] ^= s[2];
        s[0] ^= s[3];
        s[2] ^= t;
        s[3] = s[3].rotate_left(45);
        result
    }

    /// A uniform double in `[0, 1)`: the 53 high bits of [`Self::next_u64`] times 2⁻⁵³.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// A uniform double in `[a, b)` (or `(b, a]` if `b < a`): `a + (b − a) · uniform()`.
    pub fn uniform_range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.uniform()
    }

    /// A standard normal deviate N(0, 1) by the Marsaglia polar method (module docs): the
    /// deviate of the next [`Self::polar_point`].
    pub fn gaussian(&mut self) -> f64 {
        self.polar_point().deviate()
    }

    /// The uniforms of the next Gaussian deviate (module docs): pairs `v1 = 2 uniform() − 1`,
    /// `v2 = 2 uniform() − 1` until `0 < s = v1² + v2² < 1`; the accepted `(v1, s)`.
    #[inline]
    pub fn polar_point(&mut self) -> PolarPoint {
        loop {
            let v1 = self.signed_uniform();
            let v2 = self.signed_uniform();
            let s = v1 * v1 + v2 * v2;
            if s > 0.0 && s < 1.0 {
                return PolarPoint { v1, s };
            }
        }
    }

    /// `2 uniform() − 1` in one multiplication: with `k` the 53 high bits,
    /// `2 · (k · 2⁻⁵³) = k · 2⁻⁵²` exactly (scalings by powers of two), so `k · 2⁻⁵² − 1` is
    /// the same number, bit for bit.
    #[inline(always)]
    fn signed_uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 52) as f64) - 1.0
    }
}

/// An accepted point of the polar method: `v1` and `s = v1² + v2² ∈ (0, 1)`, from
/// [`RandomGenerator::polar_point`] (the only way to make one, so `s` is in range).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PolarPoint {
    v1: f64,
    s: f64,
}

impl PolarPoint {
    /// The standard normal deviate `v1 · √(−2 ln s / s)` (with [`portable_ln`]).
    ///
    /// `s` is a sum of squares of multiples of 2⁻⁵² in `(0, 1)`, so at least 2⁻¹⁰⁴: a
    /// normal number, for which [`portable_ln`]'s check is always passed and is left out.
    #[inline(always)]
    pub fn deviate(self) -> f64 {
        self.v1 * (-2.0 * ln_normal(self.s) / self.s).sqrt()
    }
}

/// `out[i] = points[i].deviate()`, bit for bit, for as many entries as both have: the
/// transforms of points drawn beforehand, one loop of straight-line code (no call, no
/// branch), so the independent logarithms overlap (and are vectorised where the target
/// allows) instead of running one after the other.
#[inline]
pub fn deviates_into(points: &[PolarPoint], out: &mut [f64]) {
    for (z, point) in out.iter_mut().zip(points) {
        *z = point.deviate();
    }
}

// FMU-state snapshots (plain bytes) of the types above: every field, in order.
crate::plain_state!(RandomGenerator { state });

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitmix64_matches_the_reference_output() {
        // First output of the reference splitmix64.c from x = 0.
        let mut x = 0u64;
        assert_eq!(splitmix64(&mut x), 0xE220_A839_7B1D_CDAF);
        assert_eq!(splitmix64(&mut x), 0x6E78_9E6A_A1B9_65F4);
    }

    #[test]
    fn xoshiro256starstar_matches_the_reference_outputs() {
        // Reference xoshiro256starstar.c started at s = {1, 2, 3, 4}.
        let mut g = RandomGenerator::from_state([1, 2, 3, 4]).unwrap();
        let expected: [u64; 10] = [
            11520,
            0,
            1509978240,
            1215971899390074240,
            1216172134540287360,
            607988272756665600,
            16172922978634559625,
            8476171486693032832,
            10595114339597558777,
            2904607092377533576,
        ];
        for want in expected {
            assert_eq!(g.next_u64(), want);
        }
    }

    #[test]
    fn seeding_uses_splitmix64() {
        let g = RandomGenerator::new(0);
        let mut x = 0;
        let want = [
            splitmix64(&mut x),
            splitmix64(&mut x),
            splitmix64(&mut x),
            splitmix64(&mut x),
        ];
        assert_eq!(g.state(), want);
        assert_eq!(want[0], 0xE220_A839_7B1D_CDAF);
    }

    #[test]
    fn same_seed_same_samples_and_state_restores_bit_for_bit() {
        let mut a = RandomGenerator::new(42);
        let mut b = RandomGenerator::new(42);
        for _ in 0..100 {
            assert_eq!(a.gaussian().to_bits(), b.gaussian().to_bits());
        }
        let saved = a.state();
        let next: Vec<u64> = (0..10).map(|_| a.next_u64()).collect();
        let mut restored = RandomGenerator::from_state(saved).unwrap();
        let again: Vec<u64> = (0..10).map(|_| restored.next_u64()).collect();
        assert_eq!(next, again);
        assert_ne!(
            RandomGenerator::new(43).next_u64(),
            RandomGenerator::new(42).next_u64()
        );
        assert_ne!(
            RandomGenerator::for_stream(42, 0).state(),
            RandomGenerator::for_stream(42, 1).state()
        );
    }

    #[test]
    fn all_zero_state_is_rejected() {
        assert_eq!(
            RandomGenerator::from_state([0; 4]).unwrap_err().parameter,
            "rng_state"
        );
    }

    #[test]
    fn portable_ln_matches_the_platform_logarithm() {
        let mut g = RandomGenerator::new(7);
        for _ in 0..10_000 {
            let x = g.uniform() * 1e3 + 1e-300;
            let rel = (portable_ln(x) - x.ln()).abs() / x.ln().abs().max(1e-300);
            assert!(
                rel < 4e-16 || (portable_ln(x) - x.ln()).abs() < 4e-16,
                "x = {x}"
            );
        }
        assert_eq!(portable_ln(1.0), 0.0);
        assert!((portable_ln(2f64.powi(-104)) - 2f64.powi(-104).ln()).abs() < 1e-13);
        assert!(portable_ln(0.0).is_nan());
        assert!(portable_ln(-1.0).is_nan());
    }

    #[test]
    fn uniform_and_gaussian_statistics_are_sane() {
        let mut g = RandomGenerator::new(2024);
        let n = 200_000;
        let (mut sum, mut sum2) = (0.0, 0.0);
        for _ in 0..n {
            let u = g.uniform();
            assert!((0.0..1.0).contains(&u));
            sum += u;
            sum2 += u * u;
        }
        let mean = sum / n as f64;
        let var = sum2 / n as f64 - mean * mean;
        // σ of the mean: √(1/12/n) ≈ 6.5e-4; of the variance ≈ 2e-4.
        assert!((mean - 0.5).abs() < 4.0 * 6.5e-4, "uniform mean {mean}");
        assert!(
            (var - 1.0 / 12.0).abs() < 4.0 * 2e-4,
            "uniform variance {var}"
        );

        let (mut sum, mut sum2, mut sum4) = (0.0, 0.0, 0.0);
        for _ in 0..n {
            let z = g.gaussian();
            sum += z;
            sum2 += z * z;
            sum4 += z * z * z * z;
        }
        let mean = sum / n as f64;
        let var = sum2 / n as f64 - mean * mean;
        let kurtosis = sum4 / n as f64 / (var * var);
        assert!(mean.abs() < 4.0 / (n as f64).sqrt(), "gaussian mean {mean}");
        assert!(
            (var - 1.0).abs() < 4.0 * (2.0 / n as f64).sqrt(),
            "variance {var}"
        );
        assert!(
            (kurtosis - 3.0).abs() < 4.0 * (24.0 / n as f64).sqrt(),
            "{kurtosis}"
        );
        let r = g.uniform_range(-2.0, 3.0);
        assert!((-2.0..3.0).contains(&r));
    }
    /// The polar method as one loop, with the checked logarithm (the former `gaussian`).
    fn reference_gaussian(g: &mut RandomGenerator) -> f64 {
        loop {
            let v1 = 2.0 * g.uniform() - 1.0;
            let v2 = 2.0 * g.uniform() - 1.0;
            let s = v1 * v1 + v2 * v2;
            if s > 0.0 && s < 1.0 {
                return v1 * (-2.0 * portable_ln(s) / s).sqrt();
            }
        }
    }

    #[test]
    fn batched_deviates_are_the_gaussians_bit_for_bit() {
        // Points of two streams drawn first and transformed together give, stream by stream,
        // the deviates of the polar method drawn one after another; so does gaussian().
        let (mut a, mut b) = (RandomGenerator::new(11), RandomGenerator::for_stream(11, 1));
        let (mut a_ref, mut b_ref) = (a.clone(), b.clone());
        let mut single = RandomGenerator::new(12);
        let mut single_ref = single.clone();
        let mut points = [PolarPoint::default(); 7];
        let mut out = [0.0; 7];
        for _ in 0..20_000 {
            for (k, point) in points.iter_mut().enumerate() {
                *point = if k < 4 {
                    a.polar_point()
                } else {
                    b.polar_point()
                };
            }
            deviates_into(&points, &mut out);
            for (k, z) in out.iter().enumerate() {
                let want = if k < 4 {
                    reference_gaussian(&mut a_ref)
                } else {
                    reference_gaussian(&mut b_ref)
                };
                assert_eq!(z.to_bits(), want.to_bits());
            }
            let want = reference_gaussian(&mut single_ref);
            assert_eq!(single.gaussian().to_bits(), want.to_bits());
        }
        assert_eq!((a, b), (a_ref, b_ref));
    }

    #[test]
    fn gaussian_samples_are_pinned_bit_for_bit() {
        // Recorded once; any platform or refactoring that changes a bit fails here.
        let mut g = RandomGenerator::new(1);
        let pinned: [u64; 3] = [0x3ffe267c87ac62eb, 0x3ff4d55c9633557c, 0x3fdc0d732ae4b3dd];
        for want in pinned {
            assert_eq!(g.gaussian().to_bits(), want);
        }
        let mut g = RandomGenerator::new(1);
        assert_eq!(g.next_u64(), 0xb3f2af6d0fc710c5);
        assert_eq!(g.next_u64(), 0x853b559647364cea);
    }
}
