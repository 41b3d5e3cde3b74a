//! Runtime CPU dispatch of the hot kernels.
//!
//! The build targets baseline x86-64, so one binary runs on any x86-64 CPU (older Atom and
//! Celeron boards on robots have no AVX2). The row kernels that dominate the time, the LS
//! neighbourhood moments and fits ([`super::normals`]) and the DSAC hypotheses and refits
//! ([`super::dsac`]), are compiled twice with `multiversion`: once for baseline x86-64, once
//! for AVX2 + FMA; each call runs the version the CPU supports, detected once. Both versions
//! give the same bits: no multiply-add is fused, explicitly or by the compiler (no fast-math).
//!
//! Only code inlined into a kernel gets the AVX2 version: a function or closure the kernel
//! calls is compiled once, for baseline x86-64. So everything a kernel runs per pixel is
//! `#[inline(always)]`, and its per-lane arrays are built with `from_fn` or plain loops, never
//! `std::array::from_fn` or an array's `map` with a large closure (those run the closure in a
//! library function that is called, not inlined). Check with `objdump -d` on the `..._avx_...`
//! symbols: no calls to `{{closure}}`s or kernel functions should remain (`docs/benchmarks.md`,
//! run-time CPU dispatch, shows what it cost when they did).

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

/// `std::array::from_fn` for the kernels: element `l` is `f(l)`, built by a plain loop that
/// inlines into each compiled version of the kernel calling it. The standard one runs its
/// closure inside a library function that LLVM does not inline, which is compiled once, for
/// baseline x86-64: the work in the closure (the DSAC hypotheses of a row's pixels, the
/// covariances of the refits) then ran without AVX2 in the AVX2 version of the kernel.
/// `N` is at least 1 (checked at compile time).
#[inline(always)]
pub(crate) fn from_fn<T: Copy, const N: usize>(mut f: impl FnMut(usize) -> T) -> [T; N] {
    const { assert!(N > 0, "from_fn builds arrays of at least one element") };
    let mut out = [f(0); N];
    for (l, o) in out.iter_mut().enumerate().skip(1) {
        *o = f(l);
    }
    out
}
