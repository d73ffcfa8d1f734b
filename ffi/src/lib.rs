//! # depthor-ffi
//!
//! The C ABI of depthor-core: the functions declared in `ffi/include/depthor.h` (generated
//! from this crate by cbindgen: `build.rs`, `cbindgen.toml`; `ffi/tests/header.rs` holds the
//! committed copy equal to the generated one), built as `libdepthor_ffi.a` and
//! `libdepthor_ffi.so`. The contract (memory, lifetimes, threads, error codes) is
//! `docs/ffi.md`.
//!
//! - Every argument is checked: NULL, alignment, lengths (against the engine's input size and
//!   for address-space overflow), and overlaps between buffers that one call reads and writes.
//!   A bad argument returns a negative `DEPTHOR_E_*` code and touches nothing.
//! - Nothing allocates. The engine object lives in caller memory (`depthor_engine_size()` /
//!   `depthor_engine_align()` bytes), the arena too; the engine borrows the blob and the arena
//!   until the caller stops using the engine.
//! - Nothing unwinds into C. With the `std` feature (the Linux libraries) each entry point runs
//!   under `catch_unwind` and a panic (a bug: the core is panic-free on bad input) becomes
//!   [`DEPTHOR_E_INTERNAL`]. The no_std build (`--no-default-features`, for firmware) has a
//!   panic handler that executes `udf` on Arm (a HardFault the firmware's handler sees) and
//!   spins elsewhere.
#![no_std]
#![deny(unsafe_op_in_unsafe_fn)]
#![warn(missing_docs)]
// The C names are the API (`depthor_engine`, `depthor_calibration`, …).
#![allow(non_camel_case_types)]

#[cfg(any(test, feature = "std"))]
extern crate std;

use core::ffi::{c_char, c_uchar, c_void};
use core::mem::{align_of, size_of, MaybeUninit};
use core::ptr::{addr_of, addr_of_mut};
use core::slice;

use depthor_core::blob::{parse, BlobError};
use depthor_core::calibration::{
    Calibration, CameraIntrinsics, DistanceKind, DtofGeometry, Extrinsics,
};
use depthor_core::engine::{required_arena_bytes, Engine, Error, Memory};
use depthor_core::hal::ZoneView;
use depthor_core::projection::{project_to_sparse, ProjectionError};

/// Success.
pub const DEPTHOR_OK: i32 = 0;
/// A required pointer argument is NULL.
pub const DEPTHOR_E_NULL: i32 = -1;
/// A pointer is not aligned for its type: the engine memory to `depthor_engine_align()`, a
/// `float` buffer or a struct to its alignment.
pub const DEPTHOR_E_ALIGN: i32 = -2;
/// The blob is malformed (bad magic, truncated, a field or op out of range).
pub const DEPTHOR_E_BLOB: i32 = -3;
/// The blob's payload CRC-32 does not match its header (corrupted in storage or transfer).
pub const DEPTHOR_E_BLOB_CHECKSUM: i32 = -4;
/// The blob's format version is not one this library reads.
pub const DEPTHOR_E_BLOB_VERSION: i32 = -5;
/// The network cannot run at the requested height × width (one side 0, too large, or shapes
/// that do not fit together at that size).
pub const DEPTHOR_E_SIZE: i32 = -6;
/// The arena is smaller than `depthor_arena_bytes()` reports.
pub const DEPTHOR_E_ARENA: i32 = -7;
/// A buffer's length is wrong (RGB must be `3·H·W` bytes, depth maps `H·W` floats, the zone
/// arrays `rows·cols`), or pointer + length overflows the address space.
pub const DEPTHOR_E_LENGTH: i32 = -8;
/// Buffers overlap where one call writes one and reads or owns another (engine memory, arena,
/// blob, inputs, output).
pub const DEPTHOR_E_OVERLAP: i32 = -9;
/// The engine memory was not initialised by a successful `depthor_engine_init`.
pub const DEPTHOR_E_NOT_INIT: i32 = -10;
/// The calibration is unusable (focal length, field of view, range, rotation, distance kind).
pub const DEPTHOR_E_CALIBRATION: i32 = -11;
/// An internal error: a kernel refused its operands, or (std build) a panic was caught. A bug;
/// please report it with the blob.
pub const DEPTHOR_E_INTERNAL: i32 = -12;

