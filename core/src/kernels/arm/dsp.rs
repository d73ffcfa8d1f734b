//! Cortex-M4/M7 DSP [`crate::kernels::pack::Pairs`] kernel: `SMLAD` adds both 16-bit
//! products of a packed word and a weight word to a 32-bit accumulator in one instruction.
//! Block: 2 channels × 2 pixels (4 accumulators in registers). Per call and channel pair the
//! reduction steps become a stream on the stack (in chunks of [`CHUNK`]) of three words per
//! step: the step's absolute pixel address and the pair's two weight words, so one `LDM` reads
//! them; each pixel pair's offset from the address is an immediate of the `LDRD` (one loop per
//! pair position). A step is `LDM`, `LDRD` pixels, four `SMLAD`: 26 instructions per four steps
//! (32 multiply-accumulates) with the loop unrolled four times.

use crate::kernels::dot::{Acc, Task};
use crate::kernels::pack::{NB, PB};
use core::mem::MaybeUninit;

/// Reduction steps per stream (1.5 KiB of stack).
const CHUNK: usize = 128;

/// Adds to `a` the 2×2 sums of the `n` steps of `stream` (`[address, w_j, w_j+1]` per step);
/// the pixel pair sits `OFF` bytes past each address.
///
/// # Safety
/// `stream` holds `3·n` words; every `address + OFF` (8 bytes) must be readable and 4-aligned.
#[inline(always)]
unsafe fn block<const OFF: usize>(stream: *const u32, n: usize, a: &mut [i32; 4]) {
    let [mut a00, mut a01, mut a10, mut a11] = *a;
    let mut t = stream;
    // LDM fills registers in number order, so the three it loads are named: r0 address,
    // r1 / r2 the weight words; r3 / r4 take the pixel words. Four steps per loop, then the
    // last two and the last one.
    macro_rules! step {
        () => {
            concat!(
                "ldm {t}!, {{r0, r1, r2}}\n",
                "ldrd r3, r4, [r0, #{off}]\n",
                "smlad {a00}, r3, r1, {a00}\n",
                "smlad {a01}, r4, r1, {a01}\n",
                "smlad {a10}, r3, r2, {a10}\n",
                "smlad {a11}, r4, r2, {a11}\n",
            )
        };
    }
    let quads = n / 4;
    if quads > 0 {
        core::arch::asm!(
            "2:",
            step!(),
            step!(),
            step!(),
            step!(),
            "cmp {t}, {end}",
            "bne 2b",
            off = const OFF,
            t = inout(reg) t,
            end = in(reg) stream.add(12 * quads),
            out("r0") _,
            out("r1") _,
            out("r2") _,
            out("r3") _,
            out("r4") _,
            a00 = inout(reg) a00,
            a01 = inout(reg) a01,
            a10 = inout(reg) a10,
            a11 = inout(reg) a11,
            options(nostack, readonly),
        );
    }
    for _ in 0..n % 4 {
        core::arch::asm!(
            step!(),
            off = const OFF,
            t = inout(reg) t,
            out("r0") _,
            out("r1") _,
            out("r2") _,
            out("r3") _,
            out("r4") _,
            a00 = inout(reg) a00,
            a01 = inout(reg) a01,
            a10 = inout(reg) a10,
            a11 = inout(reg) a11,
            options(nostack, readonly),
        );
    }
    *a = [a00, a01, a10, a11];
}

/// The sums `acc[j·PB + pb ..= pb + 1]` of the channel pair `j = jb, jb + 1` over the stream,
/// from zero if `first`, else added to.
///
/// # Safety
/// As [`block`] with `OFF = 4·pb`; `acc` holds `NB·PB` sums and `jb + 1 < NB`.
#[inline(always)]
unsafe fn pair<const OFF: usize>(stream: *const u32, n: usize, acc: *mut i32, first: bool) {
    let (lo, hi) = (acc.add(OFF / 4), acc.add(PB + OFF / 4));
    let mut a = if first {
        [0; 4]
    } else {
        [*lo, *lo.add(1), *hi, *hi.add(1)]
    };
    block::<OFF>(stream, n, &mut a);
    (*lo, *lo.add(1), *hi, *hi.add(1)) = (a[0], a[1], a[2], a[3]);
}

/// [`pair`] for the pixel pair at `pb` (`0, 2, …, PB − 2`): the byte offset `4·pb` as an
/// immediate. `acc` points at the pair's first channel row.
///
/// # Safety
/// As [`pair`] with `OFF = 4·pb`.
#[inline(always)]
unsafe fn pair_at(pb: usize, stream: *const u32, n: usize, acc: *mut i32, first: bool) {
    const _: () = assert!(PB == 32);
    match pb {
        0 => pair::<0>(stream, n, acc, first),
        2 => pair::<8>(stream, n, acc, first),
        4 => pair::<16>(stream, n, acc, first),
        6 => pair::<24>(stream, n, acc, first),
        8 => pair::<32>(stream, n, acc, first),
        10 => pair::<40>(stream, n, acc, first),
        12 => pair::<48>(stream, n, acc, first),
        14 => pair::<56>(stream, n, acc, first),
        16 => pair::<64>(stream, n, acc, first),
        18 => pair::<72>(stream, n, acc, first),
        20 => pair::<80>(stream, n, acc, first),
        22 => pair::<88>(stream, n, acc, first),
        24 => pair::<96>(stream, n, acc, first),
        26 => pair::<104>(stream, n, acc, first),
        28 => pair::<112>(stream, n, acc, first),
        _ => pair::<120>(stream, n, acc, first),
    }
}

