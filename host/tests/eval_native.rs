//! `depthor eval --native` end to end: a simulated recording at 340×250 (wider than the `mcu`
//! model's 4:3, and not a multiple of its 160×120) scored with and without `--native`. The native
//! run scores exactly the valid reference pixels of the centred 333×250 crop at the recording's
//! resolution, its saved predictions have that size and agree with the model-size predictions
//! they were upsampled from, and its RMSE is close to the model-size one but not equal.

mod common;

use common::{arg as s, depthor_ok};
use depthor_host::recording::Recording;
use std::path::Path;

/// The recording's size and the crop the model's input comes from: 340 / 250 is wider than
/// 160 / 120, so the crop is the full height and round(250 · 4 / 3) = 333 columns, 3 trimmed on
/// the left ((340 − 333) / 2, rounded down) and 4 on the right.
const REC: (u32, u32) = (340, 250);
const CROP: (u32, u32, u32, u32) = (3, 0, 333, 250);
const MODEL: (u32, u32) = (160, 120);
/// Below the scenes' farthest depths, so that part of each frame is not scored and the count of
/// scored pixels depends on where the crop lies.
const MAX_DEPTH: f32 = 4.0;

fn summary(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
}

/// `(frame, pixels, rmse)` of every int8 row of `frames.csv`.
fn int8_rows(out: &Path) -> Vec<(String, u64, f64)> {
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (frame, method, pixels, rmse) = (col("frame"), col("method"), col("pixels"), col("rmse"));
    lines
        .map(|l| l.split(',').collect::<Vec<_>>())
        .filter(|f| f[method] == "int8")
        .map(|f| {
            (
                f[frame].to_string(),
                f[pixels].parse().unwrap(),
                f[rmse].parse().unwrap(),
            )
        })
        .collect()
}

fn depth_png(out: &Path, id: &str) -> image::ImageBuffer<image::Luma<u16>, Vec<u16>> {
    let img = image::open(out.join(format!("depth/rec/int8/{id}.png"))).unwrap();
    assert!(matches!(img, image::DynamicImage::ImageLuma16(_)));
    img.to_luma16()
}

