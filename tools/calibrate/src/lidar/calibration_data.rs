//! The calibration data-set directory: recorded (or generated) checkerboard views that
//! `harvest calibrate lidar-camera --data DIR` calibrates from, and that `--write-generated DIR`
//! writes from the generated scenes, so a grower's own captures go through the same path.
//!
//! Layout of `DIR`:
//!
//! ```text
//! DIR/
//!   camera.toml   colour camera intrinsics and (optionally) the checkerboard
//!   00.png        view 00: the colour camera's image of the board
//!   00.csv        view 00: the LiDAR points of the integration window
//!   01.png
//!   01.csv
//!   ...
//! ```
//!
//! - A view is a stem (`NN`, digits in practice) present as both `NN.png` and `NN.csv`; a PNG
//!   without its CSV, or a CSV without its PNG, is an error naming the file. Views are taken in
//!   numeric order of their stems (non-numeric stems after, alphabetically); other files and
//!   sub-directories are ignored.
//! - `NN.png`: 8-bit grey or RGB (an alpha channel is ignored); RGB is converted to grey with the
//!   Rec. 709 luma weights. Its size must be the one `camera.toml` states, since the corners are
//!   projected through those intrinsics.
//! - `NN.csv`: the header line `x_m,y_m,z_m,intensity`, then one point per line: position in the
//!   LiDAR frame (metres) and the return's intensity (reflectivity, 0-255), e.g.
//!   `2.0134,-0.1022,0.0871,108`. Blank lines are skipped; every other line needs four finite
//!   numbers. The corner finder ([`crate::lidar::cloud_corners`]) fits the board as the cloud's plane,
//!   so the cloud should hold the board's returns (the board hanging in the air, or the cloud
//!   cropped to the board's neighbourhood).
//! - `camera.toml`: the colour camera's [`CameraIntrinsics`] (their serde form: `width_px`,
//!   `height_px`, `fx_px`, `fy_px`, `cx_px`, `cy_px`, `distortion = [k1, k2, p1, p2, k3]`) as
//!   the `[intrinsics]` table, and the [`Checkerboard`] as the optional `[board]` table
//!   (`inner_columns`, `inner_rows`, `square_m`, `border_m`; default the paper's 7 x 5 inner
//!   corners of 5 cm). Unknown keys are refused.

use crate::lidar::board_image::GreyImage;
use crate::lidar::checkerboard::Checkerboard;
use harvest_ipc::camera_model::CameraIntrinsics;
use harvest_ipc::config_file::ConfigFileError;
use harvest_ipc::payloads::LidarPoint;
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{DynamicImage, ExtendedColorType, ImageEncoder, ImageFormat};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// Name of the camera file in the data-set directory.
pub const CAMERA_FILE: &str = "camera.toml";
/// Header line of every cloud CSV.
pub const CLOUD_HEADER: &str = "x_m,y_m,z_m,intensity";

/// The file stem of the view at `index` in a written data set (`00`, `01`, ...).
pub fn view_name(index: usize) -> String {
    format!("{index:02}")
}

/// `camera.toml`: the colour camera and the board of a data set.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraFile {
    /// The colour camera the images were taken with.
    pub intrinsics: CameraIntrinsics,
    /// The checkerboard (default: the paper's).
    #[serde(default)]
    pub board: Checkerboard,
}

impl CameraFile {
    /// Checks what the TOML types cannot: positive sizes and focal lengths, finite values, a
    /// usable board. The message names the key and value.
    pub fn validate(&self) -> Result<(), String> {
        if let Some(problem) = self.intrinsics.problem() {
            return Err(problem);
        }
        self.board.validate()
    }
}

/// One view of a data set: its name (the file stem) and its two files.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DataView {
    pub name: String,
    pub image_path: PathBuf,
    pub cloud_path: PathBuf,
}

/// An opened data-set directory: the camera file read and checked, the views listed (their
/// files are read one view at a time, [`DataSet::read_image`] and [`DataSet::read_cloud`]).
#[derive(Debug, Clone, PartialEq)]
pub struct DataSet {
    pub dir: PathBuf,
    pub intrinsics: CameraIntrinsics,
    pub board: Checkerboard,
    pub views: Vec<DataView>,
}

