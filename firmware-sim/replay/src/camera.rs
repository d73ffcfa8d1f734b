//! [`ReplayCamera`]: an [`RgbCamera`] that delivers the frames of a replay [`Image`] in order.

use depthor_core::hal::{ErrorKind, ErrorType, RgbCamera, RgbFrame};

use crate::format::Image;

/// Replays the RGB frames of an image, one per [`RgbCamera::capture`], then reports
/// [`ErrorKind::EndOfStream`].
#[derive(Clone, Copy, Debug)]
pub struct ReplayCamera<'a> {
    image: Image<'a>,
    next: u32,
}

impl<'a> ReplayCamera<'a> {
    /// A camera positioned at the image's first frame.
    pub fn new(image: Image<'a>) -> Self {
        ReplayCamera { image, next: 0 }
    }

    /// Index of the frame the next capture delivers.
    pub fn next_index(&self) -> u32 {
        self.next
    }
}

impl ErrorType for ReplayCamera<'_> {
    type Error = ErrorKind;
}

impl RgbCamera for ReplayCamera<'_> {
    fn resolution(&self) -> (u32, u32) {
        let (h, w) = self.image.size();
        (u32::from(w), u32::from(h))
    }

    fn capture(&mut self, frame: &mut RgbFrame<'_>) -> Result<(), ErrorKind> {
        if (frame.width, frame.height) != self.resolution() {
            return Err(ErrorKind::BufferShape);
        }
        let src = self.image.frame(self.next).ok_or(ErrorKind::EndOfStream)?;
        if frame.data.len() != src.rgb.len() {
            return Err(ErrorKind::BufferShape);
        }
        frame.data.copy_from_slice(src.rgb);
        self.next += 1;
        Ok(())
    }
}
