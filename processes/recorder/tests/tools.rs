//! `rec info`, `rec cat` and `rec export` on a real recording.

mod common;

use common::*;
use harvest_ipc::Context;
use harvest_ipc::payloads::RgbdFrame;
use harvest_ipc::payloads::rgbd_frame::{
    DEPTH_HEIGHT_PX, DEPTH_WIDTH_PX, RGB_HEIGHT_PX, RGB_WIDTH_PX,
};
use harvest_recording::export::{ExportOptions, export};
use harvest_recording::payload_codec::zeroed_box;
use harvest_recording::rec_cat::{CatOptions, cat};
use harvest_recording::rec_info::info;
use std::path::{Path, PathBuf};
use std::time::Duration;

fn record(dir: &Path) -> PathBuf {
    let domain = unique_domain("tools");
    let recorder = RunningRecorder::start(&domain, test_args(dir));
    recorder.wait_ready();
    let context = Context::new(&domain, "publisher").expect("node");
    let mut publishers = TestPublishers::open(&context);
    publishers.send(10, 3, 2);
    let report = recorder.stop().expect("recording");
    report.files[0].clone()
}

fn cat_lines(file: &Path, options: &CatOptions) -> Vec<serde_json::Value> {
    let mut out = Vec::new();
    let report = cat(file, options, &mut out).expect("cat");
    assert!(report.undecodable.is_empty(), "{:?}", report.undecodable);
    let lines: Vec<serde_json::Value> = String::from_utf8(out)
        .expect("utf-8")
        .lines()
        .map(|line| serde_json::from_str(line).expect("JSON line"))
        .collect();
    assert_eq!(lines.len() as u64, report.printed);
    lines
}

