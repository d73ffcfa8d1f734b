//! Produces the embedded texture set `host/assets/textures/` from the CC0 photos in
//! `../shared/data/textures`: each named file is resized to 256×256 and saved as JPEG.
//!
//! `cargo run -p depthor-host --example shrink_textures -- <src_dir> <dst_dir> <name>...`
use image::codecs::jpeg::JpegEncoder;
use image::imageops::FilterType;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    anyhow::ensure!(
        args.len() >= 3,
        "usage: shrink_textures <src_dir> <dst_dir> <name>..."
    );
    let (src, dst) = (&args[0], &args[1]);
    for name in &args[2..] {
        let img = image::open(format!("{src}/{name}"))?.to_rgb8();
        let small = image::imageops::resize(&img, 256, 256, FilterType::Lanczos3);
        let file = std::fs::File::create(format!("{dst}/{name}"))?;
        let mut enc = JpegEncoder::new_with_quality(std::io::BufWriter::new(file), 82);
        enc.encode_image(&small)?;
    }
    Ok(())
}
