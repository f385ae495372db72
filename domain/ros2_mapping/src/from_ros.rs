//! Standard ROS 2 messages into the stack's buffers: colour images (raw or compressed), depth
//! images and point clouds. Each function checks what it reads and names the field it refuses.

use crate::error::FieldError;
use harvest_ipc::payloads::point_cloud::POINT_CLOUD_CAPACITY;
use harvest_ipc::payloads::rgbd_frame::{
    DEPTH_HEIGHT_PX, DEPTH_PIXELS, DEPTH_WIDTH_PX, RGB_BYTES, RGB_HEIGHT_PX, RGB_WIDTH_PX,
};
use harvest_ipc::payloads::{LidarPoint, PointCloud, PointCloudMeta};
use harvest_ros2::msgs::sensor_msgs::{CompressedImage, Image, PointCloud2, PointField};

/// Colour encodings [`color_image_into`] takes.
pub const COLOR_ENCODINGS: [&str; 9] = [
    "rgb8",
    "bgr8",
    "rgba8",
    "bgra8",
    "mono8",
    "bayer_rggb8",
    "bayer_bggr8",
    "bayer_gbrg8",
    "bayer_grbg8",
];

/// Depth encodings [`depth_image_into`] takes.
pub const DEPTH_ENCODINGS: [&str; 3] = ["16UC1", "mono16", "32FC1"];

fn check_size(
    width: u32,
    height: u32,
    expected: (usize, usize),
    what: &str,
) -> Result<(), FieldError> {
    if width as usize != expected.0 {
        return Err(FieldError::new(
            "width",
            format!(
                "{width} x {height} px: the stack's {what} is {} x {} px",
                expected.0, expected.1
            ),
        ));
    }
    if height as usize != expected.1 {
        return Err(FieldError::new(
            "height",
            format!(
                "{width} x {height} px: the stack's {what} is {} x {} px",
                expected.0, expected.1
            ),
        ));
    }
    Ok(())
}

/// The rows of an image of `bytes_per_pixel`, checked against `step` and `data`.
fn rows(image: &Image, bytes_per_pixel: usize) -> Result<Vec<&[u8]>, FieldError> {
    let (width, height, step) = (
        image.width as usize,
        image.height as usize,
        image.step as usize,
    );
    let row_bytes = width * bytes_per_pixel;
    if step < row_bytes {
        return Err(FieldError::new(
            "step",
            format!(
                "{step} bytes a row, less than {width} px x {bytes_per_pixel} bytes of {}",
                image.encoding
            ),
        ));
    }
    let needed = step * height.saturating_sub(1) + row_bytes;
    if image.data.len() < needed {
        return Err(FieldError::new(
            "data",
            format!(
                "{} bytes, {height} rows of {step} bytes need {needed}",
                image.data.len()
            ),
        ));
    }
    Ok((0..height)
        .map(|row| &image.data[row * step..row * step + row_bytes])
        .collect())
}

/// Which colour each pixel of a 2x2 Bayer tile filters (0 red, 1 green, 2 blue), row-major.
fn bayer_tile(encoding: &str) -> Option<[usize; 4]> {
    match encoding {
        "bayer_rggb8" => Some([0, 1, 1, 2]),
        "bayer_bggr8" => Some([2, 1, 1, 0]),
        "bayer_gbrg8" => Some([1, 2, 0, 1]),
        "bayer_grbg8" => Some([1, 0, 2, 1]),
        _ => None,
    }
}

