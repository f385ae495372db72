//! `harvest recorder`: taps every selected catalogue channel of a domain into MCAP files
//! ([`recorder`]), written on a thread of their own ([`writer_thread`]) into size-limited
//! segments of an output directory ([`output_dir`]). Besides the raw channels it writes them
//! mapped for Foxglove at the viewing rates ([`view_thread`]), records the camera as H.264 video
//! and depth at a reduced rate ([`video_thread`]), and keeps the recent raw channels
//! in a RAM ring from which it writes a clip around each trigger ([`flight_thread`],
//! [`clip_writer`]). The format is `harvest-recording`; the tools
//! that read it (`harvest rec`, `harvest replay`) are `harvest-rec`.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod buffer_pool;
pub mod clip_writer;
pub mod disk_space;
pub mod flight_thread;
pub mod output_dir;
pub mod recorder;
pub mod shared_queue;
pub mod tap;
pub mod video_thread;
pub mod view_thread;
pub mod writer_thread;

pub use recorder::{
    RecorderArgs, RecorderControl, RecorderError, RecordingReport, run_recorder, run_recorder_until,
};
