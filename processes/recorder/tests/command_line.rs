//! The clap definitions the `harvest` binary embeds parse the documented command lines.

use clap::{CommandFactory, Parser, Subcommand};
use harvest_rec::{RecCommand, ReplayArgs};
use harvest_recorder::RecorderArgs;
use harvest_recorder::recorder::CameraRecord;
use harvest_recorder::recorder::LayerArg;
use harvest_recording::segment_writer::ChunkCompression;
use std::time::Duration;

#[derive(Debug, Parser)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
#[allow(clippy::large_enum_variant)] // parsed once per test
enum Command {
    Recorder(RecorderArgs),
    Replay(ReplayArgs),
    Rec {
        #[command(subcommand)]
        command: RecCommand,
    },
}

fn parse(line: &str) -> Command {
    Cli::try_parse_from(std::iter::once("harvest").chain(line.split_whitespace()))
        .unwrap_or_else(|error| panic!("{line}: {error}"))
        .command
}

#[test]
fn definitions_are_consistent() {
    Cli::command().debug_assert();
}

#[test]
fn recorder_defaults_and_options() {
    let Command::Recorder(args) = parse("recorder") else {
        panic!("recorder")
    };
    assert_eq!(args.compression, ChunkCompression::Zstd);
    assert_eq!(args.camera, CameraRecord::Video);
    assert_eq!(args.video_rate, 10.0);
    assert_eq!(args.depth_rate, 2.0);
    assert_eq!(args.max_age, None);
    assert_eq!(args.layers, vec![LayerArg::Stack]);
    assert_eq!(args.output_dir, std::path::PathBuf::from("recordings"));
    assert_eq!(args.split_size, 1 << 30);
    let line = "recorder --compression zstd --compression-level 3 --chunk-size 8MiB --split-size 2GB \
--split-duration 5m --max-total-size 100GiB --include arm* --include camera/* --exclude */command \
--layer stack --layer hardware --launch-file launch.toml --calibration cal.toml --scenario dense \
--note operator=ana --output-dir /data/rec --camera raw --max-age 168h --video-rate 5 \
--video-bitrate 1000000 --depth-rate 1";
    let Command::Recorder(args) = parse(line) else {
        panic!("recorder")
    };
    assert_eq!(args.compression, ChunkCompression::Zstd);
    assert_eq!(args.camera, CameraRecord::Raw);
    assert_eq!(args.max_age, Some(Duration::from_secs(168 * 3600)));
    assert_eq!(
        (args.video_rate, args.video_bitrate, args.depth_rate),
        (5.0, 1_000_000, 1.0)
    );
    assert_eq!(args.compression_level, Some(3));
    assert_eq!(args.chunk_size, 8 << 20);
    assert_eq!(args.split_size, 2_000_000_000);
    assert_eq!(args.split_duration, Some(Duration::from_secs(300)));
    assert_eq!(args.include, vec!["arm*", "camera/*"]);
    assert_eq!(args.layers, vec![LayerArg::Stack, LayerArg::Hardware]);
    assert_eq!(args.notes, vec!["operator=ana"]);
    assert!(Cli::try_parse_from(["harvest", "recorder", "--split-size", "lots"]).is_err());
}

#[test]
fn replay_and_rec_commands() {
    let Command::Replay(args) = parse(
        "replay a.mcap b.mcap --rate 2 --loop --start-offset 1.5s --duration 10s --fast --include arm*",
    ) else {
        panic!("replay")
    };
    assert_eq!(args.files.len(), 2);
    assert_eq!(args.rate, 2.0);
    assert!(args.loop_playback && args.fast && !args.no_keyboard);
    assert_eq!(args.start_offset, Some(Duration::from_millis(1500)));
    assert!(
        Cli::try_parse_from(["harvest", "replay"]).is_err(),
        "a file is required"
    );
    assert!(
        matches!(parse("rec info a.mcap b.mcap"), Command::Rec { command: RecCommand::Info { files } } if files.len() == 2)
    );
    assert!(matches!(
        parse("rec cat a.mcap --topic arm* --start 1s --end 2s"),
        Command::Rec {
            command: RecCommand::Cat {
                start: Some(_),
                end: Some(_),
                ..
            }
        }
    ));
    assert!(matches!(
        parse("rec export a.mcap --png frames --foxglove out.mcap"),
        Command::Rec {
            command: RecCommand::Export {
                png: Some(_),
                foxglove: Some(_),
                ..
            }
        }
    ));
    assert!(matches!(
        parse("rec recover in.mcap out.mcap --force"),
        Command::Rec {
            command: RecCommand::Recover { force: true, .. }
        }
    ));
}