/// Every status code, in order (the tests and `depthor_status_message` use it).
pub const ALL_STATUS: [i32; 13] = [
    DEPTHOR_OK,
    DEPTHOR_E_NULL,
    DEPTHOR_E_ALIGN,
    DEPTHOR_E_BLOB,
    DEPTHOR_E_BLOB_CHECKSUM,
    DEPTHOR_E_BLOB_VERSION,
    DEPTHOR_E_SIZE,
    DEPTHOR_E_ARENA,
    DEPTHOR_E_LENGTH,
    DEPTHOR_E_OVERLAP,
    DEPTHOR_E_NOT_INIT,
    DEPTHOR_E_CALIBRATION,
    DEPTHOR_E_INTERNAL,
];

/// `depthor_calibration.distance_kind`: distances along the sensor's optical axis (VL53L5CX).
pub const DEPTHOR_DISTANCE_Z: u32 = 0;
/// `depthor_calibration.distance_kind`: distances along each zone's ray.
pub const DEPTHOR_DISTANCE_RADIAL: u32 = 1;

/// Bytes of `depthor_engine_storage` on 32-bit targets (Cortex-M: the engine object is
/// 33 080 B on thumbv7em).
pub const DEPTHOR_ENGINE_STORAGE_BYTES_32: usize = 36864;
/// Bytes of `depthor_engine_storage` on 64-bit targets (49 416 B on x86-64).
pub const DEPTHOR_ENGINE_STORAGE_BYTES_64: usize = 53248;
/// Bytes of `depthor_engine_storage`, the header's statically sized engine memory, on this
/// target: at least `depthor_engine_size()` (checked at compile time below).
pub const DEPTHOR_ENGINE_STORAGE_BYTES: usize = if cfg!(target_pointer_width = "32") {
    DEPTHOR_ENGINE_STORAGE_BYTES_32
} else {
    DEPTHOR_ENGINE_STORAGE_BYTES_64
};

/// Written into [`EngineState::magic`] by a successful init ("DPTE").
const MAGIC: u32 = 0x4450_5445;

/// The engine object: opaque, in caller memory of `depthor_engine_size()` bytes aligned to
/// `depthor_engine_align()` (or a `depthor_engine_storage`). C sees only its name.
// Not `repr(C)`: cbindgen then declares it opaquely (`typedef struct depthor_engine
// depthor_engine;`). Its one field is the `repr(C)` state; C reads the size and alignment from
// `depthor_engine_size()` / `depthor_engine_align()`, never from a layout of its own.
pub struct depthor_engine(EngineState);

/// What a `depthor_engine` holds.
#[repr(C)]
struct EngineState {
    /// [`MAGIC`] once `depthor_engine_init` succeeded, anything else before.
    magic: u32,
    /// The blob the engine borrows (for the overlap checks of `depthor_engine_run`).
    blob: *const u8,
    blob_len: usize,
    /// The arena the engine borrows (same reason).
    arena: *mut u8,
    arena_len: usize,
    /// Initialised when `magic == MAGIC`.
    engine: MaybeUninit<Engine<'static>>,
}

/// Statically sized, suitably aligned engine memory (e.g. a static in firmware):
///
/// ```c
/// static depthor_engine_storage mem;
/// depthor_engine *engine = (depthor_engine *)&mem;
/// ```
///
/// At least `depthor_engine_size()` bytes aligned to `depthor_engine_align()` on every target
/// of its pointer width (checked at compile time on each target the library is built for).
#[repr(C)]
pub union depthor_engine_storage {
    /// The engine's bytes.
    pub bytes: [c_uchar; DEPTHOR_ENGINE_STORAGE_BYTES],
    /// Aligns the storage for a `uint64_t`.
    pub align_u64: u64,
    /// Aligns the storage for a `double`.
    pub align_double: f64,
    /// Aligns the storage for a pointer.
    pub align_ptr: *mut c_void,
}