/// Demosaics a Bayer mosaic: each pixel keeps its own colour and takes the mean of the other
/// two colours over its 3x3 neighbourhood (bilinear interpolation at interior pixels).
fn demosaic(rows: &[&[u8]], tile: [usize; 4], width: usize, rgb: &mut [u8]) {
    let height = rows.len();
    let colour_at = |x: usize, y: usize| tile[(y % 2) * 2 + x % 2];
    for (y, row) in rows.iter().enumerate() {
        let neighbour_rows = &rows[y.saturating_sub(1)..(y + 2).min(height)];
        let first_row = y.saturating_sub(1);
        for (x, own_value) in row.iter().enumerate().take(width) {
            let own = colour_at(x, y);
            let first_column = x.saturating_sub(1);
            let mut sums = [0u32; 3];
            let mut counts = [0u32; 3];
            for (dy, neighbour_row) in neighbour_rows.iter().enumerate() {
                let columns = &neighbour_row[first_column..(x + 2).min(width)];
                for (dx, value) in columns.iter().enumerate() {
                    let colour = colour_at(first_column + dx, first_row + dy);
                    sums[colour] += u32::from(*value);
                    counts[colour] += 1;
                }
            }
            let pixel = &mut rgb[(y * width + x) * 3..(y * width + x) * 3 + 3];
            for (colour, out) in pixel.iter_mut().enumerate() {
                *out = if colour == own {
                    *own_value
                } else {
                    (sums[colour] + counts[colour] / 2)
                        .checked_div(counts[colour])
                        .unwrap_or(0) as u8
                };
            }
        }
    }
}

/// A colour `Image` into the stack's RGB8 buffer (1920 x 1080): rgb8, bgr8, rgba8, bgra8, mono8
/// or an 8-bit Bayer mosaic.
pub fn color_image_into(image: &Image, rgb: &mut [u8]) -> Result<(), FieldError> {
    check_size(
        image.width,
        image.height,
        (RGB_WIDTH_PX, RGB_HEIGHT_PX),
        "colour image",
    )?;
    if rgb.len() != RGB_BYTES {
        return Err(FieldError::new(
            "data",
            "the destination is not a colour frame",
        ));
    }
    let width = RGB_WIDTH_PX;
    let encoding = image.encoding.as_str();
    if let Some(tile) = bayer_tile(encoding) {
        demosaic(&rows(image, 1)?, tile, width, rgb);
        return Ok(());
    }
    let (bytes_per_pixel, order): (usize, [usize; 3]) = match encoding {
        "rgb8" => (3, [0, 1, 2]),
        "bgr8" => (3, [2, 1, 0]),
        "rgba8" => (4, [0, 1, 2]),
        "bgra8" => (4, [2, 1, 0]),
        "mono8" => (1, [0, 0, 0]),
        other => {
            return Err(FieldError::new(
                "encoding",
                format!(
                    "{other:?} is not a colour encoding the stack takes ({})",
                    COLOR_ENCODINGS.join(", ")
                ),
            ));
        }
    };
    for (y, row) in rows(image, bytes_per_pixel)?.into_iter().enumerate() {
        let out = &mut rgb[y * width * 3..(y + 1) * width * 3];
        if bytes_per_pixel == 3 && order == [0, 1, 2] {
            out.copy_from_slice(row);
            continue;
        }
        for (pixel, source) in out
            .chunks_exact_mut(3)
            .zip(row.chunks_exact(bytes_per_pixel))
        {
            pixel[0] = source[order[0]];
            pixel[1] = source[order[1]];
            pixel[2] = source[order[2]];
        }
    }
    Ok(())
}

/// A `CompressedImage` (JPEG or PNG) into the stack's RGB8 buffer.
pub fn compressed_color_into(image: &CompressedImage, rgb: &mut [u8]) -> Result<(), FieldError> {
    let format = image.format.to_ascii_lowercase();
    let kind = if format.contains("compresseddepth") {
        None
    } else if format.contains("jpeg") || format.contains("jpg") {
        Some(image::ImageFormat::Jpeg)
    } else if format.contains("png") {
        Some(image::ImageFormat::Png)
    } else {
        None
    };
    let Some(kind) = kind else {
        return Err(FieldError::new(
            "format",
            format!(
                "{:?}: the stack decodes JPEG and PNG colour images",
                image.format
            ),
        ));
    };
    let decoded = image::load_from_memory_with_format(&image.data, kind)
        .map_err(|error| FieldError::new("data", format!("not a decodable image: {error}")))?
        .into_rgb8();
    check_size(
        decoded.width(),
        decoded.height(),
        (RGB_WIDTH_PX, RGB_HEIGHT_PX),
        "colour image",
    )?;
    if rgb.len() != RGB_BYTES {
        return Err(FieldError::new(
            "data",
            "the destination is not a colour frame",
        ));
    }
    rgb.copy_from_slice(decoded.as_raw());
    Ok(())
}