/// Why a data set cannot be read or written; every message names the file (and the line of a
/// CSV).
#[derive(Debug, thiserror::Error)]
pub enum DataSetError {
    /// The directory cannot be listed (missing, not a directory, no permission).
    #[error("calibration data set {dir}: {source}")]
    Dir {
        dir: PathBuf,
        source: std::io::Error,
    },
    /// A file cannot be read.
    #[error("cannot read {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// `camera.toml` is not valid TOML, has an unknown key or a wrongly typed value.
    #[error(transparent)]
    CameraFile(#[from] ConfigFileError),
    /// `camera.toml` parses but a value is unusable.
    #[error("{path}: {reason}")]
    InvalidCamera { path: PathBuf, reason: String },
    /// A view has one of its two files only.
    #[error("{path} has no matching {missing}: every view needs both NN.png and NN.csv")]
    Unpaired { path: PathBuf, missing: String },
    /// No view in the directory.
    #[error("calibration data set {dir}: no views (pairs NN.png + NN.csv)")]
    NoViews { dir: PathBuf },
    /// A PNG cannot be decoded.
    #[error("{path}: not a readable PNG: {message}")]
    Png { path: PathBuf, message: String },
    /// A PNG of another pixel format than 8-bit grey or RGB.
    #[error("{path}: {colour} pixels, expected 8-bit grey or RGB")]
    PngColour { path: PathBuf, colour: String },
    /// An image of another size than the intrinsics.
    #[error(
        "{path}: image is {width_px} x {height_px} px, {camera} says {expected_width_px} x \
         {expected_height_px} px"
    )]
    ImageSize {
        path: PathBuf,
        width_px: u32,
        height_px: u32,
        camera: PathBuf,
        expected_width_px: u32,
        expected_height_px: u32,
    },
    /// The CSV's first line is not the header.
    #[error("{path}: line 1: header `{found}`, expected `{CLOUD_HEADER}`")]
    CsvHeader { path: PathBuf, found: String },
    /// A CSV line without exactly four columns.
    #[error("{path}: line {line}: {columns} columns in `{text}`, expected 4 ({CLOUD_HEADER})")]
    CsvColumns {
        path: PathBuf,
        line: usize,
        columns: usize,
        text: String,
    },
    /// A CSV value that is not a finite number.
    #[error("{path}: line {line}: {column} = `{value}` is not a finite number")]
    CsvValue {
        path: PathBuf,
        line: usize,
        column: &'static str,
        value: String,
    },
    /// A CSV with the header only.
    #[error("{path}: empty cloud (no point after the header)")]
    EmptyCloud { path: PathBuf },
    /// A file cannot be written.
    #[error("writing {path}: {message}")]
    Write { path: PathBuf, message: String },
}

impl DataSet {
    /// Reads `dir/camera.toml` and lists the views.
    pub fn open(dir: &Path) -> Result<Self, DataSetError> {
        let dir_error = |source| DataSetError::Dir {
            dir: dir.to_owned(),
            source,
        };
        let entries = std::fs::read_dir(dir).map_err(dir_error)?;
        let mut images = Vec::new();
        let mut clouds = Vec::new();
        for entry in entries {
            let path = entry.map_err(dir_error)?.path();
            if !path.is_file() {
                continue;
            }
            let (Some(stem), Some(extension)) = (
                path.file_stem().and_then(|s| s.to_str()),
                path.extension().and_then(|s| s.to_str()),
            ) else {
                continue;
            };
            let stem = stem.to_owned();
            if extension.eq_ignore_ascii_case("png") {
                images.push((stem, path));
            } else if extension.eq_ignore_ascii_case("csv") {
                clouds.push((stem, path));
            }
        }
        let order = |(stem, _): &(String, PathBuf)| {
            let number = stem.parse::<u64>();
            (number.is_err(), number.unwrap_or(0), stem.clone())
        };
        images.sort_by_key(order);
        clouds.sort_by_key(order);
        let mut views = Vec::with_capacity(images.len());
        for (stem, image_path) in &images {
            let Some((_, cloud_path)) = clouds.iter().find(|(s, _)| s == stem) else {
                return Err(DataSetError::Unpaired {
                    path: image_path.clone(),
                    missing: format!("{stem}.csv"),
                });
            };
            views.push(DataView {
                name: stem.clone(),
                image_path: image_path.clone(),
                cloud_path: cloud_path.clone(),
            });
        }
        if let Some((stem, path)) = clouds
            .iter()
            .find(|(stem, _)| !images.iter().any(|(s, _)| s == stem))
        {
            return Err(DataSetError::Unpaired {
                path: path.clone(),
                missing: format!("{stem}.png"),
            });
        }
        let camera_path = dir.join(CAMERA_FILE);
        let camera: CameraFile =
            harvest_ipc::config_file::read_toml(&camera_path, "calibration camera file")?;
        camera
            .validate()
            .map_err(|reason| DataSetError::InvalidCamera {
                path: camera_path,
                reason,
            })?;
        if views.is_empty() {
            return Err(DataSetError::NoViews {
                dir: dir.to_owned(),
            });
        }
        tracing::info!(dir = %dir.display(), views = views.len(), "calibration data set opened");
        Ok(Self {
            dir: dir.to_owned(),
            intrinsics: camera.intrinsics,
            board: camera.board,
            views,
        })
    }

