//! Int8 kernels, one module per op family, each in TFLite-Micro layers: a `*_ref` function with
//! plain loops (the spec), a fast path with the same signature where one pays off, both run by
//! the shared `kernel_tests!` suite on named golden cases and proptest shapes; and
//! [`float`], the f32 reference of every op that the host quantizer calibrates with. The scalar
//! functions ([`scalar`]) and `mul`'s broadcasts ([`broadcast`]) are leaves that the kernels and
//! the reference share, so no kernel imports [`float`]. How an op reads its blob attributes,
//! plans and runs is in its file under `core/src/ops/`.
//!
//! Tensors are planar CHW (the graph's NCHW with N = 1), row-major, in caller-provided slices.
//! Kernels check every length up front and return [`KernelError`] instead of panicking.
//!
//! **Kernel sets** ([`isa::Isa`], chosen at run time: core reads CPUID itself on x86-64; the
//! Cortex-M DSP set is the `arm-dsp` build feature; on aarch64 Linux/Android it asks the C
//! library's `getauxval` for the dot product): `portable` (any target), `avx2`,
//! `avx512-vnni` (x86-64, `x86_64/`), `arm-dsp` (`SMLAD`, `arm/`), `neon` and `neon-dot`
//! (aarch64 `SMLAL` and `SDOT`, `aarch64/`). Integer sums are exact, so
//! every set gives the reference's bits; the f32 refinement and bins head keep each pixel's
//! operation order (lanes run pixels side by side, never reassociate), so they too give the same
//! bits. The convolution ([`conv`]) packs each output row's input rows with channels innermost
//! ([`pack`]) and runs register-blocked micro-kernels ([`dot`]) of 4 output channels × 32
//! pixels, then requantises the block (vectorised on x86).
#[cfg(target_arch = "aarch64")]
pub mod aarch64;
#[cfg(all(target_arch = "arm", feature = "arm-dsp"))]
pub mod arm;
pub mod bins;
pub mod broadcast;
pub mod conv;
mod depthwise;
pub mod dot;
pub mod elementwise;
pub mod float;
pub mod isa;
pub mod pack;
pub mod pool;
pub mod refine;
pub mod requant;
pub mod resize;
pub mod scalar;
pub mod wide;
#[cfg(target_arch = "x86_64")]
pub mod x86_64;

/// Shape of one CHW tensor (batch 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Shape {
    /// Channels.
    pub c: usize,
    /// Rows.
    pub h: usize,
    /// Columns.
    pub w: usize,
}

impl Shape {
    /// A shape from channels, rows, columns.
    pub const fn new(c: usize, h: usize, w: usize) -> Shape {
        Shape { c, h, w }
    }

    /// Number of elements, `None` on overflow.
    pub fn len(&self) -> Option<usize> {
        self.c.checked_mul(self.h)?.checked_mul(self.w)
    }

    /// True when the shape has no elements.
    pub fn is_empty(&self) -> bool {
        self.c == 0 || self.h == 0 || self.w == 0
    }

    /// Elements of one channel plane, `None` on overflow.
    pub fn plane(&self) -> Option<usize> {
        self.h.checked_mul(self.w)
    }
}

/// Why a kernel refused to run. Kernels never panic; the engine maps this to its own error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KernelError {
    /// A slice is shorter than its shape says, or shapes do not fit together.
    Shape,
    /// An attribute is out of range (zero stride, groups not dividing channels…).
    Attr,
    /// The scratch buffer is too small.
    Scratch,
    /// The requested kernel set does not run on this CPU.
    Isa,
}

impl core::fmt::Display for KernelError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            KernelError::Shape => "tensor shapes or slice lengths do not match",
            KernelError::Attr => "op attribute out of range",
            KernelError::Scratch => "scratch buffer too small",
            KernelError::Isa => "kernel set not available on this CPU",
        })
    }
}

/// Returns `Err(Shape)` unless `s` holds at least `shape.len()` elements; yields that length.
pub(crate) fn need<T>(s: &[T], shape: Shape) -> Result<usize, KernelError> {
    let n = shape.len().ok_or(KernelError::Shape)?;
    if s.len() < n {
        return Err(KernelError::Shape);
    }
    Ok(n)
}

/// The shared ref-vs-fast suite: runs `check(&case, impl)` for the reference and the fast
/// implementation on every named golden case and on proptest-generated cases.
#[cfg(test)]
macro_rules! kernel_tests {
    ($name:ident, ref: $r:path, fast: $f:path, golden: $golden:path, arb: $arb:expr, check: $check:path) => {
        mod $name {
            use super::*;
            #[test]
            fn golden_ref() {
                for c in $golden() {
                    $check(&c, $r);
                }
            }
            #[test]
            fn golden_fast() {
                for c in $golden() {
                    $check(&c, $f);
                }
            }
            proptest::proptest! {
                #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]
                #[test]
                fn arb_ref(c in $arb) {
                    $check(&c, $r);
                }
                #[test]
                fn arb_fast(c in $arb) {
                    $check(&c, $f);
                }
            }
        }
    };
}
#[cfg(test)]
pub(crate) use kernel_tests;