#[test]
fn native_scores_the_crop_at_the_recordings_resolution() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = tmp.path().join("rec");
    let (rw, rh) = (REC.0.to_string(), REC.1.to_string());
    depthor_ok(&[
        "sim",
        "--preset",
        "mcu",
        "--scenes",
        "2",
        "--seed",
        "2024",
        "--width",
        &rw,
        "--height",
        &rh,
        "--out",
        s(&rec),
    ]);
    let max_depth = MAX_DEPTH.to_string();
    let (model, native) = (tmp.path().join("model"), tmp.path().join("native"));
    let base = [
        "eval",
        "--model",
        "mcu",
        "--no-float",
        "--mosaics",
        "0",
        "--save-depth",
        "--max-depth",
        &max_depth,
        "--recording",
        s(&rec),
    ];
    depthor_ok(&[&base[..], &["--out", s(&model)]].concat());
    let stdout = depthor_ok(&[&base[..], &["--native", "--out", s(&native)]].concat());
    assert!(
        stdout.contains("scored at the recording's resolution (--native)"),
        "{stdout}"
    );

    let (sm, sn) = (summary(&model), summary(&native));
    assert_eq!(sm["scored_at"], "model");
    assert_eq!(sn["scored_at"], "native");
    // `height`/`width` stay the model's input size; the crop is reported beside it.
    for s in [&sm, &sn] {
        assert_eq!(
            (s["width"].as_u64(), s["height"].as_u64()),
            (Some(160), Some(120))
        );
        assert_eq!(s["frames"], 2);
    }
    assert_eq!(
        sn["first_native_crop"],
        serde_json::json!({"height": CROP.3, "width": CROP.2})
    );
    assert!(sm.get("first_native_crop").is_none());

    // Pixels scored: every valid reference pixel of the crop at full resolution (counted here from
    // the recording itself), none outside it; at the model's size at most 160 × 120 per frame.
    let r = Recording::open(&rec).unwrap();
    let (x0, y0, cw, ch) = CROP;
    let valid = |d: f32| d > 0.001 && d < MAX_DEPTH;
    let (rows_m, rows_n) = (int8_rows(&model), int8_rows(&native));
    assert_eq!((rows_m.len(), rows_n.len()), (2, 2));
    let mut native_total = 0;
    for (i, ((id_m, px_m, _), (id_n, px_n, _))) in rows_m.iter().zip(&rows_n).enumerate() {
        let f = r.read_frame(i).unwrap();
        assert_eq!((&f.id, &f.id), (id_m, id_n));
        assert_eq!(f.rgb.dimensions(), REC);
        let d = f.depth_m.as_ref().unwrap();
        let in_crop = (y0..y0 + ch)
            .flat_map(|y| (x0..x0 + cw).map(move |x| (y * REC.0 + x) as usize))
            .filter(|&k| valid(d[k]))
            .count() as u64;
        let shifted = (y0..y0 + ch)
            .flat_map(|y| (0..cw).map(move |x| (y * REC.0 + x) as usize))
            .filter(|&k| valid(d[k]))
            .count() as u64;
        // The scene makes the crop's position matter (else the count below proves little).
        assert_ne!(shifted, in_crop);
        let in_frame = d.iter().filter(|&&v| valid(v)).count() as u64;
        println!(
            "frame {id_n}: valid reference {in_frame} in the frame, {in_crop} in the crop; \
             scored {px_n} native, {px_m} at the model's size"
        );
        assert_eq!(*px_n, in_crop, "frame {id_n}: native pixels scored");
        assert!(*px_m <= u64::from(MODEL.0 * MODEL.1));
        assert!(*px_n > u64::from(MODEL.0 * MODEL.1) && *px_n < in_frame);
        // The same region, so the same fraction of it valid (nearest sampling, up to the edges).
        let (fm, fnat) = (
            *px_m as f64 / f64::from(MODEL.0 * MODEL.1),
            *px_n as f64 / f64::from(cw * ch),
        );
        assert!((fm - fnat).abs() < 0.02, "valid fraction {fm} vs {fnat}");
        native_total += px_n;
    }
    let (mm, mn) = (&sm["methods"]["int8"], &sn["methods"]["int8"]);
    assert_eq!(mn["pixels"].as_u64(), Some(native_total));

    // Saved predictions: the model's size by default, the crop's with --native, and the native
    // map is the model-size one upsampled: every model pixel's footprint in the crop holds values
    // within the range of that pixel's 3×3 neighbourhood (bilinear interpolation does not
    // overshoot; ±1 mm for the rounding to millimetres).
    for (id, _, _) in &rows_n {
        let (pm, pn) = (depth_png(&model, id), depth_png(&native, id));
        assert_eq!(pm.dimensions(), MODEL);
        assert_eq!(pn.dimensions(), (cw, ch));
        let (mw, mh) = MODEL;
        for y in 0..mh {
            for x in 0..mw {
                let mut lo = u16::MAX;
                let mut hi = 0;
                for (nx, ny) in (0..9).map(|k| (x as i64 + k % 3 - 1, y as i64 + k / 3 - 1)) {
                    if nx >= 0 && ny >= 0 && nx < i64::from(mw) && ny < i64::from(mh) {
                        let v = pm.get_pixel(nx as u32, ny as u32)[0];
                        (lo, hi) = (lo.min(v), hi.max(v));
                    }
                }
                // The native pixel whose centre is nearest this model pixel's centre.
                let u = ((2 * x + 1) * cw / (2 * mw)).min(cw - 1);
                let v = ((2 * y + 1) * ch / (2 * mh)).min(ch - 1);
                let got = pn.get_pixel(u, v)[0];
                assert!(
                    got + 1 >= lo && got <= hi + 1,
                    "frame {id}: native ({u}, {v}) = {got} mm outside [{lo}, {hi}] around \
                     model ({x}, {y})"
                );
            }
        }
        let mean = |p: &image::ImageBuffer<image::Luma<u16>, Vec<u16>>| {
            p.as_raw().iter().map(|&v| f64::from(v)).sum::<f64>() / p.as_raw().len() as f64
        };
        let (am, an) = (mean(&pm), mean(&pn));
        assert!((am - an).abs() / am < 0.01, "mean {am} mm vs {an} mm");
    }

    // Metrics: finite and plausible; native and model-size RMSE close, not identical (different
    // pixels, interpolated predictions).
    for (what, m) in [("model", mm), ("native", mn)] {
        for key in ["rmse", "abs_rel", "mae", "delta1", "log10"] {
            let v = m[key].as_f64().unwrap();
            assert!(v.is_finite() && v >= 0.0, "{what} {key} = {v}");
        }
        assert!((0.0..=1.0).contains(&m["delta1"].as_f64().unwrap()));
        assert_eq!(m["invalid_pred"], 0, "{what}");
    }
    let (rm, rn) = (mm["rmse"].as_f64().unwrap(), mn["rmse"].as_f64().unwrap());
    println!(
        "int8 RMSE: {rm:.5} m at {}×{}, {rn:.5} m native at {cw}×{ch} (δ1 {:.4} vs {:.4})",
        MODEL.0,
        MODEL.1,
        mm["delta1"].as_f64().unwrap(),
        mn["delta1"].as_f64().unwrap()
    );
    assert!(rm > 0.0 && rn > 0.0);
    assert!(
        (rm - rn).abs() / rm < 0.15,
        "native RMSE {rn} far from model-size {rm}"
    );
    assert!(
        (rm - rn).abs() > 1e-5,
        "native RMSE {rn} equals model-size {rm}"
    );
    // Per frame too (the CSV rows), so a summary mix-up cannot hide a frame scored the same way.
    for ((_, _, a), (_, _, b)) in rows_m.iter().zip(&rows_n) {
        assert!(
            (a - b).abs() > 1e-6 && (a - b).abs() / a < 0.2,
            "{a} vs {b}"
        );
    }
}
