//! The host build of the firmware loop (`std`): the same [`ReplayLoop`], the same engine and
//! blob ([`crate::model`]), with heap buffers in place of the firmware's statics.

use depthor_core::hal::ZoneFrame;
use embedded_hal::delay::DelayNs;

use crate::format::Image;
use crate::model::{prepare, ARENA_BUDGET_BYTES, MCU_BLOB};
use crate::pipeline::{FrameOutput, LoopError, ReplayLoop, Workspace, VL53_IO_BYTES};

/// A [`DelayNs`] that sleeps for real (the simulated sensor answers at once, so the driver
/// never waits in practice).
#[derive(Clone, Copy, Debug, Default)]
pub struct StdDelay;

impl DelayNs for StdDelay {
    fn delay_ns(&mut self, ns: u32) {
        std::thread::sleep(std::time::Duration::from_nanos(u64::from(ns)));
    }
}

/// Runs every frame of `image` through the loop with the embedded model and the VL53L5CX driver
/// over the simulated sensor (as the firmware does), holding up to `N` zones (the firmware holds
/// 64), and calls `emit` with each frame's output; returns the frame count.
pub fn replay_image<const N: usize>(
    image: Image<'_>,
    delay: impl DelayNs,
    emit: impl FnMut(&FrameOutput),
) -> Result<u32, LoopError> {
    let (h, w) = image.size();
    let pixels = usize::from(h) * usize::from(w);
    let mut arena = vec![0u8; ARENA_BUDGET_BYTES];
    let mut engine = prepare(MCU_BLOB, &mut arena, h, w).map_err(LoopError::Engine)?;
    let (mut rgb, mut sparse, mut depth) = (
        vec![0u8; 3 * pixels],
        vec![0f32; pixels],
        vec![0f32; pixels],
    );
    let mut bridge = [0f32; N];
    let mut zones = ZoneFrame::<N>::new();
    let mut ws = Workspace {
        rgb: &mut rgb,
        sparse_m: &mut sparse,
        depth_m: &mut depth,
        bridge_mm: &mut bridge,
        zones: &mut zones,
    };
    let mut io = vec![0u8; VL53_IO_BYTES];
    ReplayLoop::with_vl53l5cx(image, delay, &mut io, || 0).run_all(&mut engine, &mut ws, emit)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{mcu_calibration, mcu_frames};
    use crate::writer::image_bytes;

    struct NoDelay;
    impl DelayNs for NoDelay {
        fn delay_ns(&mut self, _ns: u32) {}
    }

    #[test]
    fn replays_every_frame_deterministically() {
        let bytes = image_bytes(&mcu_calibration(), &mcu_frames(2)).unwrap();
        let mut a = Vec::new();
        let n = replay_image::<64>(Image::parse(&bytes).unwrap(), NoDelay, |o| {
            a.push(o.to_string())
        })
        .unwrap();
        assert_eq!(n, 2);
        let mut b = Vec::new();
        replay_image::<64>(Image::parse(&bytes).unwrap(), NoDelay, |o| b.push(*o)).unwrap();
        assert_eq!(a, b.iter().map(|o| o.to_string()).collect::<Vec<_>>());
        assert!(a[0].starts_with("frame 0 depth_fnv1a64="), "{}", a[0]);
        assert_ne!(b[0].hash, b[1].hash);
    }
}
