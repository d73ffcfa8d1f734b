//! `pipeline::depth_frame`: camera and sensor through the HAL traits, projection, engine; the
//! same bits as calling the stages by hand, both output units, and errors instead of panics.

mod common;

use common::{frame, rgb_planar, tiny_net};
use depthor_core::calibration::{
    Calibration, CameraIntrinsics, DistanceKind, DtofGeometry, Extrinsics,
};
use depthor_core::engine::{required_arena_bytes, Engine};
use depthor_core::hal::{DtofSensor, ErrorKind, ErrorType, RgbCamera, RgbFrame, ZoneFrame};
use depthor_core::pipeline::DepthOut;
use depthor_core::pipeline::{depth_frame, FrameBuffers, FrameError};
use depthor_core::projection::project_to_sparse;

const H: usize = 12;
const W: usize = 16;

fn calibration() -> Calibration<'static> {
    Calibration {
        camera: CameraIntrinsics {
            width: W as u32,
            height: H as u32,
            fx: 12.0,
            fy: 12.0,
            cx: 8.0,
            cy: 6.0,
        },
        dtof: DtofGeometry {
            rows: 4,
            cols: 4,
            fov_deg: [60.0, 60.0],
            distance: DistanceKind::Z,
            max_range_m: 4.0,
        },
        dtof_to_camera: Extrinsics::IDENTITY,
        zone_rects_px: None,
    }
}

/// A camera that serves one fixed image, or fails with `fail`.
struct FixedCamera {
    rgb: Vec<u8>,
    fail: Option<ErrorKind>,
}

impl ErrorType for FixedCamera {
    type Error = ErrorKind;
}

impl RgbCamera for FixedCamera {
    fn resolution(&self) -> (u32, u32) {
        (W as u32, H as u32)
    }
    fn capture(&mut self, f: &mut RgbFrame<'_>) -> Result<(), ErrorKind> {
        if let Some(k) = self.fail {
            return Err(k);
        }
        if f.data.len() != self.rgb.len() {
            return Err(ErrorKind::BufferShape);
        }
        f.data.copy_from_slice(&self.rgb);
        Ok(())
    }
}

/// A 4×4 sensor: zone k at 1 m + 0.1 m·k, zone 5 without a target.
struct FixedSensor;

impl ErrorType for FixedSensor {
    type Error = ErrorKind;
}

impl DtofSensor for FixedSensor {
    fn geometry(&self) -> DtofGeometry {
        calibration().dtof
    }
    fn read_frame<const N: usize>(&mut self, z: &mut ZoneFrame<N>) -> Result<(), ErrorKind> {
        z.set_shape(4, 4)?;
        for k in 0..16 {
            z.distance_mm[k] = 1000.0 + 100.0 * k as f32;
            z.status[k] = if k == 5 { 255 } else { 5 };
        }
        Ok(())
    }
}

fn blob() -> Vec<u8> {
    let net = tiny_net(H, W);
    let (rgb, sparse) = frame(H, W);
    net.to_blob(&net.run_float(&rgb_planar(&rgb, H, W), &sparse))
}

