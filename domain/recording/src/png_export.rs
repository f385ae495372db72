//! Camera frames to PNG: the colour image as 8-bit RGB, the depth image as 16-bit grayscale in
//! millimetres (0 = no return), plus a `frames.csv` index of what was written.

use harvest_ipc::payloads::RgbdFrame;
use harvest_ipc::payloads::rgbd_frame::{
    DEPTH_HEIGHT_PX, DEPTH_WIDTH_PX, RGB_HEIGHT_PX, RGB_WIDTH_PX,
};
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Writes frames of any RGB-D topic into one directory.
pub struct PngWriter {
    dir: PathBuf,
    index: BufWriter<File>,
    depth_bytes: Vec<u8>,
    frames_per_topic: std::collections::BTreeMap<String, u64>,
    pub frames_written: u64,
}

impl PngWriter {
    /// Creates `dir` (if needed) and its `frames.csv`.
    pub fn create(dir: &Path) -> std::io::Result<Self> {
        std::fs::create_dir_all(dir)?;
        let mut index = BufWriter::new(File::create(dir.join("frames.csv"))?);
        writeln!(
            index,
            "topic,frame,msg_seq,capture_ns,log_time_ns,rgb_file,depth_file"
        )?;
        Ok(Self {
            dir: dir.to_path_buf(),
            index,
            depth_bytes: Vec::with_capacity(DEPTH_WIDTH_PX * DEPTH_HEIGHT_PX * 2),
            frames_per_topic: Default::default(),
            frames_written: 0,
        })
    }

    /// Writes one frame as `<topic>-<n>-rgb.png` and `<topic>-<n>-depth.png`.
    pub fn write(
        &mut self,
        topic: &str,
        log_time_ns: u64,
        frame: &RgbdFrame,
    ) -> Result<(), String> {
        let counter = self.frames_per_topic.entry(topic.to_owned()).or_insert(0);
        let number = *counter;
        *counter += 1;
        let stem = format!("{}-{number:06}", topic.replace('/', "_"));
        let rgb_name = format!("{stem}-rgb.png");
        let depth_name = format!("{stem}-depth.png");
        encode_png(
            &self.dir.join(&rgb_name),
            &frame.rgb,
            RGB_WIDTH_PX,
            RGB_HEIGHT_PX,
            ExtendedColorType::Rgb8,
        )?;
        self.depth_bytes.clear();
        self.depth_bytes
            .extend(frame.depth_mm.iter().flat_map(|depth| depth.to_ne_bytes()));
        encode_png(
            &self.dir.join(&depth_name),
            &self.depth_bytes,
            DEPTH_WIDTH_PX,
            DEPTH_HEIGHT_PX,
            ExtendedColorType::L16,
        )?;
        writeln!(
            self.index,
            "{topic},{number},{},{},{log_time_ns},{rgb_name},{depth_name}",
            frame.header.msg_seq, frame.header.capture_ns
        )
        .map_err(|error| format!("frames.csv: {error}"))?;
        self.frames_written += 1;
        Ok(())
    }

    pub fn finish(mut self) -> Result<(), String> {
        self.index
            .flush()
            .map_err(|error| format!("frames.csv: {error}"))
    }
}

fn encode_png(
    path: &Path,
    pixels: &[u8],
    width: usize,
    height: usize,
    color: ExtendedColorType,
) -> Result<(), String> {
    let file = File::create(path).map_err(|error| format!("{}: {error}", path.display()))?;
    let mut writer = BufWriter::new(file);
    PngEncoder::new_with_quality(&mut writer, CompressionType::Fast, FilterType::Adaptive)
        .write_image(pixels, width as u32, height as u32, color)
        .map_err(|error| format!("{}: {error}", path.display()))?;
    writer
        .flush()
        .map_err(|error| format!("{}: {error}", path.display()))
}
