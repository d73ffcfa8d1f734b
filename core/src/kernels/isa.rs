//! Which kernel set runs: detected at run time, never assumed from the build machine.
//!
//! On x86-64 core reads CPUID and XCR0 itself (no std needed): AVX2 needs the CPU bit and the
//! OS saving YMM state; AVX-512 VNNI needs F, BW, VNNI and the OS saving ZMM/opmask state. On
//! Arm the DSP extension is a property of the core that stable Rust does not expose as a cfg, so
//! the build states it with core's `arm-dsp` feature (the firmware enables it for its M4F). On
//! aarch64 NEON (Advanced SIMD) is part of the base architecture (the `neon` target feature of
//! every aarch64 Linux/Android target), and the ARMv8.2 dot product (`SDOT`) is read from the
//! kernel's auxiliary vector: on Linux and Android core calls the C library's
//! `getauxval(AT_HWCAP)` (glibc, musl and bionic all have it; it is what std's
//! `is_aarch64_feature_detected!("dotprod")` reads too) and tests `HWCAP_ASIMDDP`, so a kernel
//! too old to report it simply runs [`Isa::Neon`]; elsewhere (bare metal, other OSes) the
//! dot-product set is available only to a build that enables the `dotprod` target feature.
//! The ID register `ID_AA64ISAR0_EL1` is not read with `MRS`: Linux emulates that read for user
//! space only since 4.11 (`HWCAP_CPUID`), and an older phone kernel would raise `SIGILL`. Every
//! set gives the same bits as [`Isa::Portable`] (integer sums are associative and nothing
//! saturates).

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
    /// aarch64 NEON (ARMv8.0, every aarch64 core): `SMLAL` by element on 16-bit pairs.
    Neon = 5,
    /// aarch64 NEON with the ARMv8.2 dot product (`SDOT`: four signed byte products added into
    /// one 32-bit lane; Cortex-A55/A75 and later).
    NeonDot = 6,
}

impl Isa {
    /// Every kernel set, slowest first.
    pub const ALL: [Isa; 6] = [
        Isa::Portable,
        Isa::ArmDsp,
        Isa::Avx2,
        Isa::Avx512Vnni,
        Isa::Neon,
        Isa::NeonDot,
    ];

    /// Short name (`portable`, `arm-dsp`, `avx2`, `avx512-vnni`, `neon`, `neon-dot`).
    pub fn name(self) -> &'static str {
        match self {
            Isa::Portable => "portable",
            Isa::ArmDsp => "arm-dsp",
            Isa::Avx2 => "avx2",
            Isa::Avx512Vnni => "avx512-vnni",
            Isa::Neon => "neon",
            Isa::NeonDot => "neon-dot",
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
            Isa::Neon => cfg!(all(target_arch = "aarch64", target_feature = "neon")),
            Isa::NeonDot => Isa::Neon.available() && aarch64_dotprod(),
        }
    }

    /// The fastest set this CPU runs (detected once, then cached).
    pub fn best() -> Isa {
        if Isa::ArmDsp.available() {
            return Isa::ArmDsp;
        }
        if Isa::NeonDot.available() {
            return Isa::NeonDot;
        }
        if Isa::Neon.available() {
            return Isa::Neon;
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

/// Cached dot-product answer: 0 = not yet read, 1 = absent, 2 = present.
static DOTPROD: AtomicU8 = AtomicU8::new(0);

fn aarch64_dotprod() -> bool {
    let d = DOTPROD.load(Ordering::Relaxed);
    if d != 0 {
        return d == 2;
    }
    let d = if read_aarch64_dotprod() { 2 } else { 1 };
    DOTPROD.store(d, Ordering::Relaxed);
    d == 2
}

/// Whether the CPU executes `SDOT`/`UDOT` (module doc: how it is read).
#[cfg(all(
    target_arch = "aarch64",
    any(target_os = "linux", target_os = "android")
))]
fn read_aarch64_dotprod() -> bool {
    extern "C" {
        fn getauxval(kind: core::ffi::c_ulong) -> core::ffi::c_ulong;
    }
    const AT_HWCAP: core::ffi::c_ulong = 16;
    const HWCAP_ASIMDDP: core::ffi::c_ulong = 1 << 20;
    if cfg!(target_feature = "dotprod") {
        return true;
    }
    // SAFETY: `getauxval` (glibc ≥ 2.16, musl, bionic) only reads the process's auxiliary
    // vector and returns 0 for an absent entry; it takes and returns plain integers.
    unsafe { getauxval(AT_HWCAP) & HWCAP_ASIMDDP != 0 }
}

#[cfg(not(all(
    target_arch = "aarch64",
    any(target_os = "linux", target_os = "android")
)))]
fn read_aarch64_dotprod() -> bool {
    cfg!(all(target_arch = "aarch64", target_feature = "dotprod"))
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

    /// Core's own dot-product detection agrees with std's (run under `qemu-aarch64` with
    /// `-cpu max`, which has it, and `-cpu cortex-a53`, which has not).
    #[cfg(target_arch = "aarch64")]
    #[test]
    fn aarch64_detection_agrees_with_std() {
        assert!(Isa::Neon.available());
        let std_dot = std::arch::is_aarch64_feature_detected!("dotprod");
        assert_eq!(Isa::NeonDot.available(), std_dot);
        let want = if std_dot { Isa::NeonDot } else { Isa::Neon };
        assert_eq!(Isa::best(), want);
    }
}