/// Writes the stream of [`block`] for one channel pair: per step `k`, the pixel address
/// `base + 2·steps[k]` and the pair's two weight words `w[k·NB]`, `w[k·NB + 1]` (one `LDRD`,
/// one `STM` of the three: 6 instructions per step).
///
/// # Safety
/// `steps` is not empty; `stream` has room for `3·steps.len()` words; `w` is 4-aligned and
/// `w[k·NB ..= k·NB + 1]` is readable for every step `k`.
#[inline(always)]
unsafe fn fill_stream(stream: *mut u32, steps: &[u32], base: usize, w: *const u32) {
    // `STM` stores its registers in number order, so the three are named: r0 the address, r1 /
    // r2 the weight words.
    core::arch::asm!(
        "2:",
        "ldr r0, [{s}], #4",
        "ldrd r1, r2, [{w}], #{stride}",
        "add r0, {base}, r0, lsl #1",
        "stmia {st}!, {{r0, r1, r2}}",
        "cmp {s}, {end}",
        "bne 2b",
        stride = const 4 * NB,
        s = inout(reg) steps.as_ptr() => _,
        end = in(reg) steps.as_ptr().add(steps.len()),
        w = inout(reg) w => _,
        base = in(reg) base,
        st = inout(reg) stream => _,
        out("r0") _,
        out("r1") _,
        out("r2") _,
        options(nostack),
    );
}

/// Same contract as [`crate::kernels::dot::portable`] for pairs; `false` if a read would
/// leave the slices or they are not 4-aligned.
pub fn pairs(t: &Task<i16, i16>, acc: &mut Acc) -> bool {
    const _: () = assert!(NB == 4 && PB.is_multiple_of(2));
    let n = t.steps.len();
    if n == 0
        || n.checked_mul(NB * 2).is_none_or(|l| l > t.weights.len())
        || !(t.rows.as_ptr() as usize).is_multiple_of(4)
        || !(t.weights.as_ptr() as usize).is_multiple_of(4)
    {
        return false;
    }
    // Only the blocks the row uses: the narrow layers of the encoder use a fraction of PB.
    let pixels = t.pixels.clamp(1, PB);
    // Every pixel word read lies below `limit` (elements): ox0 + PB words past the step.
    let Some(limit) = t.rows.len().checked_sub((t.ox0 + PB) * 2) else {
        return false;
    };
    // An odd offset (an unaligned word) or one past `limit` refuses the call before anything
    // is read (the bounds come with the steps, made once per output row).
    let top = t.steps.max().unwrap_or(u32::MAX);
    if !t.steps.bits().is_multiple_of(2) || top as usize > limit {
        return false;
    }
    let base = t.rows.as_ptr() as usize + 4 * t.ox0;
    // The weight words of step k: NB per step, one per channel.
    let words: &[u32] = {
        // SAFETY: the weights are 4-aligned (checked) i16 pairs, n·NB words long (checked).
        unsafe { core::slice::from_raw_parts(t.weights.as_ptr().cast(), n * NB) }
    };
    let mut stream = [MaybeUninit::<u32>::uninit(); 3 * CHUNK];
    for (c, steps) in t.steps.chunks(CHUNK).enumerate() {
        for jb in (0..NB).step_by(2) {
            // SAFETY: `stream` holds 3·CHUNK ≥ 3·steps.len() words; the chunk's NB·steps.len()
            // weight words from `c·CHUNK·NB` lie in `words` (n·NB words), so the pair's words
            // at `+ jb` are readable and 4-aligned; `steps` is not empty.
            unsafe {
                fill_stream(
                    stream.as_mut_ptr().cast(),
                    steps,
                    base,
                    words.as_ptr().add(c * CHUNK * NB + jb),
                )
            };
            let rows = acc[jb * PB..].as_mut_ptr();
            for pb in (0..pixels).step_by(2) {
                // SAFETY: the first 3·steps.len() words of `stream` were written just above;
                // every address plus 4·pb + 8 ≤ 4·PB bytes stays below rows' end (`limit`,
                // checked), all are 4-aligned (even element offsets of a 4-aligned base);
                // `rows` has the two channel rows of PB sums. The first chunk starts the sums;
                // those of unused pixels stay unset.
                unsafe { pair_at(pb, stream.as_ptr().cast(), steps.len(), rows, c == 0) };
            }
        }
    }
    true
}