#[test]
fn matches_the_stages_called_by_hand_in_both_units() {
    let blob = blob();
    let mut arena = vec![0u8; required_arena_bytes(&blob, H, W).unwrap() + 64];
    let mut engine = Engine::new(&blob, &mut arena).unwrap();
    let cal = calibration();
    let (rgb, _) = frame(H, W);
    let mut camera = FixedCamera {
        rgb: rgb.clone(),
        fail: None,
    };
    let (mut rgb_buf, mut sparse_buf) = (vec![0u8; 3 * H * W], vec![0f32; H * W]);
    let mut zones = ZoneFrame::<16>::new();
    let mut out_m = vec![0f32; H * W];
    let report = depth_frame(
        &mut camera,
        &mut FixedSensor,
        &cal,
        &mut engine,
        &mut FrameBuffers {
            rgb: &mut rgb_buf,
            sparse_m: &mut sparse_buf,
            zones: &mut zones,
        },
        DepthOut::Metres(&mut out_m),
    )
    .unwrap();
    assert_eq!(report.projection.zones, 16);
    assert!(report.projection.projected >= 1 && report.projection.projected <= 15);
    assert!(report.run.macs > 0);

    // By hand: the same sparse map, the same engine call.
    let mut by_hand_zones = ZoneFrame::<16>::new();
    FixedSensor.read_frame(&mut by_hand_zones).unwrap();
    let mut sparse = vec![0f32; H * W];
    project_to_sparse(&cal, &by_hand_zones.view(), &mut sparse).unwrap();
    let mut want = vec![0f32; H * W];
    engine.run(&rgb, &sparse, &mut want).unwrap();
    let bits = |v: &[f32]| v.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&out_m), bits(&want));
    // The sparse buffer ends holding the dense depth (the engine ran in place on it).
    assert_eq!(bits(&sparse_buf), bits(&want));

    let mut out_mm = vec![0u16; H * W];
    depth_frame(
        &mut camera,
        &mut FixedSensor,
        &cal,
        &mut engine,
        &mut FrameBuffers {
            rgb: &mut rgb_buf,
            sparse_m: &mut sparse_buf,
            zones: &mut zones,
        },
        DepthOut::Millimetres(&mut out_mm),
    )
    .unwrap();
    for (mm, m) in out_mm.iter().zip(&want) {
        assert_eq!(*mm, (m * 1000.0 + 0.5).clamp(0.0, 65535.0) as u16);
    }
}

/// `depth_frame` on the fixed sensor with the given camera and buffers, metres out.
fn run(
    engine: &mut Engine<'_>,
    camera: &mut FixedCamera,
    sparse_m: &mut [f32],
    zones: &mut ZoneFrame<16>,
    out: &mut [f32],
) -> Result<(), FrameError> {
    let mut rgb = vec![0u8; 3 * H * W];
    let mut buffers = FrameBuffers {
        rgb: &mut rgb,
        sparse_m,
        zones,
    };
    let cal = calibration();
    depth_frame(
        camera,
        &mut FixedSensor,
        &cal,
        engine,
        &mut buffers,
        DepthOut::Metres(out),
    )
    .map(|_| ())
}

#[test]
fn failures_are_errors_not_panics() {
    let blob = blob();
    let mut arena = vec![0u8; required_arena_bytes(&blob, H, W).unwrap() + 64];
    let mut engine = Engine::new(&blob, &mut arena).unwrap();
    let (rgb, _) = frame(H, W);
    let mut zones = ZoneFrame::<16>::new();
    let mut sparse = vec![0f32; H * W];
    let mut out = vec![0f32; H * W];
    let mut camera = FixedCamera { rgb, fail: None };

    camera.fail = Some(ErrorKind::Timeout);
    let r = run(&mut engine, &mut camera, &mut sparse, &mut zones, &mut out);
    assert_eq!(r, Err(FrameError::Camera(ErrorKind::Timeout)));
    camera.fail = None;

    let mut short = vec![0f32; H * W - 1];
    let r = run(&mut engine, &mut camera, &mut short, &mut zones, &mut out);
    assert_eq!(r, Err(FrameError::Buffer("sparse depth buffer")));

    let r = run(
        &mut engine,
        &mut camera,
        &mut sparse,
        &mut zones,
        &mut [0f32; 3],
    );
    assert!(matches!(r, Err(FrameError::Engine(_))), "{r:?}");
    run(&mut engine, &mut camera, &mut sparse, &mut zones, &mut out).unwrap();

    // A zone frame too small for the sensor's 4×4 grid.
    let cal = calibration();
    let mut small = ZoneFrame::<8>::new();
    let mut rgb = vec![0u8; 3 * H * W];
    let r = depth_frame(
        &mut camera,
        &mut FixedSensor,
        &cal,
        &mut engine,
        &mut FrameBuffers {
            rgb: &mut rgb,
            sparse_m: &mut sparse,
            zones: &mut small,
        },
        DepthOut::Metres(&mut out),
    );
    assert_eq!(
        r.map(|_| ()),
        Err(FrameError::Sensor(ErrorKind::BufferShape))
    );
}
