//! Blob parser robustness: named corruptions give the right errors; truncated, bit-flipped
//! (with and without a repaired CRC) and random blobs never panic, also where an int16 value's
//! table entry and ops are hit (the committed `mcu_lite` blob).

mod common;

use common::{fix_crc, frame, net_of, rgb_planar, tiny_net, tiny_net_with, Widths};
use depthor_core::blob::format::{HEADER_LEN, TENSOR_ENTRY_LEN};
use depthor_core::blob::parse::{Attrs, DType, Geometry};
use depthor_core::blob::{parse, BlobError};
use depthor_core::engine::{required_arena_bytes, Engine, Error};
use depthor_core::kernels::refine::Neighbourhood;
use proptest::prelude::*;
use std::sync::OnceLock;

fn blob() -> &'static [u8] {
    static B: OnceLock<Vec<u8>> = OnceLock::new();
    B.get_or_init(|| {
        let net = tiny_net(12, 16);
        let (rgb, sparse) = frame(12, 16);
        net.to_blob(&net.run_float(&rgb_planar(&rgb, 12, 16), &sparse))
    })
}

/// Parses, plans and, when that succeeds, runs one frame: none of it may panic.
fn exercise(b: &[u8]) {
    if let Ok(g) = parse(b) {
        let (h, w) = (g.height.min(24), g.width.min(24));
        if let Ok(need) = required_arena_bytes(b, h, w) {
            if need < 1 << 22 {
                let mut arena = vec![0u8; need];
                if let Ok(mut e) = Engine::with_size(b, &mut arena, h, w) {
                    let (rgb, sparse) = frame(h, w);
                    let mut out = vec![0f32; h * w];
                    let _ = e.run(&rgb, &sparse, &mut out);
                }
            }
        }
    }
}

#[test]
fn valid_blob_parses() {
    let g = parse(blob()).unwrap();
    assert_eq!((g.height, g.width), (12, 16));
    assert_eq!(g.ops.len(), tiny_net(12, 16).ops.len());
}

#[test]
fn wrong_checksum() {
    let mut b = blob().to_vec();
    let last = b.len() - 1;
    b[last] ^= 0x40;
    assert!(matches!(parse(&b), Err(BlobError::BadChecksum { .. })));
    let mut arena = vec![0u8; 1 << 16];
    assert!(matches!(
        Engine::new(&b, &mut arena),
        Err(Error::Blob(BlobError::BadChecksum { .. }))
    ));
}

#[test]
fn wrong_version_and_magic_and_flags() {
    let mut b = blob().to_vec();
    b[4] = 2;
    assert_eq!(
        parse(&b).err(),
        Some(BlobError::UnsupportedVersion { found: 2 })
    );
    let mut b = blob().to_vec();
    b[0] = b'X';
    assert!(matches!(parse(&b), Err(BlobError::Bad { offset: 0, .. })));
    let mut b = blob().to_vec();
    b[6] = 1;
    assert!(matches!(parse(&b), Err(BlobError::Bad { offset: 6, .. })));
}

