//! Every entry point's success and error paths, called as C would call them.

use super::*;
use core::ptr::{null, null_mut};
use std::vec;
use std::vec::Vec;

static BLOB: &[u8] = include_bytes!("../../models/mcu_lite/depthor.dblob");
const H: usize = 64;
const W: usize = 64;

/// Engine memory with the header's storage alignment (8).
#[repr(C, align(8))]
struct Storage([u8; DEPTHOR_ENGINE_STORAGE_BYTES + 8]);

fn storage() -> std::boxed::Box<Storage> {
    std::boxed::Box::new(Storage([0; DEPTHOR_ENGINE_STORAGE_BYTES + 8]))
}

fn arena_bytes(blob: &[u8], h: u32, w: u32) -> Result<usize, i32> {
    let mut n = 0usize;
    // SAFETY: valid blob slice and output.
    match unsafe { depthor_arena_bytes(blob.as_ptr(), blob.len(), h, w, &mut n) } {
        DEPTHOR_OK => Ok(n),
        e => Err(e),
    }
}

/// Inits `mem` over `arena`; the status.
fn init(mem: *mut depthor_engine, blob: &[u8], arena: &mut [u8], h: u32, w: u32) -> i32 {
    // SAFETY: the test passes engine memory of at least the storage size and live buffers.
    unsafe {
        depthor_engine_init(
            mem,
            blob.as_ptr(),
            blob.len(),
            arena.as_mut_ptr(),
            arena.len(),
            h,
            w,
        )
    }
}

fn run(mem: *mut depthor_engine, rgb: &[u8], sparse: &[f32], depth: &mut [f32]) -> i32 {
    // SAFETY: live buffers of the stated lengths.
    unsafe {
        depthor_engine_run(
            mem,
            rgb.as_ptr(),
            rgb.len(),
            sparse.as_ptr(),
            sparse.len(),
            depth.as_mut_ptr(),
            depth.len(),
        )
    }
}

/// A deterministic frame: a gradient RGB and a sparse map with a point every 97 pixels.
fn frame(n: usize) -> (Vec<u8>, Vec<f32>) {
    let rgb = (0..3 * n).map(|i| (i * 7 % 251) as u8).collect();
    let sparse = (0..n)
        .map(|i| {
            if i % 97 == 0 {
                0.5 + (i % 13) as f32 * 0.25
            } else {
                0.0
            }
        })
        .collect();
    (rgb, sparse)
}