/// Two weight rows against one pixel: `(a + Σ wa_k·x_k, b + Σ wb_k·x_k)` over `n4` groups of
/// four channels. `SXTB16` splits a weight word into its even and odd bytes as 16-bit pairs,
/// which meet the pixel's `[x0|x2]`, `[x1|x3]` words in `SMLAD`: 13 instructions per 8
/// multiply-accumulates.
///
/// # Safety
/// `n4 ≥ 1`; `n4` words of `wa` and `wb` and `2·n4` words of `x` must be readable and 4-aligned.
#[inline(always)]
unsafe fn rows2(
    wa: *const u32,
    wb: *const u32,
    x: *const u32,
    n4: usize,
    a: i32,
    b: i32,
) -> (i32, i32) {
    let (mut a, mut b) = (a, b);
    core::arch::asm!(
        "2:",
        "ldr {t}, [{wa}], #4",
        "ldr {u}, [{wb}], #4",
        "ldrd {x0}, {x1}, [{x}], #8",
        "sxtb16 {s}, {t}",
        "sxtb16 {t}, {t}, ror #8",
        "smlad {a}, {s}, {x0}, {a}",
        "smlad {a}, {t}, {x1}, {a}",
        "sxtb16 {s}, {u}",
        "sxtb16 {u}, {u}, ror #8",
        "smlad {b}, {s}, {x0}, {b}",
        "smlad {b}, {u}, {x1}, {b}",
        "subs {n}, {n}, #1",
        "bne 2b",
        wa = inout(reg) wa => _,
        wb = inout(reg) wb => _,
        x = inout(reg) x => _,
        n = inout(reg) n4 => _,
        t = out(reg) _,
        u = out(reg) _,
        s = out(reg) _,
        x0 = out(reg) _,
        x1 = out(reg) _,
        a = inout(reg) a,
        b = inout(reg) b,
        options(nostack, readonly),
    );
    (a, b)
}

/// `sums[r] += Σ_k weights[r·c + k] · x_k` for every row `r` of `c` int8 weights (the rows of
/// a 1×1 head), with the pixel's `x_k = code − zp` packed by [`pack_pixel`]. `false` (nothing
/// written) unless `c` is a positive multiple of 4, the weights are 4-aligned and the slices
/// hold `sums.len()` rows and `c / 2` words.
pub fn dot_rows(weights: &[i8], c: usize, x: &[u32], sums: &mut [i32]) -> bool {
    let rows = sums.len();
    if c == 0
        || !c.is_multiple_of(4)
        || !(weights.as_ptr() as usize).is_multiple_of(4)
        || rows.checked_mul(c).is_none_or(|n| weights.len() < n)
        || x.len() < c / 2
    {
        return false;
    }
    let w = weights.as_ptr() as *const u32;
    let words = c / 4;
    let mut r = 0;
    while r + 2 <= rows {
        // SAFETY: rows r and r + 1 (c bytes each, 4-aligned as c is a multiple of 4) lie in
        // `weights`, and `x` holds c/2 words (checked above).
        let (a, b) = unsafe {
            rows2(
                w.add(r * words),
                w.add((r + 1) * words),
                x.as_ptr(),
                words,
                sums[r],
                sums[r + 1],
            )
        };
        sums[r] = a;
        sums[r + 1] = b;
        r += 2;
    }
    if r < rows {
        let row = &weights[r * c..(r + 1) * c];
        for (k, &wk) in row.iter().enumerate() {
            let word = x[k / 4 * 2 + k % 2];
            let xk = if k % 4 < 2 {
                word as i16
            } else {
                (word >> 16) as i16
            };
            sums[r] = sums[r].wrapping_add(i32::from(wk) * i32::from(xk));
        }
    }
    true
}

/// Words per row of [`widen_rows12`]' table: the bias, six weight words, the logit scale.
pub const WIDE12_ROW: usize = 8;

/// `out[r·8 ..][..8]` = row `r` of a 12-feature bins head for [`logits12`]: the bias, the
/// row's 12 int8 weights as 16-bit pairs in [`pack_pixel`]'s order (`[w0|w2], [w1|w3], [w4|w6],
/// …`), the scale's bits; `false` (nothing written) if `weights` is shorter than `12·rows`,
/// `channels` than `rows` or `out` than `8·rows` words.
pub fn widen_rows12(
    weights: &[i8],
    channels: &[crate::kernels::bins::BinChannel],
    rows: usize,
    out: &mut [u32],
) -> bool {
    let (Some(w), Some(bs), Some(out)) = (
        weights.get(..12 * rows),
        channels.get(..rows),
        out.get_mut(..WIDE12_ROW * rows),
    ) else {
        return false;
    };
    let half = |v: i8| v as i16 as u16 as u32;
    for ((row, ch), o) in w.chunks_exact(12).zip(bs).zip(out.chunks_exact_mut(8)) {
        o[0] = ch.bias as u32;
        for (q, pair) in row.chunks_exact(4).zip(o[1..7].chunks_exact_mut(2)) {
            pair[0] = half(q[0]) | half(q[2]) << 16;
            pair[1] = half(q[1]) | half(q[3]) << 16;
        }
        o[7] = ch.scale.to_bits();
    }
    true
}

