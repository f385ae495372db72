//! ROS 2 bags in and out, checked by the independent Python `rosbags` package:
//! - in: a bag `rosbags` writes from the simulator's renders (colour as bgr8, depth as 32FC1,
//!   their camera models, one topic the map leaves out) is replayed with `harvest replay
//!   --ros2 --map` into a stack running perception; the detections equal, frame by frame, those
//!   from the same renders replayed natively (within the estimator's noise; the inputs are the
//!   same pixels, so they agree to the micrometre in practice);
//! - out: `harvest rec export --ros2` of a recording with camera frames, LiDAR clouds and arm
//!   states, and of the perception run's detections, is read back by `rosbags` (its AnyReader
//!   checks each type's RIHS01 hash against the bag's definition, the test against Jazzy's);
//!   every message decodes, with the right type and stamp;
//! - a message the stack cannot take is refused, naming its topic and field.

mod common;

use common::*;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

const SCRIPTS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/ros2");

/// Runs a script of tests/ros2 under a watchdog; returns its stdout parsed as JSON.
fn run_python(script: &str, args: &[&Path]) -> Value {
    let child = Command::new("python3")
        .arg(Path::new(SCRIPTS).join(script))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("python3 runs");
    let (status, stdout, stderr) = wait_with_watchdog(child, Duration::from_secs(180));
    assert!(status.success(), "{script} failed: {stderr}");
    serde_json::from_str(stdout.trim())
        .unwrap_or_else(|error| panic!("{script}: {error}: {stdout}"))
}

fn harvest_ok(args: &[&str], what: &str) -> String {
    let (status, stdout, stderr) =
        run_harvest(&unique_domain("tool"), args, Duration::from_secs(180));
    assert!(status.success(), "{what}: {stderr}");
    stdout
}

/// `rec cat` of one topic as JSON messages.
fn cat(file: &Path, topic: &str) -> Vec<Value> {
    harvest_ok(
        &[
            "rec",
            "cat",
            file.to_str().expect("utf-8"),
            "--topic",
            topic,
        ],
        "rec cat",
    )
    .lines()
    .filter(|line| !line.trim().is_empty())
    .map(|line| {
        let record: Value = serde_json::from_str(line).expect("JSON line");
        record.get("message").cloned().unwrap_or(record)
    })
    .collect()
}

/// Perception on frames replayed by `replay_args`; returns the recording of its detections.
fn perception_run(dir: &TempDir, name: &str, replay_args: &[&str]) -> (PathBuf, String) {
    let out_dir = dir.0.join(name);
    let launch = dir.write(
        &format!("{name}.toml"),
        &format!(
            "[[process]]\nname = \"perception\"\ncommand = \"perception\"\n\
             args = [\"--calibration\", \"{SIM_CAMERA_CALIBRATION}\"]\n\n[[process]]\nname = \"recorder\"\n\
             command = \"recorder\"\nargs = [\"--output-dir\", \"{}\", \"--include\", \"perception/*\"]\n",
            out_dir.display()
        ),
    );
    let domain = unique_domain(name);
    let stack = Drained::spawn(
        &domain,
        &["up", "--launch", launch.to_str().expect("utf-8")],
    );
    std::thread::sleep(Duration::from_secs(4));
    let mut args = vec!["replay"];
    args.extend_from_slice(replay_args);
    args.extend_from_slice(&["--rate", "0.5", "--no-keyboard"]);
    let (status, _, replay_stderr) = run_harvest(&domain, &args, Duration::from_secs(180));
    assert!(status.success(), "replay failed: {replay_stderr}");
    std::thread::sleep(Duration::from_secs(3));
    let (_, _, stderr) = stack.interrupt_and_wait(Duration::from_secs(60));
    assert_eq!(leftover_files(&domain), "", "{stderr}");
    let files = mcap_files(&out_dir);
    assert_eq!(files.len(), 1, "{files:?}: {stderr}");
    (files[0].clone(), replay_stderr)
}

/// Detections per source frame (by its capture time).
fn detections_by_frame(file: &Path) -> BTreeMap<u64, Vec<Value>> {
    cat(file, "perception/apples")
        .into_iter()
        .map(|message| {
            let apples = message["apples"].as_array().cloned().unwrap_or_default();
            (
                message["source_capture_ns"]
                    .as_u64()
                    .expect("source_capture_ns"),
                apples,
            )
        })
        .collect()
}

/// A UTC time in 2020, ns: stamps above it are on the UTC base, not the stack clock.
const UTC_2020_NS: i128 = 1_000_000_000 * 1_600_000_000;