#[test]
fn info_cat_and_export_describe_the_recording() {
    let dir = TempDir::new("tools");
    let file = record(dir.path());

    let summary = info(&file).expect("info");
    assert!(summary.indexed && summary.problems.is_empty(), "{summary}");
    let channel = |topic: &str| {
        summary
            .channels
            .iter()
            .find(|c| c.topic == topic)
            .expect("channel")
            .clone()
    };
    assert_eq!(channel("arm1/state").messages, 10);
    assert_eq!(channel("arm1/state").schema, "harvest.ArmState.v2");
    assert_eq!(channel("camera/rgbd").messages, 2);
    assert!(channel("arm1/state").rate_hz > 0.0);
    assert!(
        summary.compression.contains_key("lz4"),
        "the default compression"
    );
    assert_eq!(summary.software_version(), Some(env!("CARGO_PKG_VERSION")));
    let text = summary.to_string();
    assert!(
        text.contains("arm1/state") && text.contains("complete"),
        "{text}"
    );

    // The command-line entry point prints the same.
    harvest_rec::run_rec(&harvest_rec::RecCommand::Info {
        files: vec![file.clone()],
    })
    .expect("rec info");

    // cat: every message, decoded.
    let all = cat_lines(&file, &CatOptions::default());
    let arms: Vec<_> = all
        .iter()
        .filter(|line| line["topic"] == "arm1/state")
        .collect();
    assert_eq!(arms.len(), 10);
    for (index, line) in arms.iter().enumerate() {
        assert_eq!(line["message"]["apple_id"], 1000 + index as u64);
        assert_eq!(line["message"]["header"]["msg_seq"], index as u64 + 1);
        assert_eq!(line["schema"], "harvest.ArmState.v2");
    }
    let frame_line = all
        .iter()
        .find(|line| line["topic"] == "camera/rgbd")
        .expect("frame line");
    let heartbeat = all
        .iter()
        .find(|line| line["topic"] == "system/health")
        .expect("the recorder's heartbeat");
    assert_eq!(heartbeat["message"]["process_name"], "recorder");
    assert_eq!(frame_line["message"]["rgb_bytes"], 1920 * 1080 * 3);
    // Topic filter.
    let only_arms = cat_lines(
        &file,
        &CatOptions {
            topics: vec!["arm*".into()],
            ..CatOptions::default()
        },
    );
    assert_eq!(only_arms.len(), 10);
    // Time window from the 5th arm message on.
    let first_ns = all
        .iter()
        .map(|line| line["log_time_ns"].as_u64().expect("t"))
        .min()
        .expect("lines");
    let cut_ns = arms[4]["log_time_ns"].as_u64().expect("t");
    let late = cat_lines(
        &file,
        &CatOptions {
            topics: vec!["arm1/state".into()],
            start: Some(Duration::from_nanos(cut_ns - first_ns)),
            end: None,
        },
    );
    let expected = arms
        .iter()
        .filter(|line| line["log_time_ns"].as_u64() >= Some(cut_ns))
        .count();
    assert_eq!(late.len(), expected);
    let early = cat_lines(
        &file,
        &CatOptions {
            topics: vec!["arm1/state".into()],
            start: None,
            end: Some(Duration::from_nanos(cut_ns - first_ns)),
        },
    );
    assert_eq!(
        early.len() + late.len(),
        10 + 1,
        "the cut message is in both inclusive windows"
    );
    // A window starting an hour after the last message holds nothing. (The recorder's own
    // heartbeat is stamped on the real clock, the test's messages on made-up stamps, so the
    // file may span more than an hour.)
    let log_times: Vec<u64> = cat_lines(&file, &CatOptions::default())
        .iter()
        .filter_map(|line| line["log_time_ns"].as_u64())
        .collect();
    let (earliest_ns, latest_ns) = (
        log_times.iter().copied().min().unwrap(),
        log_times.iter().copied().max().unwrap(),
    );
    let none = cat_lines(
        &file,
        &CatOptions {
            start: Some(Duration::from_nanos(latest_ns - earliest_ns) + Duration::from_secs(3600)),
            ..CatOptions::default()
        },
    );
    assert!(none.is_empty(), "{:?}", none.first());

    // export: PNG frames and a Foxglove file.
    let png_dir = dir.path().join("png");
    let foxglove = dir.path().join("foxglove.mcap");
    let report = export(
        &file,
        &ExportOptions {
            png_dir: Some(png_dir.clone()),
            foxglove: Some(foxglove.clone()),
            ..ExportOptions::default()
        },
    )
    .expect("export");
    assert_eq!(report.png_frames, 2);
    // Every channel is carried into the Foxglove export, the recorder's events (JSON) too.
    assert!(report.skipped.is_empty(), "{:?}", report.skipped);
    for index in 0..2u32 {
        let mut expected = zeroed_box::<RgbdFrame>();
        fill_frame(&mut expected, index);
        let rgb = image::open(png_dir.join(format!("camera_rgbd-{index:06}-rgb.png")))
            .expect("rgb png")
            .to_rgb8();
        assert_eq!(
            (rgb.width() as usize, rgb.height() as usize),
            (RGB_WIDTH_PX, RGB_HEIGHT_PX)
        );
        assert!(
            rgb.as_raw().as_slice() == &expected.rgb[..],
            "rgb pixels of frame {index}"
        );
        let depth = image::open(png_dir.join(format!("camera_rgbd-{index:06}-depth.png")))
            .expect("depth png")
            .to_luma16();
        assert_eq!(
            (depth.width() as usize, depth.height() as usize),
            (DEPTH_WIDTH_PX, DEPTH_HEIGHT_PX)
        );
        assert!(
            depth.as_raw().as_slice() == &expected.depth_mm[..],
            "depth of frame {index}"
        );
    }
    let index = std::fs::read_to_string(png_dir.join("frames.csv")).expect("frames.csv");
    assert_eq!(index.lines().count(), 3);

    ensure_python_mcap();
    // The official reader: JSON views stay JSON; camera frames are the mapped JPEG images
    // (protobuf `foxglove.CompressedImage`, decoded with descriptors in tests/foxglove).
    const SCRIPT: &str = r#"
import json, sys
from mcap.reader import make_reader
out = {"topics": {}, "jpeg_messages": 0}
with open(sys.argv[1], "rb") as f:
    reader = make_reader(f)
    for schema, channel, message in reader.iter_messages():
        out["topics"].setdefault(channel.topic, {"count": 0, "encoding": channel.message_encoding,
            "schema": schema.name, "schema_encoding": schema.encoding, "first": None, "log_time": message.log_time})
        entry = out["topics"][channel.topic]
        entry["count"] += 1
        if channel.message_encoding == "json":
            if entry["first"] is None:
                entry["first"] = json.loads(message.data)
        elif channel.topic == "/camera/image" and b"\xff\xd8" in message.data:
            out["jpeg_messages"] += 1
print(json.dumps(out))
"#;
    let read = python_json(SCRIPT, &foxglove);
    let arm = &read["topics"]["arm1/state"];
    assert_eq!(arm["count"], 10);
    assert_eq!(arm["encoding"], "json");
    assert_eq!(arm["schema_encoding"], "jsonschema");
    assert_eq!(arm["first"]["apple_id"], 1000);
    assert!(
        arm["log_time"].as_u64().expect("log_time") > 1_600_000_000_000_000_000,
        "stamps converted to UTC"
    );
    // The recorder's events channel, copied as it is (JSON with its schema).
    let events = &read["topics"]["recorder/events"];
    assert!(events["count"].as_u64().unwrap_or(0) >= 1, "{events}");
    assert_eq!(events["encoding"], "json");
    assert_eq!(events["schema_encoding"], "jsonschema");
    assert!(events["first"]["kind"].is_string(), "{events}");
    let image = &read["topics"]["/camera/image"];
    assert_eq!(image["schema"], "foxglove.CompressedImage");
    assert_eq!(image["encoding"], "protobuf");
    assert_eq!(image["schema_encoding"], "protobuf");
    assert_eq!(image["count"], 2, "every frame is exported");
    assert_eq!(read["jpeg_messages"], 2);
    assert_eq!(
        read["topics"]["/camera/calibration"]["schema"],
        "foxglove.CameraCalibration"
    );
    assert_eq!(read["topics"]["/arm1/joints"]["count"], 10);
    assert!(
        read["topics"]["camera/rgbd/rgb"].is_null(),
        "no raw base64 images any more"
    );
}
