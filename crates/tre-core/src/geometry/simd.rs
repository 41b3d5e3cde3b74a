//! Runtime CPU dispatch of the hot kernels.
//!
//! The build targets baseline x86-64, so one binary runs on any x86-64 CPU (older Atom and
//! Celeron boards on robots have no AVX2). The row kernels that dominate the time, the LS
//! neighbourhood moments and fits ([`super::normals`]) and the DSAC hypotheses and refits
//! ([`super::dsac`]), are compiled twice with `multiversion`: once for baseline x86-64, once
//! for AVX2 + FMA; each call runs the version the CPU supports, detected once. Both versions
//! give the same bits: no multiply-add is fused, explicitly or by the compiler (no fast-math).

/// The kernel version this CPU runs: `"avx2+fma"` or `"baseline"` (any CPU that is not x86-64,
/// or an x86-64 CPU without AVX2 and FMA).
///
/// ```
/// let v = tre_core::geometry::simd::selected();
/// assert!(v == "avx2+fma" || v == "baseline");
/// ```
#[must_use]
pub fn selected() -> &'static str {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            return "avx2+fma";
        }
    }
    "baseline"
}
