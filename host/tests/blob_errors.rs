//! Model blob errors: mutated blobs (CRC recomputed so the mutation reaches the parser) are
//! refused quickly with one line naming the blob's path and byte offset, said once.

mod common;

use depthor_core::blob::checksum::crc32;
use depthor_host::inference::Int8Model;
use std::time::{Duration, Instant};

const HEADER_LEN: usize = 32;

fn fix_crc(blob: &mut [u8]) {
    let len = u32::from_le_bytes([blob[8], blob[9], blob[10], blob[11]]) as usize;
    let end = (HEADER_LEN + len).min(blob.len());
    let c = crc32(&blob[HEADER_LEN..end]);
    blob[12..16].copy_from_slice(&c.to_le_bytes());
}

fn mcu_blob() -> Vec<u8> {
    std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../models/mcu/depthor.dblob"
    ))
    .unwrap()
}

/// No `a: b: … a: b: …` repetition: no segment of three or more words occurs twice.
fn said_once(msg: &str) -> bool {
    let parts: Vec<&str> = msg.split(": ").collect();
    (0..parts.len()).all(|i| {
        (i + 1..parts.len()).all(|j| parts[i] != parts[j] || parts[i].split(' ').count() < 3)
    })
}

#[test]
fn mutated_blobs_are_refused_quickly_naming_path_and_offset() {
    let good = mcu_blob();
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("m.dblob");
    let mut refused = 0;
    let mut slowest = Duration::ZERO;
    // Header bytes one by one, then a stride through the op list and the data.
    let positions: Vec<usize> = (16..HEADER_LEN)
        .chain((HEADER_LEN..good.len().min(8192)).step_by(13))
        .collect();
    for (k, &at) in positions.iter().enumerate() {
        let mut blob = good.clone();
        blob[at] = [0x00, 0xff, 0x80, 0x7f][k % 4];
        fix_crc(&mut blob);
        std::fs::write(&path, &blob).unwrap();
        let t = Instant::now();
        let r = Int8Model::from_file(&path, None);
        slowest = slowest.max(t.elapsed());
        if let Err(e) = r {
            refused += 1;
            let msg = e.to_string();
            assert!(msg.starts_with(&format!("{}: ", path.display())), "{msg}");
            assert!(!msg.contains('\n') && said_once(&msg), "{msg}");
        }
    }
    println!(
        "{refused} of {} mutations refused, slowest {slowest:?}",
        positions.len()
    );
    assert!(refused > 20, "{refused} of {} refused", positions.len());
    assert!(
        slowest < Duration::from_secs(3),
        "slowest refusal {slowest:?}"
    );
    // The header's input size is bounded before planning.
    let mut blob = good.clone();
    blob[16..20].copy_from_slice(&[0xff, 0xff, 0xff, 0xff]);
    fix_crc(&mut blob);
    std::fs::write(&path, &blob).unwrap();
    let t = Instant::now();
    let msg = Int8Model::from_file(&path, None).unwrap_err().to_string();
    assert!(t.elapsed() < Duration::from_secs(1));
    assert!(msg.contains("m.dblob: byte 16: "), "{msg}");
    // The largest header size still allowed is answered quickly too (planned or refused).
    for (h, w) in [(4096u16, 4096u16), (4096, 1), (1, 4096), (1, 1)] {
        let mut blob = good.clone();
        blob[16..18].copy_from_slice(&h.to_le_bytes());
        blob[18..20].copy_from_slice(&w.to_le_bytes());
        fix_crc(&mut blob);
        let t = Instant::now();
        let r = Int8Model::from_bytes(blob, None).map(|m| m.arena_bytes());
        println!(
            "{h}×{w}: {:?} in {:?}",
            r.as_ref().map_err(|e| e.to_string()),
            t.elapsed()
        );
        assert!(
            t.elapsed() < Duration::from_secs(5),
            "{h}×{w}: {:?}",
            t.elapsed()
        );
    }
}

#[test]
fn cli_blob_error_is_one_line_with_path_and_offset_said_once() {
    let good = mcu_blob();
    let tmp = tempfile::tempdir().unwrap();
    let rec = common::write_hand_made(&tmp.path().join("rec"));
    let model = tmp.path().join("mcu_bad");
    std::fs::create_dir_all(&model).unwrap();
    // Find a payload byte whose mutation the parser refuses (a "bad model blob at byte …").
    let blob_path = model.join("depthor.dblob");
    let mut found = None;
    for at in (HEADER_LEN..4096).step_by(3) {
        let mut blob = good.clone();
        blob[at] = 0;
        fix_crc(&mut blob);
        if let Err(e) = Int8Model::from_bytes(blob.clone(), None) {
            if e.to_string().contains("byte ") {
                found = Some(blob);
                break;
            }
        }
    }
    std::fs::write(&blob_path, found.expect("a refused mutation")).unwrap();
    let out = tmp.path().join("ev");
    let o = common::depthor(&[
        "eval",
        "--model",
        common::arg(&model),
        "--no-float",
        "--recording",
        common::arg(&rec),
        "--out",
        common::arg(&out),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains(&format!("{}: byte ", blob_path.display())),
        "{err}"
    );
    assert!(said_once(err.trim()), "said twice: {err}");
    println!("{}", err.trim());
    assert!(!out.exists());
}
