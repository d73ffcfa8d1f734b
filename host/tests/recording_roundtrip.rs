//! Writer → reader round trip, atomic writing, validation messages and the replay sensors.

mod common;

use depthor_core::calibration::{DistanceKind, Extrinsics};
use depthor_core::hal::{DtofSensor, ErrorKind, RgbCamera, RgbFrame, ZoneFrame};
use depthor_host::recording::{
    depth_m_to_mm, CameraMeta, DistanceMeta, DtofFrame, DtofMeta, ExtrinsicsMeta, Frame, FrameMeta,
    Recording, RecordingMeta, RecordingWriter, WriteOptions,
};
use depthor_host::sensors::{ReplayCamera, ReplayDtof};
use image::{Rgb, RgbImage};
use std::path::Path;

fn camera(width: u32, height: u32) -> CameraMeta {
    CameraMeta {
        width,
        height,
        fx: 30.5,
        fy: 31.25,
        cx: width as f32 / 2.0,
        cy: height as f32 / 2.0,
    }
}

fn header() -> RecordingMeta {
    RecordingMeta::new(
        camera(6, 4),
        Some(DtofMeta {
            rows: 2,
            cols: 3,
            fov_deg: [45.0, 30.0],
            distance: DistanceMeta::Radial,
            max_range_m: 4.0,
            zone_rects_px: None,
        }),
        Some(ExtrinsicsMeta {
            rotation: [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
            translation_m: [0.01, -0.02, 0.5],
        }),
    )
}

fn frame(id: &str, w: u32, h: u32, seed: u8) -> Frame {
    let n = (w * h) as usize;
    Frame {
        id: id.to_string(),
        rgb: RgbImage::from_fn(w, h, |x, y| Rgb([x as u8 * 10 + seed, y as u8 * 20, seed])),
        depth_m: Some((0..n).map(|i| 0.5 + i as f32 * 0.25).collect()),
        labels: Some((0..n).map(|i| (i % 4) as u8).collect()),
        dtof: Some(DtofFrame {
            distance_mm: vec![100.5, 200.0, 300.25, -4.0, 0.0, 4096.0],
            status: vec![5, 9, 255, 0, 13, 5],
            sigma_mm: Some(vec![1.0; 6]),
            signal_kcps: None,
            ambient_kcps: Some(vec![0.5, 1.5, 2.5, 3.5, 4.5, 5.5]),
        }),
    }
}

fn fmeta(id: &str, t_s: f64, camera: Option<CameraMeta>) -> FrameMeta {
    FrameMeta {
        id: id.into(),
        t_s,
        camera,
    }
}

#[test]
fn round_trip_preserves_everything_and_quantises_depth_to_mm() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("rec");
    let mut w = RecordingWriter::create(&out, header()).unwrap();
    let f0 = frame("000000", 6, 4, 1);
    let mut f1 = frame("000001", 3, 2, 2);
    // Depth edge cases: rounding to mm, clamp, unknowns.
    f1.depth_m = Some(vec![1.2344, 1.2346, 70.0, f32::NAN, -1.0, 0.0004]);
    w.add_frame(fmeta("000000", 0.0, None), &f0).unwrap();
    w.add_frame(fmeta("000001", 0.033, Some(camera(3, 2))), &f1)
        .unwrap();
    assert_eq!(w.finish().unwrap(), out);
    assert_eq!(common::entries(tmp.path()), vec!["rec"]);

    let rec = Recording::open(&out).unwrap();
    assert_eq!(rec.len(), 2);
    assert_eq!(rec.meta().frames[1].t_s, 0.033);
    assert_eq!((rec.camera(0).width, rec.camera(1).width), (6, 3));
    assert_eq!(rec.camera(1).fy, 31.25);
    let cal = rec.calibration(1).unwrap();
    let core = cal.as_core();
    assert_eq!(core.camera.width, 3);
    assert_eq!(core.dtof.distance, DistanceKind::Radial);
    assert_eq!(core.dtof_to_camera.translation_m, [0.01, -0.02, 0.5]);
    assert!(core.zone_rects_px.is_none());

    let r0 = rec.read_frame(0).unwrap();
    assert_eq!(r0.rgb, f0.rgb);
    assert_eq!(r0.labels, f0.labels);
    assert_eq!(r0.dtof, f0.dtof);
    // 0.5 + i/4 m is a whole number of mm: exact.
    assert_eq!(r0.depth_m, f0.depth_m);

    let r1 = rec.read_frame(1).unwrap();
    assert_eq!(r1.rgb, f1.rgb);
    assert_eq!(
        r1.depth_m.unwrap(),
        vec![1.234, 1.235, 65.535, 0.0, 0.0, 0.0]
    );
    assert_eq!(
        [1.2344, 70.0, f32::INFINITY, 0.0005].map(depth_m_to_mm),
        [1234, 65535, 0, 1]
    );

    // The header spells the enum and the null rectangles as docs/recording.md does.
    let text = std::fs::read_to_string(out.join("recording.json")).unwrap();
    assert!(text.contains("\"format\": \"depthor-recording/1\""));
    assert!(text.contains("\"distance\": \"radial\""));
    assert!(text.contains("\"zone_rects_px\": null"));
}

