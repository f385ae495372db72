//! Foxglove with independent clients: the default stack runs in a private domain with its
//! `harvest foxglove` bridge on a port of its own; a Python client (`websockets`, `protobuf`;
//! tests/foxglove/live_client.py) negotiates the subprotocol, subscribes and decodes with the
//! descriptors from the advertisement, while bad clients (garbage, unknown channel ids, a slow
//! reader cut off mid-frame, an unsupported subprotocol) connect to the same server. What it
//! decoded is compared with what the stack published, read back from the stack's own recording
//! (`harvest rec cat`). The official Python `mcap` reader then decodes the same recording's
//! mapped channels with the schemas stored in it (tests/foxglove/read_recording.py), the raw
//! channels are still there, and `harvest replay` still drives them.

mod common;

use common::*;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const SCRIPTS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/foxglove");

/// A TCP port free right now on the loopback interface.
fn free_port() -> u16 {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    listener.local_addr().expect("address").port()
}

/// Runs a Python script under a watchdog; returns its stdout parsed as JSON.
fn run_python(script: &str, args: &[&str], limit: Duration) -> Value {
    let child = Command::new("python3")
        .arg(Path::new(SCRIPTS).join(script))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn python3");
    let (status, stdout, stderr) = wait_with_watchdog(child, limit);
    assert!(status.success(), "{script} failed:\n{stderr}");
    serde_json::from_str(&stdout).unwrap_or_else(|error| panic!("{script}: {error}: {stdout}"))
}

/// `harvest rec cat FILE --topic T...` as JSON records.
fn recorded(file: &Path, topics: &[&str]) -> Vec<Value> {
    let mut args = vec!["rec", "cat", file.to_str().expect("utf-8")];
    for topic in topics {
        args.extend(["--topic", topic]);
    }
    let (status, stdout, stderr) =
        run_harvest(&unique_domain("cat"), &args, Duration::from_secs(120));
    assert!(status.success(), "{stderr}");
    stdout
        .lines()
        .filter(|line| !line.trim().is_empty())
        .map(|line| serde_json::from_str(line).expect("JSON line"))
        .collect()
}

fn numbers(value: &Value) -> Vec<f64> {
    value
        .as_array()
        .expect("array")
        .iter()
        .map(|v| v.as_f64().expect("number"))
        .collect()
}

fn recording_of(domain: &str) -> PathBuf {
    let dir = run_dir(domain).join("recordings");
    let mut files = mcap_files(&dir);
    // The default launch splits at 1 GiB: a fast machine fills more than one segment in the
    // test's run. Every segment carries every channel; the first one is read.
    assert!(!files.is_empty(), "no recording in {}", dir.display());
    files.remove(0)
}