/// A depth `Image` into the stack's depth buffer (640 x 480, mm, 0 = no return): 16UC1 or
/// mono16 in millimetres, 32FC1 in metres (NaN, infinite, non-positive or beyond 65.535 m
/// become 0).
pub fn depth_image_into(image: &Image, depth_mm: &mut [u16]) -> Result<(), FieldError> {
    check_size(
        image.width,
        image.height,
        (DEPTH_WIDTH_PX, DEPTH_HEIGHT_PX),
        "depth image",
    )?;
    if depth_mm.len() != DEPTH_PIXELS {
        return Err(FieldError::new(
            "data",
            "the destination is not a depth frame",
        ));
    }
    let big_endian = image.is_bigendian != 0;
    let width = DEPTH_WIDTH_PX;
    match image.encoding.as_str() {
        "16UC1" | "mono16" => {
            for (y, row) in rows(image, 2)?.into_iter().enumerate() {
                for (out, bytes) in depth_mm[y * width..(y + 1) * width]
                    .iter_mut()
                    .zip(row.chunks_exact(2))
                {
                    let pair = [bytes[0], bytes[1]];
                    *out = if big_endian {
                        u16::from_be_bytes(pair)
                    } else {
                        u16::from_le_bytes(pair)
                    };
                }
            }
        }
        "32FC1" => {
            for (y, row) in rows(image, 4)?.into_iter().enumerate() {
                for (out, bytes) in depth_mm[y * width..(y + 1) * width]
                    .iter_mut()
                    .zip(row.chunks_exact(4))
                {
                    let quad = [bytes[0], bytes[1], bytes[2], bytes[3]];
                    let metres = if big_endian {
                        f32::from_be_bytes(quad)
                    } else {
                        f32::from_le_bytes(quad)
                    };
                    let millimetres = (f64::from(metres) * 1000.0).round();
                    *out = if millimetres.is_finite()
                        && millimetres > 0.0
                        && millimetres <= f64::from(u16::MAX)
                    {
                        millimetres as u16
                    } else {
                        0
                    };
                }
            }
        }
        other => {
            return Err(FieldError::new(
                "encoding",
                format!(
                    "{other:?} is not a depth encoding the stack takes ({})",
                    DEPTH_ENCODINGS.join(", ")
                ),
            ));
        }
    }
    Ok(())
}

/// Where one scalar field sits in a point and how to read it as `f32`.
#[derive(Debug, Clone, Copy)]
struct FieldReader {
    offset: usize,
    datatype: u8,
}

impl FieldReader {
    fn find(cloud: &PointCloud2, name: &str, allowed: &[u8]) -> Result<Self, FieldError> {
        let field_name = format!("fields.{name}");
        let Some(field) = cloud.fields.iter().find(|field| field.name == name) else {
            let present: Vec<&str> = cloud.fields.iter().map(|f| f.name.as_str()).collect();
            return Err(FieldError::new(
                &field_name,
                format!("missing (the cloud has {})", present.join(", ")),
            ));
        };
        let Some(bytes) = PointField::datatype_bytes(field.datatype)
            .filter(|_| allowed.contains(&field.datatype))
        else {
            return Err(FieldError::new(
                &field_name,
                format!("datatype {} not supported here", field.datatype),
            ));
        };
        if u64::from(field.offset) + u64::from(bytes) > u64::from(cloud.point_step) {
            return Err(FieldError::new(
                &field_name,
                format!(
                    "offset {} + {bytes} bytes beyond point_step {}",
                    field.offset, cloud.point_step
                ),
            ));
        }
        Ok(Self {
            offset: field.offset as usize,
            datatype: field.datatype,
        })
    }

    fn read(&self, point: &[u8], big_endian: bool) -> f32 {
        let bytes = &point[self.offset..];
        macro_rules! value {
            ($ty:ty, $n:expr) => {{
                let mut raw = [0u8; $n];
                raw.copy_from_slice(&bytes[..$n]);
                if big_endian {
                    <$ty>::from_be_bytes(raw)
                } else {
                    <$ty>::from_le_bytes(raw)
                }
            }};
        }
        match self.datatype {
            PointField::INT8 => f32::from(bytes[0] as i8),
            PointField::UINT8 => f32::from(bytes[0]),
            PointField::INT16 => f32::from(value!(i16, 2)),
            PointField::UINT16 => f32::from(value!(u16, 2)),
            PointField::INT32 => value!(i32, 4) as f32,
            PointField::UINT32 => value!(u32, 4) as f32,
            PointField::FLOAT32 => value!(f32, 4),
            _ => value!(f64, 8) as f32,
        }
    }
}