/// The logits of a 12-feature bins head for one pixel: `logits[r] = (bias_r + Σ_k w_rk·x_k) as
/// f32 · scale_r` over the rows of `wide` ([`widen_rows12`], eight words each) with the
/// pixel's six words `x` ([`pack_pixel`]) in registers, and their maximum (from −∞, taking a
/// logit where it is greater: the fold of the portable loop): per row three `LDRD` of weight
/// words, six `SMLAD`, the conversion, product and maximum on the FPU, 21 instructions. The
/// same integers and f32 operations as the portable loop, so the same bits. `None` (nothing
/// written) unless `wide` holds `8·logits.len()` words and `x` six.
pub fn logits12(wide: &[u32], x: &[u32], logits: &mut [f32]) -> Option<f32> {
    let rows = logits.len();
    if rows == 0 {
        return Some(f32::NEG_INFINITY);
    }
    if x.len() < 6 || rows.checked_mul(WIDE12_ROW).is_none_or(|n| wide.len() < n) {
        return None;
    }
    let mut m = f32::NEG_INFINITY.to_bits();
    // SAFETY: `8·rows` words of `wide` are read (checked; 4-aligned as `u32`, which `LDRD`
    // needs), `rows ≥ 1` f32 of `logits` written (the loop stops at `end`), six words of `x`
    // read (checked) before the loop. The FP registers s16–s18 are named in the text, saved
    // and restored here (as in `bins::sums`: no `sreg` operands on this target).
    unsafe {
        core::arch::asm!(
            "vpush {{s16-s18}}",
            "vmov s18, {w0}",
            "2:",
            "ldr {acc}, [{w}], #4",
            "ldrd {w0}, {w1}, [{w}], #8",
            "smlad {acc}, {w0}, {x0}, {acc}",
            "smlad {acc}, {w1}, {x1}, {acc}",
            "ldrd {w0}, {w1}, [{w}], #8",
            "smlad {acc}, {w0}, {x2}, {acc}",
            "smlad {acc}, {w1}, {x3}, {acc}",
            "ldrd {w0}, {w1}, [{w}], #8",
            "smlad {acc}, {w0}, {x4}, {acc}",
            "smlad {acc}, {w1}, {x5}, {acc}",
            "vmov s16, {acc}",
            "vcvt.f32.s32 s16, s16",
            "vldmia {w}!, {{s17}}",
            "vmul.f32 s16, s16, s17",
            "vstmia {l}!, {{s16}}",
            "vcmp.f32 s16, s18",
            "vmrs APSR_nzcv, fpscr",
            "it gt",
            "vmovgt.f32 s18, s16",
            "cmp {l}, {end}",
            "bne 2b",
            "vmov {w0}, s18",
            "vpop {{s16-s18}}",
            l = inout(reg) logits.as_mut_ptr() => _,
            end = in(reg) logits.as_mut_ptr().add(rows),
            w = inout(reg) wide.as_ptr() => _,
            x0 = in(reg) x[0],
            x1 = in(reg) x[1],
            x2 = in(reg) x[2],
            x3 = in(reg) x[3],
            x4 = in(reg) x[4],
            x5 = in(reg) x[5],
            acc = out(reg) _,
            w0 = inout(reg) m,
            w1 = out(reg) _,
        );
    }
    Some(f32::from_bits(m))
}

/// [`pack_strided`] for 12 channels (`out` six words), unrolled in asm: per four channels
/// four `LDRSB`, two `PKHBT`, two `SSUB16` and one `STRD` (33 instructions per pixel); `false`
/// (nothing written) if `src` is shorter than `11·stride + 1`.
pub fn pack12_strided(src: &[i8], stride: usize, zp: i32, out: &mut [u32; 6]) -> bool {
    if stride.checked_mul(11).is_none_or(|last| last >= src.len()) {
        return false;
    }
    let zz = (zp as u32 & 0xffff).wrapping_mul(0x1_0001);
    macro_rules! quad {
        () => {
            concat!(
                "ldrsb {a}, [{p}]\n",
                "ldrsb {b}, [{p}, {st}]\n",
                "add {p}, {p}, {st}, lsl #1\n",
                "ldrsb {c}, [{p}]\n",
                "ldrsb {d}, [{p}, {st}]\n",
                "add {p}, {p}, {st}, lsl #1\n",
                "pkhbt {a}, {a}, {c}, lsl #16\n",
                "pkhbt {b}, {b}, {d}, lsl #16\n",
                "ssub16 {a}, {a}, {zz}\n",
                "ssub16 {b}, {b}, {zz}\n",
                "strd {a}, {b}, [{o}], #8\n",
            )
        };
    }
    // SAFETY: the bytes read are `src[k·stride]`, `k < 12`, all within `src` (checked); the
    // six words written are `out`'s (4-aligned, as `STRD` needs).
    unsafe {
        core::arch::asm!(
            quad!(),
            quad!(),
            quad!(),
            p = inout(reg) src.as_ptr() => _,
            st = in(reg) stride,
            o = inout(reg) out.as_mut_ptr() => _,
            zz = in(reg) zz,
            a = out(reg) _,
            b = out(reg) _,
            c = out(reg) _,
            d = out(reg) _,
            options(nostack),
        );
    }
    true
}

/// [`pack_pixel`] of `x_k = src[k·stride] − zp` for `k < 2·out.len()` (one pixel's channels
/// of a planar map), four codes per pass; `false` (nothing written) if `src` is too short or
/// `out` is not whole pairs of words.
pub fn pack_strided(src: &[i8], stride: usize, zp: i32, out: &mut [u32]) -> bool {
    let k = 2 * out.len();
    if !out.len().is_multiple_of(2) || k > 0 && (k - 1).saturating_mul(stride) >= src.len() {
        return false;
    }
    let mut x = src.iter().step_by(stride.max(1));
    let mut half = || x.next().map_or(0, |&v| (i32::from(v) - zp) as u32 & 0xFFFF);
    for o in out.chunks_exact_mut(2) {
        let (x0, x1, x2, x3) = (half(), half(), half(), half());
        o[0] = x0 | x2 << 16;
        o[1] = x1 | x3 << 16;
    }
    true
}

