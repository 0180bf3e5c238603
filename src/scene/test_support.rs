//! Test inputs shared by the scene's test modules.

use crate::image::{Image, PixelFormat};

/// A random texture, and the right view seeing it `shift` px further left (disparity `shift`).
pub(crate) fn shifted_pair(w: u32, h: u32, shift: u32) -> (Image, Image) {
    let texture = |x: i64, y: i64| -> u8 {
        let mut v = (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663)) as u64;
        v ^= v >> 13;
        v = v.wrapping_mul(0x5bd1_e995);
        (v >> 24) as u8
    };
    let make = |offset: i64| {
        let data = (0..h as i64)
            .flat_map(|y| (0..w as i64).map(move |x| (x, y)))
            .map(|(x, y)| texture(x + offset, y))
            .collect();
        Image::from_bytes(w, h, PixelFormat::Gray8, data).expect("valid test image")
    };
    (make(0), make(shift as i64))
}
