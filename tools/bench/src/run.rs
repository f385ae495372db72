//! `harvest bench ipc`: every case, repeated, in a domain of its own; then the report files.

use crate::affinity::AffinityRestore;
use crate::case::{CaseSpec, RunResult, run_case};
use crate::error::BenchError;
use crate::options::{BenchIpcArgs, Settings};
use crate::report::{BenchReport, CaseResult, HostInfo, check_targets, compute_ratios};
use crate::svg::render_svg;
use harvest_ipc::cleanup::{leftover_files, remove_dead_nodes};
use harvest_ipc::{Domain, ScratchDomain};
use std::path::Path;

/// Runs the benchmark: for every payload, transport and mode, `repeats` runs, each with a
/// fresh peer process (the sender, `<current exe> bench-peer ...`); this process receives.
/// Writes `--json` and `--svg` if asked and returns the report (print [`BenchReport::table`]).
pub fn run_bench_ipc(args: &BenchIpcArgs) -> Result<BenchReport, BenchError> {
    let cpus = std::thread::available_parallelism().map_or(1, usize::from);
    let settings = Settings::resolve(args, cpus)?;
    let domain = ScratchDomain::new("bench");
    let _pinned = match settings.pin_cpus {
        Some((receiver, _)) => Some(AffinityRestore::pin(receiver)?),
        None => None,
    };
    tracing::info!(domain = domain.name(), ?settings, "bench ipc starting");

    // Every repeat runs every case once, so slow drifts of the machine's load spread over all
    // transports alike instead of biasing the ones measured last.
    let mut cases = Vec::new();
    for &payload in &settings.payloads {
        for &transport in &settings.transports {
            for &mode in &settings.modes {
                cases.push((payload, transport, mode));
            }
        }
    }
    let total = cases.len() * settings.repeats;
    let mut runs: Vec<Vec<RunResult>> = vec![Vec::new(); cases.len()];
    let mut index = 0;
    for _ in 0..settings.repeats {
        for (&(payload, transport, mode), case_runs) in cases.iter().zip(&mut runs) {
            let spec = CaseSpec {
                payload,
                transport,
                mode,
                settings: &settings,
                domain: &domain,
                index,
            };
            index += 1;
            tracing::info!(
                case = spec.label(),
                run = index,
                of = total,
                "bench ipc case"
            );
            let run = run_case(&spec);
            clean_domain(&domain);
            case_runs.push(run?);
        }
    }
    let results: Vec<CaseResult> = cases
        .iter()
        .zip(runs)
        .map(|(&(payload, transport, mode), case_runs)| {
            CaseResult::measured(payload, transport, mode, case_runs)
        })
        .collect();

    let leftover: Vec<String> = leftover_files(&domain)
        .iter()
        .map(|path| path.display().to_string())
        .collect();
    if !leftover.is_empty() {
        tracing::warn!(domain = domain.name(), files = ?leftover, "iceoryx2 files left behind");
    }
    let report = BenchReport {
        tool: "harvest bench ipc",
        ratios: compute_ratios(&results),
        targets: check_targets(&results),
        settings,
        host: HostInfo {
            cpus,
            kernel: kernel_release(),
        },
        domain: domain.name().to_owned(),
        results,
        leftover_files: leftover,
    };
    if let Some(path) = &args.json {
        write_file(path, &serde_json::to_string_pretty(&report)?)?;
    }
    if let Some(path) = &args.svg {
        write_file(path, &render_svg(&report))?;
    }
    Ok(report)
}

/// Removes what a failed peer left in the domain (nothing after a clean case).
fn clean_domain(domain: &Domain) {
    match remove_dead_nodes(domain) {
        Ok(report) if !report.removed_nodes.is_empty() || !report.failed_nodes.is_empty() => {
            tracing::warn!(
                removed = ?report.removed_nodes,
                failed = ?report.failed_nodes,
                "removed stale iceoryx2 nodes of a failed case"
            );
        }
        Ok(_) => {}
        Err(error) => tracing::warn!(%error, "cannot check the benchmark domain for stale nodes"),
    }
}

pub(crate) fn kernel_release() -> String {
    std::fs::read_to_string("/proc/sys/kernel/osrelease")
        .map(|text| text.trim().to_owned())
        .unwrap_or_else(|_| "unknown".to_owned())
}

pub(crate) fn write_file(path: &Path, text: &str) -> Result<(), BenchError> {
    std::fs::write(path, text).map_err(|source| BenchError::WriteOutput {
        path: path.to_owned(),
        source,
    })
}