#[test]
fn size_and_align_fit_the_header_storage() {
    assert!(depthor_engine_size() <= DEPTHOR_ENGINE_STORAGE_BYTES);
    assert!(depthor_engine_size() >= size_of::<Engine<'static>>());
    let a = depthor_engine_align();
    assert!(a.is_power_of_two() && a <= 8, "{a}");
}

#[test]
fn arena_bytes_matches_the_core_and_native_size() {
    let need = arena_bytes(BLOB, H as u32, W as u32).unwrap();
    assert_eq!(need, required_arena_bytes(BLOB, H, W).unwrap());
    let g = parse(BLOB).unwrap();
    let native = arena_bytes(BLOB, 0, 0).unwrap();
    assert_eq!(
        native,
        required_arena_bytes(BLOB, g.height, g.width).unwrap()
    );
    assert_ne!(native, need);
}

#[test]
fn arena_bytes_error_paths() {
    let mut n = 7usize;
    // SAFETY: NULL arguments are what is tested; the others are valid.
    unsafe {
        assert_eq!(
            depthor_arena_bytes(null(), 10, 8, 8, &mut n),
            DEPTHOR_E_NULL
        );
        assert_eq!(
            depthor_arena_bytes(BLOB.as_ptr(), BLOB.len(), 8, 8, null_mut()),
            DEPTHOR_E_NULL
        );
        // Misaligned output.
        let mut words = [0usize; 2];
        let odd = words.as_mut_ptr().cast::<u8>().add(1).cast::<usize>();
        assert_eq!(
            depthor_arena_bytes(BLOB.as_ptr(), BLOB.len(), 8, 8, odd),
            DEPTHOR_E_ALIGN
        );
        // A length past the end of the address space.
        assert_eq!(
            depthor_arena_bytes(BLOB.as_ptr(), usize::MAX, 8, 8, &mut n),
            DEPTHOR_E_LENGTH
        );
    }
    assert_eq!(n, 7, "untouched on error");
    assert_eq!(arena_bytes(BLOB, 0, W as u32), Err(DEPTHOR_E_SIZE));
    assert_eq!(arena_bytes(BLOB, H as u32, 0), Err(DEPTHOR_E_SIZE));
    assert_eq!(arena_bytes(BLOB, u32::MAX, u32::MAX), Err(DEPTHOR_E_SIZE));
    for (blob, code) in bad_blobs() {
        assert_eq!(arena_bytes(&blob, H as u32, W as u32), Err(code));
        assert_eq!(arena_bytes(&blob, 0, 0), Err(code));
    }
}

/// Defective blobs and the code each must give.
fn bad_blobs() -> Vec<(Vec<u8>, i32)> {
    let mut magic = BLOB.to_vec();
    magic[0] ^= 0xff;
    let mut version = BLOB.to_vec();
    version[4] ^= 0x01;
    let mut payload = BLOB.to_vec();
    *payload.last_mut().unwrap() ^= 0x5a;
    vec![
        (magic, DEPTHOR_E_BLOB),
        (version, DEPTHOR_E_BLOB_VERSION),
        (payload, DEPTHOR_E_BLOB_CHECKSUM),
        (BLOB[..BLOB.len() / 2].to_vec(), DEPTHOR_E_BLOB),
        (BLOB[..10].to_vec(), DEPTHOR_E_BLOB),
        (Vec::new(), DEPTHOR_E_BLOB),
    ]
}

#[test]
fn run_is_bit_exact_with_the_core_engine_and_in_place() {
    let need = arena_bytes(BLOB, H as u32, W as u32).unwrap();
    let mut st = storage();
    let mem = st.0.as_mut_ptr().cast::<depthor_engine>();
    let mut arena = vec![0u8; need];
    assert_eq!(init(mem, BLOB, &mut arena, H as u32, W as u32), DEPTHOR_OK);
    let (mut h, mut w) = (0u32, 0u32);
    // SAFETY: initialised engine, valid outputs.
    assert_eq!(
        unsafe { depthor_engine_input_size(mem, &mut h, &mut w) },
        DEPTHOR_OK
    );
    assert_eq!((h as usize, w as usize), (H, W));

    let (rgb, sparse) = frame(H * W);
    let mut depth = vec![0f32; H * W];
    assert_eq!(run(mem, &rgb, &sparse, &mut depth), DEPTHOR_OK);

    let mut arena2 = vec![0u8; need];
    let mut core_engine = Engine::with_size(BLOB, &mut arena2, H, W).unwrap();
    let mut want = vec![0f32; H * W];
    core_engine.run(&rgb, &sparse, &mut want).unwrap();
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&depth), bits(&want));
    assert!(depth.iter().any(|&d| d > 0.0));

    // In place: sparse and depth are the same buffer.
    let mut both = sparse.clone();
    // SAFETY: one live buffer passed as both input and output, which the API allows.
    let code = unsafe {
        depthor_engine_run(
            mem,
            rgb.as_ptr(),
            rgb.len(),
            both.as_ptr(),
            both.len(),
            both.as_mut_ptr(),
            both.len(),
        )
    };
    assert_eq!(code, DEPTHOR_OK);
    assert_eq!(bits(&both), bits(&want));

    // A larger arena may buy a less fused plan (Memory::Budget): the same bits.
    let mut st2 = storage();
    let mem2 = st2.0.as_mut_ptr().cast::<depthor_engine>();
    let mut big = vec![0u8; 4 * need];
    assert_eq!(init(mem2, BLOB, &mut big, H as u32, W as u32), DEPTHOR_OK);
    let mut depth2 = vec![0f32; H * W];
    assert_eq!(run(mem2, &rgb, &sparse, &mut depth2), DEPTHOR_OK);
    assert_eq!(bits(&depth2), bits(&want));

    // A second frame on the same engine is still the core's.
    let (rgb2, sparse2) = frame(H * W);
    let rgb2: Vec<u8> = rgb2.iter().map(|v| v.wrapping_add(40)).collect();
    assert_eq!(run(mem, &rgb2, &sparse2, &mut depth), DEPTHOR_OK);
    core_engine.run(&rgb2, &sparse2, &mut want).unwrap();
    assert_eq!(bits(&depth), bits(&want));
}