/// Packs `x_k` (`k < 4·⌊len/4⌋`, 16-bit) as `[x0|x2], [x1|x3], [x4|x6], …` for [`dot_rows`].
pub fn pack_pixel(x: impl Iterator<Item = i32>, out: &mut [u32]) {
    let mut quad = [0u32; 4];
    for (k, v) in x.enumerate() {
        quad[k % 4] = (v as u32) & 0xFFFF;
        if k % 4 == 3 {
            if let Some(o) = out.get_mut(k / 4 * 2..k / 4 * 2 + 2) {
                o[0] = quad[0] | (quad[2] << 16);
                o[1] = quad[1] | (quad[3] << 16);
            }
        }
    }
}

/// The end of every requantisation step: from the high product `{x}`, the rounding right shift
/// by `{e}` with the zero point (`{half}` = 2^(e−1) + zp·2^e: adding `zp·2^e` before the
/// arithmetic shift adds exactly `zp` after it, and with `|x| ≤ 2^30` nothing overflows), int8
/// saturation and the store; `floor` adds the activation floor `{min}` before the store (a
/// floor of −128 is the saturation's own, so those rows skip it).
macro_rules! requant_tail {
    ($tail:tt) => {
        concat!(
            "add {lo}, {x}, {half}\n",
            "sub {lo}, {lo}, {x}, lsr #31\n",
            "asr {lo}, {lo}, {e}\n",
            "ssat {lo}, #8, {lo}\n",
            requant_floor!($tail),
            "strb {lo}, [{d}], #1\n",
        )
    };
}

/// The activation floor `{min}` of a requantisation step (`floor`), or nothing (`plain`).
macro_rules! requant_floor {
    (plain) => {
        ""
    };
    (floor) => {
        concat!("cmp {lo}, {min}\n", "it lt\n", "movlt {lo}, {min}\n")
    };
}

/// A loop of `{n}` (≥ 1) requantisation steps `$step`, four per pass (`{c}` counts the
/// passes), then the last one to three one at a time.
macro_rules! requant_loop {
    ($step:expr) => {
        concat!(
            "lsrs {c}, {n}, #2\n",
            "beq 3f\n",
            "2:\n",
            $step,
            $step,
            $step,
            $step,
            "subs {c}, {c}, #1\n",
            "bne 2b\n",
            "3:\n",
            "ands {n}, {n}, #3\n",
            "beq 4f\n",
            "5:\n",
            $step,
            "subs {n}, {n}, #1\n",
            "bne 5b\n",
            "4:\n",
        )
    };
}

/// The asm block of a requantisation loop (`requant_loop!` of `$step`) over `$n` ≥ 1 sums of
/// `$acc` into `$dst`: `{b}` is the doubled base for `SMMULR` or the base for `SMLAL`; `$extra`
/// the step's own operands.
macro_rules! requant_asm {
    ($acc:expr, $dst:expr, $n:expr, $b:expr, $step:expr; $($extra:tt)*) => {
        core::arch::asm!(
            requant_loop!($step),
            a = inout(reg) $acc.as_ptr() => _,
            d = inout(reg) $dst.as_mut_ptr() => _,
            n = inout(reg) $n => _,
            c = out(reg) _,
            b = in(reg) $b,
            x = out(reg) _,
            lo = out(reg) _,
            $($extra)*
            options(nostack),
        )
    };
}

/// One sum of [`requant_row`] from the doubled sum with `SMMLAR` (narrow sums): the rounded
/// high product of `{x}` = 2·sum by `{m}` added to `{half}` − [sum < 0] in one instruction
/// (`SMMLAR` adds its accumulate as the high word, so `(h·2^32 + 2x·m + 2^31) >> 32` is exactly
/// `h + q`), then the shift, saturation, floor and store of `requant_tail!`. The rounding's
/// `− [q < 0]` is taken from the sum's sign: with `m ≥ 0`, `q < 0` only for a negative sum and
/// `q > 0` only for a positive one, and where `q = 0` it changes nothing (`⌊(2^(e−1) − 1 +
/// zp·2^e) / 2^e⌋ = zp = ⌊(2^(e−1) + zp·2^e) / 2^e⌋`).
macro_rules! narrow_step {
    ($tail:tt) => {
        concat!(
            "ldr {x}, [{a}], #4\n",
            "add {x}, {b}, {x}, lsl #1\n",
            "sub {lo}, {half}, {x}, lsr #31\n",
            "smmlar {lo}, {x}, {m}, {lo}\n",
            "asr {lo}, {lo}, {e}\n",
            "ssat {lo}, #8, {lo}\n",
            requant_floor!($tail),
            "strb {lo}, [{d}], #1\n",
        )
    };
}

