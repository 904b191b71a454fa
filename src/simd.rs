//! Four f64 lanes for the hot loops (the QDEM element kernel, the NLGS sweep), with two
//! implementations chosen once per process:
//! - [`avx::Avx4`]: one AVX2 register, products fused (FMA), on x86-64 CPUs that have
//!   AVX2 and FMA (2013 on);
//! - [`Portable4`]: plain arrays, unfused, on any CPU, or when the environment variable
//!   [`KERNEL_ENV`] is `portable` (the baseline of `make bench`).
//!
//! The two differ in the last bits (fused against unfused rounding), so a process always
//! takes one path: on one machine, results are bitwise the same for any thread count.
//!
//! Code generic over [`F64x4`] is instantiated inside a function compiled with
//! `#[target_feature(enable = "avx2,fma")]`; it must keep closures and array `map`s off
//! its hot path, because those are compiled as functions of their own without the
//! target features, and the intrinsics inside them would stay calls (the first QDEM
//! kernel written that way ran 9× slower).

use std::ops::{Add, Div, Mul, Sub};

/// Environment variable that forces a kernel path: `portable` (the baseline of
/// `make bench`) or `auto` (the default: the fastest the CPU has).
pub const KERNEL_ENV: &str = "BALLAST_KERNEL";

/// The path [`KERNEL_ENV`] asks for (`None` when unset or `auto`); an error line naming
/// the variable for any other value.
pub fn requested_path() -> Result<Option<&'static str>, String> {
    match std::env::var(KERNEL_ENV) {
        Err(_) => Ok(None),
        Ok(v) if v == "auto" => Ok(None),
        Ok(v) if v == "portable" => Ok(Some("portable")),
        Ok(v) => Err(format!(
            "environment variable {KERNEL_ENV}={v:?}: expected \"auto\" or \"portable\""
        )),
    }
}

/// The path this process takes: `"AVX2+FMA"` or `"portable"` (reported with throughput
/// figures, which depend on it).
pub fn vector_path() -> &'static str {
    if avx2_fma() {
        "AVX2+FMA"
    } else {
        "portable"
    }
}

/// Whether the AVX2 + FMA path runs: an x86-64 CPU with both, and [`KERNEL_ENV`] not
/// asking for the portable one. Decided once per process.
#[inline(always)]
pub fn avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        static CHOICE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
        *CHOICE.get_or_init(|| {
            std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
                && requested_path() != Ok(Some("portable"))
        })
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Four f64 lanes.
pub(crate) trait F64x4:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self>
{
    /// Every lane `a`.
    fn splat(a: f64) -> Self;
    /// The four values.
    fn load(a: &[f64; 4]) -> Self;
    /// The lanes as an array.
    fn to_array(self) -> [f64; 4];
    /// `self * b + c` (fused where the hardware has it).
    fn mul_add(self, b: Self, c: Self) -> Self;
    /// `self * b − c` (fused where the hardware has it).
    fn mul_sub(self, b: Self, c: Self) -> Self;
    /// `c − self * b` (fused where the hardware has it).
    fn neg_mul_add(self, b: Self, c: Self) -> Self;
    /// `(l₀ + l₂) + (l₁ + l₃)`.
    fn sum(self) -> f64;
}

/// Plain arrays, unfused arithmetic: any CPU.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Portable4(pub [f64; 4]);

macro_rules! portable_op {
    ($trait:ident, $method:ident, $op:tt) => {
        impl $trait for Portable4 {
            type Output = Self;
            #[inline(always)]
            fn $method(self, o: Self) -> Self {
                let (a, b) = (self.0, o.0);
                Portable4([a[0] $op b[0], a[1] $op b[1], a[2] $op b[2], a[3] $op b[3]])
            }
        }
    };
}
portable_op!(Add, add, +);
portable_op!(Sub, sub, -);
portable_op!(Mul, mul, *);
portable_op!(Div, div, /);

