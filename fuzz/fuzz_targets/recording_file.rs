//! Any bytes after the MCAP magic, as a recording file, through every reader: the scanner, the
//! summary readers, `rec info`, `rec cat`, `rec export` and `rec recover` (whose output must
//! always read back complete).
#![no_main]

use harvest_recording::export::{ExportOptions, export};
use harvest_recording::rec_cat::{CatOptions, cat};
use harvest_recording::rec_info::info;
use harvest_recording::recording_file::{read_indexed_metadata, read_summary};
use harvest_recording::recover::recover;
use harvest_recording::scan::{ScanOptions, scan_file};
use libfuzzer_sys::fuzz_target;
use std::ops::ControlFlow;

const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

fuzz_target!(|data: &[u8]| {
    let dir = std::env::temp_dir().join(format!("harvest-fuzz-recording-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch dir");
    let input = dir.join("input.mcap");
    let mut bytes = MCAP_MAGIC.to_vec();
    bytes.extend_from_slice(data);
    std::fs::write(&input, &bytes).expect("write input");

    if let Ok(outcome) = scan_file(&input, ScanOptions::default(), |_| ControlFlow::Continue(())) {
        assert!(outcome.valid_bytes <= bytes.len() as u64);
    }
    if let Ok(Some(summary)) = read_summary(&input) {
        let _ = read_indexed_metadata(&input, &summary.metadata_indexes);
    }
    if let Ok(summary) = info(&input) {
        let _ = summary.to_string();
    }
    let _ = cat(&input, &CatOptions::default(), &mut std::io::sink());
    let _ = export(
        &input,
        &ExportOptions {
            png_dir: Some(dir.join("png")),
            foxglove: Some(dir.join("foxglove.mcap")),
            ..ExportOptions::default()
        },
    );
    let output = dir.join("recovered.mcap");
    if recover(&input, &output, true).is_ok() {
        let again = scan_file(&output, ScanOptions::default(), |_| ControlFlow::Continue(()))
            .expect("a recovered file is readable");
        assert!(again.is_intact(), "recovered file damaged: {again:?}");
    }
});
