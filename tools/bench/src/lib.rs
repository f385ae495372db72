//! harvest-bench: latency benchmarks of the stack's inter-process transport.
//!
//! `harvest bench ipc` measures one-way latency between two separate processes for payloads
//! from 64 B to 16 MiB (and the stack's real `RgbdFrame`, `AppleDetections` and
//! `LaserScanRequest`), through our layer (harvest_ipc), raw iceoryx2 and a copying Unix socket
//! baseline, and with the `zenoh` feature through Zenoh over loopback TCP and over Zenoh's
//! shared memory, each with event-driven and busy-poll wake-ups. The measuring process
//! receives; it starts one sending peer per run as `<current exe> bench-peer ...`
//! ([`PEER_SUBCOMMAND`]).
//!
//! - [`run_bench_ipc`] / [`BenchIpcArgs`]: the benchmark, returning a [`BenchReport`].
//! - [`run_bench_peer`] / [`BenchPeerArgs`]: the hidden peer subcommand.
//! - [`run_bench_pipeline`] / [`BenchPipelineArgs`]: `harvest bench pipeline`, per-hop latency
//!   in a running stack and the arm control loop's jitter ([`pipeline`]).
//! - [`run_bench_detector`] / [`BenchDetectorArgs`]: `harvest bench detector`, perception's
//!   detectors' latency per frame (ONNX models beside the colour segmentation) ([`detector`]).
//! - [`run_bench_video`] / [`BenchVideoArgs`]: `harvest bench video`, the recorder's camera
//!   video per 1080p frame on one core, its bytes, and the depth PNG ([`video`]).
//! - [`run_bench_lidar_livox`] / [`BenchLidarLivoxArgs`]: `harvest bench lidar-livox`, the
//!   Livox Mid-70 driver against the fake device on loopback ([`lidar_livox`]).
//! - [`run_bench_camera_gige`] / [`BenchCameraGigeArgs`]: `harvest bench camera-gige`, the
//!   GigE Vision camera driver against Aravis's fake camera on loopback ([`camera_gige`]).
//! - [`run_bench_console`] / [`BenchConsoleArgs`]: `harvest bench console`, the operator
//!   console's cost per viewer, capture-to-browser latency in Chromium, e-stop click to arms
//!   braked under load, memory with viewers coming and going ([`console`]).
//! - [`run_bench_remote`] / [`BenchRemoteArgs`]: `harvest bench remote`, the Zenoh link with
//!   several robots and one station: camera latency and bandwidth, command round trip, the
//!   station's CPU per robot ([`remote`]).
//! - [`run_soak`] / [`SoakArgs`]: `harvest soak`, the stack for a long time under kills,
//!   operator commands and bad inputs, with memory, descriptors and shared memory sampled
//!   ([`soak`]).

#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod affinity;
pub mod bench_payload;
pub mod camera_gige;
pub mod case;
pub mod child_stop;
pub mod console;
pub mod control;
pub mod detector;
pub mod driver_child;
pub mod error;
pub mod json_report;
pub mod lidar_livox;
pub mod message;
pub mod options;
pub mod payload_case;
pub mod peer;
pub mod pipeline;
pub mod proc_cpu;
pub mod remote;
pub mod report;
pub mod run;
pub mod scene_frame;
pub mod sender_write;
pub mod settle;
pub mod soak;
pub mod socket_io;
pub mod stats;
pub mod svg;
pub mod transport;
pub mod video;
pub mod watchdog;

pub use bench_payload::BenchPayload;
pub use camera_gige::{BenchCameraGigeArgs, CameraGigeReport, run_bench_camera_gige};
pub use console::{BenchConsoleArgs, ConsoleReport, run_bench_console};
pub use detector::{BenchDetectorArgs, run_bench_detector};
pub use error::BenchError;
pub use lidar_livox::{BenchLidarLivoxArgs, LidarLivoxReport, run_bench_lidar_livox};
pub use options::{BenchIpcArgs, BenchPeerArgs, PEER_SUBCOMMAND, Transport, WakeMode};
pub use payload_case::PayloadCase;
pub use peer::run_bench_peer;
pub use pipeline::{BenchPipelineArgs, PipelineComparison, PipelineReport, run_bench_pipeline};
pub use remote::{
    BenchRemoteArgs, BenchRemoteStationArgs, run_bench_remote, run_bench_remote_station,
};
pub use report::BenchReport;
pub use run::run_bench_ipc;
pub use sender_write::SenderWrite;
pub use soak::{SoakArgs, SoakReport, run_soak};
pub use svg::render_svg;
pub use video::{BenchVideoArgs, VideoBenchReport, run_bench_video};
