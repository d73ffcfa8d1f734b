//! Cortex-M4/M7 row of the int8 bilinear resize into other quantisation parameters
//! ([`crate::kernels::resize`]'s rescaled path): the column blend of the two blended input
//! values as one `SMLAD` of a word of neighbouring 16-bit blends (accumulating the input zero-point offset), the
//! rescale as one `SMMLA` (the rounding half and the output zero point in its accumulate word),
//! one shift and the int8 saturation: 8 instructions per output element, two per pass (the
//! compiled loop took 19). Exact integer steps: the same bits as the portable path.

/// The per-call constants of [`rescaled_row`].
#[derive(Clone, Copy, Debug)]
pub struct RowRescale {
    /// `−zp_in·d`: the input zero point's share of the weighted sum, taken off by `SMLAD`.
    pub neg_offset: i32,
    /// The factor `k` (`s_in / (s_out·d) · 2^shift`).
    pub k: i32,
    /// `2^(shift − 33) + zp_out·2^(shift − 32)`: `SMMLA`'s accumulate word.
    pub add: i32,
    /// `shift − 32`, `1 ..= 23`.
    pub sh: u32,
}

/// `out[o] = sat8((((n_o − zp_in·d)·k + 2^(shift−1)) >> shift) + zp_out)` (the output zero
/// point added inside the shift, which is exact) with `n_o` the `SMLAD` of the word at byte
/// offset `taps[2o]` of `blend` (`[v_x0 | v_x0+1]`: two neighbouring 16-bit blends, read as one
/// word, unaligned where `x0` is odd, which Cortex-M4/M7 `LDR` allows) and the packed weights
/// `taps[2o + 1]` (`[den − f | f]`), for every `o < out.len()`.
///
/// # Safety
/// `taps` holds `2·out.len()` words; every `taps[2o]` is even and `taps[2o] + 4` bytes of
/// `blend` are readable; `r.sh` is `1 ..= 31`; the core reads unaligned words with `LDR`.
pub unsafe fn rescaled_row(blend: &[i16], taps: &[u32], r: &RowRescale, out: &mut [i8]) {
    macro_rules! step {
        () => {
            concat!(
                "ldrd {off}, {w}, [{t}], #8\n",
                "ldr {v}, [{p}, {off}]\n",
                "smlad {off}, {v}, {w}, {neg}\n",
                "smmla {off}, {off}, {k}, {add}\n",
                "asr {off}, {off}, {sh}\n",
                "ssat {off}, #8, {off}\n",
                "strb {off}, [{o}], #1\n",
            )
        };
    }
    let n = out.len();
    let (mut t, mut o) = (taps.as_ptr(), out.as_mut_ptr());
    // Two outputs per pass, then the odd one.
    if n >= 2 {
        core::arch::asm!(
            "2:",
            step!(),
            step!(),
            "cmp {o}, {end}",
            "bne 2b",
            t = inout(reg) t,
            p = in(reg) blend.as_ptr(),
            o = inout(reg) o,
            end = in(reg) out.as_mut_ptr().add(n & !1),
            neg = in(reg) r.neg_offset,
            k = in(reg) r.k,
            add = in(reg) r.add,
            sh = in(reg) r.sh,
            off = out(reg) _,
            w = out(reg) _,
            v = out(reg) _,
            options(nostack),
        );
    }
    if n % 2 == 1 {
        core::arch::asm!(
            step!(),
            t = inout(reg) t => _,
            p = in(reg) blend.as_ptr(),
            o = inout(reg) o => _,
            neg = in(reg) r.neg_offset,
            k = in(reg) r.k,
            add = in(reg) r.add,
            sh = in(reg) r.sh,
            off = out(reg) _,
            w = out(reg) _,
            v = out(reg) _,
            options(nostack),
        );
    }
}