const _: () = assert!(size_of::<depthor_engine>() <= DEPTHOR_ENGINE_STORAGE_BYTES);
const _: () = assert!(size_of::<depthor_engine>() <= size_of::<depthor_engine_storage>());
const _: () = assert!(align_of::<depthor_engine>() <= align_of::<depthor_engine_storage>());
// The header's storage union aligns to uint64_t / double / void *: 8 bytes on every target.
const _: () = assert!(align_of::<depthor_engine>() <= 8);

/// Calibration for `depthor_project_to_sparse` (the core's `Calibration` without per-zone
/// rectangles).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct depthor_calibration {
    /// Camera image width in pixels.
    pub width: u32,
    /// Camera image height in pixels.
    pub height: u32,
    /// Focal length x, pixels.
    pub fx: f32,
    /// Focal length y, pixels.
    pub fy: f32,
    /// Principal point x, pixels.
    pub cx: f32,
    /// Principal point y, pixels.
    pub cy: f32,
    /// dToF zone rows.
    pub zone_rows: u16,
    /// dToF zone columns.
    pub zone_cols: u16,
    /// `DEPTHOR_DISTANCE_Z` or `DEPTHOR_DISTANCE_RADIAL`.
    pub distance_kind: u32,
    /// Full horizontal field of view of the zone grid, degrees.
    pub fov_h_deg: f32,
    /// Full vertical field of view of the zone grid, degrees.
    pub fov_v_deg: f32,
    /// Largest distance the sensor reports, metres.
    pub max_range_m: f32,
    /// dToF → camera rotation, row-major 3×3.
    pub rotation: [f32; 9],
    /// dToF → camera translation, metres.
    pub translation_m: [f32; 3],
}

/// What `depthor_project_to_sparse` did (the core's `ProjectionStats`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct depthor_projection_stats {
    /// Zones in the frame.
    pub zones: u32,
    /// Zones written into the sparse map.
    pub projected: u32,
    /// Zones skipped for their target status.
    pub invalid_status: u32,
    /// Zones skipped for a distance ≤ 0, beyond range or not finite.
    pub bad_distance: u32,
    /// Zones whose point lies behind the camera.
    pub behind_camera: u32,
    /// Zones whose point falls outside the image.
    pub out_of_image: u32,
    /// Points that landed on a pixel already written (the nearer kept).
    pub collisions: u32,
    /// Sum of the four skip counters.
    pub skipped: u32,
}

/// Runs `f`, turning a panic into [`DEPTHOR_E_INTERNAL`] (std build).
#[cfg(feature = "std")]
fn guard(f: impl FnOnce() -> i32) -> i32 {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).unwrap_or(DEPTHOR_E_INTERNAL)
}

/// Runs `f` (no_std build: a panic goes to the panic handler below and never returns).
#[cfg(not(feature = "std"))]
fn guard(f: impl FnOnce() -> i32) -> i32 {
    f()
}

/// The no_std build's panic handler (a staticlib must have one). Nothing in depthor-core
/// panics on bad input; reaching this is a bug.
#[cfg(all(not(feature = "std"), not(test)))]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    #[cfg(all(target_arch = "arm", target_os = "none"))]
    // SAFETY: `udf` only raises an undefined-instruction exception (HardFault/UsageFault);
    // it touches no memory and does not return.
    unsafe {
        core::arch::asm!("udf #0", options(noreturn))
    }
    #[cfg(not(all(target_arch = "arm", target_os = "none")))]
    loop {
        core::hint::spin_loop();
    }
}

/// The status code of a core engine error.
fn engine_status(e: &Error) -> i32 {
    match e {
        Error::ArenaTooSmall { .. } => DEPTHOR_E_ARENA,
        Error::Blob(b) => blob_status(b),
        Error::ShapeMismatch { .. } => DEPTHOR_E_LENGTH,
        Error::Plan(_) => DEPTHOR_E_SIZE,
        _ => DEPTHOR_E_INTERNAL,
    }
}