/// A `PointCloud2` into the stack's cloud: x, y, z (float32 or float64, metres) and the
/// intensity field named `intensity_field` (any numeric type; `None`: no intensity, 0); every
/// other field (the Livox driver's tag, line, timestamp, ...) is ignored. Points beyond the
/// stack's capacity are dropped and the cloud marked truncated. `capture_ns` and the window
/// are the caller's.
pub fn point_cloud_into(
    cloud: &PointCloud2,
    intensity_field: Option<&str>,
    out: &mut PointCloud,
) -> Result<(), FieldError> {
    const FLOATS: [u8; 2] = [PointField::FLOAT32, PointField::FLOAT64];
    const NUMBERS: [u8; 8] = [1, 2, 3, 4, 5, 6, 7, 8];
    let x = FieldReader::find(cloud, "x", &FLOATS)?;
    let y = FieldReader::find(cloud, "y", &FLOATS)?;
    let z = FieldReader::find(cloud, "z", &FLOATS)?;
    let intensity = match intensity_field {
        Some(name) => Some(FieldReader::find(cloud, name, &NUMBERS)?),
        None => None,
    };
    let (width, height) = (cloud.width as usize, cloud.height as usize);
    let (point_step, row_step) = (cloud.point_step as usize, cloud.row_step as usize);
    if point_step == 0 {
        return Err(FieldError::new("point_step", "0 bytes a point"));
    }
    if height > 1 && row_step < width * point_step {
        return Err(FieldError::new(
            "row_step",
            format!("{row_step} bytes a row, less than {width} points x {point_step} bytes"),
        ));
    }
    let row_step = if height > 1 {
        row_step
    } else {
        width * point_step
    };
    let needed = row_step * height.saturating_sub(1) + width * point_step;
    if height > 0 && width > 0 && cloud.data.len() < needed {
        return Err(FieldError::new(
            "data",
            format!(
                "{} bytes, {height} row(s) of {width} points of {point_step} bytes need {needed}",
                cloud.data.len()
            ),
        ));
    }
    out.meta = PointCloudMeta {
        integration_ns: out.meta.integration_ns,
        ..PointCloudMeta::default()
    };
    let mut count = 0;
    'rows: for row in 0..height {
        for column in 0..width {
            if count == POINT_CLOUD_CAPACITY {
                out.meta.flags |= PointCloudMeta::FLAG_TRUNCATED;
                break 'rows;
            }
            let start = row * row_step + column * point_step;
            let point = &cloud.data[start..start + point_step];
            out.points[count] = LidarPoint {
                x_m: x.read(point, cloud.is_bigendian),
                y_m: y.read(point, cloud.is_bigendian),
                z_m: z.read(point, cloud.is_bigendian),
                intensity: intensity.map_or(0.0, |field| field.read(point, cloud.is_bigendian)),
            };
            count += 1;
        }
    }
    out.meta.point_count = count as u32;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_ipc::payload::boxed_zeroed;

    fn image(
        encoding: &str,
        width: u32,
        height: u32,
        bytes_per_pixel: u32,
        data: Vec<u8>,
    ) -> Image {
        Image {
            encoding: encoding.into(),
            width,
            height,
            step: width * bytes_per_pixel,
            data,
            ..Image::default()
        }
    }

    #[test]
    fn bgr_and_mono_become_rgb() {
        let pixels = RGB_WIDTH_PX * RGB_HEIGHT_PX;
        let bgr: Vec<u8> = (0..pixels).flat_map(|_| [10, 20, 30]).collect();
        let mut rgb = vec![0u8; RGB_BYTES];
        color_image_into(&image("bgr8", 1920, 1080, 3, bgr), &mut rgb).unwrap();
        assert_eq!(&rgb[..6], &[30, 20, 10, 30, 20, 10]);
        color_image_into(&image("mono8", 1920, 1080, 1, vec![7; pixels]), &mut rgb).unwrap();
        assert_eq!(&rgb[..3], &[7, 7, 7]);
    }

    #[test]
    fn a_bayer_mosaic_of_one_colour_demosaics_to_that_colour() {
        // An orange scene (200, 100, 50) seen through an RGGB filter.
        let mosaic: Vec<u8> = (0..RGB_HEIGHT_PX)
            .flat_map(|y| {
                (0..RGB_WIDTH_PX).map(move |x| match (y % 2, x % 2) {
                    (0, 0) => 200,
                    (1, 1) => 50,
                    _ => 100,
                })
            })
            .collect();
        let mut rgb = vec![0u8; RGB_BYTES];
        color_image_into(&image("bayer_rggb8", 1920, 1080, 1, mosaic), &mut rgb).unwrap();
        assert!(rgb.chunks_exact(3).all(|p| p == [200, 100, 50]));
    }

    #[test]
    fn refusals_name_the_field() {
        let mut rgb = vec![0u8; RGB_BYTES];
        let error = color_image_into(
            &image("rgb8", 1280, 720, 3, vec![0; 1280 * 720 * 3]),
            &mut rgb,
        )
        .unwrap_err();
        assert_eq!(error.field, "width");
        let error = color_image_into(&image("rgb16", 1920, 1080, 6, vec![]), &mut rgb).unwrap_err();
        assert_eq!(error.field, "encoding");
        let error =
            color_image_into(&image("rgb8", 1920, 1080, 3, vec![0; 100]), &mut rgb).unwrap_err();
        assert_eq!(error.field, "data");
        let mut depth = vec![0u16; DEPTH_PIXELS];
        let error = depth_image_into(&image("8UC1", 640, 480, 1, vec![0; 640 * 480]), &mut depth)
            .unwrap_err();
        assert_eq!(error.field, "encoding");
    }

    #[test]
    fn float_depth_in_metres_becomes_millimetres() {
        let values = [1.2345f32, f32::NAN, -1.0, 70.0];
        let data: Vec<u8> = (0..DEPTH_PIXELS)
            .flat_map(|i| values[i % 4].to_le_bytes())
            .collect();
        let mut depth = vec![0u16; DEPTH_PIXELS];
        depth_image_into(&image("32FC1", 640, 480, 4, data), &mut depth).unwrap();
        assert_eq!(&depth[..4], &[1235, 0, 0, 0]);
    }

    #[test]
    fn livox_clouds_keep_xyz_and_intensity() {
        // The Livox ROS driver 2 point: x, y, z, intensity float32, tag, line u8, timestamp f64.
        let fields = vec![
            PointField::scalar("x", 0, PointField::FLOAT32),
            PointField::scalar("y", 4, PointField::FLOAT32),
            PointField::scalar("z", 8, PointField::FLOAT32),
            PointField::scalar("intensity", 12, PointField::FLOAT32),
            PointField::scalar("tag", 16, PointField::UINT8),
            PointField::scalar("line", 17, PointField::UINT8),
            PointField::scalar("timestamp", 18, PointField::FLOAT64),
        ];
        let mut data = Vec::new();
        for i in 0..3 {
            for value in [i as f32, 2.0, 3.0, 40.0] {
                data.extend_from_slice(&value.to_le_bytes());
            }
            data.extend_from_slice(&[1, 2]);
            data.extend_from_slice(&0.5f64.to_le_bytes());
        }
        let cloud = PointCloud2 {
            height: 1,
            width: 3,
            fields,
            point_step: 26,
            row_step: 78,
            data,
            ..PointCloud2::default()
        };
        let mut out = boxed_zeroed::<PointCloud>();
        point_cloud_into(&cloud, Some("intensity"), &mut out).unwrap();
        assert_eq!(out.meta.point_count, 3);
        assert_eq!(out.points[2].x_m, 2.0);
        assert_eq!(out.points[2].intensity, 40.0);
        let error = point_cloud_into(&cloud, Some("reflectivity"), &mut out).unwrap_err();
        assert_eq!(error.field, "fields.reflectivity");
    }
}
