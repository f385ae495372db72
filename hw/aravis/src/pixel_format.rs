//! The GenICam pixel format codes (PFNC, as `ArvPixelFormat`) this crate's users handle. A
//! code's bits 16-23 hold the bits per pixel.

/// 8-bit monochrome.
pub const MONO_8: u32 = 0x0108_0001;
/// 8-bit Bayer, first row G R.
pub const BAYER_GR_8: u32 = 0x0108_0008;
/// 8-bit Bayer, first row R G.
pub const BAYER_RG_8: u32 = 0x0108_0009;
/// 8-bit Bayer, first row G B.
pub const BAYER_GB_8: u32 = 0x0108_000A;
/// 8-bit Bayer, first row B G.
pub const BAYER_BG_8: u32 = 0x0108_000B;
/// 24-bit RGB, packed.
pub const RGB_8: u32 = 0x0218_0014;

/// Bits per pixel of a PFNC code.
pub fn bits_per_pixel(format: u32) -> u32 {
    (format >> 16) & 0xff
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bits_per_pixel_come_from_the_code() {
        assert_eq!(bits_per_pixel(MONO_8), 8);
        assert_eq!(bits_per_pixel(BAYER_RG_8), 8);
        assert_eq!(bits_per_pixel(RGB_8), 24);
        // The fake camera's GenICam file lists BayerRG8 as 17301513.
        assert_eq!(BAYER_RG_8, 17_301_513);
    }
}