fn blob_status(e: &BlobError) -> i32 {
    match e {
        BlobError::BadChecksum { .. } => DEPTHOR_E_BLOB_CHECKSUM,
        BlobError::UnsupportedVersion { .. } => DEPTHOR_E_BLOB_VERSION,
        _ => DEPTHOR_E_BLOB,
    }
}

/// Byte range `[p, p + count·size_of::<T>())` of a caller buffer, or `None` when the length
/// is not a valid slice length (over `isize::MAX` bytes or past the end of the address space).
fn span<T>(p: *const T, count: usize) -> Option<(usize, usize)> {
    let bytes = count.checked_mul(size_of::<T>())?;
    if bytes > isize::MAX as usize {
        return None;
    }
    let start = p as usize;
    Some((start, start.checked_add(bytes)?))
}

/// Whether two byte ranges share a byte (empty ranges share none).
fn overlap(a: (usize, usize), b: (usize, usize)) -> bool {
    a.0 < a.1 && b.0 < b.1 && a.0 < b.1 && b.0 < a.1
}

fn aligned<T>(p: *const T) -> bool {
    p.is_aligned()
}

/// `(height, width)` from the C arguments: `(0, 0)` is the blob's native size `native()`.
fn input_size(
    height: u32,
    width: u32,
    native: impl FnOnce() -> Result<(usize, usize), i32>,
) -> Result<(usize, usize), i32> {
    match (height, width) {
        (0, 0) => native(),
        (0, _) | (_, 0) => Err(DEPTHOR_E_SIZE),
        (h, w) => Ok((
            usize::try_from(h).map_err(|_| DEPTHOR_E_SIZE)?,
            usize::try_from(w).map_err(|_| DEPTHOR_E_SIZE)?,
        )),
    }
}

/// Bytes of engine memory `depthor_engine_init` needs (a `depthor_engine` object).
#[no_mangle]
pub extern "C" fn depthor_engine_size() -> usize {
    size_of::<depthor_engine>()
}

/// Alignment the engine memory needs, in bytes (a power of two, at most 8).
#[no_mangle]
pub extern "C" fn depthor_engine_align() -> usize {
    align_of::<depthor_engine>()
}

/// Arena bytes `blob` needs at `height × width` (`0, 0`: the blob's native size), written to
/// `*out_bytes` on success. Parses and plans; nothing runs. Stack: ≈ 90 KB on a Cortex-M4F
/// for `mcu_lite` (docs/ffi.md).
///
/// # Safety
/// `blob` must point to `blob_len` readable bytes and `out_bytes` to a writable `size_t`
/// (NULL is checked; other invalid pointers cannot be).
#[no_mangle]
pub unsafe extern "C" fn depthor_arena_bytes(
    blob: *const u8,
    blob_len: usize,
    height: u32,
    width: u32,
    out_bytes: *mut usize,
) -> i32 {
    guard(|| {
        if blob.is_null() || out_bytes.is_null() {
            return DEPTHOR_E_NULL;
        }
        if !aligned(out_bytes) {
            return DEPTHOR_E_ALIGN;
        }
        let (Some(b), Some(o)) = (span(blob, blob_len), span(out_bytes, 1)) else {
            return DEPTHOR_E_LENGTH;
        };
        if overlap(b, o) {
            return DEPTHOR_E_OVERLAP;
        }
        // SAFETY: non-NULL, a valid slice length (`span`), and the caller promises `blob_len`
        // readable bytes that nothing writes during the call (`out_bytes` does not overlap).
        let blob = unsafe { slice::from_raw_parts(blob, blob_len) };
        let size = input_size(height, width, || {
            parse(blob)
                .map(|g| (g.height, g.width))
                .map_err(|e| blob_status(&e))
        });
        let need = match size
            .and_then(|(h, w)| required_arena_bytes(blob, h, w).map_err(|e| engine_status(&e)))
        {
            Ok(n) => n,
            Err(code) => return code,
        };
        // SAFETY: non-NULL, aligned (checked above), writable by the caller's contract.
        unsafe { out_bytes.write(need) };
        DEPTHOR_OK
    })
}