#[test]
fn dropped_or_failed_writer_leaves_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("rec");
    {
        let mut w = RecordingWriter::create(&out, header()).unwrap();
        w.add_frame(fmeta("a", 0.0, None), &frame("a", 6, 4, 0))
            .unwrap();
        // A partial directory exists while writing …
        assert_eq!(common::entries(tmp.path()).len(), 1);
        assert!(common::entries(tmp.path())[0].starts_with("rec.partial-"));
    }
    // … and is gone after the drop, with no destination.
    assert!(common::entries(tmp.path()).is_empty());

    let mut w = RecordingWriter::create(&out, header()).unwrap();
    let err = w
        .add_frame(fmeta("b", 0.0, None), &frame("b", 5, 4, 0))
        .unwrap_err();
    assert_eq!(
        err.to_string(),
        format!(
            "{}: size: expected 6×4 (the frame's camera), found 5×4",
            out.join("frames/b/rgb.png").display()
        )
    );
    let mut bad = frame("c", 6, 4, 0);
    bad.dtof.as_mut().unwrap().status[2] = 77;
    let err = w.add_frame(fmeta("c", 0.0, None), &bad).unwrap_err();
    assert_eq!(err.field, "status[2]");
    let mut nan = frame("d", 6, 4, 0);
    nan.dtof.as_mut().unwrap().distance_mm[4] = f32::NAN;
    assert_eq!(
        w.add_frame(fmeta("d", 0.0, None), &nan).unwrap_err().field,
        "distance_mm[4]"
    );
    assert!(w.meta().frames.is_empty());
    drop(w);
    assert!(common::entries(tmp.path()).is_empty());
}

#[test]
fn existing_destination_is_refused_unless_overwrite() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("rec");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("keep.txt"), "x").unwrap();
    let err = RecordingWriter::create(&out, header()).unwrap_err();
    assert_eq!(err.field, "output");
    assert!(out.join("keep.txt").exists());

    let mut w =
        RecordingWriter::create_with(&out, header(), WriteOptions { overwrite: true }).unwrap();
    w.add_frame(fmeta("x", 1.0, None), &frame("x", 6, 4, 3))
        .unwrap();
    w.finish().unwrap();
    assert!(!out.join("keep.txt").exists());
    assert_eq!(Recording::open(&out).unwrap().len(), 1);
    assert_eq!(common::entries(tmp.path()), vec!["rec"]);

    // An empty existing directory is simply replaced.
    let empty = tmp.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let w = RecordingWriter::create(&empty, header()).unwrap();
    w.finish().unwrap();
    assert!(Recording::open(&empty).unwrap().is_empty());
}

