//! Four int8 lanes per word for the reductions of [`crate::kernels::pool`]: `SSUB8` + `SEL`
//! keep the larger signed byte per lane, `SXTAB16` adds sign-extended bytes to 16-bit lanes.
//! Exact integer results, so the pools give the same bits as their portable loops.

/// Per byte lane, the larger signed byte of `a` and `b`.
#[inline(always)]
pub fn max4(a: u32, b: u32) -> u32 {
    let r: u32;
    // SAFETY: register-only DSP instructions; `SSUB8` sets the GE flags `SEL` reads.
    unsafe {
        core::arch::asm!(
            "ssub8 {r}, {a}, {b}",
            "sel {r}, {a}, {b}",
            a = in(reg) a,
            b = in(reg) b,
            r = out(reg) r,
            options(pure, nomem, nostack),
        );
    }
    r
}

/// Per byte lane, the larger and the smaller signed byte of `a` and `b`: one `SSUB8` sets the
/// GE flags both `SEL`s read.
#[inline(always)]
pub fn max_min4(a: u32, b: u32) -> (u32, u32) {
    let (hi, lo): (u32, u32);
    // SAFETY: register-only DSP instructions; `SSUB8` sets the GE flags the `SEL`s read.
    unsafe {
        core::arch::asm!(
            "ssub8 {hi}, {a}, {b}",
            "sel {hi}, {a}, {b}",
            "sel {lo}, {b}, {a}",
            a = in(reg) a,
            b = in(reg) b,
            hi = out(reg) hi,
            lo = out(reg) lo,
            options(pure, nomem, nostack),
        );
    }
    (hi, lo)
}

/// Bytes 0 and 2 of `x`, sign-extended, added to the 16-bit halves of `even`; bytes 1 and 3 to
/// those of `odd` (each half wraps at 16 bits: callers add at most 256 bytes per half).
#[inline(always)]
pub fn add4(even: u32, odd: u32, x: u32) -> (u32, u32) {
    let (e, o): (u32, u32);
    // SAFETY: register-only DSP instructions.
    unsafe {
        core::arch::asm!(
            "sxtab16 {e}, {e}, {x}",
            "sxtab16 {o}, {o}, {x}, ror #8",
            x = in(reg) x,
            e = inout(reg) even => e,
            o = inout(reg) odd => o,
            options(pure, nomem, nostack, preserves_flags),
        );
    }
    (e, o)
}

/// The word of bytes `b[0..4]` (little-endian; Cortex-M4/M7 load it unaligned).
#[inline(always)]
pub fn word(b: &[i8]) -> u32 {
    match b {
        [a, b, c, d, ..] => u32::from_le_bytes([*a as u8, *b as u8, *c as u8, *d as u8]),
        _ => 0,
    }
}

/// The signed 16-bit halves of `v`, low first.
#[inline(always)]
pub fn halves(v: u32) -> (i32, i32) {
    (
        i32::from(v as u16 as i16),
        i32::from((v >> 16) as u16 as i16),
    )
}

/// The largest of `x` (`i8::MIN` when empty).
pub fn max_i8(x: &[i8]) -> i8 {
    let mut m = 0x8080_8080u32;
    let mut words = x.chunks_exact(4);
    for w in &mut words {
        m = max4(m, word(w));
    }
    let lanes = m.to_le_bytes().map(|b| b as i8);
    let mut best = lanes.into_iter().max().unwrap_or(i8::MIN);
    for &v in words.remainder() {
        best = best.max(v);
    }
    best
}

/// The smallest and the largest of `x` in one pass (`(i8::MAX, i8::MIN)` when empty).
pub fn min_max_i8(x: &[i8]) -> (i8, i8) {
    let (mut hi, mut lo) = (0x8080_8080u32, 0x7F7F_7F7Fu32);
    let mut words = x.chunks_exact(4);
    for w in &mut words {
        let v = word(w);
        hi = max_min4(hi, v).0;
        lo = max_min4(lo, v).1;
    }
    let lanes = |m: u32| m.to_le_bytes().map(|b| b as i8);
    let mut big = lanes(hi).into_iter().max().unwrap_or(i8::MIN);
    let mut small = lanes(lo).into_iter().min().unwrap_or(i8::MAX);
    for &v in words.remainder() {
        big = big.max(v);
        small = small.min(v);
    }
    (small, big)
}

/// The sum of `x`, exact.
pub fn sum_i8(x: &[i8]) -> i32 {
    let mut total = 0i32;
    // 128 words put at most 256 bytes into each 16-bit half: |sum| ≤ 32 768, the i16 range
    // once the halves are read signed (−32 768 is the only value at the edge).
    for block in x.chunks(4 * 128) {
        let (mut e, mut o) = (0u32, 0u32);
        let mut words = block.chunks_exact(4);
        for w in &mut words {
            (e, o) = add4(e, o, word(w));
        }
        let ((e0, e1), (o0, o1)) = (halves(e), halves(o));
        total += e0 + e1 + o0 + o1;
        total += words.remainder().iter().map(|&v| i32::from(v)).sum::<i32>();
    }
    total
}