    /// Reads a view's image as grey, checking its size against the intrinsics.
    pub fn read_image(&self, view: &DataView) -> Result<GreyImage, DataSetError> {
        let image = read_png_grey(&view.image_path)?;
        let (width_px, height_px) = (image.width_px as u32, image.height_px as u32);
        if width_px != self.intrinsics.width_px || height_px != self.intrinsics.height_px {
            return Err(DataSetError::ImageSize {
                path: view.image_path.clone(),
                width_px,
                height_px,
                camera: self.dir.join(CAMERA_FILE),
                expected_width_px: self.intrinsics.width_px,
                expected_height_px: self.intrinsics.height_px,
            });
        }
        Ok(image)
    }

    /// Reads a view's cloud.
    pub fn read_cloud(&self, view: &DataView) -> Result<Vec<LidarPoint>, DataSetError> {
        read_cloud_csv(&view.cloud_path)
    }
}

/// Reads a PNG as an 8-bit grey image (RGB converted with the Rec. 709 luma weights, alpha
/// ignored).
pub fn read_png_grey(path: &Path) -> Result<GreyImage, DataSetError> {
    let bytes = std::fs::read(path).map_err(|source| DataSetError::Read {
        path: path.to_owned(),
        source,
    })?;
    let decoded =
        image::load_from_memory_with_format(&bytes, ImageFormat::Png).map_err(|error| {
            DataSetError::Png {
                path: path.to_owned(),
                message: error.to_string(),
            }
        })?;
    let grey = match decoded {
        DynamicImage::ImageLuma8(grey) => grey,
        DynamicImage::ImageLumaA8(_) | DynamicImage::ImageRgb8(_) | DynamicImage::ImageRgba8(_) => {
            decoded.to_luma8()
        }
        other => {
            return Err(DataSetError::PngColour {
                path: path.to_owned(),
                colour: format!("{:?}", other.color()),
            });
        }
    };
    Ok(GreyImage {
        width_px: grey.width() as usize,
        height_px: grey.height() as usize,
        pixels: grey.into_raw(),
    })
}

/// Reads a cloud CSV (see the module doc for the format).
pub fn read_cloud_csv(path: &Path) -> Result<Vec<LidarPoint>, DataSetError> {
    let text = std::fs::read_to_string(path).map_err(|source| DataSetError::Read {
        path: path.to_owned(),
        source,
    })?;
    parse_cloud_csv(&text, path)
}

/// Parses cloud CSV text; `path` names it in errors.
pub fn parse_cloud_csv(text: &str, path: &Path) -> Result<Vec<LidarPoint>, DataSetError> {
    const COLUMNS: [&str; 4] = ["x_m", "y_m", "z_m", "intensity"];
    let mut lines = text.lines();
    let header = lines.next().unwrap_or("").trim();
    let columns: Vec<&str> = header.split(',').map(str::trim).collect();
    if columns != COLUMNS {
        return Err(DataSetError::CsvHeader {
            path: path.to_owned(),
            found: header.to_owned(),
        });
    }
    let mut points = Vec::new();
    for (offset, line) in lines.enumerate() {
        let number = offset + 2;
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != COLUMNS.len() {
            return Err(DataSetError::CsvColumns {
                path: path.to_owned(),
                line: number,
                columns: fields.len(),
                text: line.to_owned(),
            });
        }
        let mut values = [0.0f32; 4];
        for ((value, field), column) in values.iter_mut().zip(&fields).zip(COLUMNS) {
            *value = field
                .parse::<f32>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| DataSetError::CsvValue {
                    path: path.to_owned(),
                    line: number,
                    column,
                    value: (*field).to_owned(),
                })?;
        }
        let [x_m, y_m, z_m, intensity] = values;
        points.push(LidarPoint {
            x_m,
            y_m,
            z_m,
            intensity,
        });
    }
    if points.is_empty() {
        return Err(DataSetError::EmptyCloud {
            path: path.to_owned(),
        });
    }
    tracing::trace!(path = %path.display(), points = points.len(), "cloud read");
    Ok(points)
}

