//! A GigE Vision camera's pixel formats -> the frame's RGB8: Mono8 (grey in all three channels),
//! the four 8-bit Bayer layouts (bilinear demosaicing) and RGB8 (copied).
//!
//! Bilinear demosaicing: at a red (blue) site the sample is the pixel's own, green the mean of
//! the 4 edge neighbours, blue (red) the mean of the 4 diagonal ones; at a green site the other
//! two colours are the means of the 2 neighbours along the row and the 2 along the column, each
//! to the colour that lies that way. The border pixels use mirrored neighbours. The interior
//! runs without bounds arithmetic; the cost is a few milliseconds per 1920x1080 frame.

/// The pixel formats the driver converts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
pub enum PixelFormat {
    /// 8-bit grey.
    Mono8,
    /// 8-bit Bayer, first row R G.
    BayerRG8,
    /// 8-bit Bayer, first row G R.
    BayerGR8,
    /// 8-bit Bayer, first row G B.
    BayerGB8,
    /// 8-bit Bayer, first row B G.
    BayerBG8,
    /// Packed 8-bit RGB.
    RGB8,
}

impl PixelFormat {
    /// Every format, for messages.
    pub const ALL: [Self; 6] = [
        Self::Mono8,
        Self::BayerRG8,
        Self::BayerGR8,
        Self::BayerGB8,
        Self::BayerBG8,
        Self::RGB8,
    ];

    /// The GenICam (PFNC) code.
    pub fn code(self) -> u32 {
        use harvest_aravis::pixel_format as pf;
        match self {
            Self::Mono8 => pf::MONO_8,
            Self::BayerRG8 => pf::BAYER_RG_8,
            Self::BayerGR8 => pf::BAYER_GR_8,
            Self::BayerGB8 => pf::BAYER_GB_8,
            Self::BayerBG8 => pf::BAYER_BG_8,
            Self::RGB8 => pf::RGB_8,
        }
    }

    /// The format of a PFNC code, if the driver converts it.
    pub fn from_code(code: u32) -> Option<Self> {
        Self::ALL.into_iter().find(|format| format.code() == code)
    }

    /// Bytes per pixel on the wire.
    pub fn bytes_per_pixel(self) -> usize {
        match self {
            Self::RGB8 => 3,
            _ => 1,
        }
    }

    /// The red sample's position in the 2x2 Bayer cell (column, row); None for non-Bayer.
    fn red_site(self) -> Option<(usize, usize)> {
        match self {
            Self::BayerRG8 => Some((0, 0)),
            Self::BayerGR8 => Some((1, 0)),
            Self::BayerGB8 => Some((0, 1)),
            Self::BayerBG8 => Some((1, 1)),
            Self::Mono8 | Self::RGB8 => None,
        }
    }
}

/// An image that does not fit the conversion.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "{format:?} {width}x{height} needs {expected} bytes in and {rgb_expected} out, got {actual} and {rgb_actual}"
)]
pub struct SizeError {
    /// The format.
    pub format: PixelFormat,
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Bytes the source needs.
    pub expected: usize,
    /// Bytes the source has.
    pub actual: usize,
    /// Bytes the RGB output needs.
    pub rgb_expected: usize,
    /// Bytes the RGB output has.
    pub rgb_actual: usize,
}

/// Converts `source` (`width` x `height` in `format`, rows unpadded) into `rgb` (RGB8, same
/// size). Images of less than 2x2 pixels are refused for the Bayer formats.
pub fn to_rgb(
    format: PixelFormat,
    width: usize,
    height: usize,
    source: &[u8],
    rgb: &mut [u8],
) -> Result<(), SizeError> {
    let expected = width * height * format.bytes_per_pixel();
    let rgb_expected = width * height * 3;
    let too_small = format.red_site().is_some() && (width < 2 || height < 2);
    if source.len() != expected || rgb.len() != rgb_expected || too_small {
        return Err(SizeError {
            format,
            width,
            height,
            expected,
            actual: source.len(),
            rgb_expected,
            rgb_actual: rgb.len(),
        });
    }
    match format {
        PixelFormat::RGB8 => rgb.copy_from_slice(source),
        PixelFormat::Mono8 => {
            for (pixel, &grey) in rgb.chunks_exact_mut(3).zip(source) {
                pixel.fill(grey);
            }
        }
        bayer => {
            let Some(red_site) = bayer.red_site() else {
                return Ok(());
            };
            demosaic_bilinear(red_site, width, height, source, rgb);
        }
    }
    Ok(())
}