/// Prepares an engine in the caller's `engine` memory for `height × width` (`0, 0`: the
/// blob's native size): validates the blob, plans the arena and caches constants in it. The
/// plan is the fastest that fits `arena_len` (`Memory::Budget`): at the
/// `depthor_arena_bytes()` minimum the smallest, with more arena possibly a less fused one;
/// the output bits are the same.
/// The engine borrows `blob` and `arena` until it is no longer used; the engine memory, arena
/// and blob must not overlap. Calling it again on the same memory re-initialises it (nothing to
/// release first). A failed call leaves the memory marked uninitialised. Stack: the planner's
/// tables plus a temporary engine object, ≈ 148 KB on a Cortex-M4F for `mcu_lite`.
///
/// # Safety
/// `engine` must point to `depthor_engine_size()` writable bytes aligned to
/// `depthor_engine_align()` (misalignment is checked), `blob` to `blob_len` readable bytes and
/// `arena` to `arena_len` writable bytes; `blob` and `arena` must stay valid, and `arena`
/// untouched by the caller, while the engine is used.
#[no_mangle]
pub unsafe extern "C" fn depthor_engine_init(
    engine: *mut depthor_engine,
    blob: *const u8,
    blob_len: usize,
    arena: *mut u8,
    arena_len: usize,
    height: u32,
    width: u32,
) -> i32 {
    guard(|| {
        if engine.is_null() || blob.is_null() || arena.is_null() {
            return DEPTHOR_E_NULL;
        }
        if !aligned(engine) {
            return DEPTHOR_E_ALIGN;
        }
        let (Some(e), Some(b), Some(a)) = (
            span(engine, 1),
            span(blob, blob_len),
            span(arena.cast_const(), arena_len),
        ) else {
            return DEPTHOR_E_LENGTH;
        };
        if overlap(e, b) || overlap(e, a) || overlap(a, b) {
            return DEPTHOR_E_OVERLAP;
        }
        // SAFETY: `engine` is non-NULL and aligned; the caller provides
        // `depthor_engine_size()` writable bytes. Clearing the magic first means a failed
        // init leaves an engine that `depthor_engine_run` refuses.
        unsafe { addr_of_mut!((*engine).0.magic).write(0) };
        // SAFETY: non-NULL, valid slice lengths (`span`); the caller keeps `blob` alive and
        // unmodified for as long as the engine is used ('static stands for that promise).
        let blob_s: &'static [u8] = unsafe { slice::from_raw_parts(blob, blob_len) };
        // SAFETY: as above for `arena`, which overlaps neither the blob nor the engine
        // memory (checked), so this is the only reference to those bytes.
        let arena_s: &'static mut [u8] = unsafe { slice::from_raw_parts_mut(arena, arena_len) };
        let size = input_size(height, width, || {
            parse(blob_s)
                .map(|g| (g.height, g.width))
                .map_err(|e| blob_status(&e))
        });
        let (h, w) = match size {
            Ok(hw) => hw,
            Err(code) => return code,
        };
        // The fastest plan that fits the arena the caller gave (`Memory::Budget`): with the
        // `depthor_arena_bytes()` minimum that is the smallest plan, the least fused where
        // plans tie; a larger arena may buy a less fused, faster one. The bits are the same.
        // One call site: one engine temporary on the stack.
        match Engine::with_memory(blob_s, arena_s, h, w, Memory::Budget(arena_len)) {
            Ok(prepared) => {
                // SAFETY: `engine` is valid for writes of a whole `depthor_engine` (caller's
                // contract), aligned, and overlaps neither borrowed buffer (checked).
                unsafe {
                    addr_of_mut!((*engine).0.blob).write(blob);
                    addr_of_mut!((*engine).0.blob_len).write(blob_len);
                    addr_of_mut!((*engine).0.arena).write(arena);
                    addr_of_mut!((*engine).0.arena_len).write(arena_len);
                    addr_of_mut!((*engine).0.engine).write(MaybeUninit::new(prepared));
                    addr_of_mut!((*engine).0.magic).write(MAGIC);
                }
                DEPTHOR_OK
            }
            Err(e) => engine_status(&e),
        }
    })
}