/// The doubling high product of the sum `{x}` by `{m}` with `SMLAL`, pre-clamped to 31 bits
/// (any sum), into `{x}`.
macro_rules! wide_high {
    () => {
        concat!(
            "mov {lo}, #0x40000000\n",
            "mov {hi}, #0\n",
            "smlal {lo}, {hi}, {x}, {m}\n",
            "lsr {lo}, {lo}, #31\n",
            "orr {x}, {lo}, {hi}, lsl #1\n",
            "ssat {x}, #31, {x}\n",
        )
    };
}

/// The high product of one sum of [`requant_row`] with `SMLAL` and the 31-bit pre-clamp (any
/// sum), then the tail.
macro_rules! wide_step {
    ($tail:tt) => {
        concat!(
            "ldr {x}, [{a}], #4\n",
            "add {x}, {x}, {b}\n",
            wide_high!(),
            requant_tail!($tail),
        )
    };
}

/// `requant_one` of the conv over a row for one multiplier `m ≥ 0` and right shift `e`
/// (`1 ..= 22`), `max` 127: `dst[i] = max(min, sat8(zp + rdbpot(srdhm(base + acc[i], m), e)))`.
/// `narrow` (every `|base + acc[i]| < 2^30`): `SMMULR` of the doubled sum is the doubling high
/// multiply, `(2x·m + 2^31) >> 32 = ⌊(x·m + 2^30) / 2^31⌋`, in `SMMLAR` with the rounding
/// term (`narrow_step!`): 10.5 instructions per element (7.5 where the floor `min` is −128);
/// otherwise `SMLAL` and an `SSAT` pre-clamp, 16.5 (13.5).
/// `false` (nothing written) outside those cases.
///
/// The pre-clamp of the high product `q` to `[−2^30, 2^30 − 1]` keeps `q + 2^(e−1)` in i32 and
/// changes no result: beyond it `|q| / 2^e ≥ 2^30 / 2^22 = 256`, which saturates either way
/// (with `narrow`, `|q| ≤ |x| < 2^30` already).
#[allow(clippy::too_many_arguments)]
pub fn requant_row(
    acc: &[i32],
    dst: &mut [i8],
    base: i32,
    (m, e): (i32, i32),
    zp: i32,
    min: i32,
    max: i32,
    narrow: bool,
) -> bool {
    let n = acc.len().min(dst.len());
    if !(1..=22).contains(&e) || m < 0 || max != 127 || !(-128..=127).contains(&min) || n == 0 {
        return n == 0;
    }
    let half = (1i32 << (e - 1)) + (zp << e);
    // One asm block per (narrow, floor) case; the operands only some cases use: the floor,
    // `SMLAL`'s high word.
    macro_rules! run {
        ($step:ident, $tail:tt, $b:expr; $($extra:tt)*) => {
            // SAFETY: `n` ≥ 1 words of `acc` and `n` bytes of `dst` exist (n ≤ both lengths).
            unsafe {
                requant_asm!(acc, dst, n, $b, $step!($tail);
                    m = in(reg) m, half = in(reg) half, e = in(reg) e, $($extra)*)
            }
        };
    }
    let base2 = base.wrapping_mul(2);
    match (narrow, min > -128) {
        (true, true) => run!(narrow_step, floor, base2; min = in(reg) min,),
        (true, false) => run!(narrow_step, plain, base2;),
        (false, true) => run!(wide_step, floor, base; min = in(reg) min, hi = out(reg) _,),
        (false, false) => run!(wide_step, plain, base; hi = out(reg) _,),
    }
    true
}

/// The constants of [`requant_row_signed`], picked by the sum's sign bit: per sign (`[sum ≥ 0,
/// sum < 0]`, 16 bytes apart) the multiplier, `2^(shift − 1) + zp·2^shift − [sum < 0]` (the
/// zero point and the rounding's `− [q < 0]` folded in, as in `narrow_step!`) and the right
/// shift, for one `LDM`.
#[repr(C)]
struct SignQuant {
    /// `[m, half, shift, unused]` for sums ≥ 0, then for sums < 0.
    k: [[i32; 4]; 2],
}

/// The sign bit of the sum `{x}` picks the constants: `r2` = `{kp}` + 16·sign. The steps
/// below name `r0`–`r2` in the text (explicit operands have no names): `LDM` fills registers
/// in number order.
macro_rules! pick_sign {
    () => {
        concat!("lsr r2, {x}, #31\n", "add r2, {kp}, r2, lsl #4\n",)
    };
}

/// The end of a [`requant_row_signed`] step from `{lo}` = the high product plus the picked
/// rounding term, the picked shift in `r2`: shift, saturation, floor and store.
macro_rules! signed_tail {
    ($tail:tt) => {
        concat!(
            "asr {lo}, {lo}, r2\n",
            "ssat {lo}, #8, {lo}\n",
            requant_floor!($tail),
            "strb {lo}, [{d}], #1\n",
        )
    };
}

/// One sum of [`requant_row_signed`] with narrow sums: one `LDM` of the picked multiplier
/// (`r0`), rounding term (`r1`) and shift (`r2`, over the address), the doubled sum's `SMMLAR`
/// with the rounding term (as `narrow_step!`): 9 instructions (12 with a floor).
macro_rules! signed_narrow_step {
    ($tail:tt) => {
        concat!(
            "ldr {x}, [{a}], #4\n",
            "add {x}, {b}, {x}, lsl #1\n",
            pick_sign!(),
            "ldm r2, {{r0, r1, r2}}\n",
            "smmlar {lo}, {x}, r0, r1\n",
            signed_tail!($tail),
        )
    };
}

