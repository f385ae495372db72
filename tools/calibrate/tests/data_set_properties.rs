//! Property test of the LiDAR-camera calibration data-set reader: a data set
//! written by `write_data_set`, then its `camera.toml` mutated (values replaced by anything,
//! lines dropped or doubled, bytes changed), its cloud CSVs edited (fields replaced by anything,
//! lines cut) and its PNGs damaged (bytes changed, cut, or image sizes rewritten with a valid
//! checksum), through `DataSet::open`, the per-view readers and the whole calibration. Every
//! failure is an error naming a file; never a panic.

use harvest_calibrate::lidar::board_image::GreyImage;
use harvest_calibrate::lidar::calibration::calibrate_data_set;
use harvest_calibrate::lidar::calibration_data::{CameraFile, DataSet, view_name, write_data_set};
use harvest_calibrate::lidar::checkerboard::Checkerboard;
use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use harvest_ipc::payloads::LidarPoint;
use harvest_test_support::toml_mutation::{mutate_toml, toml_edit};
use proptest::prelude::*;
use std::path::{Path, PathBuf};

/// Cases: each writes and reads a two-view data set of small files.
const CASES: u32 = 96;

/// Field values that break a cloud CSV.
const WILD_FIELDS: &[&str] = &[
    "nan", "inf", "-inf", "1e39", "-1e39", "1e-50", "", "-", "0x10", "1,2", " ", "\"3\"",
];

/// A scratch directory removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new() -> Self {
        use std::sync::atomic::{AtomicU64, Ordering};
        static NEXT: AtomicU64 = AtomicU64::new(0);
        let path = std::env::temp_dir().join(format!(
            "harvest-data-set-prop-{}-{}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&path).expect("temp dir");
        Self(path)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// CRC-32 (ISO-HDLC, as PNG chunks use it).
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = 0xffff_ffffu32;
    for &byte in bytes {
        crc ^= u32::from(byte);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xedb8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// How a PNG is damaged.
#[derive(Debug, Clone)]
enum PngDamage {
    None,
    Bytes(Vec<(prop::sample::Index, u8)>),
    Cut(prop::sample::Index),
    /// IHDR width and height rewritten, checksum fixed (a well-formed header of any size).
    Size(u32, u32),
}

fn png_damage() -> impl Strategy<Value = PngDamage> {
    let size = prop_oneof![
        Just(0u32),
        Just(1),
        Just(64),
        Just(48),
        Just(u32::MAX),
        Just(1 << 16),
        any::<u32>()
    ];
    prop_oneof![
        1 => Just(PngDamage::None),
        2 => prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..4).prop_map(PngDamage::Bytes),
        1 => any::<prop::sample::Index>().prop_map(PngDamage::Cut),
        2 => (size.clone(), size).prop_map(|(w, h)| PngDamage::Size(w, h)),
    ]
}

fn damage_png(path: &Path, damage: &PngDamage) {
    let mut bytes = std::fs::read(path).expect("png");
    match damage {
        PngDamage::None => {}
        PngDamage::Bytes(edits) => {
            for (at, value) in edits {
                let at = at.index(bytes.len());
                bytes[at] = *value;
            }
        }
        PngDamage::Cut(at) => bytes.truncate(at.index(bytes.len())),
        PngDamage::Size(width, height) => {
            // Signature (8), IHDR length (4), "IHDR" (4), width, height, ... CRC at 29..33.
            bytes[16..20].copy_from_slice(&width.to_be_bytes());
            bytes[20..24].copy_from_slice(&height.to_be_bytes());
            let crc = crc32(&bytes[12..29]);
            bytes[29..33].copy_from_slice(&crc.to_be_bytes());
        }
    }
    std::fs::write(path, bytes).expect("write png");
}

fn camera() -> CameraFile {
    CameraFile {
        intrinsics: CameraIntrinsics::from_horizontal_fov(64, 48, 60.0),
        board: Checkerboard::paper(),
    }
}

fn image() -> GreyImage {
    GreyImage {
        width_px: 64,
        height_px: 48,
        pixels: (0..64 * 48).map(|i| (i % 251) as u8).collect(),
    }
}

fn cloud() -> Vec<LidarPoint> {
    (0..6)
        .map(|i| LidarPoint {
            x_m: 2.0 + i as f32 * 0.1,
            y_m: -0.3 + i as f32 * 0.05,
            z_m: 0.1 * i as f32,
            intensity: 10.0 * i as f32,
        })
        .collect()
}

/// Replaces fields of a CSV: (line, column, value).
fn edit_csv(path: &Path, edits: &[(prop::sample::Index, prop::sample::Index, &'static str)]) {
    let text = std::fs::read_to_string(path).expect("csv");
    let mut lines: Vec<Vec<String>> = text
        .lines()
        .map(|line| line.split(',').map(str::to_owned).collect())
        .collect();
    for (line, column, value) in edits {
        let line = line.index(lines.len());
        let fields = &mut lines[line];
        let column = column.index(fields.len());
        fields[column] = (*value).to_owned();
    }
    let text: Vec<String> = lines.iter().map(|fields| fields.join(",")).collect();
    std::fs::write(path, text.join("\n")).expect("write csv");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    #[test]
    fn a_damaged_data_set_is_read_or_refused_by_name(
        camera_edits in prop::collection::vec(toml_edit(), 0..3),
        csv_edits in prop::collection::vec(
            (any::<prop::sample::Index>(), any::<prop::sample::Index>(), prop::sample::select(WILD_FIELDS)),
            0..3,
        ),
        png in png_damage(),
    ) {
        let dir = TempDir::new();
        let image = image();
        let cloud = cloud();
        write_data_set(
            &dir.0,
            &camera(),
            [(view_name(0), &image, cloud.as_slice()), (view_name(1), &image, &cloud[1..])],
        )
        .expect("write");
        let camera_path = dir.0.join("camera.toml");
        let text = std::fs::read_to_string(&camera_path).expect("camera");
        std::fs::write(&camera_path, mutate_toml(&text, &camera_edits)).expect("camera");
        edit_csv(&dir.0.join("01.csv"), &csv_edits);
        damage_png(&dir.0.join("00.png"), &png);

        let data = match DataSet::open(&dir.0) {
            Ok(data) => data,
            Err(error) => {
                let message = error.to_string();
                prop_assert!(message.contains("harvest-data-set-prop"), "{message}");
                return Ok(());
            }
        };
        for view in &data.views {
            if let Err(error) = data.read_image(view) {
                prop_assert!(error.to_string().contains(".png"), "{error}");
            }
            if let Err(error) = data.read_cloud(view) {
                prop_assert!(error.to_string().contains(".csv"), "{error}");
            }
        }
        if let Err(error) = calibrate_data_set(&data, &RigidTransform::IDENTITY) {
            prop_assert!(!error.to_string().is_empty());
        }
    }
}