#[test]
fn native_size_init() {
    let need = arena_bytes(BLOB, 0, 0).unwrap();
    let mut st = storage();
    let mem = st.0.as_mut_ptr().cast::<depthor_engine>();
    let mut arena = vec![0u8; need];
    assert_eq!(init(mem, BLOB, &mut arena, 0, 0), DEPTHOR_OK);
    let (mut h, mut w) = (0u32, 0u32);
    // SAFETY: initialised engine, valid outputs.
    assert_eq!(
        unsafe { depthor_engine_input_size(mem, &mut h, &mut w) },
        DEPTHOR_OK
    );
    let g = parse(BLOB).unwrap();
    assert_eq!((h as usize, w as usize), (g.height, g.width));
}

#[test]
fn init_error_paths() {
    let need = arena_bytes(BLOB, H as u32, W as u32).unwrap();
    let mut st = storage();
    let base = st.0.as_mut_ptr();
    let mem = base.cast::<depthor_engine>();
    let mut arena = vec![0u8; need];
    let (hh, ww) = (H as u32, W as u32);
    // SAFETY: NULL arguments are what is tested; the others are valid.
    unsafe {
        let a = arena.as_mut_ptr();
        assert_eq!(
            depthor_engine_init(null_mut(), BLOB.as_ptr(), BLOB.len(), a, need, hh, ww),
            DEPTHOR_E_NULL
        );
        assert_eq!(
            depthor_engine_init(mem, null(), BLOB.len(), a, need, hh, ww),
            DEPTHOR_E_NULL
        );
        assert_eq!(
            depthor_engine_init(mem, BLOB.as_ptr(), BLOB.len(), null_mut(), need, hh, ww),
            DEPTHOR_E_NULL
        );
        // Misaligned engine memory.
        let odd = base.add(1).cast::<depthor_engine>();
        assert_eq!(
            depthor_engine_init(odd, BLOB.as_ptr(), BLOB.len(), a, need, hh, ww),
            DEPTHOR_E_ALIGN
        );
        // Arena overlapping the engine memory, and the blob.
        assert_eq!(
            depthor_engine_init(mem, BLOB.as_ptr(), BLOB.len(), base.add(64), need, hh, ww),
            DEPTHOR_E_OVERLAP
        );
        let mut blob_copy = BLOB.to_vec();
        let bp = blob_copy.as_mut_ptr();
        assert_eq!(
            depthor_engine_init(mem, bp, BLOB.len(), bp.add(100), need, hh, ww),
            DEPTHOR_E_OVERLAP
        );
        assert_eq!(
            depthor_engine_init(mem, BLOB.as_ptr(), usize::MAX, a, need, hh, ww),
            DEPTHOR_E_LENGTH
        );
    }
    // The arena one alignment unit short of the need fails wherever it lies; the need works.
    assert_eq!(
        init(mem, BLOB, &mut arena[..need - 16], hh, ww),
        DEPTHOR_E_ARENA
    );
    assert_eq!(init(mem, BLOB, &mut arena[..0], hh, ww), DEPTHOR_E_ARENA);
    assert_eq!(init(mem, BLOB, &mut arena, 0, ww), DEPTHOR_E_SIZE);
    assert_eq!(init(mem, BLOB, &mut arena, hh, 0), DEPTHOR_E_SIZE);
    assert_eq!(
        init(mem, BLOB, &mut arena, u32::MAX, u32::MAX),
        DEPTHOR_E_SIZE
    );
    for (blob, code) in bad_blobs() {
        assert_eq!(init(mem, &blob, &mut arena, hh, ww), code);
    }
    // A failed init leaves memory the engine calls refuse, even over a good engine.
    assert_eq!(init(mem, BLOB, &mut arena, hh, ww), DEPTHOR_OK);
    assert_eq!(init(mem, BLOB, &mut arena[..16], hh, ww), DEPTHOR_E_ARENA);
    let (rgb, sparse) = frame(H * W);
    let mut depth = vec![0f32; H * W];
    assert_eq!(run(mem, &rgb, &sparse, &mut depth), DEPTHOR_E_NOT_INIT);
}