/// The CSV text of a cloud (shortest round-trip decimal form of each value, so reading it back
/// gives the same points).
pub fn cloud_csv(points: &[LidarPoint]) -> String {
    let mut text = String::with_capacity(32 * (points.len() + 1));
    text.push_str(CLOUD_HEADER);
    text.push('\n');
    for p in points {
        let _ = writeln!(text, "{},{},{},{}", p.x_m, p.y_m, p.z_m, p.intensity);
    }
    text
}

/// Writes a data set: `camera.toml`, then per view `NAME.png` (8-bit grey) and `NAME.csv`.
/// Creates `dir` if needed; existing files of the same names are replaced.
pub fn write_data_set<'a>(
    dir: &Path,
    camera: &CameraFile,
    views: impl IntoIterator<Item = (String, &'a GreyImage, &'a [LidarPoint])>,
) -> Result<(), DataSetError> {
    let write_error = |path: &Path, message: String| DataSetError::Write {
        path: path.to_owned(),
        message,
    };
    std::fs::create_dir_all(dir).map_err(|error| write_error(dir, error.to_string()))?;
    let camera_path = dir.join(CAMERA_FILE);
    let toml =
        toml::to_string(camera).map_err(|error| write_error(&camera_path, error.to_string()))?;
    let text = format!(
        "# Colour camera intrinsics and checkerboard of this LiDAR-camera calibration data set\n\
         # (format: `harvest calibrate lidar-camera --help`).\n{toml}"
    );
    std::fs::write(&camera_path, text)
        .map_err(|error| write_error(&camera_path, error.to_string()))?;
    for (name, image, cloud) in views {
        let image_path = dir.join(format!("{name}.png"));
        write_png_grey(&image_path, image)?;
        let cloud_path = dir.join(format!("{name}.csv"));
        std::fs::write(&cloud_path, cloud_csv(cloud))
            .map_err(|error| write_error(&cloud_path, error.to_string()))?;
    }
    Ok(())
}

/// Writes an 8-bit grey PNG.
pub fn write_png_grey(path: &Path, image: &GreyImage) -> Result<(), DataSetError> {
    let write_error = |message: String| DataSetError::Write {
        path: path.to_owned(),
        message,
    };
    let (Ok(width), Ok(height)) = (
        u32::try_from(image.width_px),
        u32::try_from(image.height_px),
    ) else {
        return Err(write_error(format!(
            "image of {} x {} px is too large for PNG",
            image.width_px, image.height_px
        )));
    };
    let file = std::fs::File::create(path).map_err(|error| write_error(error.to_string()))?;
    let mut writer = std::io::BufWriter::new(file);
    PngEncoder::new_with_quality(&mut writer, CompressionType::Fast, FilterType::Adaptive)
        .write_image(&image.pixels, width, height, ExtendedColorType::L8)
        .map_err(|error| write_error(error.to_string()))?;
    writer
        .flush()
        .map_err(|error| write_error(error.to_string()))
}

