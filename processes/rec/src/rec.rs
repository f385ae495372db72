//! `harvest rec info|cat|export|clips|recover`: the recording tools' command line.

use harvest_foxglove_mapping::ImageSettings;
use harvest_recording::clip_list::{format_clips, list_clips};
use harvest_recording::export::{ExportError, ExportOptions, export};
use harvest_recording::metadata;
use harvest_recording::rec_cat::{CatError, CatOptions, cat};
use harvest_recording::rec_info::{InfoError, info};
use harvest_recording::recover::{RecoverError, recover};
use harvest_recording::ros2_export::{Ros2ExportError, export_ros2};
use harvest_recording::units::parse_duration;
use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

/// `harvest rec` subcommands.
#[derive(Debug, Clone, clap::Subcommand)]
pub enum RecCommand {
    /// Channels, types, counts, rates, duration, size, compression and metadata.
    Info {
        #[arg(required = true, value_name = "FILE")]
        files: Vec<PathBuf>,
    },
    /// Messages as JSON lines.
    Cat {
        #[arg(value_name = "FILE")]
        file: PathBuf,
        /// Only topics matching one of these globs; repeatable.
        #[arg(long = "topic", value_name = "GLOB")]
        topics: Vec<String>,
        /// Skip messages before this offset from the first message (e.g. 2.5s).
        #[arg(long, value_parser = parse_duration)]
        start: Option<Duration>,
        /// Stop at this offset from the first message.
        #[arg(long, value_parser = parse_duration)]
        end: Option<Duration>,
    },
    /// Camera frames as PNG and/or the recording as a Foxglove-readable MCAP (the mapped
    /// channels at full rate, protobuf, plus each message's JSON view).
    Export {
        #[arg(value_name = "FILE")]
        file: PathBuf,
        /// Write each RGB-D frame as `<topic>-<n>-rgb.png` and `-depth.png` (16-bit mm) here.
        #[arg(long, value_name = "DIR")]
        png: Option<PathBuf>,
        /// Write an MCAP Foxglove and Lichtblick open: camera JPEG with overlays, 3D scene,
        /// transforms, plots, event log (every message mapped, not only the viewing rate).
        #[arg(long, value_name = "OUT.mcap")]
        foxglove: Option<PathBuf>,
        /// Write a rosbag2 bag (directory OUT: metadata.yaml and an MCAP file, CDR) with
        /// standard ROS 2 types: images, camera info, detections, joint states, point clouds.
        #[arg(long, value_name = "OUT")]
        ros2: Option<PathBuf>,
        /// Integer factor the exported camera images are downscaled by; the default is the live
        /// view's (960x540); 1 exports full-size 1920x1080 images (about 3x the file size).
        #[arg(long, default_value_t = ImageSettings::VIEWING.scale)]
        image_scale: u32,
        /// JPEG quality of the exported camera images, 1-100.
        #[arg(long, default_value_t = ImageSettings::VIEWING.jpeg_quality)]
        jpeg_quality: u8,
        /// Only topics matching one of these globs; repeatable.
        #[arg(long = "topic", value_name = "GLOB")]
        topics: Vec<String>,
        #[arg(long, value_parser = parse_duration)]
        start: Option<Duration>,
        #[arg(long, value_parser = parse_duration)]
        end: Option<Duration>,
    },
    /// The flight-recorder clips of a directory: trigger, time, length, size.
    Clips {
        #[arg(value_name = "DIR", default_value = "recordings/clips")]
        dir: PathBuf,
    },
    /// Rewrite a truncated, index-less or damaged recording into a valid file; report the loss.
    Recover {
        #[arg(value_name = "IN")]
        input: PathBuf,
        #[arg(value_name = "OUT")]
        output: PathBuf,
        /// Overwrite OUT if it exists.
        #[arg(long)]
        force: bool,
    },
}