/// One sum of [`requant_row_signed`] with `SMLAL` and the pre-clamp (any sum): the
/// `wide_high!` steps on `r0` (multiplier) and `r1` (high word), then the rounding term and
/// the shift loaded from the picked constants.
macro_rules! signed_wide_step {
    ($tail:tt) => {
        concat!(
            "ldr {x}, [{a}], #4\n",
            "add {x}, {x}, {b}\n",
            pick_sign!(),
            "ldr r0, [r2]\n",
            "mov {lo}, #0x40000000\n",
            "mov r1, #0\n",
            "smlal {lo}, r1, {x}, r0\n",
            "lsr {lo}, {lo}, #31\n",
            "orr {x}, {lo}, r1, lsl #1\n",
            "ssat {x}, #31, {x}\n",
            "ldr r1, [r2, #4]\n",
            "add {lo}, {x}, r1\n",
            "ldr r2, [r2, #8]\n",
            signed_tail!($tail),
        )
    };
}

/// [`requant_row`] with a multiplier and shift per sign of `base + acc[i]` (`pos` for ≥ 0,
/// `neg` below: the leaky ReLU's two slopes): with `narrow` the doubled sum's `SMMLAR`, 12.5
/// instructions per element (9.5 without a floor), otherwise `SMLAL` and the pre-clamp, 20.5
/// (17.5). `false` (nothing written) unless both shifts are `1 ..= 22`, both multipliers ≥ 0
/// and `max` is 127.
#[allow(clippy::too_many_arguments)]
pub fn requant_row_signed(
    acc: &[i32],
    dst: &mut [i8],
    base: i32,
    pos: (i32, i32),
    neg: (i32, i32),
    zp: i32,
    min: i32,
    max: i32,
    narrow: bool,
) -> bool {
    let n = acc.len().min(dst.len());
    let ok = |(m, e): (i32, i32)| m >= 0 && (1..=22).contains(&e);
    if !ok(pos) || !ok(neg) || max != 127 || !(-128..=127).contains(&min) || n == 0 {
        return n == 0;
    }
    let half = |(_, e): (i32, i32)| (1 << (e - 1)) + (zp << e);
    let table = SignQuant {
        k: [
            [pos.0, half(pos), pos.1, 0],
            [neg.0, half(neg) - 1, neg.1, 0],
        ],
    };
    macro_rules! run {
        ($step:ident, $tail:tt, $b:expr; $($extra:tt)*) => {
            // SAFETY: `n` ≥ 1 words of `acc` and `n` bytes of `dst` exist (n ≤ both lengths);
            // `table` holds the constants of both signs (sign bit 1 picks those 16 bytes on,
            // 4-aligned words for `LDM`/`LDR`). With `narrow` every |base + acc| < 2^30, so
            // doubling it keeps its sign and `SMMLAR` is the doubling high multiply plus the
            // rounding term (as in `requant_row`). r0–r2 are declared clobbered.
            unsafe {
                requant_asm!(acc, dst, n, $b, $step!($tail);
                    kp = in(reg) core::ptr::addr_of!(table), $($extra)* out("r0") _,
                    out("r1") _, out("r2") _,)
            }
        };
    }
    let base2 = base.wrapping_mul(2);
    match (narrow, min > -128) {
        (true, true) => run!(signed_narrow_step, floor, base2; min = in(reg) min,),
        (true, false) => run!(signed_narrow_step, plain, base2;),
        (false, true) => run!(signed_wide_step, floor, base; min = in(reg) min,),
        (false, false) => run!(signed_wide_step, plain, base;),
    }
    true
}

/// One kernel row of the depthwise ring (`depthwise::ring_rows`) at stride 2: `acc[ox]` (from
/// zero where `first`) plus the `J = words.len()` (1 ..= 4) `SMLAD` of the words at
/// `row + 4·ox + 4·j` bytes against `words[j]`. `false` (nothing done) for other `J`.
///
/// # Safety
/// `row` is 4-aligned and `4·(acc.len() − 1 + J)` bytes from it are readable.
pub unsafe fn pair_row_s2(row: *const i16, words: &[u32], first: bool, acc: &mut [i32]) -> bool {
    if acc.is_empty() {
        return true;
    }
    let w = |j: usize| words.get(j).copied().unwrap_or(0);
    // One word per tap pair; `{s}` starts at zero or at the pixel's sum.
    macro_rules! run {
        ($start:literal, $($taps:literal),*) => {
            core::arch::asm!(
                "2:",
                $start,
                $(concat!("ldr {x}, [{p}, #", $taps, "]\n", "smlad {s}, {x}, {w", $taps, "}, {s}\n"),)*
                "add {p}, {p}, #4",
                "str {s}, [{a}], #4",
                "cmp {a}, {end}",
                "bne 2b",
                p = inout(reg) row => _,
                a = inout(reg) acc.as_mut_ptr() => _,
                end = in(reg) acc.as_mut_ptr().add(acc.len()),
                w0 = in(reg) w(0),
                w4 = in(reg) w(1),
                w8 = in(reg) w(2),
                w12 = in(reg) w(3),
                x = out(reg) _,
                s = out(reg) _,
                options(nostack),
            )
        };
    }
    // `asm!` wants every operand used: the weight words past `J` are named in an assembler
    // comment of the first instruction (their registers hold 0 and are never read).
    match (words.len(), first) {
        (1, true) => run!("mov {s}, #0 /* {w4} {w8} {w12} */", "0"),
        (1, false) => run!("ldr {s}, [{a}] /* {w4} {w8} {w12} */", "0"),
        (2, true) => run!("mov {s}, #0 /* {w8} {w12} */", "0", "4"),
        (2, false) => run!("ldr {s}, [{a}] /* {w8} {w12} */", "0", "4"),
        (3, true) => run!("mov {s}, #0 /* {w12} */", "0", "4", "8"),
        (3, false) => run!("ldr {s}, [{a}] /* {w12} */", "0", "4", "8"),
        (4, true) => run!("mov {s}, #0", "0", "4", "8", "12"),
        (4, false) => run!("ldr {s}, [{a}]", "0", "4", "8", "12"),
        _ => return false,
    }
    true
}