#[test]
fn corrupt_fields_with_valid_crc_are_bad_blob() {
    // Unknown opcode in the first op record (right after the tensor table).
    let g = parse(blob()).unwrap();
    let first_op = g.ops[0].offset;
    let mut b = blob().to_vec();
    b[first_op] = 200;
    fix_crc(&mut b);
    assert!(matches!(
        parse(&b),
        Err(BlobError::Bad {
            what: "op: unknown opcode",
            ..
        })
    ));
    // A zero int8 scale in tensor 0.
    let mut b = blob().to_vec();
    b[HEADER_LEN + 4..HEADER_LEN + 8].copy_from_slice(&0f32.to_le_bytes());
    fix_crc(&mut b);
    assert!(matches!(parse(&b), Err(BlobError::Bad { offset, .. }) if offset == HEADER_LEN + 4));
    // payload_len beyond the blob.
    let mut b = blob().to_vec();
    b[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(matches!(parse(&b), Err(BlobError::Bad { offset: 8, .. })));
}

#[test]
fn conv_padding_beyond_the_kernel_is_refused() {
    // Found by `parse_blob` (a timeout): pad_h 65 526 on a 7×7 kernel planned 12.8 M MACs for a
    // 4×4 run. Any conv of the tiny net: its pad_h set one past dil_h·(kh − 1) is named.
    let g = parse(blob()).unwrap();
    let op = g.ops.iter().find(|o| o.code == 1).expect("a conv");
    let b = blob().to_vec();
    let Attrs::Conv {
        geometry: Geometry(v),
        ..
    } = op.attrs
    else {
        unreachable!()
    };
    // The op's 9 geometry words, as the blob stores them, locate its attributes.
    let words: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
    let at = b
        .windows(18)
        .position(|w| w == words.as_slice())
        .expect("geometry bytes");
    let reach = v[4] * (v[0] - 1);
    for (pad, ok) in [(reach, true), (reach + 1, false), (u16::MAX - 9, false)] {
        let mut b = b.clone();
        b[at + 12..at + 14].copy_from_slice(&pad.to_le_bytes());
        fix_crc(&mut b);
        let got = parse(&b);
        if ok {
            assert!(
                got.is_ok(),
                "pad_h {pad} (= the reach) refused: {:?}",
                got.err()
            );
        } else {
            assert!(
                matches!(got, Err(BlobError::Bad { offset, what }) if offset == at + 12 && what.contains("padding")),
                "pad_h {pad}: {:?}",
                got.err()
            );
        }
    }
}

/// Where the refine op's attributes start: `T = 4`, the neighbourhood code, σ = 1, 1.5, 2.
fn refine_attrs_at(b: &[u8], code: u16) -> usize {
    let mut want = Vec::from(4u16.to_le_bytes());
    want.extend(code.to_le_bytes());
    for s in [1.0f32, 1.5, 2.0] {
        want.extend(s.to_le_bytes());
    }
    let at = b.windows(want.len()).position(|w| w == want.as_slice());
    at.expect("the tiny net's refine attributes")
}

#[test]
fn refine_neighbourhood_code_is_checked() {
    // An unknown code is named.
    let mut b = blob().to_vec();
    let at = refine_attrs_at(&b, 0) + 2;
    b[at] = 7;
    fix_crc(&mut b);
    assert!(matches!(
        parse(&b),
        Err(BlobError::Bad { offset, what: "refine: neighbourhood must be 0 (window) or 1 (dilated)" }) if offset == at
    ));
    // The dilated code on heads of 8, 24, 48 channels: the types do not match.
    b[at] = 1;
    fix_crc(&mut b);
    assert!(matches!(parse(&b), Err(BlobError::Bad { .. })));
    // And the dilated net read as a window one.
    let net = tiny_net_with(12, 16, Neighbourhood::Dilated);
    let (rgb, sparse) = frame(12, 16);
    let mut d = net.to_blob(&net.run_float(&rgb_planar(&rgb, 12, 16), &sparse));
    assert!(parse(&d).is_ok());
    let at = refine_attrs_at(&d, 1) + 2;
    d[at] = 0;
    fix_crc(&mut d);
    assert!(matches!(parse(&d), Err(BlobError::Bad { .. })));
}

#[test]
fn every_truncation_is_an_error() {
    let b = blob();
    for n in 0..b.len() {
        assert!(parse(&b[..n]).is_err(), "truncated to {n} parsed");
    }
}

#[test]
fn every_single_byte_corruption_with_repaired_crc_is_safe() {
    // Walk the header, tensor table and op list (the data section is weights: any value is
    // valid there) and set each byte to a few values with the CRC repaired, so validation past
    // the checksum is exercised.
    let g = parse(blob()).unwrap();
    let data_start = g.ops.iter().map(|o| o.offset).max().unwrap() + 64;
    for i in 0..data_start.min(blob().len()) {
        for v in [0u8, 0x81, 0xff] {
            let mut b = blob().to_vec();
            b[i] = v;
            fix_crc(&mut b);
            exercise(&b);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]
    #[test]
    fn random_bytes_never_panic(v in proptest::collection::vec(any::<u8>(), 0..512)) {
        exercise(&v);
        let mut b = b"DPTH\x01\x00\x00\x00".to_vec();
        b.extend_from_slice(&v);
        fix_crc(&mut b);
        exercise(&b);
    }

    #[test]
    fn random_mutations_never_panic(edits in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..8), repair in any::<bool>()) {
        let mut b = blob().to_vec();
        for (i, v) in edits {
            let n = b.len();
            b[i % n] = v;
        }
        if repair {
            fix_crc(&mut b);
        }
        exercise(&b);
    }
}

/// The committed `mcu_lite` blob: it stores one value as int16 (dtype 2), so its table entry and
/// the ops writing and reading it reach the int16 checks and kernels.
fn int16_blob() -> &'static [u8] {
    include_bytes!("../../models/mcu_lite/depthor.dblob")
}

/// A run size the 1/32-stride `mcu_lite` accepts, small enough for many debug-build runs.
const SMALL: (usize, usize) = (32, 32);

/// As [`exercise`] at [`SMALL`]; true when a frame ran to the end.
fn exercise_small(b: &[u8]) -> bool {
    exercise_small_at(b, SMALL.0, SMALL.1)
}

/// As [`exercise_small`] at `h × w`.
fn exercise_small_at(b: &[u8], h: usize, w: usize) -> bool {
    let Ok(need) = required_arena_bytes(b, h, w) else {
        return false;
    };
    if need >= 1 << 22 {
        return false;
    }
    let mut arena = vec![0u8; need];
    let Ok(mut e) = Engine::with_size(b, &mut arena, h, w) else {
        return false;
    };
    let (rgb, sparse) = frame(h, w);
    let mut out = vec![0f32; h * w];
    e.run(&rgb, &sparse, &mut out).is_ok()
}

#[test]
fn int16_blob_runs_at_a_small_size() {
    let g = parse(int16_blob()).unwrap();
    assert!(
        g.tensors.iter().any(|t| t.dtype == DType::I16),
        "no int16 value left to test"
    );
    assert!(exercise_small(int16_blob()));
}