/// A `rec` tool failed.
#[derive(Debug, thiserror::Error)]
pub enum RecError {
    #[error(transparent)]
    Info(#[from] InfoError),
    #[error(transparent)]
    Cat(#[from] CatError),
    #[error(transparent)]
    Export(#[from] ExportError),
    #[error(transparent)]
    Recover(#[from] RecoverError),
    #[error(transparent)]
    Ros2Export(#[from] Ros2ExportError),
    /// The clip directory cannot be read.
    #[error("cannot list the clips in {dir}: {source}")]
    Clips {
        dir: PathBuf,
        source: std::io::Error,
    },
    /// Printing to stdout failed.
    #[error("writing to stdout: {0}")]
    Stdout(std::io::Error),
}

/// Runs one `harvest rec` command, printing to stdout (reports) and stderr (warnings).
pub fn run_rec(command: &RecCommand) -> Result<(), RecError> {
    let stdout = std::io::stdout();
    match command {
        RecCommand::Info { files } => {
            let mut out = stdout.lock();
            for (index, file) in files.iter().enumerate() {
                let recording = info(file)?;
                if index > 0 {
                    writeln!(out).map_err(RecError::Stdout)?;
                }
                write!(out, "{recording}").map_err(RecError::Stdout)?;
                if let Some(version) = recording
                    .software_version()
                    .filter(|v| *v != metadata::SOFTWARE_VERSION)
                {
                    tracing::warn!(
                        file = %file.display(),
                        recorded_with = version,
                        "recording made by another software version: payloads of another layout version will not decode"
                    );
                }
            }
        }
        RecCommand::Cat {
            file,
            topics,
            start,
            end,
        } => {
            let options = CatOptions {
                topics: topics.clone(),
                start: *start,
                end: *end,
            };
            let mut out = std::io::BufWriter::with_capacity(1 << 16, stdout.lock());
            let report = cat(file, &options, &mut out)?;
            for (topic, (count, reason)) in &report.undecodable {
                eprintln!("rec cat: skipped {count} message(s) of {topic}: {reason}");
            }
            let mapped_views: u64 = report.mapped_views.values().sum();
            if mapped_views > 0 {
                eprintln!(
                    "rec cat: left out {mapped_views} message(s) of the channels mapped for Foxglove (protobuf views of the raw channels)"
                );
            }
            if let Some(reason) = &report.incomplete {
                eprintln!("rec cat: {}: {reason}", file.display());
            }
        }
        RecCommand::Export {
            file,
            png,
            foxglove,
            ros2,
            image_scale,
            jpeg_quality,
            topics,
            start,
            end,
        } => {
            if let Some(out) = ros2 {
                let report = export_ros2(file, out, topics, *start, *end)?;
                let mut out_lock = stdout.lock();
                writeln!(
                    out_lock,
                    "{} message(s) written to the ROS 2 bag {}",
                    report.messages(),
                    out.display()
                )
                .map_err(RecError::Stdout)?;
                for (topic, count) in &report.written {
                    writeln!(out_lock, "  {topic:<28} {count:>8}").map_err(RecError::Stdout)?;
                }
                for (topic, (count, reason)) in &report.skipped {
                    eprintln!("rec export --ros2: skipped {count} message(s) of {topic}: {reason}");
                }
                if let Some(reason) = &report.incomplete {
                    eprintln!("rec export --ros2: {}: {reason}", file.display());
                }
                if png.is_none() && foxglove.is_none() {
                    return Ok(());
                }
            }
            let options = ExportOptions {
                png_dir: png.clone(),
                foxglove: foxglove.clone(),
                foxglove_image: ImageSettings {
                    scale: *image_scale,
                    jpeg_quality: *jpeg_quality,
                },
                topics: topics.clone(),
                start: *start,
                end: *end,
            };
            let report = export(file, &options)?;
            let mut out = stdout.lock();
            if let Some(dir) = png {
                writeln!(
                    out,
                    "{} frame(s) written to {}",
                    report.png_frames,
                    dir.display()
                )
                .map_err(RecError::Stdout)?;
            }
            if let Some(path) = foxglove {
                writeln!(
                    out,
                    "{} message(s) written to {}",
                    report.foxglove_messages,
                    path.display()
                )
                .map_err(RecError::Stdout)?;
            }
            for (topic, (count, reason)) in &report.skipped {
                eprintln!("rec export: skipped {count} message(s) of {topic}: {reason}");
            }
            if let Some(reason) = &report.incomplete {
                eprintln!("rec export: {}: {reason}", file.display());
            }
        }
        RecCommand::Clips { dir } => {
            let clips = list_clips(dir).map_err(|source| RecError::Clips {
                dir: dir.clone(),
                source,
            })?;
            write!(stdout.lock(), "{}", format_clips(&clips)).map_err(RecError::Stdout)?;
        }
        RecCommand::Recover {
            input,
            output,
            force,
        } => {
            let report = recover(input, output, *force)?;
            write!(stdout.lock(), "{report}").map_err(RecError::Stdout)?;
        }
    }
    Ok(())
}