/// The inverse direction, for fake cameras: samples `rgb` (RGB8, `width` x `height`) into
/// `out` in `format` (Mono8: the Rec. 601 luma; Bayer: each site's own colour; RGB8: copied).
pub fn from_rgb(
    format: PixelFormat,
    width: usize,
    height: usize,
    rgb: &[u8],
    out: &mut [u8],
) -> Result<(), SizeError> {
    let expected = width * height * format.bytes_per_pixel();
    let rgb_expected = width * height * 3;
    if out.len() != expected || rgb.len() != rgb_expected {
        return Err(SizeError {
            format,
            width,
            height,
            expected,
            actual: out.len(),
            rgb_expected,
            rgb_actual: rgb.len(),
        });
    }
    match (format, format.red_site()) {
        (PixelFormat::RGB8, _) => out.copy_from_slice(rgb),
        (_, Some((red_x, red_y))) => {
            for (index, sample) in out.iter_mut().enumerate() {
                let (x, y) = (index % width, index / width);
                let channel = match (y % 2 == red_y, x % 2 == red_x) {
                    (true, true) => 0,
                    (false, false) => 2,
                    _ => 1,
                };
                *sample = rgb[index * 3 + channel];
            }
        }
        _ => {
            for (sample, pixel) in out.iter_mut().zip(rgb.chunks_exact(3)) {
                let luma = 299 * u32::from(pixel[0])
                    + 587 * u32::from(pixel[1])
                    + 114 * u32::from(pixel[2]);
                *sample = ((luma + 500) / 1000) as u8;
            }
        }
    }
    Ok(())
}

/// Mirrors an index one step outside `0..len` back inside (`-1 -> 1`, `len -> len - 2`).
#[inline]
fn mirror(index: isize, len: usize) -> usize {
    if index < 0 {
        (-index) as usize
    } else if index as usize >= len {
        2 * (len - 1) - index as usize
    } else {
        index as usize
    }
}

/// One pixel's RGB from its neighbourhood; `at(dx, dy)` reads the raw sample at an offset.
#[inline(always)]
fn pixel_rgb(red_row: bool, red_col: bool, at: impl Fn(isize, isize) -> u16) -> [u8; 3] {
    let cross = || (at(-1, 0) + at(1, 0) + at(0, -1) + at(0, 1) + 2) / 4;
    let diagonal = || (at(-1, -1) + at(1, -1) + at(-1, 1) + at(1, 1) + 2) / 4;
    let along_row = || (at(-1, 0) + at(1, 0)).div_ceil(2);
    let along_col = || (at(0, -1) + at(0, 1)).div_ceil(2);
    let own = at(0, 0);
    let [r, g, b] = match (red_row, red_col) {
        (true, true) => [own, cross(), diagonal()],
        (false, false) => [diagonal(), cross(), own],
        // Green on a red row: red to the sides, blue above and below.
        (true, false) => [along_row(), own, along_col()],
        // Green on a blue row: blue to the sides, red above and below.
        (false, true) => [along_col(), own, along_row()],
    };
    [r as u8, g as u8, b as u8]
}

