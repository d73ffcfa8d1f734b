//! Fuzzes the replay flash image (`depthor_replay::format::Image::parse`, `DPTHRPLY` v1, what
//! the firmware reads from flash) and, when it parses, the firmware loop over it: the replay
//! camera, the simulated zone bridge read back by the real driver, projection with the image's
//! calibration, and the int8 engine (the fuzz targets' micro test network run at the image's
//! size, up to 32×32) — `ReplayLoop::process`, at most 4 frames.
//!
//! Input: `mode, image…`. Bit 0 of `mode` recomputes the trailing CRC, so mutations reach the
//! checks behind it (zone counts, reserved fields, the frames themselves). Checks: nothing
//! panics; every frame of a parsed image is readable with the header's sizes; a frame the loop
//! completes has a finite depth map.
#![no_main]

#[path = "common.rs"]
mod common;

use std::collections::BTreeMap;
use std::mem::MaybeUninit;
use std::sync::Mutex;

use common::{NoDelay, MICRO_BLOB};
use depthor_core::blob::checksum::crc32;
use depthor_core::engine::{required_arena_bytes_io, Engine, Io, Memory};
use depthor_core::hal::{RgbCamera, RgbFrame, ZoneFrame};
use depthor_replay::camera::ReplayCamera;
use depthor_replay::format::{Image, CRC_LEN};
use depthor_replay::pipeline::{ReplayLoop, Workspace};
use libfuzzer_sys::fuzz_target;

/// Zones the loop's workspace holds (the firmware's is 64).
const ZONES: usize = 256;

/// As the firmware prepares it (`depthor_replay::model::prepare`): the frame buffers in the
/// arena (`Io::Arena`), the loop captures and projects into `Engine::staging`. `None` where the
/// size does not plan.
fn prepare(h: usize, w: usize) -> Option<&'static mut Engine<'static>> {
    let need = required_arena_bytes_io(MICRO_BLOB, h, w, Memory::Streamed, Io::Arena).ok()?;
    let arena: &'static mut [u8] = Box::leak(vec![0u8; need].into_boxed_slice());
    let slot = Box::leak(Box::new(MaybeUninit::<Engine<'static>>::uninit()));
    let engine = Engine::init_in(slot, MICRO_BLOB, arena, h, w, Memory::Streamed, Io::Arena);
    Some(engine.expect("the engine accepts the arena it asked for"))
}

/// One engine per image size, prepared on first use: parsing and planning depend only on the
/// fixed blob and the size (as in the firmware, which prepares once at boot), so executions
/// skip them (`parse_blob` fuzzes both). Leaked into a `static`, so LeakSanitizer sees them
/// reachable.
static ENGINES: Mutex<BTreeMap<(usize, usize), Option<&'static mut Engine<'static>>>> =
    Mutex::new(BTreeMap::new());

fuzz_target!(|input: &[u8]| {
    let Some((&mode, rest)) = input.split_first() else {
        return;
    };
    let mut bytes = rest.to_vec();
    if mode & 1 == 1 && bytes.len() >= CRC_LEN {
        let body = bytes.len() - CRC_LEN;
        let c = crc32(&bytes[..body]);
        bytes[body..].copy_from_slice(&c.to_le_bytes());
    }
    let Ok(image) = Image::parse(&bytes) else {
        return;
    };
    let (h, w) = image.size();
    let (rows, cols) = image.zone_grid();
    let (h, w, zones) = (
        usize::from(h),
        usize::from(w),
        usize::from(rows) * usize::from(cols),
    );
    let shown = image.frame_count().min(64);
    for i in 0..shown {
        let f = image
            .frame(i)
            .expect("every frame of a parsed image is readable");
        assert_eq!(f.rgb.len(), 3 * h * w);
        assert_eq!((f.zones(), f.distance_mm().count()), (zones, zones));
    }
    assert!(image.frame(image.frame_count()).is_none());

    // The camera alone, over every frame shown above and one past the end.
    let mut camera = ReplayCamera::new(image);
    let mut rgb = vec![0u8; 3 * h * w];
    for _ in 0..=shown.min(4) {
        let mut frame = RgbFrame {
            width: w as u32,
            height: h as u32,
            data: &mut rgb,
        };
        if camera.capture(&mut frame).is_err() {
            break;
        }
    }

    // The firmware loop, at small sizes only.
    if h * w > 32 * 32 {
        return;
    }
    let mut engines = ENGINES.lock().unwrap_or_else(|e| e.into_inner());
    let Some(engine) = engines.entry((h, w)).or_insert_with(|| prepare(h, w)) else {
        return;
    };
    let mut bridge = [0f32; ZONES];
    let mut zone_frame = Box::new(ZoneFrame::<ZONES>::new());
    let mut ws = Workspace {
        bridge_mm: &mut bridge,
        zones: &mut zone_frame,
    };
    let mut replay = ReplayLoop::new(image, NoDelay);
    for _ in 0..4 {
        match replay.process(engine, &mut ws) {
            Ok(Some(p)) => {
                let depth = engine.output_m().expect("output after a completed frame");
                assert!(depth[..p.pixels].iter().all(|v| v.is_finite()));
            }
            Ok(None) | Err(_) => break,
        }
    }
});
