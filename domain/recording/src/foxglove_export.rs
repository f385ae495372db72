//! Re-encoding a recording for Foxglove, which only decodes well-known encodings: every
//! message becomes JSON (`message_encoding = json`, schema encoding `jsonschema`), and RGB-D
//! frames additionally become `foxglove.RawImage` (`<topic>/rgb` as `rgb8`, `<topic>/depth`
//! as `16UC1` in mm) and `foxglove.CameraCalibration` (`<topic>/rgb/calibration`,
//! `<topic>/depth/calibration`). Stamps are converted to UTC with the recording's
//! `harvest.clock` record when it has one.

use crate::base64;
use crate::json_schema::infer_schema;
use crate::wall_clock::ClockPair;
use harvest_ipc::camera_model::CameraIntrinsics;
use harvest_ipc::payloads::RgbdFrame;
use harvest_ipc::payloads::rgbd_frame::{
    DEPTH_HEIGHT_PX, DEPTH_WIDTH_PX, RGB_HEIGHT_PX, RGB_WIDTH_PX,
};
use mcap::records::{MessageHeader, Metadata};
use mcap::{WriteOptions, Writer};
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

const RAW_IMAGE_SCHEMA: &str = r#"{"title":"foxglove.RawImage","type":"object","properties":{"timestamp":{"type":"object","properties":{"sec":{"type":"integer","minimum":0},"nsec":{"type":"integer","minimum":0,"maximum":999999999}}},"frame_id":{"type":"string"},"width":{"type":"integer","minimum":0},"height":{"type":"integer","minimum":0},"encoding":{"type":"string"},"step":{"type":"integer","minimum":0},"data":{"type":"string","contentEncoding":"base64"}}}"#;
const CALIBRATION_SCHEMA: &str = r#"{"title":"foxglove.CameraCalibration","type":"object","properties":{"timestamp":{"type":"object","properties":{"sec":{"type":"integer","minimum":0},"nsec":{"type":"integer","minimum":0,"maximum":999999999}}},"frame_id":{"type":"string"},"width":{"type":"integer","minimum":0},"height":{"type":"integer","minimum":0},"distortion_model":{"type":"string"},"D":{"type":"array","items":{"type":"number"}},"K":{"type":"array","items":{"type":"number"},"minItems":9,"maxItems":9},"R":{"type":"array","items":{"type":"number"},"minItems":9,"maxItems":9},"P":{"type":"array","items":{"type":"number"},"minItems":12,"maxItems":12}}}"#;

/// A Foxglove-readable MCAP being written.
pub struct FoxgloveWriter {
    writer: Writer<BufWriter<File>>,
    /// Output topic -> channel id.
    channels: BTreeMap<String, u16>,
    clock: Option<ClockPair>,
    text: Vec<u8>,
    pub messages_written: u64,
}

impl FoxgloveWriter {
    pub fn create(path: &Path) -> Result<Self, String> {
        let file = File::create(path).map_err(|error| format!("{}: {error}", path.display()))?;
        let options = WriteOptions::new()
            .profile("")
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(1)
            .compression_threads(0)
            .chunk_size(Some(8 << 20));
        let writer = Writer::with_options(BufWriter::with_capacity(1 << 20, file), options)
            .map_err(|error| crate::mcap_error::mcap_error_text(&error))?;
        Ok(Self {
            writer,
            channels: BTreeMap::new(),
            clock: None,
            text: Vec::new(),
            messages_written: 0,
        })
    }

    /// Uses `pair` to convert stamps to UTC from now on.
    pub fn set_clock(&mut self, pair: ClockPair) {
        self.clock.get_or_insert(pair);
    }

    fn stamp(&self, monotonic_ns: u64) -> u64 {
        self.clock
            .map(|pair| pair.to_realtime_ns(monotonic_ns))
            .unwrap_or(monotonic_ns)
    }

    pub fn write_metadata(&mut self, metadata: &Metadata) -> Result<(), String> {
        self.writer
            .write_metadata(metadata)
            .map_err(|error| crate::mcap_error::mcap_error_text(&error))
    }

    fn channel(
        &mut self,
        topic: &str,
        schema_name: &str,
        schema: &dyn Fn() -> String,
    ) -> Result<u16, String> {
        if let Some(id) = self.channels.get(topic) {
            return Ok(*id);
        }
        let error_text = |error: mcap::McapError| crate::mcap_error::mcap_error_text(&error);
        let schema_id = self
            .writer
            .add_schema(schema_name, "jsonschema", schema().as_bytes())
            .map_err(error_text)?;
        let id = self
            .writer
            .add_channel(schema_id, topic, "json", &BTreeMap::new())
            .map_err(error_text)?;
        self.channels.insert(topic.to_owned(), id);
        Ok(id)
    }

    fn write_json(
        &mut self,
        channel_id: u16,
        sequence: u32,
        log_time_ns: u64,
        publish_time_ns: u64,
        value: &Value,
    ) -> Result<(), String> {
        self.text.clear();
        serde_json::to_writer(&mut self.text, value).map_err(|error| error.to_string())?;
        let header = MessageHeader {
            channel_id,
            sequence,
            log_time: self.stamp(log_time_ns),
            publish_time: self.stamp(publish_time_ns),
        };
        self.writer
            .write_to_known_channel(&header, &self.text)
            .map_err(|error| crate::mcap_error::mcap_error_text(&error))?;
        self.messages_written += 1;
        Ok(())
    }