impl F64x4 for Portable4 {
    #[inline(always)]
    fn splat(a: f64) -> Self {
        Portable4([a; 4])
    }
    #[inline(always)]
    fn load(a: &[f64; 4]) -> Self {
        Portable4(*a)
    }
    #[inline(always)]
    fn to_array(self) -> [f64; 4] {
        self.0
    }
    #[inline(always)]
    fn mul_add(self, b: Self, c: Self) -> Self {
        self * b + c
    }
    #[inline(always)]
    fn mul_sub(self, b: Self, c: Self) -> Self {
        self * b - c
    }
    #[inline(always)]
    fn neg_mul_add(self, b: Self, c: Self) -> Self {
        c - self * b
    }
    #[inline(always)]
    fn sum(self) -> f64 {
        let a = self.0;
        (a[0] + a[2]) + (a[1] + a[3])
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) mod avx {
    //! The AVX2 + FMA lanes: `__m256d`. Its operations are only reached from functions
    //! compiled with `#[target_feature(enable = "avx2,fma")]`, which callers enter only
    //! when [`super::avx2_fma`] holds.
    use super::F64x4;
    use std::arch::x86_64::*;
    use std::ops::{Add, Div, Mul, Sub};

    /// One AVX register of four f64.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Avx4(pub __m256d);

    macro_rules! avx_op {
        ($trait:ident, $method:ident, $intrinsic:ident) => {
            impl $trait for Avx4 {
                type Output = Self;
                #[inline(always)]
                fn $method(self, o: Self) -> Self {
                    // SAFETY: reached only with AVX2 (module note).
                    Avx4(unsafe { $intrinsic(self.0, o.0) })
                }
            }
        };
    }
    avx_op!(Add, add, _mm256_add_pd);
    avx_op!(Sub, sub, _mm256_sub_pd);
    avx_op!(Mul, mul, _mm256_mul_pd);
    avx_op!(Div, div, _mm256_div_pd);

    impl F64x4 for Avx4 {
        #[inline(always)]
        fn splat(a: f64) -> Self {
            // SAFETY: as the operators.
            Avx4(unsafe { _mm256_set1_pd(a) })
        }
        #[inline(always)]
        fn load(a: &[f64; 4]) -> Self {
            // SAFETY: four f64 in bounds; as the operators.
            Avx4(unsafe { _mm256_loadu_pd(a.as_ptr()) })
        }
        #[inline(always)]
        fn to_array(self) -> [f64; 4] {
            let mut a = [0.0; 4];
            // SAFETY: four f64 in bounds; as the operators.
            unsafe { _mm256_storeu_pd(a.as_mut_ptr(), self.0) };
            a
        }
        #[inline(always)]
        fn mul_add(self, b: Self, c: Self) -> Self {
            // SAFETY: reached only with FMA (module note).
            Avx4(unsafe { _mm256_fmadd_pd(self.0, b.0, c.0) })
        }
        #[inline(always)]
        fn mul_sub(self, b: Self, c: Self) -> Self {
            // SAFETY: as `mul_add`.
            Avx4(unsafe { _mm256_fmsub_pd(self.0, b.0, c.0) })
        }
        #[inline(always)]
        fn neg_mul_add(self, b: Self, c: Self) -> Self {
            // SAFETY: as `mul_add`.
            Avx4(unsafe { _mm256_fnmadd_pd(self.0, b.0, c.0) })
        }
        #[inline(always)]
        fn sum(self) -> f64 {
            // SAFETY: as the operators.
            unsafe {
                let pair = _mm_add_pd(
                    _mm256_castpd256_pd128(self.0),
                    _mm256_extractf128_pd::<1>(self.0),
                );
                _mm_cvtsd_f64(_mm_add_sd(pair, _mm_unpackhi_pd(pair, pair)))
            }
        }
    }
}

/// Asks for the `lines` 64-byte cache lines from `p` to be loaded ahead of their use: a
/// hint that changes no result (nothing on CPUs other than x86-64). For data a loop will
/// read out of sequence, which the hardware prefetcher does not foresee (the NLGS sweep's
/// records of the contacts that carry an impulse, [`crate::nscd::body_nlgs`]).
#[inline(always)]
pub(crate) fn prefetch<T>(p: *const T, lines: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = p as *const i8;
        for line in 0..lines {
            // SAFETY: a prefetch never faults, whatever the address; SSE is part of
            // x86-64.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64 * line)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (p, lines);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[inline(always)]
    fn check<V: F64x4>() {
        let a = V::load(&[1.0, 2.0, 3.0, 4.0]);
        let b = V::splat(0.5);
        let c = V::load(&[10.0, 20.0, 30.0, 40.0]);
        assert_eq!(a.mul_add(b, c).to_array(), [10.5, 21.0, 31.5, 42.0]);
        assert_eq!(a.mul_sub(b, c).to_array(), [-9.5, -19.0, -28.5, -38.0]);
        assert_eq!(a.neg_mul_add(b, c).to_array(), [9.5, 19.0, 28.5, 38.0]);
        assert_eq!((c / a - b).to_array(), [9.5, 9.5, 9.5, 9.5]);
        assert_eq!(a.sum(), 10.0);
    }

    #[test]
    fn both_lane_types_compute_the_same_small_sums() {
        check::<Portable4>();
        #[cfg(target_arch = "x86_64")]
        if avx2_fma() {
            #[target_feature(enable = "avx2,fma")]
            unsafe fn on_avx() {
                check::<avx::Avx4>();
            }
            // SAFETY: the CPU has AVX2 and FMA.
            unsafe { on_avx() };
        }
    }
}