#[test]
fn int16_entries_and_their_ops_corrupted_are_safe() {
    // Every byte of each int16 tensor's table entry and of the op records writing or reading it,
    // set to a few values with the CRC repaired: an error or a run, never a panic.
    let b0 = int16_blob();
    let g = parse(b0).unwrap();
    let mut ranges = std::vec::Vec::new();
    for (id, t) in g.tensors.iter().enumerate() {
        if t.dtype != DType::I16 {
            continue;
        }
        let at = HEADER_LEN + id * TENSOR_ENTRY_LEN;
        ranges.push(at..at + TENSOR_ENTRY_LEN);
        for (k, op) in g.ops.iter().enumerate() {
            if op.output as usize == id || op.inputs.iter().any(|&i| i as usize == id) {
                let end = g.ops.get(k + 1).map_or(op.offset + 64, |n| n.offset);
                ranges.push(op.offset..end);
            }
        }
    }
    assert!(
        ranges.len() >= 3,
        "an int16 value, its producer and a reader"
    );
    let mut ran = 0;
    for i in ranges.into_iter().flatten() {
        for v in [0u8, 1, 2, 3, 0x7f, 0x81, 0xff] {
            let mut b = b0.to_vec();
            b[i] = v;
            fix_crc(&mut b);
            ran += usize::from(exercise_small(&b));
        }
    }
    assert!(
        ran > 0,
        "some corruptions (scale bytes, say) still make a runnable blob"
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn int16_blob_random_table_mutations_never_panic(edits in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..6)) {
        let b0 = int16_blob();
        let table_end = HEADER_LEN + parse(b0).unwrap().tensors.len() * TENSOR_ENTRY_LEN;
        let mut b = b0.to_vec();
        for (i, v) in edits {
            b[HEADER_LEN + i % (table_end - HEADER_LEN)] = v;
        }
        fix_crc(&mut b);
        exercise_small(&b);
    }
}

/// Checks that the committed blob `core/fuzz/seeds/<name>` is `blob`, every opcode of the
/// vocabulary included, and that it runs at each of `sizes`; with `DEPTHOR_WRITE_FUZZ_SEEDS`
/// set, rewrites it first.
fn check_fuzz_seed(name: &str, blob: &[u8], sizes: &[(usize, usize)]) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/seeds")
        .join(name);
    if std::env::var_os("DEPTHOR_WRITE_FUZZ_SEEDS").is_some() {
        std::fs::write(&path, blob).unwrap();
    }
    let seed = std::fs::read(&path).unwrap();
    assert!(
        seed == blob,
        "{} is stale: rewrite it (see the doc)",
        path.display()
    );
    let g = parse(&seed).unwrap();
    // Every opcode but the stand-alone relu and leaky_relu tables (the convs fuse them).
    use depthor_core::blob::format::opcode::{LEAKY_RELU, RELU};
    for code in (1..=18u8).filter(|&c| c != RELU && c != LEAKY_RELU) {
        assert!(
            g.ops.iter().any(|op| op.code == code),
            "opcode {code} missing"
        );
    }
    for &(h, w) in sizes {
        assert!(exercise_small_at(&seed, h, w), "{h}×{w}");
    }
}

/// `core/fuzz/seeds/tiny_net.dblob` (the core's unit tests of the parser and the engine embed
/// it) is this file's 12×16 test network. Rewrite the seeds after changing the network with
/// `DEPTHOR_WRITE_FUZZ_SEEDS=1 cargo test -p depthor-core --test blob fuzz_seed`.
#[test]
fn fuzz_seed_blob_is_the_test_network() {
    check_fuzz_seed("tiny_net.dblob", blob(), &[(12, 16)]);
}

/// The fuzzing seed blob `core/fuzz/seeds/micro_net.dblob` (the `engine_run` and
/// `replay_image` targets embed it; `parse_blob`'s seeds are it with a mode byte in front) is
/// the test network at 4×4 with few channels ([`Widths::MICRO`]): every opcode, 8 KB, so
/// that each fuzz execution is cheap.
#[test]
fn fuzz_seed_blob_is_the_micro_network() {
    let net = net_of(4, 4, Neighbourhood::Window, Widths::MICRO);
    let (rgb, sparse) = frame(4, 4);
    let blob = net.to_blob(&net.run_float(&rgb_planar(&rgb, 4, 4), &sparse));
    if std::env::var_os("DEPTHOR_WRITE_FUZZ_SEEDS").is_some() {
        let seeds = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/seeds/parse_blob");
        std::fs::create_dir_all(&seeds).unwrap();
        // Mode 0: CRC as stored, native size, streamed plan; 1: CRC repaired, whole plan, 8×8.
        for (mode, name) in [(0u8, "micro_net"), (0b100011, "micro_net_whole_8x8")] {
            let mut seed = vec![mode];
            seed.extend_from_slice(&blob);
            std::fs::write(seeds.join(name), seed).unwrap();
        }
    }
    check_fuzz_seed(
        "micro_net.dblob",
        &blob,
        &[(4, 4), (8, 8), (12, 16), (32, 32)],
    );
}