/// A fresh, empty directory under the system temp dir for one test of this crate.
#[cfg(test)]
pub(crate) fn temp_dir(test: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("harvest-lidar-data-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> CameraFile {
        CameraFile {
            intrinsics: CameraIntrinsics::from_horizontal_fov(64, 48, 60.0),
            board: Checkerboard::paper(),
        }
    }

    fn points() -> Vec<LidarPoint> {
        (0..5)
            .map(|i| LidarPoint {
                x_m: 2.0 + i as f32 * 0.1234567,
                y_m: -0.3 / (i as f32 + 1.0),
                z_m: 1e-7 * i as f32,
                intensity: 12.5 * i as f32,
            })
            .collect()
    }

    fn gradient(width_px: usize, height_px: usize) -> GreyImage {
        GreyImage {
            width_px,
            height_px,
            pixels: (0..width_px * height_px).map(|i| (i % 251) as u8).collect(),
        }
    }

    #[test]
    fn written_views_read_back_identically() {
        let dir = temp_dir("roundtrip");
        let image = gradient(64, 48);
        let cloud = points();
        let views = [
            (view_name(0), &image, cloud.as_slice()),
            (view_name(10), &image, &cloud[..2]),
            (view_name(2), &image, &cloud[1..]),
        ];
        write_data_set(&dir, &camera(), views).expect("write");
        let data = DataSet::open(&dir).expect("open");
        assert_eq!(data.intrinsics, camera().intrinsics);
        assert_eq!(data.board, Checkerboard::paper());
        let names: Vec<&str> = data.views.iter().map(|v| v.name.as_str()).collect();
        assert_eq!(names, ["00", "02", "10"], "numeric order");
        assert_eq!(data.read_image(&data.views[0]).expect("png"), image);
        assert_eq!(data.read_cloud(&data.views[0]).expect("csv"), cloud);
        assert_eq!(data.read_cloud(&data.views[1]).expect("csv"), &cloud[1..]);
        std::fs::remove_dir_all(&dir).expect("clean up");
    }

    #[test]
    fn rgb_images_are_read_as_grey() {
        let dir = temp_dir("rgb");
        let path = dir.join("00.png");
        // Pure red, green, blue and white pixels.
        let rgb = [255u8, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255];
        image::save_buffer_with_format(
            &path,
            &rgb,
            4,
            1,
            ExtendedColorType::Rgb8,
            ImageFormat::Png,
        )
        .expect("write rgb");
        let grey = read_png_grey(&path).expect("rgb png");
        assert_eq!((grey.width_px, grey.height_px), (4, 1));
        // Rec. 709 luma: green brightest, blue darkest, white stays white.
        let [r, g, b, w] = [0, 1, 2, 3].map(|u| grey.get(u, 0).expect("pixel"));
        assert!(g > r && r > b, "{r} {g} {b}");
        assert_eq!(w, 255);
        assert!((i32::from(r) - 54).abs() <= 1 && (i32::from(g) - 182).abs() <= 1);
        // A grey picture saved as RGB reads back as the same grey image.
        let grey = gradient(16, 8);
        let rgb: Vec<u8> = grey.pixels.iter().flat_map(|&g| [g, g, g]).collect();
        image::save_buffer_with_format(
            &path,
            &rgb,
            16,
            8,
            ExtendedColorType::Rgb8,
            ImageFormat::Png,
        )
        .expect("write grey as rgb");
        assert_eq!(read_png_grey(&path).expect("rgb png"), grey);
        let sixteen = [0u8; 8];
        image::save_buffer_with_format(
            &path,
            &sixteen,
            4,
            1,
            ExtendedColorType::L16,
            ImageFormat::Png,
        )
        .expect("write 16-bit");
        let error = read_png_grey(&path).expect_err("16-bit").to_string();
        assert!(error.contains("00.png") && error.contains("L16"), "{error}");
        std::fs::remove_dir_all(&dir).expect("clean up");
    }

    #[test]
    fn csv_errors_name_the_file_the_line_and_the_value() {
        let path = Path::new("/data/07.csv");
        let ok = parse_cloud_csv(
            "x_m,y_m,z_m,intensity\r\n1,2,3,4\r\n\r\n5, 6 ,7,8\r\n",
            path,
        )
        .expect("crlf, blank line and spaces");
        assert_eq!(ok.len(), 2);
        assert_eq!(ok[1].y_m, 6.0);
        let cases = [
            (
                "x,y,z,i\n1,2,3,4\n",
                "/data/07.csv: line 1: header `x,y,z,i`",
            ),
            ("", "line 1: header ``"),
            (
                "x_m,y_m,z_m,intensity\n1,2,3,4\n1,2,3\n",
                "/data/07.csv: line 3: 3 columns in `1,2,3`",
            ),
            (
                "x_m,y_m,z_m,intensity\n1,2,3,4,5\n",
                "line 2: 5 columns in `1,2,3,4,5`",
            ),
            (
                "x_m,y_m,z_m,intensity\n1,2,3,4\n\n1,2,abc,4\n",
                "/data/07.csv: line 4: z_m = `abc` is not a finite number",
            ),
            (
                "x_m,y_m,z_m,intensity\nnan,2,3,4\n",
                "line 2: x_m = `nan` is not a finite number",
            ),
            (
                "x_m,y_m,z_m,intensity\n1,2,3,\n",
                "line 2: intensity = `` is not a finite number",
            ),
            ("x_m,y_m,z_m,intensity\n\n", "/data/07.csv: empty cloud"),
        ];
        for (text, expected) in cases {
            let error = parse_cloud_csv(text, path).expect_err(text).to_string();
            assert!(error.contains(expected), "{text:?}: {error}");
        }
    }

    #[test]
    fn directory_errors_name_the_file() {
        let missing = std::env::temp_dir().join("harvest-lidar-data-no-such-dir");
        let error = DataSet::open(&missing).expect_err("missing").to_string();
        assert!(error.contains("harvest-lidar-data-no-such-dir"), "{error}");

        let dir = temp_dir("errors");
        let image = gradient(64, 48);
        let cloud = points();
        write_data_set(&dir, &camera(), [(view_name(0), &image, cloud.as_slice())]).expect("write");
        // A PNG without its CSV, then a CSV without its PNG.
        std::fs::write(dir.join("01.png"), b"").expect("write");
        let error = DataSet::open(&dir).expect_err("unpaired png").to_string();
        assert!(error.contains("01.png has no matching 01.csv"), "{error}");
        std::fs::remove_file(dir.join("01.png")).expect("remove");
        std::fs::write(dir.join("02.csv"), cloud_csv(&cloud)).expect("write");
        let error = DataSet::open(&dir).expect_err("unpaired csv").to_string();
        assert!(error.contains("02.csv has no matching 02.png"), "{error}");
        // An unreadable PNG: open succeeds, reading the view names the file.
        std::fs::write(dir.join("02.png"), b"not a png").expect("write");
        let data = DataSet::open(&dir).expect("paired");
        let error = data
            .read_image(&data.views[1])
            .expect_err("bad png")
            .to_string();
        assert!(error.contains("02.png: not a readable PNG"), "{error}");
        // An image of another size than camera.toml.
        write_png_grey(&dir.join("02.png"), &gradient(32, 48)).expect("write");
        let error = data
            .read_image(&data.views[1])
            .expect_err("size")
            .to_string();
        assert!(
            error.contains("02.png: image is 32 x 48 px")
                && error.contains("camera.toml says 64 x 48 px"),
            "{error}"
        );
        // camera.toml: unknown key, invalid value, board optional, missing.
        let camera_path = dir.join(CAMERA_FILE);
        let good = std::fs::read_to_string(&camera_path).expect("camera.toml");
        assert!(
            good.contains("[intrinsics]") && good.contains("[board]"),
            "{good}"
        );
        std::fs::write(&camera_path, good.replace("fx_px", "focal_px")).expect("write");
        let error = DataSet::open(&dir).expect_err("unknown key").to_string();
        assert!(
            error.contains("camera.toml") && error.contains("focal_px"),
            "{error}"
        );
        std::fs::write(&camera_path, good.replace("width_px = 64", "width_px = 0")).expect("write");
        let error = DataSet::open(&dir).expect_err("zero width").to_string();
        assert!(
            error.contains("camera.toml: intrinsics size 0 x 48"),
            "{error}"
        );
        let without_board = good.split("[board]").next().expect("intrinsics part");
        std::fs::write(&camera_path, without_board).expect("write");
        assert_eq!(
            DataSet::open(&dir).expect("default board").board,
            Checkerboard::paper()
        );
        std::fs::remove_file(&camera_path).expect("remove");
        let error = DataSet::open(&dir).expect_err("no camera.toml").to_string();
        assert!(error.contains("camera.toml"), "{error}");
        // No views at all.
        let empty = temp_dir("no-views");
        std::fs::write(empty.join(CAMERA_FILE), &good).expect("write");
        let error = DataSet::open(&empty).expect_err("no views").to_string();
        assert!(error.contains("no views"), "{error}");
        std::fs::remove_dir_all(&dir).expect("clean up");
        std::fs::remove_dir_all(&empty).expect("clean up");
    }
}