#[test]
fn header_validation_names_fields() {
    let check = |edit: &dyn Fn(&mut RecordingMeta), field: &str| {
        let mut m = header();
        edit(&mut m);
        let tmp = tempfile::tempdir().unwrap();
        let err = RecordingWriter::create(tmp.path().join("r"), m).unwrap_err();
        assert_eq!(err.field, field, "{err}");
        assert!(common::entries(tmp.path()).is_empty());
    };
    check(&|m| m.format = "depthor-recording/2".into(), "format");
    check(&|m| m.camera.height = 0, "camera.height");
    check(&|m| m.camera.fx = f32::INFINITY, "camera.fx");
    check(
        &|m| m.dtof.as_mut().unwrap().fov_deg[1] = 180.0,
        "dtof.fov_deg[1]",
    );
    check(
        &|m| m.dtof.as_mut().unwrap().zone_rects_px = Some(vec![[0.0; 4]; 5]),
        "dtof.zone_rects_px",
    );
    check(
        &|m| {
            let mut r = vec![[0.0, 0.0, 1.0, 1.0]; 6];
            r[3] = [5.0, 0.0, 1.0, 1.0];
            m.dtof.as_mut().unwrap().zone_rects_px = Some(r)
        },
        "dtof.zone_rects_px[3]",
    );
    check(
        &|m| m.dtof_to_camera.as_mut().unwrap().rotation[2][1] = f32::NAN,
        "dtof_to_camera.rotation[2][1]",
    );
    check(&|m| m.frames.push(fmeta("x", 0.0, None)), "frames");
}