    /// Writes a message's JSON view on its own topic, with a schema inferred from it.
    pub fn write_payload(
        &mut self,
        topic: &str,
        type_name: &str,
        sequence: u32,
        log_time_ns: u64,
        publish_time_ns: u64,
        value: &Value,
    ) -> Result<(), String> {
        let id = self.channel(topic, type_name, &|| {
            infer_schema(type_name, value).to_string()
        })?;
        self.write_json(id, sequence, log_time_ns, publish_time_ns, value)
    }

    /// Writes a frame as two raw images and two calibrations.
    pub fn write_frame(
        &mut self,
        topic: &str,
        sequence: u32,
        log_time_ns: u64,
        publish_time_ns: u64,
        frame: &RgbdFrame,
    ) -> Result<(), String> {
        let stamp_ns = self.stamp(frame.header.capture_ns);
        let timestamp =
            json!({ "sec": stamp_ns / 1_000_000_000, "nsec": stamp_ns % 1_000_000_000 });
        let rgb_topic = format!("{topic}/rgb");
        let depth_topic = format!("{topic}/depth");
        let stamps = (sequence, log_time_ns, publish_time_ns);
        let rgb = RawImage {
            frame_id: "camera_color",
            encoding: "rgb8",
            width: RGB_WIDTH_PX,
            height: RGB_HEIGHT_PX,
            bytes_per_px: 3,
        };
        self.write_raw_image(&rgb_topic, &rgb, &frame.rgb, &timestamp, stamps)?;
        let depth_bytes: Vec<u8> = frame
            .depth_mm
            .iter()
            .flat_map(|depth| depth.to_le_bytes())
            .collect();
        let depth = RawImage {
            frame_id: "camera_depth",
            encoding: "16UC1",
            width: DEPTH_WIDTH_PX,
            height: DEPTH_HEIGHT_PX,
            bytes_per_px: 2,
        };
        self.write_raw_image(&depth_topic, &depth, &depth_bytes, &timestamp, stamps)?;
        let calibrations = [
            (
                format!("{rgb_topic}/calibration"),
                "camera_color",
                frame.meta.rgb_intrinsics,
            ),
            (
                format!("{depth_topic}/calibration"),
                "camera_depth",
                frame.meta.depth_intrinsics,
            ),
        ];
        for (calibration_topic, frame_id, intrinsics) in calibrations {
            let calibration = calibration_json(&timestamp, frame_id, &intrinsics);
            let id = self.channel(&calibration_topic, "foxglove.CameraCalibration", &|| {
                CALIBRATION_SCHEMA.to_owned()
            })?;
            self.write_json(id, sequence, log_time_ns, publish_time_ns, &calibration)?;
        }
        Ok(())
    }

    fn write_raw_image(
        &mut self,
        topic: &str,
        image: &RawImage,
        pixels: &[u8],
        timestamp: &Value,
        (sequence, log_time_ns, publish_time_ns): (u32, u64, u64),
    ) -> Result<(), String> {
        let mut data = String::new();
        base64::encode_into(pixels, &mut data);
        let message = json!({
            "timestamp": timestamp,
            "frame_id": image.frame_id,
            "width": image.width,
            "height": image.height,
            "encoding": image.encoding,
            "step": image.width * image.bytes_per_px,
            "data": data,
        });
        let id = self.channel(topic, "foxglove.RawImage", &|| RAW_IMAGE_SCHEMA.to_owned())?;
        self.write_json(id, sequence, log_time_ns, publish_time_ns, &message)
    }

    pub fn finish(mut self) -> Result<(), String> {
        self.writer
            .finish()
            .map_err(|error| crate::mcap_error::mcap_error_text(&error))?;
        Ok(())
    }
}

/// The fixed fields of one raw image stream.
struct RawImage {
    frame_id: &'static str,
    encoding: &'static str,
    width: usize,
    height: usize,
    bytes_per_px: usize,
}

/// Pinhole intrinsics as a `foxglove.CameraCalibration` (OpenCV `plumb_bob` = k1,k2,p1,p2,k3).
fn calibration_json(timestamp: &Value, frame_id: &str, intrinsics: &CameraIntrinsics) -> Value {
    let CameraIntrinsics {
        width_px,
        height_px,
        fx_px,
        fy_px,
        cx_px,
        cy_px,
        distortion,
    } = *intrinsics;
    json!({
        "timestamp": timestamp,
        "frame_id": frame_id,
        "width": width_px,
        "height": height_px,
        "distortion_model": "plumb_bob",
        "D": distortion,
        "K": [fx_px, 0.0, cx_px, 0.0, fy_px, cy_px, 0.0, 0.0, 1.0],
        "R": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        "P": [fx_px, 0.0, cx_px, 0.0, 0.0, fy_px, cy_px, 0.0, 0.0, 0.0, 1.0, 0.0],
    })
}