#[test]
fn run_error_paths() {
    let need = arena_bytes(BLOB, H as u32, W as u32).unwrap();
    let mut st = storage();
    let base = st.0.as_mut_ptr();
    let mem = base.cast::<depthor_engine>();
    let mut arena = vec![0u8; need];
    let (rgb, sparse) = frame(H * W);
    let mut depth = vec![0f32; H * W];
    let n = H * W;

    // Zeroed (never initialised) memory.
    assert_eq!(run(mem, &rgb, &sparse, &mut depth), DEPTHOR_E_NOT_INIT);
    assert_eq!(init(mem, BLOB, &mut arena, H as u32, W as u32), DEPTHOR_OK);
    let d = depth.as_mut_ptr();
    // SAFETY: bad arguments are what is tested; every pointer passed is live.
    unsafe {
        let (r, s) = (rgb.as_ptr(), sparse.as_ptr());
        assert_eq!(
            depthor_engine_run(null_mut(), r, 3 * n, s, n, d, n),
            DEPTHOR_E_NULL
        );
        assert_eq!(
            depthor_engine_run(mem, null(), 3 * n, s, n, d, n),
            DEPTHOR_E_NULL
        );
        assert_eq!(
            depthor_engine_run(mem, r, 3 * n, null(), n, d, n),
            DEPTHOR_E_NULL
        );
        assert_eq!(
            depthor_engine_run(mem, r, 3 * n, s, n, null_mut(), n),
            DEPTHOR_E_NULL
        );
        // Misaligned engine, sparse and depth pointers.
        let odd = base.add(4).cast::<depthor_engine>();
        assert_eq!(
            depthor_engine_run(odd, r, 3 * n, s, n, d, n),
            DEPTHOR_E_ALIGN
        );
        let s_odd = s.cast::<u8>().add(1).cast::<f32>();
        assert_eq!(
            depthor_engine_run(mem, r, 3 * n, s_odd, n - 1, d, n),
            DEPTHOR_E_ALIGN
        );
        let d_odd = d.cast::<u8>().add(2).cast::<f32>();
        assert_eq!(
            depthor_engine_run(mem, r, 3 * n, s, n, d_odd, n - 1),
            DEPTHOR_E_ALIGN
        );
        // Wrong lengths, each buffer.
        assert_eq!(
            depthor_engine_run(mem, r, 3 * n - 1, s, n, d, n),
            DEPTHOR_E_LENGTH
        );
        assert_eq!(
            depthor_engine_run(mem, r, 3 * n, s, n - 1, d, n),
            DEPTHOR_E_LENGTH
        );
        assert_eq!(
            depthor_engine_run(mem, r, 3 * n, s, n, d, n - 1),
            DEPTHOR_E_LENGTH
        );
        assert_eq!(depthor_engine_run(mem, r, 0, s, n, d, n), DEPTHOR_E_LENGTH);
        // Output overlapping the RGB, the sparse input (not the same buffer), the arena, the
        // engine memory; RGB overlapping the arena.
        let mut big = vec![0f32; 2 * n];
        let b = big.as_mut_ptr();
        assert_eq!(
            depthor_engine_run(mem, b.cast::<u8>(), 3 * n, s, n, b, n),
            DEPTHOR_E_OVERLAP
        );
        assert_eq!(
            depthor_engine_run(mem, r, 3 * n, b, n, b.add(1), n),
            DEPTHOR_E_OVERLAP
        );
        let a = arena.as_mut_ptr();
        assert!(need >= 4 * n, "arena holds a depth map");
        assert_eq!(
            depthor_engine_run(mem, r, 3 * n, s, n, a.cast::<f32>(), n),
            DEPTHOR_E_OVERLAP
        );
        assert_eq!(
            depthor_engine_run(mem, a, 3 * n, s, n, d, n),
            DEPTHOR_E_OVERLAP
        );
        assert_eq!(
            depthor_engine_run(mem, r, 3 * n, base.cast::<f32>(), n, d, n),
            DEPTHOR_E_OVERLAP
        );
    }
    assert!(depth.iter().all(|&v| v == 0.0), "output untouched on error");
    // The engine still runs after all those refusals.
    assert_eq!(run(mem, &rgb, &sparse, &mut depth), DEPTHOR_OK);
}

