//! Tests of [`super::blob_format`] (kept apart: the core's tests include that file by path).
use super::blob_format::*;
use depthor_core::blob::checksum::crc32;
use depthor_core::blob::format::{dtype, opcode};
use depthor_core::kernels::conv::{Activation, ConvGeometry};
use depthor_core::kernels::requant::QParams;

#[test]
fn writer_layout_and_crc() {
    let mut bw = BlobWriter::new(4, 6);
    let q = QParams {
        scale: 0.5,
        zero_point: -3,
    };
    assert_eq!(bw.tensor(dtype::I8, 3, q), 0);
    bw.tensor(dtype::I8, 1, q);
    bw.tensor(dtype::F32, 1, q);
    assert_eq!(bw.param(&[1, 2, 3]), 0);
    assert_eq!(bw.param(&[4]), 16);
    bw.op(opcode::ADD, &[0, 1, 1], 2, &[]);
    bw.io(0, 1, 2);
    let b = bw.finish();
    assert_eq!(&b[0..4], b"DPTH");
    assert_eq!(u16::from_le_bytes([b[16], b[17]]), 4);
    assert_eq!(u16::from_le_bytes([b[18], b[19]]), 6);
    // 3 tensors × 16 + op record (8 + 3 ids padded to 8) = 64 bytes, then the data section
    // at blob offset 32 + 64 = 96 (16-aligned), 17 bytes of data.
    let payload_len = u32::from_le_bytes([b[8], b[9], b[10], b[11]]) as usize;
    assert_eq!(payload_len, 64 + 17);
    assert_eq!(b[96..99], [1, 2, 3]);
    assert_eq!(b[112], 4);
    let crc = u32::from_le_bytes([b[12], b[13], b[14], b[15]]);
    assert_eq!(crc, crc32(&b[32..]));
    // Tensor 0's zero point.
    assert_eq!(i32::from_le_bytes([b[40], b[41], b[42], b[43]]), -3);
}

#[test]
fn attributes_have_the_parsed_lengths() {
    let g = ConvGeometry::POINTWISE;
    assert_eq!(
        conv_attrs(&g, Activation::LeakyRelu(0.1), [0, 16, 32]).len(),
        36
    );
    assert_eq!(bins_head_attrs(8, 0.1, 10.0, [0, 16, 32]).len(), 24);
    assert_eq!(refine_attrs(4, 1, [1.0, 2.0, 3.0]).len(), 16);
    assert_eq!(upsample_attrs(0, 1, 2).len(), 8);
    assert_eq!(pixel_shuffle_attrs(2).len(), 4);
}