/// Whether `engine` holds an initialised engine; its blob and arena spans if so.
///
/// # Safety
/// `engine` must be non-NULL, aligned and point to `depthor_engine_size()` readable bytes.
unsafe fn initialised(engine: *const depthor_engine) -> Option<((usize, usize), (usize, usize))> {
    // SAFETY: the caller's contract; the magic is a plain u32 in caller memory.
    let magic = unsafe { addr_of!((*engine).0.magic).read() };
    if magic != MAGIC {
        return None;
    }
    // SAFETY: written by the successful init that wrote MAGIC.
    let (b, bl, a, al) = unsafe {
        (
            addr_of!((*engine).0.blob).read(),
            addr_of!((*engine).0.blob_len).read(),
            addr_of!((*engine).0.arena).read(),
            addr_of!((*engine).0.arena_len).read(),
        )
    };
    Some((span(b, bl)?, span(a.cast_const(), al)?))
}

/// The input size `engine` runs at, into `*height` and `*width`.
///
/// # Safety
/// `engine` must point to engine memory (`depthor_engine_size()` bytes); `height` and `width`
/// to writable `uint32_t`s.
#[no_mangle]
pub unsafe extern "C" fn depthor_engine_input_size(
    engine: *const depthor_engine,
    height: *mut u32,
    width: *mut u32,
) -> i32 {
    guard(|| {
        if engine.is_null() || height.is_null() || width.is_null() {
            return DEPTHOR_E_NULL;
        }
        if !aligned(engine) || !aligned(height) || !aligned(width) {
            return DEPTHOR_E_ALIGN;
        }
        // SAFETY: non-NULL and aligned; the caller's contract for the bytes.
        if unsafe { initialised(engine) }.is_none() {
            return DEPTHOR_E_NOT_INIT;
        }
        // SAFETY: the magic says a successful init wrote the engine; only shared access here.
        let eng = unsafe { (*addr_of!((*engine).0.engine)).assume_init_ref() };
        let (h, w) = eng.input_shape();
        let (Ok(h), Ok(w)) = (u32::try_from(h), u32::try_from(w)) else {
            return DEPTHOR_E_INTERNAL;
        };
        // SAFETY: non-NULL, aligned, writable by the caller's contract.
        unsafe {
            height.write(h);
            width.write(w);
        }
        DEPTHOR_OK
    })
}