#[test]
fn input_size_error_paths() {
    let mut st = storage();
    let mem = st.0.as_mut_ptr().cast::<depthor_engine>();
    let (mut h, mut w) = (0u32, 0u32);
    // SAFETY: bad arguments are what is tested; every pointer passed is live.
    unsafe {
        assert_eq!(
            depthor_engine_input_size(null(), &mut h, &mut w),
            DEPTHOR_E_NULL
        );
        assert_eq!(
            depthor_engine_input_size(mem, null_mut(), &mut w),
            DEPTHOR_E_NULL
        );
        assert_eq!(
            depthor_engine_input_size(mem, &mut h, null_mut()),
            DEPTHOR_E_NULL
        );
        assert_eq!(
            depthor_engine_input_size(mem, &mut h, &mut w),
            DEPTHOR_E_NOT_INIT
        );
    }
}

#[test]
fn status_messages_are_distinct_and_static() {
    let text = |c: i32| {
        let p = depthor_status_message(c);
        assert!(!p.is_null());
        // SAFETY: the function returns static NUL-terminated strings.
        unsafe { core::ffi::CStr::from_ptr(p) }.to_str().unwrap()
    };
    let all: Vec<&str> = ALL_STATUS.iter().map(|&c| text(c)).collect();
    for (i, a) in all.iter().enumerate() {
        assert!(!a.is_empty());
        assert!(all[i + 1..].iter().all(|b| b != a), "{a}");
        assert_ne!(*a, text(1000));
    }
    assert_eq!(text(1), "unknown status code");
    assert_eq!(text(i32::MIN), "unknown status code");
    let mut codes = ALL_STATUS.to_vec();
    codes.sort();
    codes.dedup();
    assert_eq!(codes.len(), ALL_STATUS.len());
    assert!(ALL_STATUS[1..].iter().all(|&c| c < 0));
}

fn calibration() -> depthor_calibration {
    let cal = depthor_replay::synthetic::mcu_calibration();
    let r = cal.dtof_to_camera.rotation;
    depthor_calibration {
        width: cal.camera.width,
        height: cal.camera.height,
        fx: cal.camera.fx,
        fy: cal.camera.fy,
        cx: cal.camera.cx,
        cy: cal.camera.cy,
        zone_rows: cal.dtof.rows,
        zone_cols: cal.dtof.cols,
        distance_kind: match cal.dtof.distance {
            DistanceKind::Z => DEPTHOR_DISTANCE_Z,
            DistanceKind::Radial => DEPTHOR_DISTANCE_RADIAL,
        },
        fov_h_deg: cal.dtof.fov_deg[0],
        fov_v_deg: cal.dtof.fov_deg[1],
        max_range_m: cal.dtof.max_range_m,
        rotation: [
            r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2],
        ],
        translation_m: cal.dtof_to_camera.translation_m,
    }
}

fn project(
    c: &depthor_calibration,
    dist: &[f32],
    status: &[u8],
    out: &mut [f32],
    stats: *mut depthor_projection_stats,
) -> i32 {
    assert_eq!(dist.len(), status.len());
    // SAFETY: live buffers of the stated lengths.
    unsafe {
        depthor_project_to_sparse(
            c,
            dist.as_ptr(),
            status.as_ptr(),
            dist.len(),
            out.as_mut_ptr(),
            out.len(),
            stats,
        )
    }
}

