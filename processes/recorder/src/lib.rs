//! harvest-recorder: the MCAP recorder process and the recording tools.
//!
//! - [`recorder`]: `harvest recorder`, taps every selected catalogue channel into MCAP.
//! - [`replay`]: `harvest replay`, republishes a recording into a domain's channels.
//! - [`rec`]: `harvest rec info|cat|export|recover`.
//!
//! Recording layout: one MCAP channel per topic, `message_encoding` and schema encoding
//! [`harvest_ipc::codec::ENCODING`], schema named `<TYPE_NAME>.v<VERSION>` with the payload's
//! layout text as data (see [`schema`]); `log_time` = receive time and `publish_time` =
//! `header.publish_ns`, both `CLOCK_MONOTONIC` ns, with a `harvest.clock` metadata record
//! mapping them to UTC (see [`metadata`]).

pub mod base64;
pub mod export;
pub mod foxglove_export;
pub mod json_schema;
pub mod keyboard;
pub mod mcap_error;
pub mod metadata;
pub mod output_dir;
pub mod payload_codec;
pub mod png_export;
pub mod rec;
pub mod rec_cat;
pub mod rec_info;
pub mod recorder;
pub mod recording_file;
pub mod recover;
pub mod replay;
pub mod scan;
pub mod schema;
pub mod segment_writer;
pub mod tap;
pub mod time_window;
pub mod topic_filter;
pub mod units;
pub mod wall_clock;
pub mod writer_thread;

pub use rec::{RecCommand, RecError, run_rec};
pub use recorder::{
    RecorderArgs, RecorderControl, RecorderError, RecordingReport, run_recorder, run_recorder_until,
};
pub use replay::{ReplayArgs, ReplayError, ReplayReport, run_replay};