/// Runs one frame: `rgb888` is `3·H·W` bytes (interleaved, row-major), `sparse_m` the sparse
/// depth (`H·W` floats, metres, 0 = no point), `depth_m` receives the dense depth (`H·W`
/// floats, metres). `sparse_m` may equal `depth_m` (same pointer and length): the frame then
/// runs in place, the least memory. Other overlaps are refused. Lengths count elements (bytes
/// for RGB, floats for the depth maps).
///
/// # Safety
/// `engine` must point to engine memory; the buffers to their stated lengths of readable
/// (`rgb888`, `sparse_m`) or writable (`depth_m`) memory. One thread at a time per engine.
#[no_mangle]
pub unsafe extern "C" fn depthor_engine_run(
    engine: *mut depthor_engine,
    rgb888: *const u8,
    rgb_len: usize,
    sparse_m: *const f32,
    sparse_len: usize,
    depth_m: *mut f32,
    depth_len: usize,
) -> i32 {
    guard(|| {
        if engine.is_null() || rgb888.is_null() || sparse_m.is_null() || depth_m.is_null() {
            return DEPTHOR_E_NULL;
        }
        if !aligned(engine) || !aligned(sparse_m) || !aligned(depth_m) {
            return DEPTHOR_E_ALIGN;
        }
        // SAFETY: non-NULL and aligned; the caller's contract for the bytes.
        let Some((blob_r, arena_r)) = (unsafe { initialised(engine) }) else {
            return DEPTHOR_E_NOT_INIT;
        };
        // SAFETY: the magic says a successful init wrote the engine; shared access only.
        let (h, w) = unsafe { (*addr_of!((*engine).0.engine)).assume_init_ref() }.input_shape();
        let n = h * w;
        if Some(rgb_len) != n.checked_mul(3) || sparse_len != n || depth_len != n {
            return DEPTHOR_E_LENGTH;
        }
        let (Some(eng_r), Some(rgb_r), Some(sp_r), Some(d_r)) = (
            span(engine.cast_const(), 1),
            span(rgb888, rgb_len),
            span(sparse_m, sparse_len),
            span(depth_m.cast_const(), depth_len),
        ) else {
            return DEPTHOR_E_LENGTH;
        };
        let in_place = sparse_m == depth_m.cast_const();
        let owned = [eng_r, arena_r];
        if owned.iter().any(|&o| overlap(o, rgb_r) || overlap(o, sp_r))
            || [eng_r, arena_r, blob_r, rgb_r]
                .iter()
                .any(|&o| overlap(o, d_r))
            || (!in_place && overlap(sp_r, d_r))
        {
            return DEPTHOR_E_OVERLAP;
        }
        // SAFETY: initialised (magic), and no argument overlaps the engine memory, so this is
        // the only reference to it during the call (one thread per engine: the contract).
        let eng = unsafe { (*addr_of_mut!((*engine).0.engine)).assume_init_mut() };
        // SAFETY: non-NULL, aligned, lengths checked against the engine and by `span`; the
        // output overlaps no input, nor the engine, arena or blob (checked).
        let out = unsafe { slice::from_raw_parts_mut(depth_m, depth_len) };
        // SAFETY: as above; RGB is only read, and overlaps neither the output nor what the
        // engine writes.
        let rgb = unsafe { slice::from_raw_parts(rgb888, rgb_len) };
        let result = if in_place {
            eng.run_in_place(rgb, out)
        } else {
            // SAFETY: as for `rgb`; it does not overlap `out` (not in place, checked).
            let sparse = unsafe { slice::from_raw_parts(sparse_m, sparse_len) };
            eng.run(rgb, sparse, out)
        };
        match result {
            Ok(_) => DEPTHOR_OK,
            Err(e) => engine_status(&e),
        }
    })
}

