//! Inputs the cargo-fuzz targets in `fuzz/` found (docs/testing.md, "Fuzzing"), kept
//! as regression tests. This file has its own process, so its allocator counts only its tests.

use harvest_recording::record_lengths::{RecordError, check_length_prefixes};
use harvest_recording::scan::{ScanOptions, scan_file};
use std::alloc::{GlobalAlloc, Layout, System};
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The system allocator, remembering the largest single request.
struct LargestRequest;

static LARGEST_REQUEST_BYTES: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call is forwarded unchanged to the system allocator.
unsafe impl GlobalAlloc for LargestRequest {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LARGEST_REQUEST_BYTES.fetch_max(layout.size(), Ordering::Relaxed);
        // SAFETY: the caller's contract is `System::alloc`'s.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract is `System::dealloc`'s.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LARGEST_REQUEST_BYTES.fetch_max(new_size, Ordering::Relaxed);
        // SAFETY: the caller's contract is `System::realloc`'s.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: LargestRequest = LargestRequest;

/// `recording_file` target, out-of-memory: after the magic, a Header record (opcode 0x01) of
/// 5 bytes whose profile string claims 0xffff_f700 bytes. The `mcap` crate reserved the claimed
/// 4 GiB before reading; the scanner now refuses the record, naming the field.
#[test]
fn header_whose_profile_claims_4_gib_is_refused_without_allocating_it() {
    let tail: [u8; 22] = [
        0x01, 0x05, 0, 0, 0, 0, 0, 0, 0, 0, 0xf7, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x05,
        0, 0, 0x02,
    ];
    let path = std::env::temp_dir().join(format!(
        "harvest-recording-fuzz-regression-{}.mcap",
        std::process::id()
    ));
    let mut bytes = mcap::MAGIC.to_vec();
    bytes.extend_from_slice(&tail);
    std::fs::write(&path, &bytes).unwrap();

    let outcome = scan_file(&path, ScanOptions::default(), |_| ControlFlow::Continue(()));
    std::fs::remove_file(&path).unwrap();
    let outcome = outcome.unwrap();
    assert!(
        outcome
            .warnings
            .iter()
            .any(|warning| warning.contains("profile claims 4294964992 bytes")),
        "warnings: {:?}",
        outcome.warnings
    );
    // The scanner's own read buffer is 1 MiB; nothing near the claimed 4 GiB.
    let largest = LARGEST_REQUEST_BYTES.load(Ordering::Relaxed);
    assert!(largest < 64 << 20, "largest allocation {largest} bytes");
}

/// Every string of a record's layout is checked, map entries included.
#[test]
fn length_prefixes_past_the_record_are_named() {
    // Metadata: name "ab", then a map of 12 bytes whose value claims 1000 bytes.
    let mut body = vec![2, 0, 0, 0, b'a', b'b', 12, 0, 0, 0, 1, 0, 0, 0, b'k'];
    body.extend_from_slice(&1000u32.to_le_bytes());
    body.extend_from_slice(b"vvv");
    match check_length_prefixes(mcap::records::op::METADATA, &body) {
        Err(RecordError::LengthPastEnd {
            field,
            claimed_bytes,
            ..
        }) => {
            assert_eq!(field, "metadata");
            assert_eq!(claimed_bytes, 1000);
        }
        other => panic!("expected a length past the end, got {other:?}"),
    }
    // The same record with the value's real length is accepted.
    let len_at = body.len() - 7;
    body[len_at..len_at + 4].copy_from_slice(&3u32.to_le_bytes());
    check_length_prefixes(mcap::records::op::METADATA, &body).unwrap();
}

/// The summary reader (`rec info`, `read_summary`) gets the same check: a summary section whose
/// Schema record claims a 4 GiB name is refused, naming the field (the `mcap` crate alone says
/// "Record parse failed"), without a large allocation. Written after the scanner's case.
#[test]
fn summary_record_claiming_4_gib_is_refused_without_allocating_it() {
    // Magic, Header (profile "", library ""), the summary section with one Schema record
    // (id 1, name claiming 0xffff_f000 bytes), the footer pointing at it, magic.
    let mut bytes = mcap::MAGIC.to_vec();
    bytes.push(mcap::records::op::HEADER);
    bytes.extend_from_slice(&8u64.to_le_bytes());
    bytes.extend_from_slice(&[0u8; 8]);
    let summary_start = bytes.len() as u64;
    let schema_body: Vec<u8> = [1u8, 0]
        .into_iter()
        .chain(0xffff_f000u32.to_le_bytes())
        .chain(*b"ab")
        .collect();
    bytes.push(mcap::records::op::SCHEMA);
    bytes.extend_from_slice(&(schema_body.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&schema_body);
    bytes.push(mcap::records::op::FOOTER);
    bytes.extend_from_slice(&20u64.to_le_bytes());
    bytes.extend_from_slice(&summary_start.to_le_bytes());
    bytes.extend_from_slice(&0u64.to_le_bytes());
    bytes.extend_from_slice(&0u32.to_le_bytes());
    bytes.extend_from_slice(mcap::MAGIC);
    let path = std::env::temp_dir().join(format!(
        "harvest-recording-summary-regression-{}.mcap",
        std::process::id()
    ));
    std::fs::write(&path, &bytes).unwrap();

    let outcome = harvest_recording::recording_file::read_summary(&path);
    std::fs::remove_file(&path).unwrap();
    let error = outcome.expect_err("the summary must be refused");
    assert!(
        error.contains("summary section") && error.contains("claims 4294963200 bytes"),
        "{error}"
    );
    let largest = LARGEST_REQUEST_BYTES.load(Ordering::Relaxed);
    assert!(largest < 64 << 20, "largest allocation {largest} bytes");
}