#[test]
fn reader_names_fields_of_hand_made_json() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = common::write_hand_made(&tmp.path().join("rec"));
    let path = rec.join("recording.json");
    let good = common::recording_json(&["000000"]);
    let cases = [
        (
            "\"distance\": \"z\"",
            "\"distance\": \"slant\"",
            "dtof.distance",
        ),
        ("\"rows\": 2", "\"rows\": 70000", "dtof.rows"),
        ("\"rows\": 2", "\"rows\": 2, \"extra\": 1", "dtof.extra"),
        (
            "\"t_s\": 0.5",
            "\"t_s\": 0.5, \"camera\": {\"width\": 1}",
            "frames[0].camera.height",
        ),
        ("\"id\": \"000000\"", "\"id\": \"../x\"", "frames[0].id"),
        ("\"fx\": 32.0", "\"fx\": 1e39", "camera.fx"),
        (
            "[0.0, 0.0, 0.0]",
            "[0.0, 0.0]",
            "dtof_to_camera.translation_m",
        ),
    ];
    for (from, to, field) in cases {
        assert!(good.contains(from), "{from}");
        std::fs::write(&path, good.replacen(from, to, 1)).unwrap();
        let err = Recording::open(&rec).unwrap_err();
        assert_eq!(
            (err.path.as_path(), err.field.as_str()),
            (path.as_path(), field),
            "{err}"
        );
    }

    std::fs::write(&path, &good).unwrap();
    let dtof = rec.join("frames/000000/dtof.json");
    let cases = [
        (
            r#"{"distance_mm": [1,2,3,4], "status": [5,5,5,14]}"#,
            "status[3]",
        ),
        (
            r#"{"distance_mm": [1,2,3,4], "status": [5,5,5,256]}"#,
            "status[3]",
        ),
        (
            r#"{"distance_mm": [1,2,3,"4"], "status": [5,5,5,5]}"#,
            "distance_mm[3]",
        ),
        (
            r#"{"distance_mm": [1,2,3,4], "status": [5,5,5,5], "sigma_mm": [1]}"#,
            "sigma_mm",
        ),
        (r#"{"status": [5,5,5,5]}"#, "distance_mm"),
        (r#"[1, 2]"#, "(root)"),
    ];
    let rec_ok = Recording::open(&rec).unwrap();
    for (text, field) in cases {
        std::fs::write(&dtof, text).unwrap();
        let err = rec_ok.read_frame(0).unwrap_err();
        assert_eq!(
            (err.path.as_path(), err.field.as_str()),
            (dtof.as_path(), field),
            "{err}"
        );
    }
    // Labels outside 0..=3 name the pixel.
    std::fs::write(&dtof, common::DTOF_JSON).unwrap();
    let mut labels = image::GrayImage::new(64, 48);
    labels.put_pixel(5, 2, image::Luma([9]));
    labels.save(rec.join("frames/000000/labels.png")).unwrap();
    let err = rec_ok.read_frame(0).unwrap_err();
    assert_eq!(err.field, "pixel (x 5, y 2)", "{err}");
}

fn write_two_frames(dir: &Path) -> Recording {
    let mut w = RecordingWriter::create(dir, header()).unwrap();
    w.add_frame(fmeta("f0", 0.0, None), &frame("f0", 6, 4, 1))
        .unwrap();
    let mut f1 = frame("f1", 6, 4, 2);
    f1.dtof.as_mut().unwrap().distance_mm[0] = 777.0;
    w.add_frame(fmeta("f1", 0.1, None), &f1).unwrap();
    Recording::open(w.finish().unwrap()).unwrap()
}

#[test]
fn replay_sensors_play_frames_in_order_then_end_of_stream() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = write_two_frames(&tmp.path().join("rec"));

    let mut dtof = ReplayDtof::new(rec.clone()).unwrap();
    assert_eq!(dtof.geometry().zones(), 6);
    let mut small = ZoneFrame::<4>::new();
    assert_eq!(
        dtof.read_frame(&mut small).unwrap_err().kind,
        ErrorKind::BufferShape
    );
    assert_eq!(dtof.position(), 0, "shape errors do not advance");
    let mut z = ZoneFrame::<64>::new();
    dtof.read_frame(&mut z).unwrap();
    assert_eq!((z.rows, z.cols, z.len()), (2, 3, 6));
    assert_eq!(
        z.distance_mm[..6],
        [100.5, 200.0, 300.25, -4.0, 0.0, 4096.0]
    );
    assert_eq!(z.status[..6], [5, 9, 255, 0, 13, 5]);
    assert!(z.has_sigma && !z.has_signal && z.has_ambient);
    assert_eq!(z.ambient_kcps[5], 5.5);
    dtof.read_frame(&mut z).unwrap();
    assert_eq!(z.distance_mm[0], 777.0);
    assert_eq!(
        dtof.read_frame(&mut z).unwrap_err().kind,
        ErrorKind::EndOfStream
    );

    let mut cam = ReplayCamera::new(rec.clone());
    assert_eq!(cam.resolution(), (6, 4));
    let mut buf = vec![0u8; 6 * 4 * 3];
    let mut wrong = vec![0u8; 5];
    let mut bad = RgbFrame {
        width: 6,
        height: 4,
        data: &mut wrong,
    };
    assert_eq!(
        cam.capture(&mut bad).unwrap_err().kind,
        ErrorKind::BufferShape
    );
    for expect in [frame("f0", 6, 4, 1), frame("f1", 6, 4, 2)] {
        let mut f = RgbFrame {
            width: 6,
            height: 4,
            data: &mut buf,
        };
        cam.capture(&mut f).unwrap();
        assert_eq!(buf, expect.rgb.as_raw().as_slice());
    }
    let mut f = RgbFrame {
        width: 6,
        height: 4,
        data: &mut buf,
    };
    assert_eq!(
        cam.capture(&mut f).unwrap_err().kind,
        ErrorKind::EndOfStream
    );

    // A corrupt file is BadData carrying the recording error, and the stream moves on.
    std::fs::write(rec.frame_file(0, "dtof.json"), "{").unwrap();
    let mut dtof = ReplayDtof::new(rec).unwrap();
    let err = dtof.read_frame(&mut z).unwrap_err();
    assert_eq!(err.kind, ErrorKind::BadData);
    assert_eq!(err.source.unwrap().field, "JSON syntax");
    dtof.read_frame(&mut z).unwrap();
    assert_eq!(z.distance_mm[0], 777.0);
}

#[test]
fn conversions_to_core_types() {
    let e: Extrinsics = header().dtof_to_camera.unwrap().into();
    assert_eq!(e.apply([1.0, 2.0, 3.0]), [1.01, -3.02, 2.5]);
    let back: ExtrinsicsMeta = Extrinsics::IDENTITY.into();
    assert_eq!(back.rotation, Extrinsics::IDENTITY.rotation);
    let g = (&header().dtof.unwrap()).into();
    assert_eq!(DtofMeta::from_geometry(&g, None), header().dtof.unwrap());
}