/// Rasterises one dToF frame's zones into the sparse depth map `sparse_m` (`width·height`
/// floats, metres, 0 = no point; zero-filled first, the nearer point kept on a collision):
/// `distance_mm` (millimetres) and `status` (ST `target_status`; 5 and 9 are valid) hold
/// `zones = zone_rows·zone_cols` values each, row-major.
/// `stats` (may be NULL) receives the counters. A frame with `projected == 0` has no metric
/// depth: do not run the engine on it.
///
/// # Safety
/// The pointers must point to their stated lengths of readable (`cal`, `distance_mm`,
/// `status`) or writable (`sparse_m`, `stats`) memory.
#[no_mangle]
pub unsafe extern "C" fn depthor_project_to_sparse(
    cal: *const depthor_calibration,
    distance_mm: *const f32,
    status: *const u8,
    zones: usize,
    sparse_m: *mut f32,
    sparse_len: usize,
    stats: *mut depthor_projection_stats,
) -> i32 {
    guard(|| {
        if cal.is_null() || distance_mm.is_null() || status.is_null() || sparse_m.is_null() {
            return DEPTHOR_E_NULL;
        }
        if !aligned(cal) || !aligned(distance_mm) || !aligned(sparse_m) || !aligned(stats) {
            return DEPTHOR_E_ALIGN;
        }
        let (Some(c_r), Some(d_r), Some(st_r), Some(s_r), Some(o_r)) = (
            span(cal, 1),
            span(distance_mm, zones),
            span(status, zones),
            span(sparse_m.cast_const(), sparse_len),
            span(stats.cast_const(), usize::from(!stats.is_null())),
        ) else {
            return DEPTHOR_E_LENGTH;
        };
        if [c_r, d_r, st_r, o_r].iter().any(|&r| overlap(r, s_r))
            || [c_r, d_r, st_r].iter().any(|&r| overlap(r, o_r))
        {
            return DEPTHOR_E_OVERLAP;
        }
        // SAFETY: non-NULL, aligned, readable by the caller's contract; plain-old-data.
        let c = unsafe { cal.read() };
        let distance = match c.distance_kind {
            DEPTHOR_DISTANCE_Z => DistanceKind::Z,
            DEPTHOR_DISTANCE_RADIAL => DistanceKind::Radial,
            _ => return DEPTHOR_E_CALIBRATION,
        };
        let r = c.rotation;
        let calibration = Calibration {
            camera: CameraIntrinsics {
                width: c.width,
                height: c.height,
                fx: c.fx,
                fy: c.fy,
                cx: c.cx,
                cy: c.cy,
            },
            dtof: DtofGeometry {
                rows: c.zone_rows,
                cols: c.zone_cols,
                fov_deg: [c.fov_h_deg, c.fov_v_deg],
                distance,
                max_range_m: c.max_range_m,
            },
            dtof_to_camera: Extrinsics {
                rotation: [[r[0], r[1], r[2]], [r[3], r[4], r[5]], [r[6], r[7], r[8]]],
                translation_m: c.translation_m,
            },
            zone_rects_px: None,
        };
        // SAFETY: non-NULL, aligned, valid slice lengths (`span`), readable by the caller's
        // contract; they do not overlap the output (checked).
        let view = unsafe {
            ZoneView {
                rows: c.zone_rows,
                cols: c.zone_cols,
                distance_mm: slice::from_raw_parts(distance_mm, zones),
                status: slice::from_raw_parts(status, zones),
            }
        };
        // SAFETY: as above; writable by the caller's contract and overlapping no input.
        let out = unsafe { slice::from_raw_parts_mut(sparse_m, sparse_len) };
        match project_to_sparse(&calibration, &view, out) {
            Ok(s) => {
                if !stats.is_null() {
                    let counters = depthor_projection_stats {
                        zones: s.zones,
                        projected: s.projected,
                        invalid_status: s.invalid_status,
                        bad_distance: s.bad_distance,
                        behind_camera: s.behind_camera,
                        out_of_image: s.out_of_image,
                        collisions: s.collisions,
                        skipped: s.skipped(),
                    };
                    // SAFETY: non-NULL, aligned, writable, overlapping no input (checked).
                    unsafe { stats.write(counters) };
                }
                DEPTHOR_OK
            }
            Err(ProjectionError::BadCalibration(_)) => DEPTHOR_E_CALIBRATION,
            Err(_) => DEPTHOR_E_LENGTH,
        }
    })
}

/// A static, NUL-terminated English description of `status` (never NULL; an unknown code
/// gives "unknown status code").
#[no_mangle]
pub extern "C" fn depthor_status_message(status: i32) -> *const c_char {
    let s: &'static core::ffi::CStr = match status {
        DEPTHOR_OK => c"success",
        DEPTHOR_E_NULL => c"a required pointer is NULL",
        DEPTHOR_E_ALIGN => {
            c"a pointer is misaligned for its type (engine memory: depthor_engine_align())"
        }
        DEPTHOR_E_BLOB => c"the model blob is malformed",
        DEPTHOR_E_BLOB_CHECKSUM => c"the model blob's checksum does not match (corrupted)",
        DEPTHOR_E_BLOB_VERSION => c"the model blob's format version is not supported",
        DEPTHOR_E_SIZE => c"the network cannot run at this height x width",
        DEPTHOR_E_ARENA => c"the arena is smaller than depthor_arena_bytes() reports",
        DEPTHOR_E_LENGTH => c"a buffer has the wrong length",
        DEPTHOR_E_OVERLAP => c"buffers overlap where they must not",
        DEPTHOR_E_NOT_INIT => c"the engine memory was not initialised by depthor_engine_init",
        DEPTHOR_E_CALIBRATION => c"the calibration is unusable",
        DEPTHOR_E_INTERNAL => c"internal error (a bug; please report it with the blob)",
        _ => c"unknown status code",
    };
    s.as_ptr()
}

// Test only; `cbindgen.toml` keeps it out of depthor.h.
#[cfg(feature = "panic-probe")]
pub mod probe;

#[cfg(test)]
mod tests;