/// One output row of the 3×3 depthwise ring strip (`depthwise::ring3`): `acc[ox]` = the
/// 12 halfwords from `strip + 8·sx·ox` bytes (three columns of `[row, row, row, 0]`) against
/// the 12 halfwords of `taps`, as six `SMLAD` over word pairs: 11 instructions per pixel
/// (nine multiply-accumulates).
///
/// # Safety
/// `strip` is 4-aligned and `((acc.len() − 1)·sx + 3)·4` halfwords from it are readable;
/// `sx` is 1 or 2.
pub unsafe fn ring3_row(strip: *const i16, taps: &[i16; 12], sx: usize, acc: &mut [i32]) {
    if acc.is_empty() {
        return;
    }
    // Halfword pairs as words, the lower address in the low half (as `LDRD` reads the strip).
    let w: [u32; 6] = core::array::from_fn(|k| {
        (taps[2 * k] as u16 as u32) | ((taps[2 * k + 1] as u16 as u32) << 16)
    });
    if sx == 1 {
        ring3::<8>(strip, &w, acc);
    } else {
        ring3::<16>(strip, &w, acc);
    }
}

/// [`ring3_row`] with the pixel step `STEP` bytes as an immediate: two pixels per pass, each
/// reading its first column post-indexed (the pointer then sits at the next pixel, the other
/// two columns at `8 − STEP` and `16 − STEP` bytes from it): 11 instructions per pixel, then
/// the odd one.
///
/// # Safety
/// The conditions of [`ring3_row`] with `STEP = 8·sx` bytes, and `acc` is not empty.
#[inline(always)]
unsafe fn ring3<const STEP: usize>(strip: *const i16, w: &[u32; 6], acc: &mut [i32]) {
    macro_rules! pixel {
        () => {
            concat!(
                "ldrd {x0}, {x1}, [{p}], #{step}\n",
                "smuad {s}, {x0}, {w0}\n",
                "smlad {s}, {x1}, {w1}, {s}\n",
                "ldrd {x0}, {x1}, [{p}, #{c1}]\n",
                "smlad {s}, {x0}, {w2}, {s}\n",
                "smlad {s}, {x1}, {w3}, {s}\n",
                "ldrd {x0}, {x1}, [{p}, #{c2}]\n",
                "smlad {s}, {x0}, {w4}, {s}\n",
                "smlad {s}, {x1}, {w5}, {s}\n",
                "str {s}, [{a}], #4\n",
            )
        };
    }
    let n = acc.len();
    let mut p = strip;
    let mut a = acc.as_mut_ptr();
    if n >= 2 {
        core::arch::asm!(
            "2:",
            pixel!(),
            pixel!(),
            "cmp {a}, {end}",
            "bne 2b",
            step = const STEP,
            c1 = const 8 - STEP as isize,
            c2 = const 16 - STEP as isize,
            p = inout(reg) p,
            a = inout(reg) a,
            end = in(reg) a.add(n & !1),
            w0 = in(reg) w[0],
            w1 = in(reg) w[1],
            w2 = in(reg) w[2],
            w3 = in(reg) w[3],
            w4 = in(reg) w[4],
            w5 = in(reg) w[5],
            x0 = out(reg) _,
            x1 = out(reg) _,
            s = out(reg) _,
            options(nostack),
        );
    }
    if n % 2 == 1 {
        core::arch::asm!(
            pixel!(),
            step = const STEP,
            c1 = const 8 - STEP as isize,
            c2 = const 16 - STEP as isize,
            p = inout(reg) p => _,
            a = inout(reg) a => _,
            w0 = in(reg) w[0],
            w1 = in(reg) w[1],
            w2 = in(reg) w[2],
            w3 = in(reg) w[3],
            w4 = in(reg) w[4],
            w5 = in(reg) w[5],
            x0 = out(reg) _,
            x1 = out(reg) _,
            s = out(reg) _,
            options(nostack),
        );
    }
}