fn demosaic_bilinear(
    (red_x, red_y): (usize, usize),
    width: usize,
    height: usize,
    raw: &[u8],
    rgb: &mut [u8],
) {
    let border = |x: usize, y: usize, rgb: &mut [u8]| {
        let at = |dx: isize, dy: isize| {
            let xs = mirror(x as isize + dx, width);
            let ys = mirror(y as isize + dy, height);
            u16::from(raw[ys * width + xs])
        };
        let value = pixel_rgb(y % 2 == red_y, x % 2 == red_x, at);
        rgb[(y * width + x) * 3..][..3].copy_from_slice(&value);
    };
    for y in 0..height {
        if y == 0 || y == height - 1 {
            for x in 0..width {
                border(x, y, rgb);
            }
            continue;
        }
        border(0, y, rgb);
        border(width - 1, y, rgb);
        let above = &raw[(y - 1) * width..y * width];
        let row = &raw[y * width..(y + 1) * width];
        let below = &raw[(y + 1) * width..(y + 2) * width];
        let out = &mut rgb[y * width * 3..(y + 1) * width * 3];
        let red_row = y % 2 == red_y;
        for x in 1..width - 1 {
            let at = |dx: isize, dy: isize| {
                let column = (x as isize + dx) as usize;
                u16::from(match dy {
                    -1 => above[column],
                    0 => row[column],
                    _ => below[column],
                })
            };
            let value = pixel_rgb(red_row, x % 2 == red_x, at);
            out[x * 3..x * 3 + 3].copy_from_slice(&value);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mosaic(format: PixelFormat, width: usize, height: usize, rgb: &[u8]) -> Vec<u8> {
        let mut raw = vec![0; width * height * format.bytes_per_pixel()];
        from_rgb(format, width, height, rgb, &mut raw).expect("sizes fit");
        raw
    }

    #[test]
    fn a_flat_colour_survives_every_bayer_layout_including_the_border() {
        let (width, height) = (8, 6);
        let colour = [200u8, 120, 30];
        let rgb_in: Vec<u8> = colour.repeat(width * height);
        for format in [
            PixelFormat::BayerRG8,
            PixelFormat::BayerGR8,
            PixelFormat::BayerGB8,
            PixelFormat::BayerBG8,
        ] {
            let raw = mosaic(format, width, height, &rgb_in);
            let mut rgb = vec![0; width * height * 3];
            to_rgb(format, width, height, &raw, &mut rgb).expect("sizes fit");
            assert_eq!(rgb, rgb_in, "{format:?}");
        }
    }

    #[test]
    fn a_horizontal_ramp_is_interpolated_linearly() {
        // Red rises 10 per column, green and blue constant: bilinear is exact on a ramp away
        // from the border.
        let (width, height) = (10, 6);
        let mut rgb_in = vec![0u8; width * height * 3];
        for y in 0..height {
            for x in 0..width {
                rgb_in[(y * width + x) * 3..][..3].copy_from_slice(&[(10 * x) as u8, 90, 40]);
            }
        }
        let raw = mosaic(PixelFormat::BayerRG8, width, height, &rgb_in);
        let mut rgb = vec![0; width * height * 3];
        to_rgb(PixelFormat::BayerRG8, width, height, &raw, &mut rgb).expect("sizes fit");
        for y in 1..height - 1 {
            for x in 1..width - 1 {
                let i = (y * width + x) * 3;
                assert_eq!(&rgb[i..i + 3], &rgb_in[i..i + 3], "pixel ({x}, {y})");
            }
        }
    }

    #[test]
    fn mono_is_grey_rgb_is_copied_and_wrong_sizes_are_refused() {
        let mut rgb = vec![0; 2 * 2 * 3];
        to_rgb(PixelFormat::Mono8, 2, 2, &[1, 2, 3, 4], &mut rgb).expect("fits");
        assert_eq!(rgb, [1, 1, 1, 2, 2, 2, 3, 3, 3, 4, 4, 4]);
        let source: Vec<u8> = (0..12).collect();
        to_rgb(PixelFormat::RGB8, 2, 2, &source, &mut rgb).expect("fits");
        assert_eq!(rgb, source);
        let mut grey = [0u8; 4];
        from_rgb(PixelFormat::Mono8, 2, 2, &[90; 12], &mut grey).expect("fits");
        assert_eq!(grey, [90; 4]);
        assert!(to_rgb(PixelFormat::Mono8, 2, 2, &[1, 2, 3], &mut rgb).is_err());
        assert!(to_rgb(PixelFormat::BayerRG8, 1, 4, &[1, 2, 3, 4], &mut rgb[..12]).is_err());
    }

    #[test]
    fn codes_round_trip() {
        for format in PixelFormat::ALL {
            assert_eq!(PixelFormat::from_code(format.code()), Some(format));
        }
        assert_eq!(PixelFormat::from_code(0), None);
    }
}