/// The header stamps of a topic as `read_bag.py` reports them, ns.
fn stamps_ns(topic: &Value) -> Vec<u64> {
    topic["stamps"]
        .as_array()
        .expect("stamps")
        .iter()
        .map(|stamp| stamp.as_u64().expect("stamp"))
        .collect()
}

fn position(apple: &Value) -> [f64; 3] {
    let p = &apple["position_in_camera_m"];
    [0, 1, 2].map(|i| p[i].as_f64().expect("position"))
}

#[test]
fn ros2_bags_drive_perception_and_exports_read_back() {
    let _stack = one_stack_at_a_time();
    ensure_python("rosbags.rosbag2, numpy, PIL", &["rosbags", "pillow"]);
    let dir = TempDir::new("ros2");

    // The simulator's renders (raw frames: `--camera raw`), LiDAR clouds and arm states,
    // recorded natively.
    let record_dir = dir.0.join("recorded");
    // The same frames as a continuous record holds them (the default: H.264 video and depth
    // images), by a second recorder.
    let video_dir = dir.0.join("recorded_video");
    let launch = dir.write(
        "record.toml",
        &format!(
            "[[process]]\nname = \"sim\"\ncommand = \"sim\"\nargs = [\"--camera-rate-hz\", \"2\", \"--lidar\"]\n\n\
             [[process]]\nname = \"camera\"\ncommand = \"camera\"\n\n\
             [[process]]\nname = \"lidar\"\ncommand = \"lidar\"\nargs = [\"--integration-s\", \"1.0\"]\n\n\
             [[process]]\nname = \"arm1\"\ncommand = \"arm\"\nargs = [\"--id\", \"1\", \"--without-operator\"]\n\n\
             [[process]]\nname = \"arm2\"\ncommand = \"arm\"\nargs = [\"--id\", \"2\", \"--without-operator\"]\n\n\
             [[process]]\nname = \"recorder\"\ncommand = \"recorder\"\nargs = [\"--output-dir\", \"{}\", \"--camera\", \"raw\", \
             \"--include\", \"camera/rgbd\", \"--include\", \"lidar/points\", \"--include\", \"arm*/state\"]\n\n\
             [[process]]\nname = \"recorder_video\"\ncommand = \"recorder\"\nargs = [\"--output-dir\", \"{}\", \
             \"--include\", \"camera/rgbd\"]\n",
            record_dir.display(),
            video_dir.display()
        ),
    );
    run_up_for("ros2rec", &launch, "6s", Duration::from_secs(120));
    let recordings = mcap_files(&record_dir);
    assert_eq!(recordings.len(), 1, "{recordings:?}");
    let recording = &recordings[0];
    let frames = cat(recording, "camera/rgbd");
    assert!(frames.len() >= 4, "only {} frames recorded", frames.len());

    // Out: the recording as a ROS 2 bag, read back by rosbags.
    let bag_out = dir.0.join("exported");
    let printed = harvest_ok(
        &[
            "rec",
            "export",
            recording.to_str().expect("utf-8"),
            "--ros2",
            bag_out.to_str().expect("utf-8"),
        ],
        "rec export --ros2",
    );
    let read = run_python("read_bag.py", &[&bag_out]);
    let topics = &read["topics"];
    assert!(read["metadata_yaml_has_hash"].as_bool().unwrap_or(false));
    for (topic, ty) in [
        ("/camera/color/image_raw", "sensor_msgs/msg/Image"),
        ("/camera/color/camera_info", "sensor_msgs/msg/CameraInfo"),
        ("/camera/depth/image_raw", "sensor_msgs/msg/Image"),
        ("/camera/depth/camera_info", "sensor_msgs/msg/CameraInfo"),
    ] {
        assert_eq!(topics[topic]["type"], ty, "{topic}: {printed}");
        assert_eq!(
            topics[topic]["count"].as_u64(),
            Some(frames.len() as u64),
            "{topic}"
        );
    }
    assert_eq!(topics["/camera/color/image_raw"]["encoding"], "rgb8");
    assert_eq!(
        topics["/camera/color/image_raw"]["size"],
        serde_json::json!([1920, 1080, 5760, 6220800])
    );
    assert_eq!(topics["/camera/depth/image_raw"]["encoding"], "16UC1");
    // Stamps: each frame's capture time on the recording's UTC base (one offset for all).
    let captures: Vec<u64> = frames
        .iter()
        .map(|frame| frame["header"]["capture_ns"].as_u64().expect("capture_ns"))
        .collect();
    let stamps = stamps_ns(&topics["/camera/color/image_raw"]);
    let offset = stamps[0] as i128 - captures[0] as i128;
    assert!(offset > UTC_2020_NS, "stamps are UTC: offset {offset}");
    for (stamp, capture) in stamps.iter().zip(&captures) {
        assert_eq!(*stamp as i128 - *capture as i128, offset);
    }
    // The continuous record exports to the same topics: every video frame decoded into an
    // `Image`, each recorded depth image with it.
    let video_recordings = mcap_files(&video_dir);
    assert_eq!(video_recordings.len(), 1, "{video_recordings:?}");
    let video = cat(&video_recordings[0], "camera/video");
    let depth = cat(&video_recordings[0], "camera/depth");
    assert!(
        video.len() >= 4,
        "only {} video frames recorded",
        video.len()
    );
    let video_bag = dir.0.join("exported_video");
    let printed = harvest_ok(
        &[
            "rec",
            "export",
            video_recordings[0].to_str().expect("utf-8"),
            "--ros2",
            video_bag.to_str().expect("utf-8"),
        ],
        "rec export --ros2 (video)",
    );
    let read_video = run_python("read_bag.py", &[&video_bag]);
    let video_topics = &read_video["topics"];
    for (topic, count) in [
        ("/camera/color/image_raw", video.len()),
        ("/camera/color/camera_info", video.len()),
        ("/camera/depth/image_raw", depth.len()),
        ("/camera/depth/camera_info", depth.len()),
    ] {
        assert_eq!(
            video_topics[topic]["count"].as_u64(),
            Some(count as u64),
            "{topic}: {printed}"
        );
    }
    assert_eq!(video_topics["/camera/color/image_raw"]["encoding"], "rgb8");
    assert_eq!(
        video_topics["/camera/color/image_raw"]["size"],
        topics["/camera/color/image_raw"]["size"]
    );
    assert_eq!(video_topics["/camera/depth/image_raw"]["encoding"], "16UC1");
    let video_stamps = stamps_ns(&video_topics["/camera/color/image_raw"]);
    assert!(
        video_stamps.windows(2).all(|pair| pair[0] < pair[1]),
        "{video_stamps:?}"
    );
    assert!(i128::from(video_stamps[0]) > UTC_2020_NS, "UTC");

    let k = &topics["/camera/color/camera_info"]["k"];
    assert_eq!(k[0], frames[0]["meta"]["rgb_intrinsics"]["fx_px"]);
    let clouds = cat(recording, "lidar/points");
    assert!(!clouds.is_empty(), "no LiDAR cloud recorded");
    assert_eq!(
        topics["/lidar/points"]["type"],
        "sensor_msgs/msg/PointCloud2"
    );
    assert_eq!(
        topics["/lidar/points"]["count"].as_u64(),
        Some(clouds.len() as u64)
    );
    assert_eq!(
        topics["/lidar/points"]["fields"],
        serde_json::json!(["x", "y", "z", "intensity"])
    );
    assert_eq!(
        topics["/lidar/points"]["points"][0].as_u64(),
        clouds[0]["meta"]["point_count"].as_u64()
    );
    for arm in [1, 2] {
        let states = cat(recording, &format!("arm{arm}/state"));
        let topic = &topics[format!("/arm{arm}/joint_states")];
        assert_eq!(topic["type"], "sensor_msgs/msg/JointState");
        assert_eq!(
            topic["count"].as_u64(),
            Some(states.len() as u64),
            "arm{arm}"
        );
        assert_eq!(topic["names"][0], format!("arm{arm}_d"));
        let first = states[0]["header"]["capture_ns"]
            .as_u64()
            .expect("capture_ns");
        assert_eq!(
            topic["stamps"][0]
                .as_u64()
                .map(|s| s as i128 - first as i128),
            Some(offset)
        );
        assert_eq!(topic["positions"][0][1], states[0]["joint_position"][1]);
    }

    // In: the same renders as a bag written by rosbags, with a map file.
    let png_dir = dir.0.join("frames");
    harvest_ok(
        &[
            "rec",
            "export",
            recording.to_str().expect("utf-8"),
            "--png",
            png_dir.to_str().expect("utf-8"),
        ],
        "rec export --png",
    );
    let meta = &frames[0]["meta"];
    let meta_path = dir.write("meta.json", &meta.to_string());
    let bag_in = dir.0.join("from_rosbags");
    let written = run_python("write_bag.py", &[&png_dir, &meta_path, &bag_in]);
    assert_eq!(written["frames"].as_u64(), Some(frames.len() as u64));
    let color_from_depth = &meta["color_from_depth"];
    let map = dir.write(
        "map.toml",
        &format!(
            "[camera]\ncolor = \"/cam/color/image_raw\"\ncolor_info = \"/cam/color/camera_info\"\n\
             depth = \"/cam/depth/image_rect\"\ndepth_info = \"/cam/depth/camera_info\"\n\
             max_stamp_difference_ms = 10.0\n\n[camera.color_from_depth]\nrotation = {}\ntranslation_m = {}\n",
            color_from_depth["rotation"], color_from_depth["translation_m"]
        ),
    );
    let recording_arg = recording.to_str().expect("utf-8").to_owned();
    let (native, _) = perception_run(
        &dir,
        "native",
        &[&recording_arg, "--include", "camera/rgbd"],
    );
    let bag_arg = bag_in.to_str().expect("utf-8").to_owned();
    let map_arg = map.to_str().expect("utf-8").to_owned();
    let (from_bag, replay_report) =
        perception_run(&dir, "frombag", &[&bag_arg, "--ros2", "--map", &map_arg]);
    assert!(
        replay_report.contains(&format!("{} camera frame(s)", frames.len())),
        "every pair becomes a frame: {replay_report}"
    );
    assert!(
        replay_report.contains("skipped /chatter"),
        "{replay_report}"
    );

    let native_by_frame = detections_by_frame(&native);
    let bag_by_frame = detections_by_frame(&from_bag);
    let common: Vec<&u64> = native_by_frame
        .keys()
        .filter(|k| bag_by_frame.contains_key(*k))
        .collect();
    assert!(
        common.len() >= 3,
        "too few frames processed in both runs: {} native, {} from the bag",
        native_by_frame.len(),
        bag_by_frame.len()
    );
    let mut apples = 0;
    let mut worst_m: f64 = 0.0;
    for capture_ns in common {
        let (a, b) = (&native_by_frame[capture_ns], &bag_by_frame[capture_ns]);
        assert_eq!(a.len(), b.len(), "frame {capture_ns}: apple counts differ");
        for apple in a {
            let p = position(apple);
            let nearest = b
                .iter()
                .map(|other| {
                    let q = position(other);
                    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
                })
                .fold(f64::INFINITY, f64::min);
            // Well inside the sphere fit's noise (millimetres at these ranges).
            assert!(
                nearest < 0.002,
                "frame {capture_ns}: apple {p:?} moved {nearest} m"
            );
            worst_m = worst_m.max(nearest);
        }
        apples += a.len();
    }
    assert!(
        apples > 0,
        "perception found no apples in the replayed frames"
    );
    eprintln!(
        "{} frames recorded; {} processed natively, {} from the bag; {apples} apples compared, largest difference {worst_m:e} m",
        frames.len(),
        native_by_frame.len(),
        bag_by_frame.len()
    );

    // Out: the detections as vision_msgs/Detection3DArray.
    let detections_bag = dir.0.join("detections");
    harvest_ok(
        &[
            "rec",
            "export",
            from_bag.to_str().expect("utf-8"),
            "--ros2",
            detections_bag.to_str().expect("utf-8"),
        ],
        "rec export --ros2 (detections)",
    );
    let read = run_python("read_bag.py", &[&detections_bag]);
    let topic = &read["topics"]["/perception/apples"];
    assert_eq!(topic["type"], "vision_msgs/msg/Detection3DArray");
    assert_eq!(topic["count"].as_u64(), Some(bag_by_frame.len() as u64));
    assert_eq!(topic["frame_id"], "camera_color_optical_frame");
    let first = topic["detections"]
        .as_array()
        .and_then(|all| {
            all.iter()
                .find(|d| !d.as_array().is_some_and(Vec::is_empty))
        })
        .and_then(|d| d.get(0))
        .expect("a detection");
    assert_eq!(first["class"], "apple");
    assert!(first["size"].as_f64().unwrap_or(0.0) > 0.03, "{first}");

    // Refused: a map that swaps the colour and depth images (the bag's colour image, which
    // comes first, is 1920 x 1080, not a depth image of the stack's 640 x 480).
    let wrong_map = dir.write(
        "wrong.toml",
        "[camera]\ncolor = \"/cam/depth/image_rect\"\ncolor_info = \"/cam/color/camera_info\"\n\
         depth = \"/cam/color/image_raw\"\ndepth_info = \"/cam/depth/camera_info\"\n",
    );
    let (status, _, stderr) = run_harvest(
        &unique_domain("ros2bad"),
        &[
            "replay",
            &bag_arg,
            "--ros2",
            "--map",
            wrong_map.to_str().expect("utf-8"),
            "--fast",
            "--no-keyboard",
        ],
        Duration::from_secs(60),
    );
    assert!(!status.success());
    assert!(
        stderr.contains("topic /cam/color/image_raw (sensor_msgs/msg/Image): field `width`"),
        "the refusal names topic and field: {stderr}"
    );
}
