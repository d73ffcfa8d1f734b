//! Which kernel set runs: detected at run time, never assumed from the build machine.
//!
//! On x86-64 core reads CPUID and XCR0 itself (no std needed): AVX2 needs the CPU bit and the
//! OS saving YMM state; AVX-512 VNNI needs F, BW, VNNI and the OS saving ZMM/opmask state. On
//! Arm the DSP extension is a property of the core that stable Rust does not expose as a cfg, so
//! the build states it with core's `arm-dsp` feature (the firmware enables it for its M4F). Every set gives the same bits as
//! [`Isa::Portable`] (integer sums are associative and nothing saturates).

use core::sync::atomic::{AtomicU8, Ordering};

/// A kernel set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
#[repr(u8)]
pub enum Isa {
    /// Plain Rust loops (any target).
    Portable = 1,
    /// Cortex-M4/M7 DSP extension: `SMLAD` dual 16-bit multiply-accumulate.
    ArmDsp = 2,
    /// x86-64 AVX2: `vpmaddwd` on 16-bit pairs.
    Avx2 = 3,
    /// x86-64 AVX-512 F+BW+VNNI: `vpdpbusd` on unsigned×signed byte quads.
    Avx512Vnni = 4,
}

impl Isa {
    /// Every kernel set, slowest first.
    pub const ALL: [Isa; 4] = [Isa::Portable, Isa::ArmDsp, Isa::Avx2, Isa::Avx512Vnni];

    /// Short name (`portable`, `arm-dsp`, `avx2`, `avx512-vnni`).
    pub fn name(self) -> &'static str {
        match self {
            Isa::Portable => "portable",
            Isa::ArmDsp => "arm-dsp",
            Isa::Avx2 => "avx2",
            Isa::Avx512Vnni => "avx512-vnni",
        }
    }

    /// The set of that name, if any.
    pub fn from_name(name: &str) -> Option<Isa> {
        Isa::ALL.into_iter().find(|i| i.name() == name)
    }

    /// Whether this CPU can run the set.
    pub fn available(self) -> bool {
        match self {
            Isa::Portable => true,
            Isa::ArmDsp => cfg!(all(target_arch = "arm", feature = "arm-dsp")),
            Isa::Avx2 | Isa::Avx512Vnni => x86_level() >= self as u8,
        }
    }

    /// The fastest set this CPU runs (detected once, then cached).
    pub fn best() -> Isa {
        if Isa::ArmDsp.available() {
            return Isa::ArmDsp;
        }
        match x86_level() {
            4 => Isa::Avx512Vnni,
            3 => Isa::Avx2,
            _ => Isa::Portable,
        }
    }

    /// `self` if this CPU runs it, else the fastest set it does run.
    pub fn or_best(self) -> Isa {
        if self.available() {
            self
        } else {
            Isa::best()
        }
    }
}

/// Cached x86 level: 0 = not yet read, 1 = neither, 3 = AVX2, 4 = AVX-512 VNNI.
static X86_LEVEL: AtomicU8 = AtomicU8::new(0);

fn x86_level() -> u8 {
    let l = X86_LEVEL.load(Ordering::Relaxed);
    if l != 0 {
        return l;
    }
    let l = read_x86_level();
    X86_LEVEL.store(l, Ordering::Relaxed);
    l
}

/// Under Miri, the portable set only: Miri interprets no `cpuid`/`xgetbv` (inline assembly)
/// and too few vendor intrinsics for the AVX kernels, so the SIMD paths are not what it checks.
#[cfg(all(target_arch = "x86_64", miri))]
fn read_x86_level() -> u8 {
    1
}

#[cfg(all(target_arch = "x86_64", not(miri)))]
fn read_x86_level() -> u8 {
    use core::arch::x86_64::{__cpuid, __cpuid_count};
    #[allow(unused_unsafe)]
    // SAFETY: CPUID exists on every x86-64 CPU.
    let (l0, l1) = unsafe { (__cpuid(0), __cpuid(1)) };
    let osxsave = l1.ecx & (1 << 27) != 0;
    let avx = l1.ecx & (1 << 28) != 0;
    if l0.eax < 7 || !osxsave || !avx {
        return 1;
    }
    // SAFETY: OSXSAVE is set, so XGETBV is enabled.
    let xcr0 = unsafe { xcr0() };
    #[allow(unused_unsafe)]
    // SAFETY: leaf 7 exists (checked above).
    let l7 = unsafe { __cpuid_count(7, 0) };
    let avx2 = l7.ebx & (1 << 5) != 0 && xcr0 & 0x6 == 0x6;
    let avx512 = l7.ebx & (1 << 16) != 0 // F
        && l7.ebx & (1 << 30) != 0 // BW
        && l7.ecx & (1 << 11) != 0 // VNNI
        && xcr0 & 0xE6 == 0xE6; // SSE, YMM, opmask, ZMM hi256, hi16 ZMM
    if avx2 && avx512 {
        4
    } else if avx2 {
        3
    } else {
        1
    }
}

/// # Safety
/// The CPU must support `XGETBV` (CPUID.1:ECX.OSXSAVE, checked by the caller before calling).
#[cfg(all(target_arch = "x86_64", not(miri)))]
#[target_feature(enable = "xsave")]
unsafe fn xcr0() -> u64 {
    core::arch::x86_64::_xgetbv(0)
}

#[cfg(not(target_arch = "x86_64"))]
fn read_x86_level() -> u8 {
    1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn best_is_available_and_names_round_trip() {
        assert!(Isa::best().available());
        assert!(Isa::Portable.available());
        for i in Isa::ALL {
            assert_eq!(Isa::from_name(i.name()), Some(i));
            assert!(i.or_best().available());
        }
        std::println!("kernel set on this CPU: {}", Isa::best().name());
    }
}
