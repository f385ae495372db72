//! harvest-recording: the stack's MCAP recording format, as pure file work (no ports).
//!
//! Recording layout: one MCAP channel per topic, `message_encoding` and schema encoding
//! [`harvest_ipc::codec::ENCODING`], schema named `<TYPE_NAME>.v<VERSION>` with the payload's
//! layout text as data (see [`schema`]); `log_time` = receive time and `publish_time` =
//! `header.publish_ns`, both in Unix-epoch ns (the stack's `CLOCK_MONOTONIC` stamp plus the
//! session's offset in the `harvest.clock` record; older files: `CLOCK_MONOTONIC` ns), see
//! [`time_base`].
//!
//! Writing: [`segment_writer`]; [`seal`] ends a file whose writing failed. Reading damaged files as far as they are valid: [`scan`],
//! [`recording_file`]; [`recover`] rewrites what is valid. Tools' back ends: [`rec_info`],
//! [`rec_cat`], [`export`] (JSON, PNG, Foxglove), [`ros2_export`] (rosbag2). Users: the recorder process, `harvest rec`,
//! `harvest replay` and `harvest monitor --recording`.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod annexb;
pub mod camera_record;
pub mod clip_list;
pub mod export;
pub mod flight_ring;
pub mod foxglove_export;
pub mod json_schema;
pub mod mcap_error;
pub mod metadata;
pub mod payload_codec;
pub mod png_export;
pub mod rec_cat;
pub mod rec_info;
pub mod record_lengths;
pub mod recorded_events;
pub mod recording_file;
pub mod recover;
pub mod resident_buffer;
pub mod ros2_export;
pub mod scan;
pub mod schema;
pub mod seal;
pub mod segment_writer;
pub mod time_base;
pub mod time_window;
pub mod topic_filter;
pub mod units;
pub mod video_codec;
pub mod wall_clock;