#[test]
fn default_stack_is_seen_live_and_recorded_by_independent_foxglove_clients() {
    let _stack = one_stack_at_a_time();
    ensure_python(
        "websockets, google.protobuf, mcap",
        &["websockets", "protobuf", "mcap"],
    );
    let domain = unique_domain("fox");
    let port = free_port();
    let stack = Command::new(HARVEST)
        .args(["up", "--duration", "30s"])
        .current_dir(run_dir(&domain))
        .env("HARVEST_DOMAIN", &domain)
        .env("HARVEST_FOXGLOVE_LISTEN", format!("127.0.0.1:{port}"))
        .env("RUST_LOG", "info")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn harvest up");
    // The bridge listens once the stack has started (watchdog: 40 s).
    let deadline = Instant::now() + Duration::from_secs(40);
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(
            Instant::now() < deadline,
            "the bridge never listened on {port}"
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    let url = format!("ws://127.0.0.1:{port}");
    let live = run_python(
        "live_client.py",
        &["--url", &url, "--seconds", "14"],
        Duration::from_secs(90),
    );
    let (status, _, stderr) = wait_with_watchdog(stack, Duration::from_secs(120));
    assert!(status.success(), "harvest up failed:\n{stderr}");
    // The bad clients hurt neither the stack nor the bridge.
    for process in ["foxglove", "camera", "perception", "recorder"] {
        assert_eq!(
            summary_restarts(&stderr, process),
            Some(0),
            "{process}:\n{stderr}"
        );
    }
    let file = recording_of(&domain);

    // Negotiation, advertisement, schemas.
    assert_eq!(live["negotiated_subprotocol"], "foxglove.sdk.v1");
    assert_eq!(live["server_name"], "harvest");
    assert_eq!(live["old_protocol"], "refused 400", "{live}");
    let advertised: BTreeMap<&str, &Value> = live["advertised"]
        .as_array()
        .expect("advertised")
        .iter()
        .map(|channel| (channel["topic"].as_str().expect("topic"), channel))
        .collect();
    for (topic, schema) in [
        ("/camera/image", "foxglove.CompressedImage"),
        ("/camera/annotations", "foxglove.ImageAnnotations"),
        ("/apples/detected", "foxglove.SceneUpdate"),
        ("/robot_model", "foxglove.SceneUpdate"),
        ("/tf", "foxglove.FrameTransforms"),
        ("/vacuum", "harvest.VacuumView"),
        ("/events", "foxglove.Log"),
    ] {
        let channel = advertised
            .get(topic)
            .unwrap_or_else(|| panic!("{topic} advertised"));
        assert_eq!(channel["schemaName"], schema);
        assert_eq!(channel["encoding"], "protobuf");
        assert_eq!(channel["schemaEncoding"], "protobuf");
    }

    // Camera: downscaled JPEG, calibration scaled alike.
    let images = live["images"].as_array().expect("images");
    assert!(!images.is_empty(), "no camera image received");
    for image in images {
        assert_eq!(
            (image["width"].as_u64(), image["height"].as_u64()),
            (Some(960), Some(540))
        );
        assert_eq!(image["format"], "jpeg");
        assert_eq!(image["frame_id"], "camera_color");
    }
    let full = harvest_ipc::camera_model::CameraIntrinsics::tl460_rgb();
    let k = numbers(&live["calibration"]["K"]);
    assert!((k[0] - full.fx_px / 2.0).abs() < 1e-9, "{k:?}");
    assert!(
        (k[2] - ((full.cx_px + 0.5) / 2.0 - 0.5)).abs() < 1e-9,
        "{k:?}"
    );

    // Annotations and spheres against the detections the stack published for the same frame.
    let mut detections_by_frame: BTreeMap<u64, Value> = BTreeMap::new();
    for record in recorded(&file, &["perception/apples"]) {
        let message = record["message"].clone();
        detections_by_frame.insert(message["source_frame_seq"].as_u64().expect("seq"), message);
    }
    let image_stamps: Vec<u64> = images
        .iter()
        .map(|image| image["stamp_ns"].as_u64().expect("stamp"))
        .collect();
    let mut matched_sets = 0;
    let mut matched_apples = 0;
    let mut synced_with_an_image = 0;
    let mut stamp_to_frame = BTreeMap::new();
    for set in live["annotations"].as_array().expect("annotations") {
        let seq = set["source_frame_seq"].as_u64().expect("seq");
        let stamp = set["stamp_ns"].as_u64().expect("stamp");
        stamp_to_frame.insert(stamp, seq);
        if image_stamps.contains(&stamp) {
            synced_with_an_image += 1;
        }
        let Some(published) = detections_by_frame.get(&seq) else {
            continue;
        };
        let apples = published["apples"].as_array().expect("apples");
        let circles = set["circles"].as_array().expect("circles");
        assert_eq!(circles.len(), apples.len(), "frame {seq}");
        for (circle, apple) in circles.iter().zip(apples) {
            let b = numbers(&apple["box_px"]);
            assert_eq!(circle["apple_id"], apple["apple_id"], "frame {seq}");
            assert_eq!(
                circle["x"].as_f64(),
                Some((b[0] + b[2] / 2.0) / 2.0),
                "frame {seq}"
            );
            assert_eq!(
                circle["y"].as_f64(),
                Some((b[1] + b[3] / 2.0) / 2.0),
                "frame {seq}"
            );
            assert_eq!(
                circle["diameter"].as_f64(),
                Some((b[2] + b[3]) / 4.0),
                "frame {seq}"
            );
            matched_apples += 1;
        }
        matched_sets += 1;
    }
    assert!(
        matched_sets > 0 && matched_apples > 0,
        "no annotation matched a published set"
    );
    assert!(
        synced_with_an_image > 0,
        "no annotation carried an image's timestamp"
    );
    let mut matched_spheres = 0;
    for update in live["detected"].as_array().expect("detected") {
        for entity in update["entities"].as_array().expect("entities") {
            assert_eq!(entity["frame_id"], "robot");
            let stamp = entity["stamp_ns"].as_u64().expect("stamp");
            let Some(published) = stamp_to_frame
                .get(&stamp)
                .and_then(|seq| detections_by_frame.get(seq))
            else {
                continue;
            };
            let id: u64 = entity["id"]
                .as_str()
                .and_then(|id| id.strip_prefix("detected/"))
                .and_then(|id| id.parse().ok())
                .expect("detected/<id>");
            let apple = published["apples"]
                .as_array()
                .expect("apples")
                .iter()
                .find(|apple| apple["apple_id"].as_u64() == Some(id))
                .expect("the sphere's apple was published");
            assert_eq!(
                numbers(&entity["position"]),
                numbers(&apple["position_in_robot_m"])
            );
            matched_spheres += 1;
        }
    }
    assert!(matched_spheres > 0, "no sphere matched a published apple");

    // Arms: the transform chain ends where the arm said its end-effector was (eq. 1).
    let mut states: Vec<(String, Vec<f64>, Vec<f64>)> = Vec::new();
    for record in recorded(&file, &["arm1/state", "arm2/state"]) {
        let arm = record["topic"]
            .as_str()
            .expect("topic")
            .split('/')
            .next()
            .expect("arm");
        let message = &record["message"];
        states.push((
            arm.to_owned(),
            numbers(&message["joint_position"]),
            numbers(&message["end_effector_in_robot_m"]),
        ));
    }
    let tips: BTreeMap<(String, u64), Vec<f64>> = live["arm_tips"]
        .as_array()
        .expect("tips")
        .iter()
        .map(|tip| {
            (
                (
                    tip["arm"].as_str().expect("arm").to_owned(),
                    tip["stamp_ns"].as_u64().expect("stamp"),
                ),
                numbers(&tip["tip"]),
            )
        })
        .collect();
    let mut matched_tips = 0;
    for arm in ["arm1", "arm2"] {
        for joints in live["joints"][format!("/{arm}/joints")]
            .as_array()
            .expect("joints")
        {
            let position = numbers(&joints["position"]);
            let Some(tip) =
                tips.get(&(arm.to_owned(), joints["stamp_ns"].as_u64().expect("stamp")))
            else {
                continue;
            };
            let Some((_, _, end_effector)) = states
                .iter()
                .find(|(name, joint_position, _)| name == arm && *joint_position == position)
            else {
                continue;
            };
            for axis in 0..3 {
                assert!(
                    (tip[axis] - end_effector[axis]).abs() < 1e-6,
                    "{arm}: chain ends at {tip:?}, the arm reported {end_effector:?}"
                );
            }
            matched_tips += 1;
        }
    }
    assert!(matched_tips >= 10, "only {matched_tips} arm states matched");
    assert_eq!(live["model"]["arm1/tube"], "arm1_link3");
    assert_eq!(live["model"]["arm2/cup"], "arm2_end_effector");
    assert!(!live["vacuum"].as_array().expect("vacuum").is_empty());
    assert!(!live["events"].as_array().expect("events").is_empty());

    // Bad clients: answered with status messages, and the good client kept receiving.
    assert!(
        live["garbage_statuses"].as_u64().expect("statuses") > 0,
        "{live}"
    );
    assert_eq!(live["raw_handshake"], "HTTP/1.1 101 Switching Protocols");
    assert!(
        live["images_after_bad_clients"].as_u64().expect("count") > 0,
        "no image after the bad clients"
    );

    // The recording opens as it is: mapped channels decode with the schemas in the file.
    let read = run_python(
        "read_recording.py",
        &[file.to_str().expect("utf-8")],
        Duration::from_secs(120),
    );
    assert_eq!(read["decode_errors"], serde_json::json!([]));
    assert_eq!(read["log_time_order"], true);
    let channels = &read["channels"];
    for (topic, schema) in [
        ("/camera/image", "foxglove.CompressedImage"),
        ("/camera/annotations", "foxglove.ImageAnnotations"),
        ("/tf", "foxglove.FrameTransforms"),
        ("/robot_model", "foxglove.SceneUpdate"),
        ("/vacuum", "harvest.VacuumView"),
        ("/events", "foxglove.Log"),
        ("camera/video", "foxglove.CompressedVideo"),
    ] {
        assert_eq!(channels[topic]["schema_name"], schema, "{topic}");
        assert_eq!(channels[topic]["schema_encoding"], "protobuf", "{topic}");
        assert!(channels[topic]["count"].as_u64() > Some(0), "{topic}");
    }
    // The camera goes into the continuous record as H.264 video and PNG depth, not raw frames.
    for (raw, encoding) in [
        ("perception/apples", "bincode2-fixint-le"),
        ("arm1/state", "bincode2-fixint-le"),
        ("vacuum/state", "bincode2-fixint-le"),
        ("camera/depth", "bincode2-fixint-le+png16"),
    ] {
        assert_eq!(channels[raw]["message_encoding"], encoding, "{raw}");
        assert!(channels[raw]["count"].as_u64() > Some(0), "{raw}");
    }
    assert_eq!(channels["camera/rgbd"], Value::Null);
    // Mapped at the viewing rate: at most about 10 images per second. (Not compared with the
    // video's count: the encoder may drop a frame when it is behind, and both are admitted at
    // 10 Hz by rate limiters of their own.)
    let image = &channels["/camera/image"];
    let recorded_images = image["count"].as_u64().expect("images");
    let span_s = (image["last_log_time"].as_u64().expect("last")
        - image["first_log_time"].as_u64().expect("first")) as f64
        / 1e9;
    assert!(
        recorded_images as f64 <= span_s * 10.0 * 1.1 + 2.0,
        "{recorded_images} images over {span_s:.1} s"
    );
    assert!(read["annotation_circles"].as_u64() > Some(0));
    let pairs = read["transform_pairs"].to_string();
    for pair in [
        "[\"robot\",\"camera_color\"]",
        "[\"arm1_link3\",\"arm1_end_effector\"]",
    ] {
        assert!(pairs.contains(pair), "{pair} not in {pairs}");
    }

    // The raw channels still drive the stack: replay republishes them (the mapped ones are
    // left out).
    let (status, _, stderr) = run_harvest(
        &unique_domain("foxrp"),
        &[
            "replay",
            file.to_str().expect("utf-8"),
            "--include",
            "camera/rgbd",
            "--rate",
            "4",
            "--no-keyboard",
        ],
        Duration::from_secs(120),
    );
    assert!(status.success(), "replay failed: {stderr}");
    assert!(stderr.contains("camera/rgbd"), "{stderr}");
    assert_eq!(
        leftover_files(&domain),
        "",
        "iceoryx2 resources left behind"
    );
}
