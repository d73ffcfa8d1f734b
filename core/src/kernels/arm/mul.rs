//! Cortex-M4/M7 loop of the int8 `mul`'s high-word product (`Product::apply_high` in
//! [`crate::kernels::elementwise`]): both codes in one word (`PKHBT`), both zero points off in one
//! `SSUB16`, the product by `SMULBT`, the magnitude's high word by `UMULL`; 16 instructions per
//! element, two per pass (the compiled loop took 25). Exact integer steps: the same bits as the portable loop.

/// The constants of [`high_row`]: the high-word product of `apply_high`.
#[derive(Clone, Copy, Debug)]
pub struct HighProduct {
    /// Zero points of the two operands and of the output.
    pub zp: [i32; 3],
    /// The multiplier `M < 2^31`.
    pub m: u32,
    /// The product's right shift `r`, `33 ..= 62`.
    pub right: u32,
}

/// `out[i] = sat8(zp_out ± ((hi(|p|·M) + 2^(r−33)) >> (r − 32)))` with
/// `p = (out[i] − zp_a)·(b[i] − zp_b)`, the sign of `p` on the magnitude, over
/// `min(out.len(), b.len())` elements. `false` (nothing written) unless `r` is `33 ..= 62`,
/// `M < 2^31` and both operand zero points are int8 codes.
pub fn high_row(q: &HighProduct, out: &mut [i8], b: &[i8]) -> bool {
    let n = out.len().min(b.len());
    let [za, zb, zo] = q.zp;
    let code = -128..=127;
    if !(33..=62).contains(&q.right) || q.m >= 1 << 31 || !code.contains(&za) || !code.contains(&zb)
    {
        return false;
    }
    if n == 0 {
        return true;
    }
    // The two zero points as the 16-bit halves `SSUB16` takes off `[a | b]`.
    let zz = (za as u16 as u32) | ((zb as u16 as u32) << 16);
    let k = 1u32 << (q.right - 33);
    let s = q.right - 32;
    macro_rules! step {
        () => {
            concat!(
                "ldrsb {x}, [{o}]\n",
                "ldrsb {y}, [{b}], #1\n",
                "pkhbt {x}, {x}, {y}, lsl #16\n",
                "ssub16 {x}, {x}, {zz}\n",
                "smulbt {x}, {x}, {x}\n",
                // |p|, its high product word, the rounding and the shift.
                "eor {y}, {x}, {x}, asr #31\n",
                "sub {y}, {y}, {x}, asr #31\n",
                "umull {y}, {hi}, {y}, {m}\n",
                "add {hi}, {hi}, {k}\n",
                "lsr {hi}, {hi}, {s}\n",
                // p's sign back on, the output zero point, int8 saturation.
                "eor {hi}, {hi}, {x}, asr #31\n",
                "sub {hi}, {hi}, {x}, asr #31\n",
                "add {hi}, {hi}, {zo}\n",
                "ssat {hi}, #8, {hi}\n",
                "strb {hi}, [{o}], #1\n",
            )
        };
    }
    let (mut o, mut bp) = (out.as_mut_ptr(), b.as_ptr());
    // Two elements per pass, then the odd one.
    if n >= 2 {
        // SAFETY: `2·⌊n/2⌋ ≤ n` bytes of `out` and of `b` exist (n ≤ both lengths); each byte
        // of `out` is read before it is written, and the loop stops when `o` reaches `end`.
        unsafe {
            core::arch::asm!(
                "2:",
                step!(),
                step!(),
                "cmp {o}, {end}",
                "bne 2b",
                o = inout(reg) o,
                b = inout(reg) bp,
                end = in(reg) out.as_mut_ptr().add(n & !1),
                zz = in(reg) zz,
                m = in(reg) q.m,
                k = in(reg) k,
                s = in(reg) s,
                zo = in(reg) zo,
                x = out(reg) _,
                y = out(reg) _,
                hi = out(reg) _,
                options(nostack),
            );
        }
    }
    if n % 2 == 1 {
        // SAFETY: the last byte of `out` and of `b` (index n − 1, where `o` and `bp` point).
        unsafe {
            core::arch::asm!(
                step!(),
                o = inout(reg) o => _,
                b = inout(reg) bp => _,
                zz = in(reg) zz,
                m = in(reg) q.m,
                k = in(reg) k,
                s = in(reg) s,
                zo = in(reg) zo,
                x = out(reg) _,
                y = out(reg) _,
                hi = out(reg) _,
                options(nostack),
            );
        }
    }
    true
}