#[test]
fn projection_matches_the_core_and_its_error_paths() {
    let cal = depthor_replay::synthetic::mcu_calibration();
    let frames = depthor_replay::synthetic::mcu_frames(1);
    let f = &frames[0];
    let dist: Vec<f32> = f.distance_mm.iter().map(|&d| f32::from(d)).collect();
    let c = calibration();
    let n = (c.width * c.height) as usize;
    let mut out = vec![1f32; n];
    let mut stats = depthor_projection_stats::default();
    assert_eq!(
        project(&c, &dist, &f.status, &mut out, &mut stats),
        DEPTHOR_OK
    );

    let view = ZoneView {
        rows: cal.dtof.rows,
        cols: cal.dtof.cols,
        distance_mm: &dist,
        status: &f.status,
    };
    let mut want = vec![0f32; n];
    let s = project_to_sparse(&cal, &view, &mut want).unwrap();
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&out), bits(&want));
    assert_eq!(
        (
            stats.zones,
            stats.projected,
            stats.collisions,
            stats.skipped
        ),
        (s.zones, s.projected, s.collisions, s.skipped())
    );
    assert_eq!(
        (
            stats.invalid_status,
            stats.bad_distance,
            stats.behind_camera,
            stats.out_of_image
        ),
        (
            s.invalid_status,
            s.bad_distance,
            s.behind_camera,
            s.out_of_image
        )
    );
    assert!(stats.projected > 0 && stats.skipped > 0);
    // Stats are optional.
    assert_eq!(
        project(&c, &dist, &f.status, &mut out, null_mut()),
        DEPTHOR_OK
    );

    // SAFETY: bad arguments are what is tested; every pointer passed is live.
    unsafe {
        let (d, st, o) = (dist.as_ptr(), f.status.as_ptr(), out.as_mut_ptr());
        let z = dist.len();
        assert_eq!(
            depthor_project_to_sparse(null(), d, st, z, o, n, null_mut()),
            DEPTHOR_E_NULL
        );
        assert_eq!(
            depthor_project_to_sparse(&c, null(), st, z, o, n, null_mut()),
            DEPTHOR_E_NULL
        );
        assert_eq!(
            depthor_project_to_sparse(&c, d, null(), z, o, n, null_mut()),
            DEPTHOR_E_NULL
        );
        assert_eq!(
            depthor_project_to_sparse(&c, d, st, z, null_mut(), n, null_mut()),
            DEPTHOR_E_NULL
        );
        let o_odd = o.cast::<u8>().add(1).cast::<f32>();
        assert_eq!(
            depthor_project_to_sparse(&c, d, st, z, o_odd, n - 1, null_mut()),
            DEPTHOR_E_ALIGN
        );
        let s_odd = (&mut stats as *mut depthor_projection_stats)
            .cast::<u8>()
            .add(1)
            .cast();
        assert_eq!(
            depthor_project_to_sparse(&c, d, st, z, o, n, s_odd),
            DEPTHOR_E_ALIGN
        );
        assert_eq!(
            depthor_project_to_sparse(&c, d, st, z - 1, o, n, null_mut()),
            DEPTHOR_E_LENGTH
        );
        assert_eq!(
            depthor_project_to_sparse(&c, d, st, z, o, n - 1, null_mut()),
            DEPTHOR_E_LENGTH
        );
        // The output overlapping the distances.
        let mut both = vec![0f32; n];
        let b = both.as_mut_ptr();
        assert_eq!(
            depthor_project_to_sparse(&c, b, st, z, b, n, null_mut()),
            DEPTHOR_E_OVERLAP
        );
    }
    let mut bad = c;
    bad.distance_kind = 7;
    assert_eq!(
        project(&bad, &dist, &f.status, &mut out, null_mut()),
        DEPTHOR_E_CALIBRATION
    );
    let mut bad = c;
    bad.fx = 0.0;
    assert_eq!(
        project(&bad, &dist, &f.status, &mut out, null_mut()),
        DEPTHOR_E_CALIBRATION
    );
    let mut bad = c;
    bad.zone_rows += 1;
    assert_eq!(
        project(&bad, &dist, &f.status, &mut out, null_mut()),
        DEPTHOR_E_LENGTH
    );
}

#[test]
fn two_engines_on_two_threads_share_one_blob() {
    // docs/ffi.md: distinct engines (own memory and arena) may run concurrently on one blob.
    let need = arena_bytes(BLOB, H as u32, W as u32).unwrap();
    let (rgb, sparse) = frame(H * W);
    let results: Vec<Vec<u32>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..2)
            .map(|_| {
                let (rgb, sparse) = (&rgb, &sparse);
                s.spawn(move || {
                    let mut st = storage();
                    let mem = st.0.as_mut_ptr().cast::<depthor_engine>();
                    let mut arena = vec![0u8; need];
                    assert_eq!(init(mem, BLOB, &mut arena, H as u32, W as u32), DEPTHOR_OK);
                    let mut depth = vec![0f32; H * W];
                    for _ in 0..3 {
                        assert_eq!(run(mem, rgb, sparse, &mut depth), DEPTHOR_OK);
                    }
                    depth.iter().map(|d| d.to_bits()).collect()
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    assert_eq!(results[0], results[1]);
}

#[test]
fn a_panic_inside_an_entry_point_becomes_internal_not_an_unwind() {
    // The std build's second line of defence (no entry point is known to panic).
    assert_eq!(guard(|| panic!("planted")), DEPTHOR_E_INTERNAL);
    assert_eq!(guard(|| DEPTHOR_E_SIZE), DEPTHOR_E_SIZE);
}
